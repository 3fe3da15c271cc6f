"""The simulated depth camera (collision_sensor.tools.depth_camera, cpp/ray_cast.hpp): rays
cast against the checker's trees equal trimesh's ray-triangle intersections on the same robot's
world meshes, and the organised cloud it renders is the robot's own surface (the self-filter
removes it)."""
import math
import os

import numpy as np
import trimesh

from collision_sensor import CollisionChecker
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.tools.depth_camera import DepthCamera, look_at


def _panda(erd_share, erd_package_paths):
    base = os.path.join(erd_share, 'robots', 'panda_description')
    return CollisionChecker.from_urdf(os.path.join(base, 'urdf', 'panda.urdf'),
                                      os.path.join(base, 'srdf', 'panda.srdf'),
                                      package_paths=erd_package_paths)


def _world_mesh(checker):
    poses = checker.link_poses()
    meshes = []
    for element in checker.model.elements:
        T = poses[element.link] @ element.T_link_element
        meshes.append(trimesh.Trimesh(element.vertices @ T[:3, :3].T + T[:3, 3], element.faces,
                                      process=False))
    return trimesh.util.concatenate(meshes)


def test_rays_equal_trimesh(erd_share, erd_package_paths):
    checker = _panda(erd_share, erd_package_paths)
    rng = np.random.default_rng(4)
    for q in random_configurations(checker, 3, 4):
        checker.check(q)
        mesh = _world_mesh(checker)
        origin = rng.normal(size=3)
        origin = 1.5 * origin / np.linalg.norm(origin) + [0.0, 0.0, 0.5]
        targets = mesh.sample(500, seed=int(rng.integers(1 << 30))) + rng.normal(0, 0.05, (500, 3))
        directions = targets - origin
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        t = checker.cast_rays(origin, directions, 10.0)
        locations, ray_index, _ = trimesh.ray.ray_triangle.RayMeshIntersector(
            mesh).intersects_location(np.tile(origin, (500, 1)), directions, multiple_hits=True)
        truth = np.full(500, np.inf)
        hits = np.linalg.norm(locations - origin, axis=1)
        np.minimum.at(truth, ray_index, hits)
        both = np.isfinite(t) & np.isfinite(truth)
        agree = (np.isfinite(t) == np.isfinite(truth))
        assert agree.mean() >= 0.995, agree.mean()   # grazing rays at shared edges may differ
        assert both.sum() > 100
        np.testing.assert_allclose(t[both], truth[both], atol=1e-6)
        assert np.isinf(checker.cast_rays(origin, directions, 0.01)).all()


def test_rendered_robot_is_its_own(erd_share, erd_package_paths):
    checker = _panda(erd_share, erd_package_paths)
    q = random_configurations(checker, 1, 9)[0]
    checker.check(q)
    camera = DepthCamera(width=64, height=48, fov=math.radians(60.0), noise=0.002)
    T = look_at([1.2, 0.8, 0.9], [0.0, 0.0, 0.4])
    points = camera.points(checker, T, np.random.default_rng(0))
    assert points.shape == (64 * 48, 3) and points.dtype == np.float32
    seen = np.isfinite(points).all(axis=1)
    assert 50 < seen.sum() < len(points)      # the robot and holes around it
    world = points[seen].astype(np.float64) @ T[:3, :3].T + T[:3, 3]
    checker.set_points('camera', world, positions=q)
    stats = checker.point_cloud_stats('camera')
    assert stats.self_filtered >= 0.999 * seen.sum()
