"""``check_motion`` on a stream (:mod:`collision_sensor.ros.motion_stream`), without ROS: which
states are swept from the one before and which start a new motion, against a fresh checker's
``check_motion`` and ``check``.

The case is the issue's: a Panda elbow move (joint 4 from -2.6 to -0.8 rad) across a 2 mm plate,
sampled sparsely (at 0.3, 0.5 and 0.8 of the way) so that every state is clear while the arm
crosses the plate between the last two.
"""
import math
import types

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.motion import interpolate
from collision_sensor.ros.motion_stream import (
    ENGINE_ERROR, FIRST_STATE, JUMP, NEW_CHECKER, NO_MOTION, STALE_GAP, MotionStream,
    joint_spans)

PLATE = (0.04, 0.04, 0.002)     # m, edge lengths: a 2 mm plate


def elbow_crossing(panda_urdf, panda_srdf, erd_package_paths):
    """Return ``(q0, q1, T_world_plate)``: the elbow move and the pose of a plate across the
    hand's path two thirds of the way (its normal along the fingertips' motion there)."""
    probe = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                       package_paths=erd_package_paths)
    names = probe.joint_names
    q0 = np.zeros(len(names))
    q0[names.index('panda_joint2')] = 0.3
    q0[names.index('panda_joint4')] = -2.6
    q1 = q0.copy()
    q1[names.index('panda_joint4')] = -0.8
    q_mid, q_next = interpolate(probe.motion_kinds, q0, q1, [2 / 3, 2 / 3 + 1e-3])

    def fingertips(q):
        probe.check(q)
        T = probe.link_poses()['panda_hand']
        return T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, 0.1])

    p = fingertips(q_mid)
    z = fingertips(q_next) - p
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = p
    return q0, q1, T


def scene_of(T_world_plate) -> dict:
    """The plate as a scene mapping (``CollisionChecker.from_urdf(scene=...)``)."""
    R = T_world_plate[:3, :3]
    rpy = [math.atan2(R[2, 1], R[2, 2]), -math.asin(R[2, 0]), math.atan2(R[1, 0], R[0, 0])]
    return {'objects': [{'name': 'plate', 'box': {'size': list(PLATE)},
                         'pose': {'xyz': T_world_plate[:3, 3].tolist(), 'rpy': rpy}}]}


@pytest.fixture(scope='module')
def crossing(panda_urdf, panda_srdf, erd_package_paths):
    q0, q1, T = elbow_crossing(panda_urdf, panda_srdf, erd_package_paths)

    def make(**config):
        return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                          package_paths=erd_package_paths, scene=scene_of(T),
                                          config=config)
    a, b, c = (q0 + t * (q1 - q0) for t in (0.3, 0.5, 0.8))
    oracle = make()
    for q in (a, b, c):
        assert not oracle.check(q).in_collision     # every instant clear
    assert not oracle.check_motion(a, b).in_collision
    assert oracle.check_motion(b, c).in_collision
    return types.SimpleNamespace(q0=a, q_half=b, q1=c, make=make, oracle=oracle)


def settings(**values):
    base = dict(check_motion=True, stale_timeout=1.0, joint_limit_tolerance=0.01)
    base.update(values)
    return types.SimpleNamespace(**base)


def fresh(checker):
    """A checker as the node builds one: its query run at the neutral state."""
    neutral = np.zeros(len(checker.joint_names))
    checker.check(neutral)
    checker.update(neutral)
    return checker


def answer(result):
    return result.in_collision, result.colliding_pairs


def instant(stream, checker, q, at, oracle, **values):
    """Check ``q`` on the stream; assert it was the instant, and the oracle's answer."""
    result, motion = stream.check(checker, q, at, settings(**values), False)
    assert motion == NO_MOTION and answer(result) == answer(oracle.check(q))


def expected_met(oracle, q_from, q_to):
    found = oracle.check_motion(q_from, q_to)
    now = oracle.check(q_to).colliding_pairs
    return found, tuple(pair for pair in found.colliding_pairs if pair not in now)


def test_a_stream_of_clear_states_crossing_the_plate_reports_the_contact_on_the_way(crossing):
    checker, stream = fresh(crossing.make()), MotionStream()
    result, motion = stream.check(checker, crossing.q0, 0.0, settings(), False)
    assert (result.in_collision, motion) == (False, NO_MOTION)   # the first: an instant
    assert stream.counts[FIRST_STATE] == 1 and stream.state(True) == 'sweeping'
    assert stream.check(checker, crossing.q_half, 0.2, settings(), False)[1] == NO_MOTION
    result, motion = stream.check(checker, crossing.q1, 0.4, settings(), False)
    found, met = expected_met(crossing.oracle, crossing.q_half, crossing.q1)
    assert not result.in_collision and motion.in_collision and motion.met == met
    assert any('plate' in pair for pair in met)
    assert motion.first_contact == pytest.approx(found.first_contact, abs=1e-4)
    assert stream.counts['swept'] == 2 and stream.counts['met_on_the_way'] == 1
    # Off: the instants, every one clear.
    stream, checker = MotionStream(), fresh(crossing.make())
    for k, q in enumerate((crossing.q0, crossing.q_half, crossing.q1)):
        instant(stream, checker, q, 0.2 * k, crossing.oracle, check_motion=False)
    assert stream.state(False) == 'off' and not stream.counts


def test_a_gap_longer_than_stale_timeout_starts_a_new_motion(crossing):
    checker, stream = fresh(crossing.make()), MotionStream()
    stream.check(checker, crossing.q_half, 10.0, settings(), False)
    assert stream.check(checker, crossing.q1, 11.5, settings(), False)[1] == NO_MOTION
    assert stream.counts[STALE_GAP] == 1
    # Within the timeout: swept (back across the plate).
    assert stream.check(checker, crossing.q_half, 12.0, settings(), False)[1].in_collision
    # stale_timeout 0: never a gap.
    stream.check(checker, crossing.q1, 100.0, settings(stale_timeout=0.0), False)
    assert stream.counts[STALE_GAP] == 1 and stream.counts['swept'] == 2


def test_a_new_checker_with_the_same_joints_continues_the_motion(crossing):
    """The new checker carries the neutral state of its build: the first state it checks is
    swept from the last state the stream passed (the old checker's), not from there."""
    old, stream = fresh(crossing.make()), MotionStream()
    stream.check(old, crossing.q_half, 0.0, settings(), False)
    new = fresh(crossing.make(padding=0.001))
    stream.replace_checker(old, new)
    assert stream.state(True) == 'sweeping'
    result, motion = stream.check(new, crossing.q1, 0.2, settings(), False)
    padded = crossing.make(padding=0.001)
    found, met = expected_met(padded, crossing.q_half, crossing.q1)
    assert motion.in_collision and motion.met == met
    assert motion.first_contact == pytest.approx(found.first_contact, abs=1e-4)
    assert stream.counts[NEW_CHECKER] == 0 and stream.counts['swept'] == 1
    # And from the neutral state the new checker was built at, it would have been another
    # answer (so the bridge is what decided): the neutral pose is not q_half.
    assert not np.allclose(np.zeros_like(crossing.q_half), crossing.q_half)


def test_a_new_robot_an_engine_error_and_a_jump_start_new_motions(crossing, ur5_urdf,
                                                                  ur5_srdf,
                                                                  erd_package_paths):
    checker, stream = fresh(crossing.make()), MotionStream()
    stream.check(checker, crossing.q_half, 0.0, settings(), False)
    other = fresh(CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf,
                                             package_paths=erd_package_paths))
    stream.replace_checker(checker, other)
    assert stream.state(True) == f'new_motion: {NEW_CHECKER}'
    q = np.full(len(other.joint_names), 0.3)
    assert stream.check(other, q, 0.1, settings(), False) == (other.check(q), NO_MOTION)
    assert stream.counts[NEW_CHECKER] == 1
    # An engine error: the next state checked from scratch, as an instant.
    stream.replace_checker(other, checker)
    stream.check(checker, crossing.q_half, 0.2, settings(), False)
    stream.restart(ENGINE_ERROR)
    assert stream.check(checker, crossing.q1, 0.3, settings(), True)[1] == NO_MOTION
    assert stream.counts[ENGINE_ERROR] == 1
    # A jump farther than a joint's range (joint_limit_policy accept lets 1e9 rad in): no
    # sweep (it would take without bound), the instant.
    far = crossing.q1.copy()
    far[checker.joint_names.index('panda_joint1')] = 1e9
    instant(stream, checker, far, 0.4, crossing.oracle)
    assert stream.counts[JUMP] == 1
    spans = joint_spans(checker, 0.01)
    lower, upper = checker.joint_limits['panda_joint1']
    assert spans[0] == pytest.approx(upper - lower + 0.02)


def test_partial_states_are_swept_from_the_last_state(crossing):
    """require_all_joints off: a mapping of the joints heard; the others keep their values."""
    checker, stream = fresh(crossing.make()), MotionStream()
    names = checker.joint_names
    stream.check(checker, dict(zip(names, crossing.q_half)), 0.0, settings(), False)
    result, motion = stream.check(checker, {'panda_joint4': float(crossing.q1[3])}, 0.2,
                                  settings(), False)
    assert motion.in_collision and motion.met == expected_met(
        crossing.oracle, crossing.q_half, crossing.q1)[1]


def test_trajectory_checks_between_states_change_no_answer_of_the_stream(crossing):
    """The node checks planned trajectories on the checker in use while joint states are
    swept on it (the engine serializes the calls; check_trajectory leaves the carried state
    alone): a stream with a trajectory checked between every two states answers as without."""
    from collision_sensor.engine.sampling import random_configurations
    from collision_sensor.engine.trajectory import TrajectoryPoint
    plain, mixed = fresh(crossing.make()), fresh(crossing.make())
    one, two = MotionStream(), MotionStream()
    rng = np.random.default_rng(4)
    frames = random_configurations(plain, 60, 9)
    arm = list(plain.joint_names[:7])
    contacts = 0
    for k, q in enumerate(frames):
        expected = one.check(plain, q, 0.01 * k, settings(), False)
        got = two.check(mixed, q, 0.01 * k, settings(), False)
        assert (answer(got[0]), got[1]) == (answer(expected[0]), expected[1]), k
        contacts += got[1].in_collision
        target = random_configurations(mixed, 1, int(rng.integers(1000)))[0]
        mixed.check_trajectory(arm, [TrajectoryPoint(1.0, target[:7], [0.0] * 7),
                                     TrajectoryPoint(2.0, q[:7], [0.0] * 7)])
    assert contacts >= 5
