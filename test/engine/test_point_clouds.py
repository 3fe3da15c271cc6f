"""Point clouds as obstacles (collision_sensor.engine.point_clouds, issue 29), against oracles.

* the self-filter against brute force: a point is removed exactly when it lies within
  ``self_filter_padding`` of the robot's triangles (trimesh's closest points) or inside one of
  its solids (trimesh's containment of the closed primitive meshes), at the cloud's state;
  points sampled on the robot's own surfaces with 2 mm noise are removed (>= 99.9 %) on the
  Panda, the UR5 and TIAGo and give no contact;
* contact verdicts against python-fcl on the kept voxels' boxes (fcl.Box against each link's
  BVH models, and its primitives, at pinocchio's poses), with and without link padding;
* distances: proximity to the cloud equals fcl's distance to the voxel boxes, and an object's
  cloud 5 cm from the hand gives ``min_distance`` within one voxel of the distance to the
  object itself;
* what a cloud can tell, both sides of the boundary: points within the padding are lost,
  points just beyond are kept and seen in the warning zone;
* NaN rows dropped; every update after clouds and motion equals a fresh checker's full check;
  a cloud's update re-checks its own pairs only.
"""
import math
import os

import fcl
import numpy as np
import pytest
import trimesh

from collision_sensor import CollisionChecker
from collision_sensor.engine.dynamic_scene import AddObject
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.errors import ConfigError, PointCloudError
from collision_sensor.model.mesh_loading import box_mesh, box_solid
from collision_sensor.model.scene import SceneObject
from engine_oracles import (
    FclOracle, surface_points, voxel_links_in_contact, voxel_manager, world_elements)

SOURCE = 'camera/points'
CLOUD = 'cloud/' + SOURCE


def _robot_files(erd_share, robot):
    base = os.path.join(erd_share, 'robots')
    return {
        'panda': (os.path.join(base, 'panda_description', 'urdf', 'panda.urdf'),
                  os.path.join(base, 'panda_description', 'srdf', 'panda.srdf')),
        'ur5': (os.path.join(base, 'ur_description', 'urdf', 'ur5_robot.urdf'),
                os.path.join(base, 'ur_description', 'srdf', 'ur5.srdf')),
        'tiago': (os.path.join(base, 'tiago_description', 'robots', 'tiago.urdf'), None),
    }[robot]


def _checker(erd_share, erd_package_paths, robot, **config):
    urdf, srdf = _robot_files(erd_share, robot)
    return CollisionChecker.from_urdf(urdf, srdf, package_paths=erd_package_paths,
                                      config=config or None), urdf


def _random_state(checker, rng):
    return random_configurations(checker, 1, int(rng.integers(1 << 30)))[0]


def _brute_force_removed(checker, points, padding, reach=np.inf):
    """(n,) bool: within ``padding`` of the robot's triangles or inside a solid of it, and
    (n,) the distance to the triangles (trimesh, all elements; those whose bounds are farther
    than ``reach`` from the points' bounds are skipped, their distances taken as inf)."""
    distance = np.full(len(points), np.inf)
    inside = np.zeros(len(points), dtype=bool)
    lo, hi = points.min(axis=0) - reach, points.max(axis=0) + reach
    for _, mesh, solid in world_elements(checker):
        if np.any(mesh.bounds[0] > hi) or np.any(mesh.bounds[1] < lo):
            continue
        _, d, _ = trimesh.proximity.closest_point(mesh, points)
        distance = np.minimum(distance, d)
        if solid:
            inside |= mesh.contains(points)
    return (distance <= padding) | inside, distance


def _kept_points(checker, points, q, **options):
    prepared = checker.prepare_points(SOURCE, points, positions=q, keep_points=True, **options)
    checker.commit_points(prepared)
    return prepared.kept.astype(np.float64), prepared.stats


def _cloud_pairs(pairs):
    return {a if b == CLOUD else b for a, b in pairs if CLOUD in (a, b)}


class VoxelOracle:
    """python-fcl on the kept voxels: one fcl.Box per voxel in a dynamic AABB tree, against
    each link's BVH models (and its solid primitives) at pinocchio's poses."""

    def __init__(self, checker, urdf):
        self.fcl = FclOracle(checker, urdf)
        self.checker = checker

    def links_in_contact(self, q, padding=0.0):
        centres, size = self.checker.cloud_voxels(SOURCE)
        return voxel_links_in_contact(self.fcl, q, centres, size,
                                      _cloud_pairs(self.checker.checked_pairs), padding)

    def distances(self, q):
        """{link: fcl's distance from the link's triangles to the nearest voxel box}."""
        centres, size = self.checker.cloud_voxels(SOURCE)
        poses = self.fcl.poses(q)
        manager, _ = voxel_manager(centres, size)
        out = {}
        for link in _cloud_pairs(self.checker.checked_pairs):
            T = poses[link]
            t = fcl.Transform(T[:3, :3], T[:3, 3])
            best = np.inf
            for model in self.fcl.models[link]:
                data = fcl.DistanceData()
                manager.distance(fcl.CollisionObject(model, t), data,
                                 fcl.defaultDistanceCallback)
                best = min(best, max(data.result.min_distance, 0.0))
            out[link] = best
        return out


@pytest.fixture(scope='module')
def panda(erd_share, erd_package_paths):
    return _checker(erd_share, erd_package_paths, 'panda')


# ---------------------------------------------------------------- the self-filter
@pytest.mark.parametrize('robot', ['panda', 'ur5', 'tiago'])
def test_own_surface_points_are_removed_and_never_in_contact(erd_share, erd_package_paths,
                                                             robot):
    checker, _ = _checker(erd_share, erd_package_paths, robot)
    rng = np.random.default_rng(29)
    for _ in range(3):
        q = _random_state(checker, rng)
        checker.check(q)
        points = surface_points(checker, rng, per_element=400 if robot == 'tiago' else 2000)
        voxels = checker.set_points(SOURCE, points, positions=q)
        stats = checker.point_cloud_stats(SOURCE)
        assert stats.points == len(points)
        assert stats.self_filtered >= 0.999 * len(points), (robot, stats)
        assert voxels == stats.voxels
        assert not _cloud_pairs(checker.update(q).colliding_pairs)
        assert not _cloud_pairs(checker.check(q).colliding_pairs)


@pytest.mark.slow
@pytest.mark.parametrize('padding', [0.0, 0.01, 0.02, 0.05])
def test_self_filter_equals_brute_force(erd_share, erd_package_paths, padding):
    checker, _ = _checker(erd_share, erd_package_paths, 'panda', self_filter_padding=padding)
    rng = np.random.default_rng(int(padding * 1000))
    for _ in range(2):
        q = _random_state(checker, rng)
        checker.check(q)
        # Points around the robot's surfaces, from inside its solids to beyond the padding.
        base = surface_points(checker, rng, per_element=150, noise=0.0)
        points = base + rng.normal(0.0, 0.03, base.shape)
        kept, stats = _kept_points(checker, points, q)
        removed, distance = _brute_force_removed(checker, points, padding)
        # Off the boundary (rounding): exactly the brute force's set.
        clear = np.abs(distance - padding) > 1e-6
        kept_set = {tuple(p) for p in np.round(kept, 5)}
        was_kept = np.array([tuple(p) in kept_set for p in np.round(
            points.astype(np.float32).astype(np.float64), 5)])
        assert not np.any(was_kept & removed & clear), points[was_kept & removed & clear][:3]
        assert not np.any(~was_kept & ~removed & clear), points[~was_kept & ~removed & clear][:3]
        assert stats.kept_points == len(kept)
        assert stats.self_filtered + stats.kept_points == len(points)


def test_attached_object_points_are_filtered(panda):
    checker, _ = panda
    rng = np.random.default_rng(3)
    q = _random_state(checker, rng)
    (vertices, faces), solid = box_mesh([0.06, 0.06, 0.06]), box_solid([0.06, 0.06, 0.06])
    T = np.eye(4)
    T[2, 3] = 0.15
    checker.apply_scene_changes([AddObject(SceneObject(
        name='held', source='test', T_world_object=T, vertices=vertices, faces=faces,
        solid=solid), attach_to='panda_hand', touch_links=('panda_leftfinger',
                                                           'panda_rightfinger'))])
    try:
        checker.check(q)
        T_world = checker.link_poses()['held']
        inside = rng.uniform(-0.03, 0.03, (2000, 3)) @ T_world[:3, :3].T + T_world[:3, 3]
        checker.set_points(SOURCE, inside, positions=q)
        assert checker.point_cloud_stats(SOURCE).self_filtered == len(inside)
        assert not _cloud_pairs(checker.update(q).colliding_pairs)
    finally:
        checker.clear_points(SOURCE)
        checker.remove_object('held')


# ---------------------------------------------------------------- against python-fcl
@pytest.mark.parametrize('filter_padding,padding', [(0.02, 0.0), (0.0, 0.0), (0.01, 0.01)])
def test_contact_equals_fcl_on_the_voxel_boxes(erd_share, erd_package_paths, filter_padding,
                                               padding):
    checker, urdf = _checker(erd_share, erd_package_paths, 'panda',
                             self_filter_padding=filter_padding, padding=padding)
    oracle = VoxelOracle(checker, urdf)
    rng = np.random.default_rng(7)
    contacts = 0
    for _ in range(6):
        q = _random_state(checker, rng)
        checker.check(q)
        base = surface_points(checker, rng, per_element=60, noise=0.0)
        points = base + rng.normal(0.0, 0.04, base.shape)
        checker.set_points(SOURCE, points, positions=q, persistence=0.0)
        engine = _cloud_pairs(checker.update(q).colliding_pairs)
        assert engine == _cloud_pairs(checker.check(q).colliding_pairs)
        expected = oracle.links_in_contact(q, padding)
        assert engine == expected, (q.tolist(), engine ^ expected)
        contacts += len(engine)
    assert contacts > 0   # the comparison saw contacts, not only their absence


def test_proximity_equals_fcl_distance_to_the_voxel_boxes(erd_share, erd_package_paths):
    """Each link's distance to the cloud is fcl's to the nearest voxel box (within fcl's GJK
    accuracy), and witnessed: ``point_a`` on the link's triangles, ``point_b`` in a voxel."""
    checker, urdf = _checker(erd_share, erd_package_paths, 'panda')
    oracle = VoxelOracle(checker, urdf)
    rng = np.random.default_rng(11)
    for _ in range(3):
        q = _random_state(checker, rng)
        checker.check(q)
        centre = checker.link_poses()['panda_hand'][:3, 3]
        points = centre + rng.uniform(-0.3, 0.3, (400, 3))
        checker.set_points(SOURCE, points, positions=q)
        records = {}
        for r in checker.proximity(q, math.inf):
            if CLOUD in (r.link_a, r.link_b):
                link, on_link, on_cloud = ((r.link_a, r.point_a, r.point_b) if r.link_b == CLOUD
                                           else (r.link_b, r.point_b, r.point_a))
                records[link] = (r.distance, on_link, on_cloud)
        truth = oracle.distances(q)
        centres, size = checker.cloud_voxels(SOURCE)
        elements = world_elements(checker)
        assert records.keys() == truth.keys()
        for link, d in truth.items():
            distance, on_link, on_cloud = records[link]
            assert distance == pytest.approx(d, abs=1e-4), link
            assert np.linalg.norm(on_link - on_cloud) == pytest.approx(distance, abs=1e-9)
            assert np.abs(centres - on_cloud).max(axis=1).min() <= 0.5 * size + 1e-9
            on_surface = min(trimesh.proximity.closest_point(mesh, on_link[None])[1][0]
                             for name, mesh, _ in elements if name == link)
            assert on_surface <= 1e-9


@pytest.mark.slow
@pytest.mark.parametrize('aligned', [True, False])
def test_object_cloud_near_the_hand_measures_min_distance_within_a_voxel(panda, aligned):
    """A plate 5 cm beyond the hand: ``min_distance`` to the cloud is never more than the
    distance to the plate's points (the voxels hold them), and less by at most a voxel's edge
    (plus the points' spacing) when the plate faces a world axis, its diagonal otherwise."""
    checker, _ = panda
    rng = np.random.default_rng(5 + aligned)
    size = checker.config.voxel_size
    spacing = 0.005
    for trial in range(3):
        q = _random_state(checker, rng)
        checker.check(q)
        hand = trimesh.util.concatenate([mesh for link, mesh, _ in world_elements(checker)
                                         if link == 'panda_hand'])
        if aligned:
            n = np.zeros(3)
            n[rng.integers(3)] = rng.choice([-1.0, 1.0])
        else:
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
        extent = (hand.vertices @ n).max()
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        s, t = np.meshgrid(np.arange(-0.1, 0.1 + 1e-9, spacing),
                           np.arange(-0.1, 0.1 + 1e-9, spacing))
        origin = hand.vertices.mean(axis=0)
        origin = origin + (extent + 0.05 - origin @ n) * n
        plate = origin + s.reshape(-1, 1) * u + t.reshape(-1, 1) * v
        checker.set_points(SOURCE, plate, positions=q)
        records = [r for r in checker.proximity(q, 0.5) if CLOUD in (r.link_a, r.link_b)]
        measured = min(r.distance for r in records)
        _, distance = _brute_force_removed(checker, plate, 0.0, reach=0.06)   # every link
        truth = distance.min()
        bound = size + spacing if aligned else math.sqrt(3.0) * size
        assert truth - bound <= measured <= truth + 1e-9, (trial, measured, truth)


# ---------------------------------------------------------------- what a cloud can tell
@pytest.mark.parametrize('gap,lost', [(0.005, True), (0.018, True), (0.024, False),
                                      (0.06, False)])
def test_padding_boundary_both_sides(panda, gap, lost):
    """A small plate of points parallel to a flat face of the base, ``gap`` from it: within the
    filter's padding (0.02) it is the robot's own (lost, no contact, not in the warning zone);
    beyond it, every point is kept and the warning zone sees it, nearer by at most a voxel."""
    checker, _ = panda
    r = checker.config.self_filter_padding
    size = checker.config.voxel_size
    q = np.zeros(len(checker.joint_names))
    checker.check(q)
    base = trimesh.util.concatenate([m for link, m, _ in world_elements(checker)
                                     if link == 'panda_link0'])
    # The largest face pointing along -x (away from the arm at q = 0).
    facing = np.flatnonzero(base.face_normals[:, 0] < -0.99)
    face = facing[np.argmax(base.area_faces[facing])]
    n = base.face_normals[face]
    p = base.triangles_center[face]
    ys, zs = np.meshgrid(np.linspace(-0.004, 0.004, 5), np.linspace(-0.004, 0.004, 5))
    plate = p + gap * n + np.column_stack([np.zeros(ys.size), ys.ravel(), zs.ravel()])
    _, distance = _brute_force_removed(checker, plate, r)
    assert np.allclose(distance, gap, atol=1e-3)
    checker.set_points(SOURCE, plate, positions=q)
    stats = checker.point_cloud_stats(SOURCE)
    result = checker.update(q)
    records = [rec for rec in checker.proximity(q, 0.5) if CLOUD in (rec.link_a, rec.link_b)]
    assert not _cloud_pairs(result.colliding_pairs) or not lost
    if lost:
        assert stats.kept_points == 0 and stats.voxels == 0
        assert not records
    else:
        assert stats.kept_points == len(plate)
        near = min(rec.distance for rec in records)
        assert distance.min() - math.sqrt(3.0) * size <= near <= distance.min() + 1e-9
    checker.clear_points(SOURCE)


# ---------------------------------------------------------------- input and state
def test_nan_rows_are_dropped(panda):
    checker, _ = panda
    rng = np.random.default_rng(2)
    q = _random_state(checker, rng)
    checker.check(q)
    points = checker.link_poses()['panda_hand'][:3, 3] + rng.uniform(-0.4, 0.4, (3000, 3))
    points = points.astype(np.float32)
    checker.set_points(SOURCE, points, positions=q)
    clean_voxels, _ = checker.cloud_voxels(SOURCE)
    clean = checker.point_cloud_stats(SOURCE)
    holes = points.copy()
    holes = np.insert(holes, rng.integers(0, len(holes), 500), np.nan, axis=0)
    holes[rng.integers(0, len(holes), 50), rng.integers(0, 3, 50)] = np.inf
    holes[rng.integers(0, len(holes), 50), rng.integers(0, 3, 50)] = -np.inf
    bad = ~np.all(np.isfinite(holes), axis=1)
    checker.set_points(SOURCE, holes, positions=q)
    stats = checker.point_cloud_stats(SOURCE)
    assert stats.invalid == bad.sum()
    assert stats.points == len(holes)
    expected = np.unique(np.floor(holes[~bad].astype(np.float64) / 0.02), axis=0)
    voxels, size = checker.cloud_voxels(SOURCE)
    got = np.unique(np.floor(voxels / size), axis=0)
    assert stats.voxels == len(voxels)
    # The kept voxels are those of the finite rows, less the robot's own.
    assert {tuple(v) for v in got} <= {tuple(v) for v in expected}
    # NaN rows inserted, finite rows damaged: what is left of the finite rows, no more.
    assert stats.kept_points <= clean.kept_points
    assert len(voxels) <= len(clean_voxels)
    checker.set_points(SOURCE, np.full((100, 3), np.nan), positions=q)
    assert checker.point_cloud_stats(SOURCE).voxels == 0
    assert not _cloud_pairs(checker.update(q).colliding_pairs)
    checker.clear_points(SOURCE)


def test_incremental_equals_fresh_full_check(erd_share, erd_package_paths):
    checker, urdf = _checker(erd_share, erd_package_paths, 'panda')
    rng = np.random.default_rng(13)
    sources = ['a', 'b']
    last = {}
    q = _random_state(checker, rng)
    for step in range(25):
        action = rng.integers(4)
        source = sources[rng.integers(2)]
        if action <= 1:
            checker.check(q) if step == 0 else None
            centre = checker.link_poses()['panda_link4'][:3, 3]
            points = centre + rng.uniform(-0.5, 0.5, (int(rng.integers(0, 800)), 3))
            checker.set_points(source, points, positions=q)
            last[source] = (points, q.copy())
        elif action == 2 and source in last:
            checker.clear_points(source)
            del last[source]
        else:
            q = q + rng.normal(0.0, 0.2, q.shape)
            q = np.clip(q, *sampling_bounds(checker))
        incremental = checker.update(q)
        fresh, _ = _checker(erd_share, erd_package_paths, 'panda')
        for name, (points, q_cloud) in last.items():
            fresh.set_points(name, points, positions=q_cloud)
        assert incremental.colliding_pairs == fresh.check(q).colliding_pairs, step
        assert incremental.colliding_pairs == checker.check(q).colliding_pairs, step


@pytest.mark.slow
@pytest.mark.parametrize('threads', [2, 3, 7])
def test_threads_give_the_cloud_of_one_thread(erd_share, erd_package_paths, threads):
    """The rows' first pass split over threads (chunks merged in order) gives what one thread
    gives, to the bit: voxels (and their order), stats, the points kept (in row order) and the
    verdicts; over clouds of 150,000 rows (chunks of >= 20,000: up to 7), the robot's own
    points among them, NaN runs, a voxel's points spread over every chunk, persistence, and
    points in a link's frame."""
    one, _ = _checker(erd_share, erd_package_paths, 'panda')
    many, _ = _checker(erd_share, erd_package_paths, 'panda')
    rng = np.random.default_rng(290 + threads)
    for step in range(4):
        q = _random_state(one, rng)
        one.check(q)
        own = surface_points(one, rng, per_element=1500)
        hand = one.link_poses()['panda_hand'][:3, 3]
        near = hand + rng.uniform(-0.3, 0.3, (60_000, 3))
        far = rng.uniform(-1.5, 1.5, (150_000 - len(own) - len(near), 3))
        points = np.concatenate([own, near, far])
        points = points[rng.permutation(len(points))].astype(np.float32)
        for start in rng.integers(0, len(points) - 2000, 20):      # holes, as a camera's
            points[start:start + int(rng.integers(1, 2000))] = np.nan
        frame = None
        if step == 3:   # in the hand's frame
            T = one.link_poses()['panda_hand']
            points = ((points - T[:3, 3]) @ T[:3, :3]).astype(np.float32)
            frame = 'panda_hand'
        options = dict(positions=q, stamp=float(step), persistence=1.5 if step else 0.0)
        a = one.prepare_points(SOURCE, points, frame, keep_points=True, threads=1, **options)
        b = many.prepare_points(SOURCE, points, frame, keep_points=True, threads=threads,
                                **options)
        assert a.stats == b.stats, step
        assert a.stats.self_filtered > 0 and a.stats.invalid > 0
        assert np.array_equal(a.kept, b.kept), step
        one.commit_points(a)
        many.commit_points(b)
        (centres_a, size), (centres_b, _) = one.cloud_voxels(SOURCE), many.cloud_voxels(SOURCE)
        assert np.array_equal(centres_a, centres_b), step
        assert one.update(q).colliding_pairs == many.update(q).colliding_pairs, step
        near_a, near_b = one.proximity(q, 0.1), many.proximity(q, 0.1)
        assert [(r.link_a, r.link_b, r.distance) for r in near_a] == \
            [(r.link_a, r.link_b, r.distance) for r in near_b], step
        for r, t in zip(near_a, near_b):
            assert np.array_equal(r.point_a, t.point_a) and np.array_equal(r.point_b, t.point_b)
    assert a.stats.persisted > 0


@pytest.fixture(scope='module')
def camera_clouds():
    """Scenario 12's cell (a Panda on a table beside a wall, a box nobody modelled) seen by
    its 640 x 480 depth camera at three random states: (q, (307200, 3) float32 world cloud)."""
    from collision_sensor.engine.sampling import random_configurations
    from benchmarks import scenario_clouds
    from benchmarks.scenario_cells import robot_cell
    from collision_sensor.tools.depth_camera import DepthCamera
    cell = robot_cell('panda')
    world = cell.checker()
    world.apply_scene_changes(scenario_clouds.cell_changes('bench'))
    states = random_configurations(world, 3, 2929)
    return cell, scenario_clouds.clouds(world, DepthCamera(noise=0.002),
                                        scenario_clouds.CAMERA_POSE, states, 2929)


@pytest.mark.parametrize('threads', [2, 3, 7])
def test_threads_give_the_camera_cloud_of_one_thread(camera_clouds, threads):
    """A real camera's clouds of the Panda (about 1,700 voxels near the robot, 45,000
    voxel-triangle candidates: the candidates are collected on up to 6 threads, the near
    voxels classified on up to 4) give on any number of threads what one thread gives, to the
    bit: stats, the points kept (row order), the voxels (their order), the links in contact,
    the distances and witness points (min_distance) and the verdicts of the pairs."""
    cell, clouds = camera_clouds
    one, many = cell.checker(), cell.checker()
    for step, (q, cloud) in enumerate(clouds):
        options = dict(positions=q, stamp=float(step), persistence=0.5 if step else 0.0)
        a = one.prepare_points(SOURCE, cloud, keep_points=True, threads=1, **options)
        b = many.prepare_points(SOURCE, cloud, keep_points=True, threads=threads, **options)
        assert a.stats == b.stats, step
        assert a.stats.self_filtered > 1000 and a.stats.kept_points > 100_000, a.stats
        assert np.array_equal(a.kept, b.kept), step
        one.commit_points(a)
        many.commit_points(b)
        (centres_a, size), (centres_b, _) = one.cloud_voxels(SOURCE), many.cloud_voxels(SOURCE)
        assert np.array_equal(centres_a, centres_b), step
        result_a, result_b = one.update(q), many.update(q)
        assert result_a.colliding_pairs == result_b.colliding_pairs, step
        assert sorted(one.checked_pairs) == sorted(many.checked_pairs)
        near_a, near_b = one.proximity(q, 0.1), many.proximity(q, 0.1)
        assert any(CLOUD in (r.link_a, r.link_b) for r in near_a), step
        assert [(r.link_a, r.link_b, r.distance) for r in near_a] == \
            [(r.link_a, r.link_b, r.distance) for r in near_b], step
        for r, t in zip(near_a, near_b):
            assert np.array_equal(r.point_a, t.point_a) and np.array_equal(r.point_b, t.point_b)


def test_a_cloud_rechecks_only_its_pairs(panda):
    checker, _ = panda
    rng = np.random.default_rng(17)
    q = _random_state(checker, rng)
    checker.check(q)
    points = checker.link_poses()['panda_hand'][:3, 3] + rng.uniform(-0.3, 0.3, (500, 3))
    checker.set_points(SOURCE, points, positions=q)
    checker.update(q)
    cloud_pairs = [p for p in checker.checked_pairs if CLOUD in p]
    assert cloud_pairs
    assert checker.update(q).rechecked_pairs == 0
    checker.set_points(SOURCE, points + 0.01, positions=q)
    result = checker.update(q)
    assert 0 < result.rechecked_pairs <= len(cloud_pairs)
    checker.clear_points(SOURCE)
    assert CLOUD not in checker.scene_object_names
    assert not [p for p in checker.checked_pairs if CLOUD in p]


def test_bad_input_and_config(panda):
    checker, _ = panda
    with pytest.raises(PointCloudError, match='frame "nowhere"'):
        checker.set_points(SOURCE, np.zeros((3, 3)), 'nowhere')
    with pytest.raises(PointCloudError) as error:      # a frame from the graph: escaped
        checker.set_points(SOURCE, np.zeros((3, 3)), 'cam\x1b[2J\nWARN fake' + 'x' * 5000)
    assert error.value.args[0].isprintable() and len(str(error.value)) < 1000
    with pytest.raises(PointCloudError, match='shape'):
        checker.set_points(SOURCE, np.zeros((3, 4)))
    with pytest.raises(PointCloudError, match='source'):
        checker.set_points('', np.zeros((3, 3)))
    for threads in (-1, 257, 1.5, True):
        with pytest.raises(PointCloudError, match='threads'):
            checker.set_points(SOURCE, np.zeros((3, 3)), threads=threads)
    assert CLOUD not in checker.scene_object_names
    for key, value in [('voxel_size', 0.0), ('voxel_size', 2.0), ('self_filter_padding', -0.1),
                       ('max_points', 0), ('max_points', 1.5)]:
        with pytest.raises(ConfigError, match=key):
            CollisionChecker(checker.model, config={key: value})


def test_max_points_caps_and_counts(erd_share, erd_package_paths):
    checker, _ = _checker(erd_share, erd_package_paths, 'panda', max_points=1000)
    points = np.random.default_rng(1).uniform(2.0, 3.0, (10_000, 3))
    checker.set_points(SOURCE, points)
    stats = checker.point_cloud_stats(SOURCE)
    assert stats.capped == 9000 and stats.kept_points == 1000


def test_points_in_a_link_frame(panda):
    """A cloud given in a link's frame (a wrist camera's) is the same obstacle as the same
    points given in the world."""
    checker, _ = panda
    rng = np.random.default_rng(23)
    q = _random_state(checker, rng)
    checker.check(q)
    T = checker.link_poses()['panda_link7']
    world = T[:3, 3] + rng.uniform(-0.5, 0.5, (2000, 3))
    checker.set_points(SOURCE, world, positions=q)
    in_world = checker.cloud_voxels(SOURCE)[0]
    local = (world - T[:3, 3]) @ T[:3, :3]
    checker.set_points(SOURCE, local, 'panda_link7', positions=q)
    in_link = checker.cloud_voxels(SOURCE)[0]
    # Voxels of points within rounding of a voxel face may differ; nearly all agree.
    a = {tuple(v) for v in np.round(in_world, 4)}
    b = {tuple(v) for v in np.round(in_link, 4)}
    assert len(a ^ b) <= 0.01 * len(a)
    checker.clear_points(SOURCE)


def test_a_cloud_is_named_a_cloud_after_scene_changes(panda):
    """The checker knows its clouds as clouds after any scene change (a regression: the
    layout's views once replaced the cloud's block, and the checker lost track of them)."""
    checker, _ = panda
    checker.set_points(SOURCE, np.random.default_rng(0).uniform(1.0, 2.0, (100, 3)))
    (vertices, faces), solid = box_mesh([0.1, 0.1, 0.1]), box_solid([0.1, 0.1, 0.1])
    checker.apply_scene_changes([AddObject(SceneObject(
        name='crate', source='test', T_world_object=np.eye(4), vertices=vertices, faces=faces,
        solid=solid))])
    try:
        assert checker.point_cloud_sources == (SOURCE,)
        assert CLOUD not in [obj.name for obj in checker.scene_objects]
        with pytest.raises(Exception, match='point cloud'):
            checker.move_object(CLOUD, np.eye(4))
    finally:
        checker.remove_object('crate')
        checker.clear_points(SOURCE)
    assert checker.point_cloud_sources == ()
