"""Proximity (cpp/distance.hpp, CollisionChecker.proximity) against python-fcl and brute force.

Triangle distances and whole-robot pair distances are checked against ``fcl.distance`` on the
same triangles (BVH models built from the checker's loaded meshes, placed by pinocchio's
kinematics: see engine_oracles.FclOracle); nearest points are checked to lie on their bodies'
surfaces and to be ``distance`` apart; colliding pairs against ``check``.
"""
import math

import fcl
import numpy as np
import pytest

from collision_sensor.engine.checker import CollisionChecker, ProximityRecord
from collision_sensor.engine.sampling import random_configurations
from engine_kernels import triangle_distance
from engine_oracles import FclOracle, distance_to_body

N_CONFIGURATIONS = 150
#: Distances agree with FCL's to this (m).
FCL_TOLERANCE = 1e-6
SCENE = {'objects': [
    {'name': 'table', 'box': {'size': [0.8, 1.2, 0.04]},
     'pose': {'xyz': [0.55, 0.0, 0.3], 'rpy': [0.1, 0.0, 0.2]}},
    {'name': 'post', 'cylinder': {'radius': 0.05, 'length': 0.6},
     'pose': {'xyz': [0.0, 0.45, 0.4]}},
    {'name': 'ball', 'sphere': {'radius': 0.12}, 'pose': {'xyz': [0.3, -0.3, 0.7]}},
]}


@pytest.fixture(scope='module')
def panda(panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    return checker, FclOracle(checker, panda_urdf)


@pytest.fixture(scope='module')
def ur5(ur5_urdf, ur5_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf,
                                         package_paths=erd_package_paths)
    return checker, FclOracle(checker, ur5_urdf)


@pytest.fixture(scope='module')
def panda_scene(panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=SCENE)
    return checker, FclOracle(checker, panda_urdf)


# ---------------------------------------------------------------- triangle / triangle

def _fcl_triangle_distance(P, Q):
    request = fcl.DistanceRequest(enable_nearest_points=True)
    objects = []
    for T in (P, Q):
        model = fcl.BVHModel()
        model.beginModel(3, 1)
        model.addSubModel(np.asarray(T, dtype=np.float64), np.array([[0, 1, 2]], dtype=np.int32))
        model.endModel()
        objects.append(fcl.CollisionObject(model, fcl.Transform()))
    return fcl.distance(objects[0], objects[1], request, fcl.DistanceResult())


def _point_triangle_distance(x, T):
    """Distance from x to the closed triangle T: our kernel on the degenerate triangle x."""
    d, _, _ = triangle_distance(np.tile(x, (1, 3, 1)), T[None])
    return d[0]


def _random_triangle_pairs(rng, n):
    P = rng.normal(size=(n, 3, 3))
    Q = rng.normal(size=(n, 3, 3)) + rng.normal(scale=2.0, size=(n, 1, 3))
    return P, Q


def _brute_force_distance(P, Q, samples=60):
    """Upper bound by dense barycentric sampling of both triangles (for degenerate input)."""
    w = np.array([(i, j, samples - i - j) for i in range(samples + 1)
                  for j in range(samples + 1 - i)], dtype=float) / samples
    a, b = w @ P, w @ Q
    return float(np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)).min())


def test_triangle_distance_agrees_with_fcl_and_points_lie_on_the_triangles():
    rng = np.random.default_rng(15)
    P, Q = _random_triangle_pairs(rng, 2000)
    d, x, y = triangle_distance(P, Q)
    for i in range(len(P)):
        theirs = _fcl_triangle_distance(P[i], Q[i])
        if theirs > 0:  # FCL answers -1 or 0 for crossing triangles
            assert d[i] == pytest.approx(theirs, abs=1e-9), (P[i].tolist(), Q[i].tolist())
        else:
            assert d[i] == 0.0, (P[i].tolist(), Q[i].tolist())
        assert np.linalg.norm(x[i] - y[i]) == pytest.approx(d[i], abs=1e-12)
        assert _point_triangle_distance(x[i], P[i]) < 1e-12
        assert _point_triangle_distance(y[i], Q[i]) < 1e-12


@pytest.mark.parametrize('P, Q, expected', [
    # crossing: an edge of Q through P's interior
    ([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0.5, 0.5, -1], [0.5, 0.5, 1], [3, 3, 0.5]], 0.0),
    # touching at a vertex on the face
    ([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0.5, 0.5, 0], [0.5, 0.5, 1], [1, 0.6, 1]], 0.0),
    # parallel faces 0.3 apart, overlapping in projection
    ([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0.2, 0.2, 0.3], [1.2, 0.2, 0.3], [0.2, 1.2, 0.3]], 0.3),
    # coplanar, apart by 1 along x
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[2, 0, 0], [3, 0, 0], [2, 1, 0]], 1.0),
    # parallel edges (edge-edge along a whole stretch)
    ([[0, 0, 0], [1, 0, 0], [0, -1, 0]], [[0, 0.5, 0], [1, 0.5, 0], [0, 1, 0]], 0.5),
    # zero-area triangles: a segment and a point
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[1, 1, 0], [1, 1, 0], [1, 1, 0]], 1.0),
    # crossing edges of two perpendicular triangles (distance 0 at an edge point)
    ([[-1, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, -1, 0], [0, 1, 0], [0, 0, -1]], 0.0),
])
def test_triangle_distance_degenerate_cases(P, Q, expected):
    P, Q = np.array(P, dtype=float), np.array(Q, dtype=float)
    d, x, y = triangle_distance(P[None], Q[None])
    assert d[0] == pytest.approx(expected, abs=1e-12)
    assert d[0] <= _brute_force_distance(P, Q) + 1e-12
    assert np.linalg.norm(x[0] - y[0]) == pytest.approx(d[0], abs=1e-12)
    assert _point_triangle_distance(x[0], P) < 1e-12
    assert _point_triangle_distance(y[0], Q) < 1e-12


# ---------------------------------------------------------------- whole robots

def _assert_on_surfaces(checker, r):
    """Each point on its body's triangles; a colliding pair's one point on both, or (a body
    inside a solid primitive, no meeting triangles) on the contained body's."""
    on_a = distance_to_body(checker, r.point_a, r.link_a) < 1e-9
    on_b = distance_to_body(checker, r.point_b, r.link_b) < 1e-9
    assert (on_a or on_b) if r.distance <= 0 else (on_a and on_b), r


def _agree_with_fcl(checker, oracle, seed, max_distance=math.inf):
    configurations = random_configurations(checker, N_CONFIGURATIONS, seed)
    worst = 0.0
    measured = 0
    for k, q in enumerate(configurations):
        records = checker.proximity(q, max_distance)
        colliding = set(checker.check(q).colliding_pairs)
        assert [r.distance for r in records] == sorted(r.distance for r in records)
        found = {(r.link_a, r.link_b): r for r in records}
        assert {pair for pair, r in found.items() if r.distance <= 0} == colliding
        poses = oracle.poses(q)
        for a, b in checker.checked_pairs:
            if (a, b) in colliding:
                continue
            theirs = oracle.pair_distance(poses, a, b)
            if theirs >= max_distance + FCL_TOLERANCE:
                assert (a, b) not in found
                continue
            if theirs < max_distance - FCL_TOLERANCE:
                assert (a, b) in found, (k, a, b, theirs)
            if (a, b) in found:
                worst = max(worst, abs(found[a, b].distance - theirs))
                assert found[a, b].distance == pytest.approx(theirs, abs=FCL_TOLERANCE), (k, a, b)
                measured += 1
        for r in records[:3]:  # the nearest points of the nearest pairs, on the surfaces
            assert abs(np.linalg.norm(r.point_a - r.point_b) - r.distance) < 1e-9
            _assert_on_surfaces(checker, r)
    assert measured > 0
    return worst


@pytest.mark.slow
def test_panda_distances_agree_with_fcl(panda):
    _agree_with_fcl(*panda, seed=1)


@pytest.mark.slow
def test_ur5_distances_agree_with_fcl(ur5):
    _agree_with_fcl(*ur5, seed=2)


@pytest.mark.slow
def test_scene_distances_agree_with_fcl(panda_scene):
    _agree_with_fcl(*panda_scene, seed=3)


def test_max_distance_keeps_exactly_the_nearer_pairs(panda_scene):
    checker, _ = panda_scene
    for q in random_configurations(checker, 30, 4):
        every = checker.proximity(q, math.inf)
        near = checker.proximity(q, 0.05)
        assert len(every) == len(checker.checked_pairs)
        expected = [r for r in every if r.distance < 0.05]
        assert [(r.link_a, r.link_b) for r in near] == [(r.link_a, r.link_b) for r in expected]
        for r, s in zip(near, expected):
            assert r.distance == s.distance
            np.testing.assert_array_equal(r.point_a, s.point_a)


def test_colliding_pairs_have_a_meeting_point_and_agree_with_update(panda):
    checker, _ = panda
    seen = 0
    for q in random_configurations(checker, 200, 5):
        records = checker.proximity(q, 0.0)  # only colliding pairs
        assert {(r.link_a, r.link_b) for r in records} == set(checker.update(q).colliding_pairs)
        for r in records:
            seen += 1
            assert r.distance == 0.0
            np.testing.assert_array_equal(r.point_a, r.point_b)
            _assert_on_surfaces(checker, r)
    assert seen > 0


def test_record_is_a_named_five_tuple(panda):
    checker, _ = panda
    record = checker.proximity(np.zeros(len(checker.joint_names)), math.inf)[0]
    assert isinstance(record, ProximityRecord)
    link_a, link_b, distance, point_a, point_b = record
    assert (link_a, link_b, distance) == (record.link_a, record.link_b, record.distance)
    assert link_a < link_b and point_a.shape == point_b.shape == (3,)


def test_proximity_moves_the_checker_like_update(panda):
    checker, _ = panda
    q = random_configurations(checker, 1, 6)[0]
    checker.proximity({'panda_joint1': 0.0})
    checker.proximity(q)
    np.testing.assert_array_equal(list(checker.positions.values()), q)
    assert checker.update(q) == checker.check(q)._replace(rechecked_pairs=0)


def test_bad_input_changes_nothing(panda):
    from collision_sensor.errors import JointStateError
    checker, _ = panda
    before = dict(checker.positions)
    with pytest.raises(JointStateError):
        checker.proximity({'panda_joint1': math.nan})
    with pytest.raises(ValueError):
        checker.proximity(before, math.nan)
    assert checker.positions == before


def test_coherent_walk_seeded_from_the_last_nearest_triangles_equals_an_unseeded_run(panda):
    """Each pair starts from the triangles nearest at the previous call (``nearest``); along a
    coherent walk that seed is nearly the answer. The answers must be those of a run whose
    seeds are wiped before every call."""
    from collision_sensor.engine.sampling import sampling_bounds
    checker, _ = panda
    lower, upper = sampling_bounds(checker)
    rng = np.random.default_rng(7)
    q = random_configurations(checker, 1, 7)[0]
    nearest = checker.packed_array('nearest')
    seeded_calls = 0
    for step in range(300):
        q = np.clip(q + rng.normal(scale=0.01, size=len(q)), lower, upper)
        seeded_calls += bool((nearest >= 0).any())
        seeded = checker.proximity(q, 0.1)
        nearest[:] = -1
        unseeded = checker.proximity(q, 0.1)
        assert [(r.link_a, r.link_b) for r in seeded] == [(r.link_a, r.link_b) for r in unseeded]
        for r, s in zip(seeded, unseeded):
            assert r.distance == pytest.approx(s.distance, abs=1e-12), step
        checker.proximity(q, 0.1)   # seeds for the next step, from this one
    assert seeded_calls > 100
