"""The demo's depth camera (collision_sensor.tools.demo_camera, ``collision_sensor_demo
--camera``): the camera is a link of the demo arm's URDF, it sees the arm and the person the
scene file does not hold, and the sensor's self-filter removes exactly the rendered points
within its padding of the arm. Oracles: yourdfpy for the arm's poses, trimesh for the distance
of each rendered point to the arm's meshes, python-fcl for the arm against the person.
"""
import os

import fcl
import numpy as np
import pytest
import trimesh
import yourdfpy

from collision_sensor import CollisionChecker
from collision_sensor.model.sequences import read_sequence
from collision_sensor.tools.demo_camera import CameraCell
from scripts import demo_cell

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIG = os.path.join(ROOT, 'config')
URDF, SRDF = os.path.join(CONFIG, 'demo_arm.urdf'), os.path.join(CONFIG, 'demo_arm.srdf')


def _resolve(uri):
    return os.path.join(ROOT, uri[len('package://collision_sensor/'):])


class ArmOracle:
    """The arm read from its files: yourdfpy's poses, trimesh meshes, fcl BVH models."""

    def __init__(self):
        self.robot = yourdfpy.URDF.load(URDF, filename_handler=_resolve, load_meshes=False,
                                        build_collision_scene_graph=False)
        self.meshes = {}
        for link in self.robot.robot.links:
            for collision in link.collisions:
                self.meshes[link.name] = trimesh.load(_resolve(collision.geometry.mesh.filename),
                                                      force='mesh')

    def posed(self, joint_names, q):
        """{link: mesh in the world} at ``q``."""
        self.robot.update_cfg(dict(zip(joint_names, q)))
        return {link: mesh.copy().apply_transform(self.robot.get_transform(link))
                for link, mesh in self.meshes.items()}

    def distance_to_arm(self, meshes, points):
        """(n,) distance of each point to the nearest arm surface (far points: > 0.1 m)."""
        distance = np.full(len(points), np.inf)
        for mesh in meshes.values():
            low, high = mesh.bounds
            near = np.flatnonzero(np.all((points > low - 0.1) & (points < high + 0.1), axis=1))
            if len(near):
                _, d, _ = trimesh.proximity.closest_point(mesh, points[near])
                distance[near] = np.minimum(distance[near], d)
        return distance

    def distance_to_person(self, meshes):
        """{link: python-fcl distance to the person (0 in contact)}."""
        radius, height = demo_cell.PERSON
        T = demo_cell.person_pose()
        person = fcl.CollisionObject(fcl.Cylinder(radius, height),
                                     fcl.Transform(T[:3, :3], T[:3, 3]))
        out = {}
        for link, mesh in meshes.items():
            model = fcl.BVHModel()
            model.beginModel(len(mesh.vertices), len(mesh.faces))
            model.addSubModel(np.asarray(mesh.vertices, dtype=np.float64),
                              np.asarray(mesh.faces, dtype=np.int32))
            model.endModel()
            obj = fcl.CollisionObject(model, fcl.Transform())
            if fcl.collide(obj, person, fcl.CollisionRequest(), fcl.CollisionResult()):
                out[link] = 0.0
            else:
                out[link] = max(0.0, fcl.distance(obj, person, fcl.DistanceRequest(),
                                                  fcl.DistanceResult()))
        return out


@pytest.fixture(scope='module')
def oracle():
    return ArmOracle()


@pytest.fixture(scope='module')
def cell():
    return CameraCell()


def test_the_camera_is_a_fixed_link_of_the_urdf_where_the_demo_says(oracle, cell):
    T = oracle.robot.get_transform(demo_cell.CAMERA_OPTICAL_FRAME)
    np.testing.assert_allclose(T, cell.T_world_camera, atol=1e-9)
    np.testing.assert_allclose(T[:3, 3], demo_cell.CAMERA_EYE, atol=1e-9)
    view = np.asarray(demo_cell.CAMERA_TARGET) - demo_cell.CAMERA_EYE
    assert np.dot(T[:3, 2], view / np.linalg.norm(view)) > 1.0 - 1e-9     # z along the view
    assert T[2, 1] < 0.0                                    # y down in the picture
    assert demo_cell.CAMERA_OPTICAL_FRAME not in {e.link for e in cell.world.model.elements}


@pytest.mark.parametrize('t', [2.0, 3.3])    # stretched out, away; the tool in the person
def test_the_self_filter_removes_the_rendered_arm_and_only_what_is_near_it(oracle, cell, t):
    seq = demo_cell.person_in_path()
    q = seq.positions[int(np.searchsorted(seq.times, t))]
    points = cell.render(seq.joint_names, q)
    valid = points[np.isfinite(points).all(axis=1)].astype(np.float64)
    T = cell.T_world_camera
    world = valid @ T[:3, :3].T + T[:3, 3]
    meshes = oracle.posed(seq.joint_names, q)
    distance = oracle.distance_to_arm(meshes, world)
    on_arm = distance < 1e-3
    assert on_arm.sum() > 300, 'the camera should see the arm'
    person = oracle.distance_to_person(meshes)
    assert (min(person.values()) == 0.0) == (t > 3.0)

    sensor = CollisionChecker.from_urdf(URDF, srdf=SRDF)
    padding = sensor.config.self_filter_padding
    prepared = sensor.prepare_points('camera', points, demo_cell.CAMERA_OPTICAL_FRAME,
                                     positions=dict(zip(seq.joint_names, q)), keep_points=True)
    kept = prepared.kept.astype(np.float64)
    # Every point the camera saw on the arm is gone, and every kept point is beyond the
    # padding (float32 points: 1 um of slack).
    assert len(kept) and oracle.distance_to_arm(meshes, kept).min() >= padding - 1e-6
    # Nothing else is removed: the kept points are those beyond the padding.
    beyond = distance > padding + 1e-6
    boundary = np.abs(distance - padding) <= 1e-6
    assert beyond.sum() <= len(kept) <= beyond.sum() + boundary.sum()
    assert prepared.stats.self_filtered == len(valid) - len(kept)


@pytest.mark.slow
def test_the_person_is_in_no_scene_file_and_the_sequence_reaches_it_only_mid_way(oracle, cell):
    with open(os.path.join(CONFIG, 'demo_scene.yaml')) as stream:
        assert demo_cell.PERSON_NAME not in stream.read()
    # The camera's world holds the person the generator placed, as a cylinder of its size.
    assert cell.person_names == {demo_cell.PERSON_NAME}
    person = cell.world.link_poses()[demo_cell.PERSON_NAME]
    np.testing.assert_allclose(person, demo_cell.person_pose(), atol=1e-12)
    # The sequence the demo plays is the one designed here (bundled as a file).
    seq = read_sequence(os.path.join(CONFIG, 'sequences', 'person_in_path.csv'))
    designed = demo_cell.person_in_path()
    assert seq.joint_names == designed.joint_names
    np.testing.assert_array_equal(seq.positions, designed.positions)
    touching = [i for i in range(0, len(seq), 5)
                if min(oracle.distance_to_person(oracle.posed(seq.joint_names,
                                                              seq.positions[i])).values()) == 0]
    assert touching and seq.times[touching[0]] > 1.0 and seq.times[touching[-1]] < 6.0
