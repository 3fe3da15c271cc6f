"""The bundled demo cell: meshes, descriptions, determinism, and what each sequence shows.

The sequences are verified here with an oracle that shares nothing with the engine:
yourdfpy for the kinematics, trimesh for reading the files, python-fcl for the answers.
"""
import filecmp
import itertools
import os
import xml.etree.ElementTree as ET

import fcl
import numpy as np
import pytest
import trimesh
import yaml
import yourdfpy

from collision_sensor.model.sequences import read_sequence
from scripts import demo_cell

# The committed files of this checkout (also under colcon test, which imports the installed
# package: the generator's default output is then not this tree).
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIG = os.path.join(ROOT, 'config')
MESHES = os.path.join(ROOT, 'meshes', 'demo_cell')
ARM_URDF = os.path.join(CONFIG, 'demo_arm.urdf')
ARM_SRDF = os.path.join(CONFIG, 'demo_arm.srdf')
SCARA_URDF = os.path.join(CONFIG, 'scara.urdf')
SCENE = os.path.join(CONFIG, 'demo_scene.yaml')
WASHER = ('washer_cabinet', 'washer_drum', 'washer_door')


def _resolve(uri: str) -> str:
    prefix = 'package://collision_sensor/'
    assert uri.startswith(prefix), uri
    return os.path.join(ROOT, uri[len(prefix):])


def _mesh_uris(urdf_path):
    """Return {link: [mesh URI, ...]} of the collision elements."""
    root = ET.parse(urdf_path).getroot()
    return {link.get('name'): [mesh.get('filename')
                               for mesh in link.findall('collision/geometry/mesh')]
            for link in root.findall('link')}


class FclCell:
    """Colliding pairs of a URDF robot and a scene YAML by python-fcl, read from the files.

    :ivar pairs: every robot-robot pair not disabled in the SRDF, and every link-object pair.
    """

    def __init__(self, urdf=ARM_URDF, srdf=ARM_SRDF, scene=SCENE):
        self.robot = yourdfpy.URDF.load(urdf, filename_handler=_resolve, load_meshes=False,
                                        build_collision_scene_graph=False)
        self.joint_names = tuple(self.robot.actuated_joint_names)
        self.elements = {}   # body -> [(bvh, T_body_element, mesh)]
        for link in self.robot.robot.links:
            for collision in link.collisions:
                mesh = trimesh.load(_resolve(collision.geometry.mesh.filename), force='mesh')
                T = collision.origin if collision.origin is not None else np.eye(4)
                self.elements.setdefault(link.name, []).append((self._bvh(mesh), T, mesh))
        self.links = sorted(self.elements)
        disabled = set()
        if srdf:
            for entry in ET.parse(srdf).getroot().iter('disable_collisions'):
                disabled.add(tuple(sorted((entry.get('link1'), entry.get('link2')))))
        self.pairs = [p for p in itertools.combinations(self.links, 2) if p not in disabled]
        self.T_world_object = {}
        for obj in yaml.safe_load(open(scene))['objects'] if scene else ():
            pose = obj.get('pose', {})
            T = trimesh.transformations.euler_matrix(*pose.get('rpy', (0, 0, 0)), 'sxyz')
            T[:3, 3] = pose.get('xyz', (0, 0, 0))
            if 'mesh' in obj:
                mesh = trimesh.load(os.path.join(os.path.dirname(scene),
                                                 obj['mesh']['filename']), force='mesh')
            else:
                mesh = trimesh.creation.box(obj['box']['size'])
            self.elements[obj['name']] = [(self._bvh(mesh), np.eye(4), mesh)]
            self.T_world_object[obj['name']] = T
            self.pairs += [tuple(sorted((link, obj['name']))) for link in self.links]
        self._boxes = {}

    @staticmethod
    def _bvh(mesh):
        model = fcl.BVHModel()
        model.beginModel(len(mesh.vertices), len(mesh.faces))
        model.addSubModel(np.asarray(mesh.vertices, dtype=np.float64),
                          np.asarray(mesh.faces, dtype=np.int32))
        model.endModel()
        return model

    def poses(self, q):
        """Return {body: T_world_body (4, 4)} for joint positions ``q`` (joint_names order)."""
        self.robot.update_cfg(dict(zip(self.joint_names, q)))
        poses = {link: self.robot.get_transform(link) for link in self.links}
        poses.update(self.T_world_object)
        return poses

    def _objects(self, q, geometry):
        out = {}
        for body, T_world_body in self.poses(q).items():
            out[body] = []
            for index, (bvh, T_body_element, mesh) in enumerate(self.elements[body]):
                shape, T_element_shape = geometry(body, index, bvh, mesh)
                T = T_world_body @ T_body_element @ T_element_shape
                out[body].append(fcl.CollisionObject(shape, fcl.Transform(T[:3, :3], T[:3, 3])))
        return out

    def _hits(self, objects, pairs):
        hits = []
        for a, b in pairs:
            if any(fcl.collide(x, y, fcl.CollisionRequest(), fcl.CollisionResult())
                   for x in objects[a] for y in objects[b]):
                hits.append((a, b))
        return tuple(sorted(hits))

    def colliding_pairs(self, q, pairs=None):
        """Return the sorted pairs whose triangles intersect."""
        objects = self._objects(q, lambda body, i, bvh, mesh: (bvh, np.eye(4)))
        return self._hits(objects, pairs or self.pairs)

    def box_level_pairs(self, q, pairs=None):
        """Return the pairs whose elements' oriented boxes (PCA and minimal) both overlap."""
        def box(body, index, bvh, mesh, method):
            key = (body, index, method)
            if key not in self._boxes:
                if method == 'minimal':
                    T_box_mesh, extents = trimesh.bounds.oriented_bounds(mesh)
                    self._boxes[key] = (fcl.Box(*extents), np.linalg.inv(T_box_mesh))
                else:
                    centre = mesh.vertices.mean(axis=0)
                    _, axes = np.linalg.eigh(np.cov((mesh.vertices - centre).T))
                    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
                    local = (mesh.vertices - centre) @ axes
                    low, high = local.min(axis=0), local.max(axis=0)
                    T = np.eye(4)
                    T[:3, :3] = axes
                    T[:3, 3] = centre + axes @ ((low + high) / 2.0)
                    self._boxes[key] = (fcl.Box(*(high - low)), T)
            return self._boxes[key]
        hits = None
        for method in ('pca', 'minimal'):
            objects = self._objects(q, lambda b, i, bvh, m: box(b, i, bvh, m, method))
            found = set(self._hits(objects, pairs or self.pairs))
            hits = found if hits is None else hits & found
        return tuple(sorted(hits))


@pytest.fixture(scope='module')
def cell():
    return FclCell()


def _stretches(flags):
    """Return [(first, last)] index runs where ``flags`` is true."""
    runs = []
    for index, flag in enumerate(flags):
        if flag and runs and runs[-1][1] == index - 1:
            runs[-1][1] = index
        elif flag:
            runs.append([index, index])
    return [tuple(run) for run in runs]


# --- meshes and descriptions -------------------------------------------------------------------

def _stl_files():
    return sorted(name for name in os.listdir(MESHES) if name.endswith('.stl'))


def test_every_mesh_is_watertight_binary_stl_with_consistent_winding():
    assert len(_stl_files()) == len(demo_cell.all_meshes())
    for name in _stl_files():
        path = os.path.join(MESHES, name)
        with open(path, 'rb') as stream:
            assert stream.read(5) != b'solid', f'{name} is not binary STL'
        mesh = trimesh.load(path, force='mesh')
        assert mesh.is_watertight, name
        assert mesh.is_winding_consistent, name
        assert mesh.volume > 0.0, f'{name} is wound inwards'


def _triangles(uris):
    return sum(len(trimesh.load(_resolve(uri), force='mesh').faces) for uri in uris)


def test_triangle_counts_match_the_papers_application():
    arm = _triangles(uri for uris in _mesh_uris(ARM_URDF).values() for uri in uris)
    washer = sum(len(trimesh.load(os.path.join(MESHES, f'{name}.stl'), force='mesh').faces)
                 for name in WASHER)
    assert arm > 2000
    assert washer > 3000


def test_arm_has_six_limited_joints_and_a_mesh_per_link():
    """Six revolute joints with limits, a mesh per arm link; the camera's two links (on fixed
    joints, for ``collision_sensor_demo --camera``) have no collision geometry."""
    robot = yourdfpy.URDF.load(ARM_URDF, filename_handler=_resolve, load_meshes=False)
    assert tuple(robot.actuated_joint_names) == demo_cell.ARM_JOINT_NAMES
    camera = (demo_cell.CAMERA_LINK, demo_cell.CAMERA_OPTICAL_FRAME)
    for joint in robot.robot.joints:
        if joint.child in camera:
            assert joint.type == 'fixed', joint.name
            continue
        assert joint.type == 'revolute'
        assert joint.limit.lower < 0.0 < joint.limit.upper
        assert joint.limit.upper - joint.limit.lower <= 2.0 * np.pi
    uris = _mesh_uris(ARM_URDF)
    assert sorted(uris) == sorted(demo_cell.ARM_LINKS + camera)
    for link in camera:
        assert uris[link] == [], link
    for link in demo_cell.ARM_LINKS:
        assert len(uris[link]) == 1 and os.path.isfile(_resolve(uris[link][0])), link


def test_scara_links_are_split_into_several_elements():
    uris = _mesh_uris(SCARA_URDF)
    assert len(uris) == 5
    for link, link_uris in uris.items():
        assert len(link_uris) >= 2, link
        assert all(os.path.isfile(_resolve(uri)) for uri in link_uris)


def test_scara_is_clear_of_itself_over_its_range():
    scara = FclCell(SCARA_URDF, srdf=None, scene=None)
    parent_of = {joint.child: joint.parent for joint in scara.robot.robot.joints}
    pairs = [(a, b) for a, b in scara.pairs if parent_of.get(a) != b and parent_of.get(b) != a]
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = [rng.uniform(j.limit.lower, j.limit.upper) for j in scara.robot.robot.joints]
        assert scara.colliding_pairs(q, pairs) == ()


def test_scene_names_the_washer_parts_and_the_floor():
    objects = yaml.safe_load(open(SCENE))['objects']
    assert [obj['name'] for obj in objects] == list(WASHER) + ['floor']
    for obj in objects[:3]:
        assert os.path.isfile(os.path.join(CONFIG, obj['mesh']['filename']))


def test_scene_loads_with_the_package_loader():
    scene = pytest.importorskip('collision_sensor.model.scene')
    objects = scene.load_scene(SCENE)
    assert [obj.name for obj in objects] == list(WASHER) + ['floor']


def test_generator_rewrites_the_committed_files_byte_for_byte(tmp_path):
    written = demo_cell.generate(str(tmp_path))
    assert written
    for path in written:
        relative = os.path.relpath(path, tmp_path)
        committed = os.path.join(ROOT, relative)
        assert os.path.isfile(committed), f'{relative} is generated but not committed'
        assert filecmp.cmp(path, committed, shallow=False), f'{relative} differs'
    generated_meshes = sorted(os.listdir(tmp_path / 'meshes' / 'demo_cell'))
    assert generated_meshes == _stl_files()


# --- the arm in its cell -----------------------------------------------------------------------

def test_home_pose_is_clear_and_the_base_sits_just_above_the_floor(cell):
    home = np.zeros(6)
    assert cell.colliding_pairs(home) == ()
    objects = cell._objects(home, lambda body, i, bvh, mesh: (bvh, np.eye(4)))
    gap = fcl.distance(objects['base_link'][0], objects['floor'][0], fcl.DistanceRequest(),
                       fcl.DistanceResult())
    assert 0.0 < gap <= 0.005


def test_paper_experiment_drives_the_arm_into_the_machine(cell):
    seq = read_sequence(os.path.join(CONFIG, 'sequences', 'paper_experiment.csv'),
                        joint_names=cell.joint_names)
    answers = [cell.colliding_pairs(q) for q in seq.positions]
    runs = _stretches([bool(pairs) for pairs in answers])
    assert not answers[0] and not answers[-1]
    assert len(runs) == 2 and all(last - first >= 20 for first, last in runs)
    touched = {body for pairs in answers for pair in pairs for body in pair}
    assert {'washer_cabinet', 'washer_drum', 'tool_link'} <= touched
    assert 'floor' not in touched


def test_into_drum_clear_is_clear_yet_in_contact_at_box_level(cell):
    seq = read_sequence(os.path.join(CONFIG, 'sequences', 'into_drum_clear.csv'),
                        joint_names=cell.joint_names)
    assert all(cell.colliding_pairs(q) == () for q in seq.positions)
    deepest = int(np.argmax(seq.positions[:, 1]))      # shoulder_lift highest: furthest in
    boxes = cell.box_level_pairs(seq.positions[deepest])
    assert {('tool_link', 'washer_drum'), ('tool_link', 'washer_cabinet')} <= set(boxes)
    in_box_contact = sum(bool(cell.box_level_pairs(q)) for q in seq.positions[::10])
    assert in_box_contact >= len(seq.positions[::10]) // 3


def test_random_sequence_stays_within_the_joint_limits():
    seq = read_sequence(os.path.join(CONFIG, 'sequences', 'random.csv'))
    lower = np.array([joint[5][0] for joint in demo_cell.ARM_JOINTS])
    upper = np.array([joint[5][1] for joint in demo_cell.ARM_JOINTS])
    assert seq.joint_names == demo_cell.ARM_JOINT_NAMES
    assert np.all(seq.positions >= lower) and np.all(seq.positions <= upper)
    steps = np.abs(np.diff(seq.positions, axis=0)).max(axis=1)
    assert np.median(steps) > 1.0    # no coherence between frames


def test_bundled_bag_holds_the_paper_experiment():
    bag = read_sequence(os.path.join(CONFIG, 'sequences', 'paper_experiment'))
    csv = read_sequence(os.path.join(CONFIG, 'sequences', 'paper_experiment.csv'))
    assert bag == csv
