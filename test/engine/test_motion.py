"""Certified motion checks against dense sampling confirmed by python-fcl.

The oracle: states along the motion at steps of at most 1e-3 rad (or m) of any variable,
interpolated by :func:`collision_sensor.engine.motion.interpolate` (MoveIt's rules) and checked
with ``check_batch``; the first sampled state in contact is confirmed by python-fcl on the
same triangles placed by pinocchio (``FclOracle``). A reported first contact is confirmed by
python-fcl too: some reported pair's distance there is within the touching tolerance.
"""
import gc
import math
import textwrap
import weakref

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import AddObject
from collision_sensor.engine.motion import FREE, TOUCH_TOLERANCE, interpolate
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.engine.traversal import COUNT_BOX_TESTS, COUNT_MEASURES, COUNT_SWEEPS
from collision_sensor.engine.trajectory import (
    TrajectoryPoint, polynomial_extremes, spline_coefficients)
from collision_sensor.errors import JointStateError
from collision_sensor.model.scene import load_scene
from engine_oracles import FclOracle, body_triangles
from small_robot import SMALL_ROBOT, SMALL_SCENE

SAMPLE_STEP = 1e-3   # rad or m, the oracle's resolution
#: fcl's distances and our contact rule agree to this (the triangle test's own tolerance is
#: 1e-12 relative; fcl's GJK-free triangle distance is exact to rounding).
FCL_SLACK = 1e-9


def cluttered_scene(rng, n=12, around=(0.3, 0.0, 0.4), spread=0.5):
    """n boxes, rods and balls around a point, none on the robot's base (within 0.25 m of the
    vertical axis below 0.4 m): a base in contact would make every state a contact."""
    objects = []
    while len(objects) < n:
        i = len(objects)
        xyz = [float(c + rng.uniform(-spread, spread)) for c in around]
        if np.hypot(xyz[0], xyz[1]) < 0.25 and xyz[2] < 0.4:
            continue
        pose = {'xyz': xyz, 'rpy': [float(x) for x in rng.uniform(-3, 3, 3)]}
        kind = i % 3
        if kind == 0:
            shape = {'box': {'size': [float(x) for x in rng.uniform(0.002, 0.15, 3)]}}
        elif kind == 1:
            shape = {'cylinder': {'radius': float(rng.uniform(0.002, 0.05)),
                                  'length': float(rng.uniform(0.05, 0.4))}}
        else:
            shape = {'sphere': {'radius': float(rng.uniform(0.01, 0.08))}}
        objects.append({'name': f'o{i}', 'pose': pose, **shape})
    return {'objects': objects}


def _steps(checker, q0, q1):
    """How many samples keep every variable's step at most SAMPLE_STEP (rotation angles of
    floating joints count as their angle)."""
    kinds = checker.motion_kinds
    Q = interpolate(kinds, q0, q1, np.array([0.0, 1.0]))
    delta = np.abs(Q[1] - Q[0])
    for j in np.flatnonzero(kinds == 2):   # a quaternion: its rotation angle
        a = Q[0, j:j + 4] / np.linalg.norm(Q[0, j:j + 4])
        b = Q[1, j:j + 4] / np.linalg.norm(Q[1, j:j + 4])
        delta[j:j + 4] = 2.0 * math.acos(min(abs(float(a @ b)), 1.0))
    return max(2, int(math.ceil(delta.max() / SAMPLE_STEP)) + 1)


def sampled_first_contact(checker, q0, q1):
    """(t, colliding pairs) of the first sampled state in contact, or (None, ())."""
    T = np.linspace(0.0, 1.0, _steps(checker, q0, q1))
    Q = interpolate(checker.motion_kinds, q0, q1, T)
    statuses = checker.check_batch(Q)
    hits = np.flatnonzero(statuses.any(axis=1))
    if not len(hits):
        return None, (), None
    i = hits[0]
    pairs = tuple(checker.checked_pairs[p] for p in np.flatnonzero(statuses[i]))
    return float(T[i]), pairs, Q[i]


def fcl_contacts(checker, oracle, q):
    """The checked pairs python-fcl finds in contact at q (padded: within the two paddings)."""
    padding = checker.paddings
    if not any(padding.values()):
        return oracle.colliding_pairs(q)
    poses = oracle.poses(q)
    return tuple((a, b) for a, b in checker.checked_pairs
                 if oracle.contains(poses, a, b) or oracle.pair_distance(poses, a, b)
                 <= padding.get(a, 0.0) + padding.get(b, 0.0) + FCL_SLACK)


def assert_motion_against_oracle(checker, oracle, q0, q1, result):
    """The contract of check_motion, against sampling and python-fcl; returns whether the
    motion has a contact."""
    t_sampled, pairs, q_sampled = sampled_first_contact(checker, q0, q1)
    if t_sampled is not None:
        assert result.in_collision, ('missed', list(q0), list(q1), t_sampled, pairs)
        assert result.first_contact <= t_sampled + 1e-12, (result, t_sampled)
        # python-fcl confirms the sampled contact (poses by pinocchio).
        assert set(fcl_contacts(checker, oracle, q_sampled)) == set(pairs)
    if not result.in_collision:
        assert result.first_contact is None and result.colliding_pairs == ()
        return False
    assert_touches(checker, oracle, q0, q1, result)
    return True


def assert_touches(checker, oracle, q0, q1, result):
    """A reported first contact: its state is in contact, or within the touching tolerance of
    it, by python-fcl (the triangles' padded distance) or a test vertex's distance to the other
    body's true primitive (check counts a vertex inside it)."""
    assert 0.0 <= result.first_contact <= 1.0 and result.colliding_pairs
    assert list(result.colliding_pairs) == sorted(result.colliding_pairs)
    q = interpolate(checker.motion_kinds, q0, q1, [result.first_contact])[0]
    poses = oracle.poses(q)
    padding = checker.paddings
    nearest = min(min(oracle.pair_distance(poses, a, b) - padding.get(a, 0.0)
                      - padding.get(b, 0.0), oracle.solid_gap(poses, a, b))
                  if not oracle.contains(poses, a, b) else 0.0
                  for a, b in result.colliding_pairs)
    assert nearest <= TOUCH_TOLERANCE + FCL_SLACK, (result, nearest)


@pytest.fixture(scope='module')
def panda_cell(panda_urdf, panda_srdf, erd_package_paths):
    rng = np.random.default_rng(7)
    scene = cluttered_scene(rng)
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    return checker, FclOracle(checker, panda_urdf)


@pytest.fixture(scope='module')
def ur5_cell(ur5_urdf, ur5_srdf, erd_package_paths):
    rng = np.random.default_rng(8)
    scene = cluttered_scene(rng, around=(0.3, 0.0, 0.3))
    checker = CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    return checker, FclOracle(checker, ur5_urdf)


def random_segments(checker, n, seed, shortest=0.2, longest=2.0):
    """n motions from clear states, 0.2 to 2 rad long (Euclidean), within the limits."""
    rng = np.random.default_rng(seed)
    lower = np.maximum(checker.kinematics.lower, -math.pi)
    upper = np.minimum(checker.kinematics.upper, math.pi)
    starts = random_configurations(checker, 20 * n, seed=seed)
    segments = []
    for q0 in starts:
        if len(segments) == n:
            break
        if checker.check(q0).in_collision:
            continue
        d = rng.normal(size=len(q0))
        d *= rng.uniform(shortest, longest) / np.linalg.norm(d)
        segments.append((q0, np.clip(q0 + d, lower, upper)))
    return segments


@pytest.mark.parametrize('cell', ['panda_cell', 'ur5_cell'])
def test_check_motion_never_misses_a_contact_and_never_reports_one_too_early(cell, request):
    checker, oracle = request.getfixturevalue(cell)
    contacts = 0
    for q0, q1 in random_segments(checker, 40, seed=3):
        result = checker.check_motion(q0, q1)
        contacts += assert_motion_against_oracle(checker, oracle, q0, q1, result)
    assert 5 <= contacts <= 35   # the cell is cluttered, not full: both answers tested


def _elbow_sweep(panda_urdf, panda_srdf, erd_package_paths, obstacle):
    """The issue's motion: joint 4 from -2.6 to -0.8 rad with both ends clear, an obstacle
    across the hand's path two thirds of the way (its normal along the hand's motion)."""
    probe = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                       package_paths=erd_package_paths)
    names = probe.joint_names
    q0 = np.zeros(len(names))
    q0[names.index('panda_joint2')] = 0.3
    q0[names.index('panda_joint4')] = -2.6
    q1 = q0.copy()
    q1[names.index('panda_joint4')] = -0.8
    q_mid, q_next = interpolate(probe.motion_kinds, q0, q1, [2 / 3, 2 / 3 + 1e-3])

    def fingertips(q):  # between the fingertips: nothing else sweeps so far from the elbow
        probe.check(q)
        T = probe.link_poses()['panda_hand']
        return T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, 0.1])

    p = fingertips(q_mid)
    v = fingertips(q_next) - p
    z = v / np.linalg.norm(v)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    rpy = [math.atan2(R[2, 1], R[2, 2]), -math.asin(R[2, 0]), math.atan2(R[1, 0], R[0, 0])]
    scene = {'objects': [dict(obstacle, name='thin', pose={'xyz': p.tolist(), 'rpy': rpy})]}
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    return checker, q0, q1


@pytest.mark.parametrize('obstacle', [
    {'box': {'size': [0.04, 0.04, 0.001]}},              # a 1 mm plate across the path
    {'cylinder': {'radius': 0.001, 'length': 0.04}},     # a 2 mm rod, along the plate's normal
])
def test_thin_obstacles_crossed_by_a_fast_motion_are_caught(panda_urdf, panda_srdf,
                                                           erd_package_paths, obstacle):
    checker, q0, q1 = _elbow_sweep(panda_urdf, panda_srdf, erd_package_paths, obstacle)
    assert not checker.check(q0).in_collision and not checker.check(q1).in_collision
    assert not checker.update(q0).in_collision and not checker.update(q1).in_collision
    result = checker.check_motion(q0, q1)
    assert result.in_collision and any('thin' in pair for pair in result.colliding_pairs)
    oracle = FclOracle(checker, panda_urdf)
    assert_motion_against_oracle(checker, oracle, q0, q1, result)
    checker.update(q0)
    assert checker.update_motion(q1).in_collision


BAR_URDF = """<robot name="bar">
  <link name="base"/>
  <link name="bar"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1.0 0.004 0.02"/></geometry></collision></link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="bar"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"""


def test_update_motion_sweeps_through_a_fin_into_a_near_miss(tmp_path):
    """A bar turns through a 1 mm fin and stops just short of a second fin of the same mesh:
    its pair keeps a front at the step's end, whose node pairs at the first fin are a few cm
    apart there (apart at the end, not all along the way). The swept step must meet the first
    fin where dense sampling does. The reach bound is tight here (a bar turning about its
    end), so a front node pair trusted beyond what the step's bound proves misses it."""
    import trimesh
    fins = []
    for angle in (0.5, 0.53):    # radial plates from 0.8 to 1 m, 1 mm thick
        T = trimesh.transformations.rotation_matrix(angle, [0, 0, 1])
        T[:3, 3] = T[:3, :3] @ [0.9, 0.0, 0.0]
        fins.append(trimesh.creation.box(extents=[0.2, 0.001, 0.1], transform=T))
    path = tmp_path / 'fins.stl'
    trimesh.util.concatenate(fins).export(str(path))
    checker = CollisionChecker.from_urdf(BAR_URDF, scene={'objects': [
        {'name': 'fins', 'mesh': {'filename': str(path)}}]})
    # Ends between the fins, 5 um to 0.5 mm from the second (a front is kept that near).
    ends = [th for th in np.linspace(0.52, 0.53, 1001)
            if 5e-6 < min((r.distance for r in checker.proximity(np.array([th]), 0.001)),
                          default=1.0) < 5e-4]
    assert len(ends) > 20
    swept = 0
    for th1 in ends[::len(ends) // 6]:
        for th0 in (0.40, 0.45, 0.49):
            q0, q1 = np.array([th0]), np.array([th1])
            checker.check(q0)
            moved = checker.update_motion(q1)
            t_sampled, _, _ = sampled_first_contact(checker, q0, q1)
            assert t_sampled is not None and moved.in_collision, (th0, th1)
            assert moved.first_contact <= t_sampled + 1e-12, (th0, th1, moved, t_sampled)
            expected = checker.check_motion(q0, q1)
            assert abs(moved.first_contact - expected.first_contact) < 1e-4
            swept += 1
    assert swept >= 18


def test_update_motion_crosses_a_fin_after_steps_its_clearance_skipped(tmp_path):
    """A bar walks towards a 1 mm fin in steps its clearance proves (its pair not re-checked,
    its travel summed), then one step crosses the fin. That step's start gap is the clearance
    less the travel since the pair was last checked: without the travel, the gaps at both ends
    exceed the step's bound and the crossing is missed (21 of these 60, when tried)."""
    import trimesh
    T = trimesh.transformations.rotation_matrix(0.5, [0, 0, 1])
    T[:3, 3] = T[:3, :3] @ [0.9, 0.0, 0.0]
    path = tmp_path / 'fin.stl'
    trimesh.creation.box(extents=[0.2, 0.001, 0.1], transform=T).export(str(path))
    checker = CollisionChecker.from_urdf(BAR_URDF, scene={'objects': [
        {'name': 'fin', 'mesh': {'filename': str(path)}}]})
    crossings = 0
    for step in (0.002, 0.005, 0.01, 0.03):
        for cross in (0.004, 0.01, 0.02, 0.05, 0.1):
            for start in (0.0, 0.2, 0.4):
                checker.check(np.array([start]))
                th = start
                while th + step < 0.5 - cross / 2:
                    th += step
                    assert not checker.update_motion(np.array([th])).in_collision
                q0, q1 = np.array([th]), np.array([1.0 - th])     # across the fin at 0.5
                moved = checker.update_motion(q1)
                expected = checker.check_motion(q0, q1)
                t_sampled, _, _ = sampled_first_contact(checker, q0, q1)
                assert moved.in_collision and expected.in_collision and t_sampled is not None
                assert moved.first_contact <= t_sampled + 1e-12
                assert abs(moved.first_contact - expected.first_contact) < 1e-4
                crossings += 1
    assert crossings == 60


@pytest.mark.parametrize('shape', ['mesh', 'sphere'])
def test_update_motion_carries_the_distance_it_measured_as_a_clearance(tmp_path, shape):
    """A bar drifts in small steps (N(1, 3) mrad, its tip 1 m out) towards a ball (a mesh, its
    boxes turned off its axes, or a primitive) and on through it, three walks. Near the ball
    the query's clearance (where its descent stopped) is below a step's bound, so update_motion
    measures the distance at the step's end instead of marching, and carries it as the pair's
    clearance: the planning then skips the pair while its travel stays below it. Each answer
    is check_motion's on a second checker that carries nothing, and dense sampling's; each
    state's statuses are a fresh check's. A distance taken as the search's cap whatever it
    finds misses 13 of these contacts by the mesh, 30 by the sphere (tried)."""
    import trimesh
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    ball.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1, 1, 0]))
    ball.apply_translation([0.9 * math.cos(0.3), 0.9 * math.sin(0.3), 0.0])
    path = tmp_path / 'ball.stl'
    ball.export(str(path))
    scene = {'objects': [{'name': 'ball', 'mesh': {'filename': str(path)}} if shape == 'mesh' else
                         {'name': 'ball', 'sphere': {'radius': 0.05},
                          'pose': {'xyz': [0.9 * math.cos(0.3), 0.9 * math.sin(0.3), 0.0]}}]}
    checker = CollisionChecker.from_urdf(BAR_URDF, scene=scene)
    fresh = CollisionChecker.from_urdf(BAR_URDF, scene=scene)
    checker.counters[:] = 0
    contacts = 0
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        q = np.array([0.0])
        checker.check(q)
        for _ in range(400):
            q_next = q + rng.normal(0.001, 0.003, 1)
            moved = checker.update_motion(q_next)
            expected = fresh.check_motion(q, q_next)
            assert moved.in_collision == expected.in_collision, (seed, q, q_next)
            if moved.in_collision:
                t_sampled, _, _ = sampled_first_contact(fresh, q, q_next)
                assert t_sampled is not None and moved.first_contact <= t_sampled + 1e-12
                assert abs(moved.first_contact - expected.first_contact) < 1e-4
                contacts += 1
            assert (checker.update(q_next).colliding_pairs ==
                    fresh.check(q_next).colliding_pairs)
            q = q_next
    assert checker.counters[COUNT_MEASURES] > 0
    assert 100 < contacts < 600      # the walks go through the ball and out


def test_check_motion_leaves_the_carried_state_as_it_was(panda_cell):
    checker, _ = panda_cell
    q0, q1 = random_segments(checker, 1, seed=5)[0]
    before = checker.update(q0)
    positions = checker.positions
    checker.check_motion(q1, q0)
    checker.check_motion(q0, q1)
    assert checker.positions == positions
    assert checker.update(q0) == before._replace(rechecked_pairs=0)


def test_check_motion_is_a_compiled_call_that_follows_its_checker():
    """A checker's check_motion is one compiled call: kept across a scene change it answers
    for the scene as it is (as a checker built with that scene does), other forms of input
    and keywords take the Python path to the same answers, a subclass's own check_motion
    stands, and a dropped checker is collected."""
    checker = CollisionChecker.from_urdf(SMALL_ROBOT, scene=SMALL_SCENE)
    names = checker.joint_names
    q0 = np.zeros(len(names))
    q1 = np.array([{'shoulder': 0.5, 'elbow': -0.5, 'extend': 0.0, 'wrist': 0.5}[n]
                   for n in names])
    kept = checker.check_motion
    before = kept(q0, q1)
    checker.check(0.5 * (q0 + q1))
    T = checker.link_poses()['lower']
    block = {'name': 'block', 'box': {'size': [0.05, 0.05, 0.05]},
             'pose': {'xyz': [float(x) for x in T[:3, 3] + T[:3, 2] * 0.2]}}
    checker.add_object(load_scene({'objects': [block]})[0])
    rebuilt = CollisionChecker.from_urdf(SMALL_ROBOT,
                                         scene={'objects': SMALL_SCENE['objects'] + [block]})
    expected = rebuilt.check_motion(q0, q1)
    assert expected.in_collision and not before.in_collision
    assert kept(q0, q1) == checker.check_motion(q0, q1) == expected
    assert CollisionChecker.check_motion(checker, q0, q1) == expected
    assert checker.check_motion(q_from=list(q0), q_to=dict(zip(names, q1))) == expected
    with pytest.raises(TypeError):
        checker.check_motion(q0)
    with pytest.raises(JointStateError, match='q_to'):
        checker.check_motion(q0, np.full(len(names), np.nan))

    calls = []

    class Logged(CollisionChecker):
        def check_motion(self, q_from, q_to):
            calls.append((q_from, q_to))
            return super().check_motion(q_from, q_to)

    logged = Logged.from_urdf(SMALL_ROBOT, scene=SMALL_SCENE)
    assert logged.check_motion(q0, q1) == before and len(calls) == 1

    gone = weakref.ref(checker)
    del checker, kept
    gc.collect()
    assert gone() is None


def _moveit_interpolate(kinds, q_from, q_to, t):
    """MoveIt's JointModel::interpolate, restated (the oracle of the engine's own): linear;
    continuous and planar theta the shorter way round (remainder: a move of exactly pi as C's,
    half to even); a floating joint's unit quaternions along the shorter arc (slerp)."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    t = np.asarray(t, float).reshape(-1, 1)
    delta = q_to - q_from
    wrap = kinds == engine.MOTION_WRAP
    delta[wrap] -= 2.0 * math.pi * np.round(delta[wrap] / (2.0 * math.pi))
    Q = q_from + t * delta
    for j in np.flatnonzero(kinds == engine.MOTION_QUATERNION):
        a = q_from[j:j + 4] / np.linalg.norm(q_from[j:j + 4])
        b = q_to[j:j + 4] / np.linalg.norm(q_to[j:j + 4])
        dot = float(a @ b)
        if dot < 0.0:
            b, dot = -b, -dot
        half = math.acos(min(dot, 1.0))
        if half > engine.SLERP_HALF_ANGLE_MIN:
            ka, kb = np.sin((1.0 - t) * half) / math.sin(half), np.sin(t * half) / math.sin(half)
        else:
            ka, kb = 1.0 - t, t
        Q[:, j:j + 4] = ka * a + kb * b
    return Q


def test_interpolate_is_moveits_and_refuses_a_zero_quaternion():
    """The engine's interpolation (the motion checks' own, bound as interpolate) against
    MoveIt's rules restated, on random motions of every kind of variable: quaternions far
    apart, opposite in sign, nearly equal (below the slerp threshold), and turns of exactly pi;
    a zero quaternion at either end is refused, naming the end and the variable."""
    kinds = np.array([engine.MOTION_LINEAR, engine.MOTION_WRAP, engine.MOTION_QUATERNION,
                      engine.MOTION_QUATERNION_REST, engine.MOTION_QUATERNION_REST,
                      engine.MOTION_QUATERNION_REST, engine.MOTION_LINEAR])
    rng = np.random.default_rng(41)
    t = np.linspace(0.0, 1.0, 11)
    for k in range(300):
        q0, q1 = rng.normal(size=7) * 3, rng.normal(size=7) * 3
        if k % 4 == 1:
            q1[2:6] = -q0[2:6] * 2.0                       # the same rotation, sign flipped
        elif k % 4 == 2:
            q1[2:6] = q0[2:6] + 1e-9 * rng.normal(size=4)  # nearly the same: the chord
        elif k % 4 == 3:
            q1[1] = q0[1] + math.pi                        # exactly half a turn
        np.testing.assert_allclose(interpolate(kinds, q0, q1, t),
                                   _moveit_interpolate(kinds, q0, q1, t), rtol=0, atol=1e-12)
    zero = np.zeros(7)
    for row, ends in ((0, (zero, q1)), (1, (q0, zero))):
        with pytest.raises(JointStateError) as error:
            interpolate(kinds, *ends, t)
        assert (error.value.row, error.value.variable) == (row, 2)


@pytest.mark.parametrize('cell', ['panda_cell', 'ur5_cell'])
def test_update_motion_is_check_motion_then_update(cell, request):
    """On a walk of small steps and jumps: update_motion answers as check_motion from the
    last state, and leaves the statuses check gives. The two march differently (update_motion
    from what its incremental query knows), so a first contact is the same contact, each
    within the touching tolerance of it by python-fcl, not the same float."""
    checker, oracle = request.getfixturevalue(cell)
    scratch = CollisionChecker(checker.model, scene=checker.scene_objects,
                               config={'allowed_collisions': [
                                   f'{a}:{b}' for a, b in _excluded(checker)]})
    rng = np.random.default_rng(17)
    lower = np.maximum(checker.kinematics.lower, -math.pi)
    upper = np.minimum(checker.kinematics.upper, math.pi)
    q = random_segments(checker, 1, seed=9)[0][0]
    checker.check(q)
    contacts = 0
    for step in range(400):
        scale = 0.3 if rng.random() < 0.05 else 0.004
        q_next = np.clip(q + rng.normal(size=len(q)) * scale, lower, upper)
        moved = checker.update_motion(q_next)
        expected = scratch.check_motion(q, q_next)
        assert moved.in_collision == expected.in_collision, (step, moved, expected)
        if moved.in_collision:
            contacts += 1
            assert (moved.first_contact == 0.0) == (expected.first_contact == 0.0)
            assert abs(moved.first_contact - expected.first_contact) < 1e-4, (moved, expected)
            for result in (moved, expected):
                assert_touches(checker, oracle, q, q_next, result)
        assert checker.update(q_next).colliding_pairs == scratch.check(q_next).colliding_pairs
        q = q_next
    assert contacts > 10


def test_update_motion_after_a_scene_change_starts_from_the_scene_as_it_is(panda_cell):
    """An object moved away from (or into) the robot standing still: the motion from the last
    state is judged in the scene as it is now, as check_motion from that state says, not by
    the pairs' statuses under the old scene."""
    checker, _ = panda_cell
    (q0, q1), = random_segments(checker, 1, seed=43, shortest=0.05, longest=0.1)
    checker.check(q0)
    T = checker.link_poses()['panda_hand']
    part = load_scene({'objects': [{'name': 'part', 'box': {'size': [0.06, 0.06, 0.06]}}]})
    far = T.copy()
    far[2, 3] += 3.0
    try:
        for pose, q in ((T, q0), (far, q0), (T, q0), (far, q1), (T, q1)):
            last = np.array([checker.positions[name] for name in checker.joint_names])
            checker.add_object(part[0], pose=pose)
            expected = checker.check_motion(last, q)
            got = checker.update_motion(q)
            assert got == expected, (pose[2, 3], got, expected)
            assert checker.update(q).colliding_pairs == checker.check(q).colliding_pairs
    finally:    # the cell is the module's: leave its scene as it was
        checker.remove_object('part')


def _excluded(checker):
    """The pairs the checker never checks, for a scratch checker built on the same model."""
    bodies = list(checker.link_names) + list(checker.scene_object_names)
    checked = set(checker.checked_pairs)
    return [(a, b) for i, a in enumerate(bodies) for b in bodies[i + 1:]
            if tuple(sorted((a, b))) not in checked]


def test_before_any_state_update_motion_is_the_instant(panda_cell):
    checker, _ = panda_cell
    fresh = CollisionChecker(checker.model, scene=checker.scene_objects,
                             config={'allowed_collisions': [
                                 f'{a}:{b}' for a, b in _excluded(checker)]})
    q = random_segments(checker, 1, seed=11)[0][1]
    result = fresh.update_motion(q)
    instant = checker.check(q)
    assert result.in_collision == instant.in_collision
    assert result.colliding_pairs == instant.colliding_pairs


def _small_on_a_base(kind):
    srdf = (f'<robot name="small"><virtual_joint name="base_joint" type="{kind}" '
            'parent_frame="odom" child_link="base"/></robot>')
    return CollisionChecker.from_urdf(SMALL_ROBOT, srdf=srdf, scene=SMALL_SCENE,
                                      config={'primitive_sections': 10})


@pytest.mark.parametrize('kind', ['floating', 'planar'])
def test_a_moving_base_interpolates_as_moveit_and_is_certified(kind, tmp_path):
    """Translation linear, rotation along the shorter arc (slerp; planar theta the shorter
    way round), the continuous elbow the shorter way: against sampling and python-fcl with
    pinocchio's own root joint."""
    checker = _small_on_a_base(kind)
    urdf = tmp_path / 'small.urdf'
    urdf.write_text(SMALL_ROBOT)
    oracle = FclOracle(checker, str(urdf))
    rng = np.random.default_rng(31)
    names = checker.joint_names
    contacts = free = 0
    for _ in range(30):
        q0, q1 = checker.kinematics.neutral(), checker.kinematics.neutral()
        for q in (q0, q1):
            for j, name in enumerate(names):
                if name.endswith(('/x', '/y', '/trans_x', '/trans_y')):
                    q[j] = rng.uniform(-0.4, 0.4)
                elif name.endswith('/trans_z'):
                    q[j] = rng.uniform(-0.1, 0.2)
                elif name.endswith('/theta'):
                    q[j] = rng.uniform(-4, 4)
                elif '/rot_' not in name:
                    low, high = checker.joint_limits[name]
                    q[j] = rng.uniform(max(low, -3.0), min(high, 3.0))
            if kind == 'floating':
                rot = [j for j, n in enumerate(names) if '/rot_' in n]
                q[rot] = rng.normal(size=4) * [0.2, 0.2, 1.0, 1.0]
        if checker.check(q0).in_collision:
            continue
        result = checker.check_motion(q0, q1)
        if assert_motion_against_oracle(checker, oracle, q0, q1, result):
            contacts += 1
        else:
            free += 1
    assert contacts >= 3 and free >= 1


#: A turntable (continuous about z) carrying an arm out along x, a post beside it at angle 0.
TURNTABLE = textwrap.dedent('''\
    <robot name="turntable">
      <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
      </link>
      <link name="arm"><collision><origin xyz="0.3 0 0.2"/>
        <geometry><box size="0.5 0.04 0.04"/></geometry></collision></link>
      <joint name="turn" type="continuous"><parent link="base"/><child link="arm"/>
        <axis xyz="0 0 1"/></joint>
    </robot>
    ''')
POST = {'objects': [{'name': 'post', 'cylinder': {'radius': 0.02, 'length': 1.0},
                     'pose': {'xyz': [0.4, 0.0, 0.5]}}]}


def test_a_continuous_joint_goes_the_shorter_way_round():
    """From 2.9 to -2.9 rad the arm turns 0.48 rad through pi, not 5.8 rad through 0, where
    the post would stop it."""
    checker = CollisionChecker.from_urdf(TURNTABLE, scene=POST)
    assert not checker.check({'turn': 2.9}).in_collision
    assert not checker.check({'turn': -2.9}).in_collision
    assert checker.check({'turn': 0.0}).in_collision   # the long way hits
    assert not checker.check_motion({'turn': 2.9}, {'turn': -2.9}).in_collision
    assert checker.check_motion({'turn': 1.5}, {'turn': -1.5}).in_collision   # through 0
    # The same pose given a turn apart is no motion at all.
    assert not checker.check_motion({'turn': 2.9}, {'turn': 2.9 - 4 * math.pi}).in_collision


#: A tool on three sliders and a turn (yaw): with the yaw still, the tool only translates.
SLIDER = textwrap.dedent('''\
    <robot name="slider">
      <link name="base"/><link name="sx"/><link name="sy"/><link name="sz"/>
      <link name="tool"><collision><origin rpy="0.3 -0.7 1.1"/>
        <geometry>{geometry}</geometry></collision></link>
      <joint name="x" type="prismatic"><parent link="base"/><child link="sx"/>
        <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="y" type="prismatic"><parent link="sx"/><child link="sy"/>
        <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="z" type="prismatic"><parent link="sy"/><child link="sz"/>
        <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="yaw" type="revolute"><parent link="sz"/><child link="tool"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
    </robot>
    ''')
#: Fixed primitives around the origin, turned, and a large ball whose tessellation's faces
#: lie up to 2.9 mm inside the true sphere (what check counts for a vertex inside it).
SLIDER_SCENE = {'objects': [
    {'name': 'block', 'box': {'size': [0.3, 0.05, 0.2]},
     'pose': {'xyz': [0.4, 0.0, 0.0], 'rpy': [0.2, 0.4, -0.3]}},
    {'name': 'rod', 'cylinder': {'radius': 0.01, 'length': 0.6},
     'pose': {'xyz': [-0.3, 0.3, 0.0], 'rpy': [1.2, 0.0, 0.5]}},
    {'name': 'ball', 'sphere': {'radius': 0.3}, 'pose': {'xyz': [0.0, -0.8, 0.2]}},
]}


#: The tool's geometry, and whether it is convex element by element (swept) or not (marched).
SLIDING_TOOLS = {
    'box': ('<box size="0.08 0.02 0.05"/>', True),
    'cylinder': ('<cylinder radius="0.03" length="0.1"/>', True),
    'ball': ('<sphere radius="0.04"/>', True),
    '2 mm cube': ('<box size="0.002 0.002 0.002"/>', True),
    'box and ball': ('<box size="0.05 0.02 0.03"/></geometry></collision><collision>'
                     '<origin xyz="0 0 0.06"/><geometry><sphere radius="0.02"/>', True),
    'convex mesh': ('<mesh filename="file://{icosphere}"/>', True),
    'ring mesh': ('<mesh filename="file://{ring}"/>', False),
}


@pytest.mark.parametrize('tool', list(SLIDING_TOOLS))
@pytest.mark.parametrize('padding', [0.0, 0.01])
def test_a_sliding_convex_body_is_swept_exactly(tool, padding, tmp_path):
    """Bodies that only translate relative to each other (sliders moving, the turn still),
    both of convex elements, are swept by ray casts, not marched: against sampling and
    python-fcl, the first contact is no later than the first sampled one and touches; the
    answer is the march's (check_path marches); and the sweep, not a march, did the work. The
    2 mm cube's leading corner enters the large ball's true sphere before any triangles meet,
    which a sweep of the tessellations alone would miss. A closed mesh counts when convex (an
    icosphere, with mesh_containment); a ring is not, and marches."""
    import trimesh
    geometry, convex = SLIDING_TOOLS[tool]
    icosphere, ring = tmp_path / 'icosphere.stl', tmp_path / 'ring.stl'
    trimesh.creation.icosphere(subdivisions=1, radius=0.04).export(str(icosphere))
    trimesh.creation.annulus(r_min=0.015, r_max=0.04, height=0.05).export(str(ring))
    urdf = tmp_path / 'slider.urdf'
    urdf.write_text(SLIDER.format(geometry=geometry.format(icosphere=icosphere, ring=ring)))
    checker = CollisionChecker.from_urdf(str(urdf), scene=SLIDER_SCENE,
                                         config={'link_padding': {'tool': padding},
                                                 'mesh_containment': True})
    oracle = FclOracle(checker, str(urdf))
    rng = np.random.default_rng(5)
    targets = [o.T_world_object[:3, 3] for o in checker.scene_objects]
    contacts = free = 0
    swept_work = marched_work = sweeps = 0
    for trial in range(24):
        yaw = rng.uniform(-3, 3)
        target = targets[trial % len(targets)] + rng.normal(0.0, 0.15, 3)
        if trial % len(targets) == 2:     # at the ball's centre: through the tessellation
            target = targets[2]
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        q0 = np.append(target - 0.7 * direction, yaw)
        q1 = np.append(target + rng.uniform(-0.5, 0.6) * direction, yaw)
        if checker.check(q0).in_collision:
            continue
        checker.counters[:] = 0
        result = checker.check_motion(q0, q1)
        swept_work += checker.counters[COUNT_BOX_TESTS]
        sweeps += checker.counters[COUNT_SWEEPS]
        checker.counters[:] = 0
        marched = checker.check_path(np.array([q0, q1]))
        marched_work += checker.counters[COUNT_BOX_TESTS]
        assert result.in_collision == (marched.first_invalid_segment is not None)
        if assert_motion_against_oracle(checker, oracle, q0, q1, result):
            contacts += 1
        else:
            free += 1
    assert contacts >= 8 and free >= 4
    if convex:
        assert sweeps >= contacts + free and swept_work * 5 < marched_work, (
            sweeps, swept_work, marched_work)
    else:
        assert sweeps == 0
        # Threaded on a thin rod through its hole: free, where its hull would meet the rod.
        straight = tmp_path / 'straight.urdf'
        straight.write_text(SLIDER.format(geometry=geometry.format(ring=ring)).replace(
            'rpy="0.3 -0.7 1.1"', 'rpy="0 0 0"'))
        threaded = CollisionChecker.from_urdf(
            str(straight), config={'mesh_containment': True}, scene={'objects': [
                {'name': 'wire', 'cylinder': {'radius': 0.005, 'length': 0.6}}]})
        q0, q1 = np.array([0.0, 0.0, -0.5, 0.3]), np.array([0.0, 0.0, 0.5, 0.3])
        assert not threaded.check(0.5 * (q0 + q1)).in_collision   # the ring around it
        assert threaded.check_motion(q0, q1) == FREE
    # A turn on the way: marched, and the same contract.
    q0, q1 = np.array([0.0, -0.1, 0.2, -1.0]), np.array([0.0, -0.45, 0.2, 1.0])
    if not checker.check(q0).in_collision:
        assert_motion_against_oracle(checker, oracle, q0, q1, checker.check_motion(q0, q1))
    # A scene change: the new object is swept (or marched) as it is now.
    checker.add_object(load_scene({'objects': [{'name': 'late', 'box': {
        'size': [0.02, 0.5, 0.5]}, 'pose': {'xyz': [0.0, 1.2, 0.0]}}]})[0])
    q0, q1 = np.array([-0.6, 1.2, 0.0, 0.0]), np.array([0.6, 1.2, 0.0, 0.0])
    result, marched = checker.check_motion(q0, q1), checker.check_path(np.array([q0, q1]))
    assert result.in_collision and result.colliding_pairs == (('late', 'tool'),)
    assert abs(result.first_contact - marched.motion.first_contact) < 1e-5


def _random_primitive(rng):
    """A box, cylinder or ball from 0.1 mm to 0.3 m: (URDF geometry, scene shape)."""
    kind = rng.integers(3)
    if kind == 0:
        size = [float(x) for x in rng.choice([1e-4, 1e-3, 0.05, 0.3], 3) * rng.uniform(0.5, 1.5, 3)]
        return f'<box size="{size[0]} {size[1]} {size[2]}"/>', {'box': {'size': size}}
    if kind == 1:
        r, length = float(rng.choice([1e-3, 0.02, 0.2])), float(rng.choice([1e-3, 0.05, 0.5]))
        return (f'<cylinder radius="{r}" length="{length}"/>',
                {'cylinder': {'radius': r, 'length': length}})
    r = float(rng.choice([1e-3, 0.02, 0.3]))
    return f'<sphere radius="{r}"/>', {'sphere': {'radius': r}}


def _random_slider(rng, urdf, spread):
    """SLIDER with a random primitive tool (written to urdf) among three random primitives
    within spread (m) of the origin, its padding 0, 1 mm or 2 cm: the checker."""
    geometry, _ = _random_primitive(rng)
    urdf.write_text(SLIDER.format(geometry=geometry))
    objects = [{'name': f'o{i}', **_random_primitive(rng)[1], 'pose': {
        'xyz': [float(x) for x in rng.uniform(-spread, spread, 3)],
        'rpy': [float(x) for x in rng.uniform(-3, 3, 3)]}} for i in range(3)]
    padding = float(rng.choice([0.0, 1e-3, 0.02]))
    return CollisionChecker.from_urdf(str(urdf), scene={'objects': objects},
                                      config={'link_padding': {'tool': padding}})


def _swept_motion(checker, oracle, q0, q1):
    """check_motion from q0 (clear) to q1 against the contract (sampling, python-fcl) and
    against the march (check_path's answer); return (it met contact, the pairs swept)."""
    checker.counters[:] = 0
    result = checker.check_motion(q0, q1)
    sweeps = int(checker.counters[COUNT_SWEEPS])
    marched = checker.check_path(np.array([q0, q1]))
    assert result.in_collision == (marched.first_invalid_segment is not None)
    return assert_motion_against_oracle(checker, oracle, q0, q1, result), sweeps


def test_sweeps_meet_the_contract_on_random_primitives(tmp_path):
    """Tools and objects of every primitive kind, from 0.1 mm slivers to 0.6 m, with and
    without padding, sliding at random: each swept answer meets the contract against sampling
    and python-fcl, and says what the march says (contact or not)."""
    rng = np.random.default_rng(12)
    urdf = tmp_path / 'slider.urdf'
    motions = contacts = sweeps = 0
    for _ in range(12):
        checker = _random_slider(rng, urdf, 0.3)
        oracle = FclOracle(checker, str(urdf))
        for _ in range(12):
            yaw = rng.uniform(-3, 3)
            q0 = np.append(rng.uniform(-0.8, 0.8, 3), yaw)
            q1 = np.append(rng.uniform(-0.8, 0.8, 3), yaw)
            if checker.check(q0).in_collision:
                continue
            contact, swept = _swept_motion(checker, oracle, q0, q1)
            motions, contacts, sweeps = motions + 1, contacts + contact, sweeps + swept
    assert motions >= 100 and contacts >= 15 and sweeps >= 2 * motions


def test_a_swept_motion_that_starts_in_contact_meets_it_at_the_start(tmp_path):
    """A sweep starts at the motion's start: from a state in contact (surfaces crossing, a
    tool wholly inside an object, within padding) the swept answer is contact at 0 with the
    pairs check finds there, as the march of check_path says."""
    rng = np.random.default_rng(21)
    urdf = tmp_path / 'slider.urdf'
    starts = 0
    for _ in range(12):
        checker = _random_slider(rng, urdf, 0.2)
        for _ in range(20):
            yaw = rng.uniform(-3, 3)
            q0 = np.append(rng.uniform(-0.3, 0.3, 3), yaw)
            q1 = np.append(rng.uniform(-0.8, 0.8, 3), yaw)
            instant = checker.check(q0)
            if not instant.in_collision:
                continue
            checker.counters[:] = 0
            result = checker.check_motion(q0, q1)
            assert checker.counters[COUNT_SWEEPS] > 0
            assert (result.in_collision, result.first_contact) == (True, 0.0)
            assert result.colliding_pairs == instant.colliding_pairs
            marched = checker.check_path(np.array([q0, q1]))
            assert marched.first_invalid_segment == 0 and marched.motion == result
            starts += 1
    assert starts >= 40
    # Wholly inside: no surfaces meet, the ball's test vertex is in the box's solid.
    urdf.write_text(SLIDER.format(geometry='<sphere radius="0.01"/>'))
    checker = CollisionChecker.from_urdf(str(urdf), scene={'objects': [
        {'name': 'crate', 'box': {'size': [0.3, 0.3, 0.3]}, 'pose': {'rpy': [0.3, 0.2, 0.1]}}]})
    q0, q1 = np.zeros(4), np.array([0.9, 0.2, 0.0, 0.0])
    assert checker.check(q0).colliding_pairs == (('crate', 'tool'),)
    checker.counters[:] = 0
    result = checker.check_motion(q0, q1)
    assert checker.counters[COUNT_SWEEPS] > 0
    assert (result.first_contact, result.colliding_pairs) == (0.0, (('crate', 'tool'),))
    # Two links on sliders moving alike (one mimics the other): no relative shift, so the
    # start is the whole motion, in contact or apart.
    for gap, contact in ((0.15, True), (0.35, False)):
        urdf.write_text(TWIN_SLIDERS.format(gap=gap))
        checker = CollisionChecker.from_urdf(str(urdf))
        q0, q1 = np.array([0.0]), np.array([0.5])
        assert checker.check(q0).in_collision == contact
        checker.counters[:] = 0
        result = checker.check_motion(q0, q1)
        assert checker.counters[COUNT_SWEEPS] > 0
        assert result == checker.check_path(np.array([q0, q1])).motion
        assert (result.in_collision, result.first_contact) == \
            ((True, 0.0) if contact else (False, None))


#: Box a and ball b on two sliders along x, b's mimicking a's, b {gap} m along x from a.
TWIN_SLIDERS = textwrap.dedent('''\
    <robot name="twin">
      <link name="base"/>
      <link name="a"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
      <link name="b"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
      <joint name="slide" type="prismatic"><parent link="base"/><child link="a"/>
        <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="twin" type="prismatic"><parent link="base"/><child link="b"/>
        <origin xyz="{gap} 0 0"/><axis xyz="1 0 0"/><mimic joint="slide"/>
        <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
    </robot>
    ''')


#: A mobile robot: a base on a floating or planar root joint, an arm on it, a ball as hand.
WALKER = textwrap.dedent('''\
    <robot name="walker">
      <link name="world"/>
      <link name="base"><collision><geometry><box size="0.3 0.2 0.1"/></geometry></collision>
      </link>
      <link name="arm"><collision><origin xyz="0 0 0.15"/>
        <geometry><cylinder radius="0.03" length="0.3"/></geometry></collision></link>
      <link name="hand"><collision><geometry><sphere radius="0.04"/></geometry></collision>
      </link>
      <joint name="root" type="{kind}"><parent link="world"/><child link="base"/></joint>
      <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>
        <origin xyz="0.1 0 0.05"/><axis xyz="0 1 0"/>
        <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <joint name="wrist" type="fixed"><parent link="arm"/><child link="hand"/>
        <origin xyz="0 0 0.32"/></joint>
    </robot>
    ''')
WALKER_SCENE = {'objects': [
    {'name': 'wall', 'box': {'size': [0.02, 1.0, 1.0]},
     'pose': {'xyz': [0.5, 0.0, 0.2], 'rpy': [0.0, 0.0, 0.3]}},
    {'name': 'rod', 'cylinder': {'radius': 0.005, 'length': 1.0},
     'pose': {'xyz': [-0.4, 0.2, 0.1], 'rpy': [1.0, 0.2, 0.0]}},
    {'name': 'ball', 'sphere': {'radius': 0.1}, 'pose': {'xyz': [0.0, -0.5, 0.3]}},
    {'name': 'plate', 'box': {'size': [0.6, 0.6, 0.002]}, 'pose': {'xyz': [0.0, 0.0, -0.3]}},
]}


@pytest.mark.parametrize('kind', ['floating', 'planar'])
def test_a_base_translating_on_its_root_joint_is_swept_within_the_contract(tmp_path, kind):
    """A floating or planar base moved in translation, its rotation and the arm's joint the
    same at both ends: its links are swept against the scene, padded or not, and every answer
    meets the contract against sampling and python-fcl and says what the march says. A base
    that also turns is marched (never swept), within the same contract."""
    rng = np.random.default_rng(3)
    urdf = tmp_path / 'walker.urdf'
    urdf.write_text(WALKER.format(kind=kind))
    motions = contacts = sweeps = 0
    for padding in (0.0, 0.01):
        checker = CollisionChecker.from_urdf(str(urdf), scene=WALKER_SCENE, config={
            'link_padding': {'hand': padding, 'base': padding}})
        oracle = FclOracle(checker, str(urdf))
        names = checker.joint_names
        moved = 3 if kind == 'floating' else 2          # the translation's variables first
        for _ in range(40):
            q0 = np.zeros(len(names))
            if kind == 'floating':
                turn = rng.normal(size=4)
                q0[3:7] = turn / np.linalg.norm(turn)   # rot_x, rot_y, rot_z, rot_w
            else:
                q0[2] = rng.uniform(-3, 3)              # theta
            q0[:moved] = rng.uniform(-0.5, 0.5, moved)
            q0[names.index('shoulder')] = rng.uniform(-2, 2)
            q1 = q0.copy()
            q1[:moved] = rng.uniform(-0.5, 0.5, moved)
            if checker.check(q0).in_collision:
                continue
            contact, swept = _swept_motion(checker, oracle, q0, q1)
            motions, contacts, sweeps = motions + 1, contacts + contact, sweeps + swept
            turned = q1.copy()
            if kind == 'floating':
                turn = q0[3:7] + 0.05 * rng.normal(size=4)
                turned[3:7] = turn / np.linalg.norm(turn)
            else:
                turned[2] += rng.uniform(0.01, 0.5)
            assert _swept_motion(checker, oracle, q0, turned)[1] == 0
    assert motions >= 30 and contacts >= 15 and sweeps >= 3 * motions


def test_padding_and_attached_objects_count_as_in_check(panda_urdf, panda_srdf,
                                                        erd_package_paths):
    config = {'link_padding': {'panda_link4': 0.003, 'panda_hand': 0.004}}
    checker, q0, q1 = _elbow_sweep(panda_urdf, panda_srdf, erd_package_paths,
                                   {'box': {'size': [0.04, 0.04, 0.001]}})
    padded = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                        package_paths=erd_package_paths, config=config)
    padded.add_object(next(o for o in checker.scene_objects if o.name == 'thin'))
    assert padded.paddings['panda_hand'] == 0.004
    assert not padded.check(q0).in_collision
    oracle = FclOracle(padded, panda_urdf)
    result = padded.check_motion(q0, q1)
    assert_motion_against_oracle(padded, oracle, q0, q1, result)
    unpadded = checker.check_motion(q0, q1)
    assert result.in_collision and result.first_contact < unpadded.first_contact
    # An object in the hand sweeps with it (attached: never against its link).
    carried = load_scene({'objects': [{'name': 'crate', 'box': {'size': [0.04, 0.04, 0.04]},
                                       'pose': {'xyz': [0.0, 0.0, 0.15]}}]})[0]
    clear = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                       package_paths=erd_package_paths)
    clear.add_object(carried, attach_to='panda_hand', touch_links=('panda_leftfinger',
                                                                    'panda_rightfinger'))
    names = clear.joint_names
    a = np.zeros(len(names))
    a[names.index('panda_joint4')] = -2.0
    a[names.index('panda_joint6')] = 1.5
    b = a.copy()
    b[names.index('panda_joint2')] = 0.9
    # A ball where the crate (not the hand) passes half way.
    clear.check(interpolate(clear.motion_kinds, a, b, [0.5])[0])
    T = clear.link_poses()['crate']
    ball = load_scene({'objects': [{'name': 'ball', 'sphere': {'radius': 0.01},
                                    'pose': {'xyz': (T[:3, 3] + T[:3, :3] @ [0.0, 0.0, 0.03])
                                             .tolist()}}]})[0]
    clear.add_object(ball)
    times = np.linspace(0, 1, 2001)
    statuses = clear.check_batch(interpolate(clear.motion_kinds, a, b, times))
    first = np.flatnonzero(statuses.any(axis=1))[0]
    assert [clear.checked_pairs[p] for p in np.flatnonzero(statuses[first])] == [('ball',
                                                                                   'crate')]
    motion = clear.check_motion(a, b)
    assert motion.in_collision and motion.colliding_pairs == (('ball', 'crate'),)
    assert motion.first_contact <= times[first]


def test_check_path_reports_the_first_segment_not_free(panda_cell):
    checker, oracle = panda_cell
    segments = random_segments(checker, 60, seed=13)
    free = [s for s in segments if not checker.check_motion(*s).in_collision]
    hit = next(s for s in segments if checker.check_motion(*s).in_collision)
    # A path: free motions chained by straight links, then one that is not free.
    waypoints = [free[0][0], free[0][1], free[1][0], free[1][1], hit[0], hit[1]]
    result = checker.check_path(np.array(waypoints))
    expected = next(i for i in range(len(waypoints) - 1)
                    if checker.check_motion(waypoints[i], waypoints[i + 1]).in_collision)
    assert result.first_invalid_segment == expected and result.in_collision
    # The path is marched as one (its pairs' intervals span waypoints): the same contact as the
    # segment alone, both certified to the touching tolerance, not to the last bit.
    assert assert_motion_against_oracle(checker, oracle, waypoints[expected],
                                        waypoints[expected + 1], result.motion)
    alone = checker.check_motion(waypoints[expected], waypoints[expected + 1])
    assert result.motion.first_contact == pytest.approx(alone.first_contact, abs=1e-4)
    assert checker.check_path(np.array(waypoints[:2])).first_invalid_segment is None
    # A single waypoint: its instant.
    _, _, in_contact = sampled_first_contact(checker, *hit)
    assert checker.check_path(in_contact[None]).first_invalid_segment == 0
    assert checker.check_path(np.array([hit[0]])).first_invalid_segment is None


def _walk_path(checker, rng, n, step):
    """A path of n waypoints from a clear state: a smooth random walk of about step rad per
    segment, within the limits."""
    lower = np.maximum(checker.kinematics.lower, -math.pi)
    upper = np.minimum(checker.kinematics.upper, math.pi)
    q = next(q for q in random_configurations(checker, 200, seed=int(rng.integers(1 << 30)))
             if not checker.check(q).in_collision)
    direction = rng.normal(size=len(q))
    rows = [q]
    for _ in range(n - 1):
        direction = 0.8 * direction + 0.6 * rng.normal(size=len(q))
        q = np.clip(q + step * direction / np.linalg.norm(direction), lower, upper)
        rows.append(q)
    return np.array(rows)


def _first_segment_not_free(checker, Q):
    """The first segment of Q that check_motion, one by one, finds not free (None: none)."""
    return next((i for i in range(len(Q) - 1)
                 if checker.check_motion(Q[i], Q[i + 1]).in_collision), None)


def _path_as_its_segments(checker, oracle, Q, trial):
    """check_path names the segment the segments checked one by one name, and its contact
    meets the contract against sampling and python-fcl; returns whether it met contact."""
    result = checker.check_path(Q)
    expected = _first_segment_not_free(checker, Q)
    assert result.first_invalid_segment == expected, trial
    if expected is None:
        return False
    assert assert_motion_against_oracle(checker, oracle, Q[expected], Q[expected + 1],
                                        result.motion)
    return True


@pytest.mark.parametrize('cell', ['panda_cell', 'ur5_cell'])
def test_a_long_path_is_its_segments_checked_one_by_one(cell, request):
    """check_path marches the whole polyline at once (pairs far from everything leap over
    waypoints); it must say what its segments checked one by one say, and its contact must
    meet the contract against sampling and python-fcl."""
    checker, oracle = request.getfixturevalue(cell)
    rng = np.random.default_rng(37)
    contacts = free = 0
    for trial in range(12):
        Q = _walk_path(checker, rng, 30, [0.01, 0.02, 0.04, 0.08][trial % 4])
        if _path_as_its_segments(checker, oracle, Q, trial):
            contacts += 1
        else:
            free += 1
    assert contacts >= 2 and free >= 2, (contacts, free)


@pytest.mark.parametrize('cell', ['panda_cell', 'ur5_cell'])
def test_a_path_of_very_unequal_segments_is_its_segments_checked_one_by_one(cell, request):
    """A pair far from everything leaps over waypoints as far as the segments' own lengths
    allow (not the longest segment's everywhere): runs of tiny segments between long ones
    must still say what the segments say one by one, and meet the contract."""
    checker, oracle = request.getfixturevalue(cell)
    rng = np.random.default_rng(43)
    contacts = free = 0
    for trial in range(16):
        Q = _walk_path(checker, rng, 80, 1.0)
        # Segments of 1e-4 to 0.5 rad: most tiny, a few long.
        steps = np.diff(Q, axis=0)
        scale = np.exp(rng.uniform(np.log(1e-4), np.log(0.5), len(steps)))
        steps *= (scale / np.linalg.norm(steps, axis=1))[:, None]
        Q = np.vstack([Q[:1], Q[0] + np.cumsum(steps, axis=0)])
        Q = np.clip(Q, checker.kinematics.lower, checker.kinematics.upper)
        if _path_as_its_segments(checker, oracle, Q, trial):
            contacts += 1
        else:
            free += 1
    assert contacts >= 2 and free >= 2, (contacts, free)


@pytest.mark.parametrize('kind', ['floating', 'planar'])
def test_a_moving_base_path_is_its_segments_checked_one_by_one(kind):
    """The same across waypoints where a base turns (slerp, theta the shorter way) and a
    continuous elbow wraps."""
    checker = _small_on_a_base(kind)
    rng = np.random.default_rng(41)
    names = checker.joint_names
    outcomes = set()
    for _ in range(16):
        q = checker.kinematics.neutral()
        while True:   # a clear start
            for j, name in enumerate(names):
                if name.endswith(('/x', '/y', '/trans_x', '/trans_y')):
                    q[j] = rng.uniform(-0.4, 0.4)
                elif name.endswith('/theta'):
                    q[j] = rng.uniform(-4, 4)
            if not checker.check(q).in_collision:
                break
        rows = [q]
        for _ in range(9):   # small steps: a base driving and turning, the arm moving
            q = q.copy()
            for j, name in enumerate(names):
                if name.endswith(('/x', '/y', '/trans_x', '/trans_y', '/trans_z')):
                    q[j] += rng.normal(0.0, 0.03)
                elif name.endswith('/theta') or '/rot_' not in name:
                    q[j] += rng.normal(0.0, 0.3)
                else:
                    q[j] += rng.normal(0.0, 0.1)
            rows.append(q)
        Q = np.array(rows)
        result = checker.check_path(Q)
        expected = _first_segment_not_free(checker, Q)
        assert result.first_invalid_segment == expected
        if expected is not None:
            alone = checker.check_motion(Q[expected], Q[expected + 1])
            assert result.motion.first_contact == pytest.approx(alone.first_contact, abs=1e-4)
        outcomes.add(expected is None)
    assert outcomes == {True, False}


def test_bad_input_names_the_culprit_and_changes_nothing(panda_cell):
    checker, _ = panda_cell
    q0, q1 = random_segments(checker, 1, seed=19)[0]
    checker.update(q0)
    positions = checker.positions
    bad = q1.copy()
    bad[2] = math.nan
    with pytest.raises(JointStateError, match='q_to: joint "panda_joint3"'):
        checker.check_motion(q0, bad)
    with pytest.raises(JointStateError, match='q_from'):
        checker.check_motion({'panda_joint1': math.inf}, q1)
    with pytest.raises(JointStateError, match='unknown joint'):
        checker.check_motion(q0, {'nope': 1.0})
    with pytest.raises(JointStateError, match='panda_joint3'):
        checker.update_motion(bad)
    with pytest.raises(JointStateError, match='configuration 1'):
        checker.check_path(np.array([q0, bad]))
    with pytest.raises(JointStateError, match='shape'):
        checker.check_path(np.zeros((3, 2)))
    assert checker.positions == positions


# ---------------------------------------------------------------- splines and trajectories

def jtc_sample(t, t0, s0, t1, s1):
    """ros2_controllers' Trajectory::interpolate_between_points at time t, restated: state
    s = (positions, velocities or None, accelerations or None) at times t0 < t1."""
    p0, v0, a0 = s0
    p1, v1, a1 = s1
    T, x = t1 - t0, t - t0
    if v0 is None or v1 is None:
        return p0 + (p1 - p0) / T * x
    if a0 is None or a1 is None:
        c2 = (-3 * p0 + 3 * p1 - 2 * v0 * T - v1 * T) / T ** 2
        c3 = (2 * p0 - 2 * p1 + v0 * T + v1 * T) / T ** 3
        return p0 + v0 * x + c2 * x ** 2 + c3 * x ** 3
    c3 = (-20 * p0 + 20 * p1 - 3 * a0 * T ** 2 + a1 * T ** 2 - 12 * v0 * T - 8 * v1 * T) / (
        2 * T ** 3)
    c4 = (30 * p0 - 30 * p1 + 3 * a0 * T ** 2 - 2 * a1 * T ** 2 + 16 * v0 * T
          + 14 * v1 * T) / (2 * T ** 4)
    c5 = (-12 * p0 + 12 * p1 - a0 * T ** 2 + a1 * T ** 2 - 6 * v0 * T - 6 * v1 * T) / (
        2 * T ** 5)
    return (p0 + v0 * x + 0.5 * a0 * x ** 2 + c3 * x ** 3 + c4 * x ** 4 + c5 * x ** 5)


@pytest.mark.parametrize('kind', ['linear', 'cubic', 'quintic'])
def test_spline_coefficients_are_the_controllers(kind):
    rng = np.random.default_rng(len(kind))
    p0, v0, a0, p1, v1, a1 = (rng.normal(size=5) for _ in range(6))
    T = 1.7
    c = spline_coefficients(p0, v0, a0, p1, v1, a1, T, kind)
    s0 = (p0, None if kind == 'linear' else v0, a0 if kind == 'quintic' else None)
    s1 = (p1, None if kind == 'linear' else v1, a1 if kind == 'quintic' else None)
    for x in np.linspace(0, T, 17):
        ours = np.polynomial.polynomial.polyval(x / T, c.T)
        assert np.allclose(ours, jtc_sample(x, 0.0, s0, T, s1), atol=1e-12)


def test_check_spline_against_dense_sampling(panda_cell):
    checker, oracle = panda_cell
    rng = np.random.default_rng(41)
    J = len(checker.joint_names)
    contacts = 0
    for i, (q0, q1) in enumerate(random_segments(checker, 30, seed=43)):
        kind = ('linear', 'cubic', 'quintic')[i % 3]
        coef = spline_coefficients(q0, rng.normal(size=J), rng.normal(size=J), q1,
                                   rng.normal(size=J), rng.normal(size=J), 1.0, kind)
        result = checker.check_spline(coef[None])
        T = np.linspace(0.0, 1.0, 4001)
        Q = np.polynomial.polynomial.polyval(T, coef.T).T
        statuses = checker.check_batch(Q)
        hits = np.flatnonzero(statuses.any(axis=1))
        if len(hits):
            assert result.first_invalid_segment == 0
            assert result.motion.first_contact <= T[hits[0]] + 1e-12
        if result.in_collision:
            contacts += 1
            q = np.polynomial.polynomial.polyval(result.motion.first_contact, coef.T)
            poses = oracle.poses(q)
            nearest = min(oracle.pair_distance(poses, a, b) if not oracle.contains(poses, a, b)
                          else 0.0 for a, b in result.motion.colliding_pairs)
            assert nearest <= TOUCH_TOLERANCE + FCL_SLACK
        if kind == 'linear':   # the straight motion: the same answer, up to the tolerance
            straight = checker.check_motion(q0, q1)
            assert result.in_collision == straight.in_collision
            if straight.in_collision:
                assert abs(result.motion.first_contact - straight.first_contact) < 1e-5
    assert contacts >= 3


def test_trajectories_follow_the_controller_and_say_why_they_are_refused(panda_urdf,
                                                                        panda_srdf,
                                                                        erd_package_paths):
    names = [f'panda_joint{i}' for i in range(1, 8)]
    start = dict(zip(names, [0.0, -0.5, 0.0, -2.2, 0.0, 1.8, 0.8]))
    stop = dict(start, panda_joint2=0.0)
    probe = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                       package_paths=erd_package_paths)
    stopped = [TrajectoryPoint(1.0, [stop[n] for n in names]),
               TrajectoryPoint(2.0, [stop[n] for n in names])]
    # The same points with the arm still turning at the first: the controller's cubic from
    # there to the stop overshoots (joint 1 by 4/27 of the velocity, a third of the way).
    moving = [stopped[0]._replace(velocities=[2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
              stopped[1]._replace(velocities=[0.0] * 7)]
    s0 = (np.array([stop[n] for n in names]), np.array(moving[0].velocities), None)
    s1 = (np.array([stop[n] for n in names]), np.zeros(7), None)

    def front(q):  # how far to the side (+y) the robot's geometry reaches at q
        probe.check(q)
        return max(float(np.max(body_triangles(probe, link)[..., 1]))
                   for link in probe.link_names)

    peak = dict(start, **dict(zip(names, jtc_sample(1.0 + 1 / 3, 1.0, s0, 2.0, s1))))
    x_stop, x_peak = front(stop), front(peak)
    assert x_peak > x_stop + 0.03
    # A wall between the two: clear of the robot at rest, in the way of the overshoot.
    wall = {'objects': [{'name': 'wall', 'box': {'size': [2.0, 0.004, 2.0]},
                         'pose': {'xyz': [0.0, 0.5 * (x_stop + x_peak) + 0.002, 0.5]}}]}
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=wall)
    checker.update(start)
    assert checker.check_trajectory(names, stopped).valid
    result = checker.check_trajectory(names, moving)
    assert not result.valid and result.first_invalid_segment == 1
    assert any('wall' in pair for pair in result.colliding_pairs)
    assert 1.0 < result.time_from_start < 2.0 and 'contact at time_from_start' in result.reason
    # The oracle: the controller's own interpolation, sampled densely.
    times = np.linspace(1.0, 2.0, 2001)
    states = [dict(start, **dict(zip(names, jtc_sample(t, 1.0, s0, 2.0, s1)))) for t in times]
    hits = [t for t, q in zip(times, states) if checker.check(q).in_collision]
    assert hits and result.time_from_start <= hits[0] + 1e-9
    checker.update(start)
    # Limits along the way: the same overshoot takes joint 4 past its upper limit.
    low, high = checker.joint_limits['panda_joint4']
    near = dict(start, panda_joint4=high - 0.05)
    swing = [TrajectoryPoint(1.0, [near[n] for n in names], [0.0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0]),
             TrajectoryPoint(2.0, [near[n] for n in names], [0.0] * 7)]
    result = checker.check_trajectory(names, swing)
    assert not result.valid and 'panda_joint4' in result.reason and 'limits' in result.reason
    assert result.first_invalid_segment == 1 and 1.0 < result.time_from_start < 2.0
    assert checker.check_trajectory(names, swing, limit_tolerance=0.5).reason.startswith(
        'contact') or checker.check_trajectory(names, swing, limit_tolerance=0.5).valid
    # Malformed ones: each says what and how to fix.
    for points, joints, message in [
            ([], names, 'no points'),
            (stopped, names + ['nope'], 'unknown joint name'),
            (stopped, names[:-1] + [names[0]], 'given twice'),
            ([TrajectoryPoint(1.0, [0.0] * 7), TrajectoryPoint(1.0, [0.0] * 7)], names,
             'does not increase'),
            ([TrajectoryPoint(1.0, [0.0] * 6)], names, '6 values for 7 joint names'),
            ([TrajectoryPoint(1.0, [math.nan] + [0.0] * 6)], names, 'NaN'),
            ([TrajectoryPoint(1.0, [0.0] * 7, (), [0.0] * 7)], names,
             'accelerations without velocities')]:
        result = checker.check_trajectory(joints, points)
        assert not result.valid and message in result.reason, (message, result)
    assert checker.positions == {**checker.positions, **start}


def test_a_trajectory_starts_at_rest_and_takes_the_wrap_around():
    """Segment 0 starts from the current state at rest and a continuous joint from the value
    nearest the first point, as the controller does."""
    checker = CollisionChecker.from_urdf(TURNTABLE, scene=POST)
    checker.update({'turn': 2.9})
    assert checker.check_trajectory(['turn'], [TrajectoryPoint(1.0, [-2.9])]).valid
    # From there to 1.0 the controller turns through 0 (4.2 rad the other way round): the post.
    result = checker.check_trajectory(['turn'], [TrajectoryPoint(1.0, [-2.9]),
                                                 TrajectoryPoint(2.0, [1.0])])
    assert not result.valid and result.first_invalid_segment == 1
    from collision_sensor.engine.trajectory import build_segments
    coef, times = build_segments(checker, ['turn'], [TrajectoryPoint(1.0, [-2.9])],
                                 np.array([2.9]))
    assert coef[0, 0, 0] == pytest.approx(-2.9 - (2 * math.pi - 5.8))
    assert coef[0, 0, 0] + coef[0, 0, 1] == pytest.approx(-2.9)
    assert list(times) == [0.0, 1.0]


def test_polynomial_extremes_against_dense_sampling():
    """The joint-limit check's extremes of splines on [0, 1], all degrees at once (leading
    zeros, constants, roots at the ends and outside), against the polynomials sampled every
    5e-5: nothing sampled beyond them, and they within the sampling's resolution of it."""
    rng = np.random.default_rng(3)
    c = rng.normal(size=(600, 6)) * rng.choice([1e-3, 1.0, 30.0], size=(600, 1))
    for k, degree in enumerate(rng.integers(0, 6, size=600)):
        c[k, degree + 1:] = 0.0
    c[:20, 1:] = 0.0                                          # constants
    c[20:40] = [0.0, 0.0, 3.0, -2.0, 0.0, 0.0]                # derivative's roots at 0 and 1
    low, t_low, high, t_high = polynomial_extremes(c)
    assert low.shape == (600,) and np.all((0.0 <= t_low) & (t_low <= 1.0))
    grid = np.linspace(0.0, 1.0, 20001)
    sampled = np.polynomial.polynomial.polyval(grid, c.T)     # (600, grid)
    slope = np.abs(np.polynomial.polynomial.polyder(c.T)).sum(axis=0)  # bounds |p'| on [0, 1]
    resolution = slope * (grid[1] - grid[0]) + 1e-12 * (1.0 + np.abs(c).sum(axis=1))
    assert np.all(low <= sampled.min(axis=1) + 1e-12 * (1.0 + np.abs(c).sum(axis=1)))
    assert np.all(low >= sampled.min(axis=1) - resolution)
    assert np.all(high >= sampled.max(axis=1) - 1e-12 * (1.0 + np.abs(c).sum(axis=1)))
    assert np.all(high <= sampled.max(axis=1) + resolution)
    np.testing.assert_allclose([np.polynomial.polynomial.polyval(t, row)
                                for t, row in zip(t_low, c)], low, atol=1e-9)
    np.testing.assert_allclose([np.polynomial.polynomial.polyval(t, row)
                                for t, row in zip(t_high, c)], high, atol=1e-9)
