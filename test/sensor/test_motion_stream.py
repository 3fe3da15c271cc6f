"""``check_motion`` on a stream of joint states, without ROS: which states the sensor sweeps
from the one before and which start a new motion (counted by reason), against a fresh
checker's ``check_motion`` and ``check`` (the case: test/motion_cases.py)."""
import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.sensor import Sensor
from motion_cases import crossing  # noqa: F401 - the case's fixture


class Clock:
    """A monotonic clock the test moves (s)."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def stream(checker, clock=None, **parameters):
    values = dict(check_motion=True, stale_timeout=1.0)
    values.update(parameters)
    return Sensor(checker, values, clock=clock or Clock())


def step(sensor, q, at=None):
    if at is not None:
        sensor.clock.now = at
    return sensor.step(sensor.checker.joint_names, q)


def expected_met(oracle, q_from, q_to):
    found = oracle.check_motion(q_from, q_to)
    now = oracle.check(q_to).colliding_pairs
    return found, tuple(pair for pair in found.colliding_pairs if pair not in now)


def counts(sensor):
    return sensor.snapshot()['motion_counts']


def test_a_stream_of_clear_states_crossing_the_plate_reports_the_contact_on_the_way(crossing):
    sensor = stream(crossing.make())
    verdict = step(sensor, crossing.q0, 0.0)
    assert not verdict.contact and verdict.met_on_the_way == ()   # the first: an instant
    assert counts(sensor) == {'first_state': 1}
    assert sensor.snapshot()['motion_state'] == 'sweeping'
    assert not step(sensor, crossing.q_half, 0.2).contact
    verdict = step(sensor, crossing.q1, 0.4)
    found, met = expected_met(crossing.oracle, crossing.q_half, crossing.q1)
    assert verdict.colliding_pairs == () and verdict.contact
    assert verdict.met_on_the_way == met and any('plate' in pair for pair in met)
    assert verdict.first_contact == pytest.approx(found.first_contact, abs=1e-4)
    assert counts(sensor) == {'first_state': 1, 'swept': 2, 'met_on_the_way': 1}
    # Off: the instants, every one clear.
    sensor = stream(crossing.make(), check_motion=False)
    for k, q in enumerate((crossing.q0, crossing.q_half, crossing.q1)):
        verdict = step(sensor, q, 0.2 * k)
        assert not verdict.contact and verdict.first_contact is None
    assert sensor.snapshot()['motion_state'] == 'off' and counts(sensor) == {}


def test_a_gap_longer_than_stale_timeout_starts_a_new_motion(crossing):
    sensor = stream(crossing.make())
    step(sensor, crossing.q_half, 10.0)
    assert not step(sensor, crossing.q1, 11.5).contact
    assert counts(sensor)['stale_gap'] == 1
    # Within the timeout: swept (back across the plate).
    assert step(sensor, crossing.q_half, 12.0).contact
    # stale_timeout 0: never a gap.
    sensor.configure(dict(check_motion=True, stale_timeout=0.0))
    step(sensor, crossing.q1, 100.0)
    assert counts(sensor)['stale_gap'] == 1 and counts(sensor)['swept'] == 2


def test_a_new_checker_with_the_same_joints_continues_the_motion(crossing):
    """The new checker carries the state of its build: the first state it checks is swept
    from the last state the stream passed (the old checker's), not from there."""
    sensor = stream(crossing.make())
    step(sensor, crossing.q_half, 0.0)
    padded = crossing.make(padding=0.001)
    padded.check(np.zeros(len(padded.joint_names)))
    sensor.use_checker(padded)
    assert sensor.snapshot()['motion_state'] == 'sweeping'
    verdict = step(sensor, crossing.q1, 0.2)
    found, met = expected_met(crossing.make(padding=0.001), crossing.q_half, crossing.q1)
    assert verdict.contact and verdict.met_on_the_way == met
    assert verdict.first_contact == pytest.approx(found.first_contact, abs=1e-4)
    assert counts(sensor).get('new_checker', 0) == 0 and counts(sensor)['swept'] == 1


def test_a_new_robot_an_engine_error_and_a_jump_start_new_motions(crossing, ur5_urdf, ur5_srdf,
                                                                  erd_package_paths):
    panda = crossing.make()
    sensor = stream(panda, joint_limit_policy='accept')
    step(sensor, crossing.q_half, 0.0)
    ur5 = CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf, package_paths=erd_package_paths)
    sensor.use_checker(ur5)
    assert sensor.snapshot()['motion_state'] == 'new_motion: new_checker'
    q = np.full(len(ur5.joint_names), 0.3)
    verdict = step(sensor, q, 0.1)
    assert verdict.colliding_pairs == ur5.check(q).colliding_pairs
    assert verdict.first_contact is None and counts(sensor)['new_checker'] == 1
    # An engine error: the next state checked from scratch, as an instant.
    sensor.use_checker(panda)
    step(sensor, crossing.q_half, 0.2)
    joint = panda.joint_names.index('panda_joint1')
    sensor.core.inject_fault(joint, 0.123, 'fault injected by the test', True)
    faulty = crossing.q1.copy()
    faulty[joint] = 0.123
    verdict = step(sensor, faulty, 0.25)
    assert verdict.failure.kind == 'engine_error' and verdict.contact
    assert 'fault injected by the test' in verdict.failure.reason
    assert sensor.snapshot()['engine_error'] and \
        sensor.snapshot()['motion_state'] == 'new_motion: engine_error'
    verdict = step(sensor, crossing.q1, 0.3)
    assert verdict.failure is None and verdict.first_contact is None
    assert counts(sensor)['engine_error'] == 1 and not sensor.snapshot()['engine_error']
    # A jump farther than a joint's range (joint_limit_policy accept lets 1e5 rad in): no sweep
    # (it would take without bound), the instant.
    far = crossing.q1.copy()
    far[joint] = 1e5
    verdict = step(sensor, far, 0.4)
    assert verdict.colliding_pairs == crossing.oracle.check(far).colliding_pairs
    assert verdict.first_contact is None and counts(sensor)['jump'] == 1


def test_partial_states_are_swept_from_the_last_state(crossing):
    """require_all_joints off: the joints heard; the others keep their values."""
    sensor = stream(crossing.make(), require_all_joints=False)
    names = list(sensor.checker.joint_names)
    sensor.step(names, crossing.q_half)
    verdict = sensor.step(['panda_joint4'], [float(crossing.q1[3])])
    assert verdict.contact and verdict.met_on_the_way == expected_met(
        crossing.oracle, crossing.q_half, crossing.q1)[1]


def test_trajectory_checks_between_states_change_no_answer_of_the_stream(crossing):
    """Planned trajectories are checked on the checker in use while joint states are swept on
    it (check_trajectory leaves the carried state alone): a stream with a trajectory checked
    between every two states answers as without."""
    from collision_sensor.engine.sampling import random_configurations
    from collision_sensor.engine.trajectory import TrajectoryPoint
    one, two = stream(crossing.make()), stream(crossing.make())
    rng = np.random.default_rng(4)
    frames = random_configurations(one.checker, 60, 9)
    arm = list(one.checker.joint_names[:7])
    contacts = 0
    for k, q in enumerate(frames):
        expected = step(one, q, 0.01 * k)
        got = step(two, q, 0.01 * k)
        assert (got.contact, got.colliding_pairs, got.met_on_the_way) == \
            (expected.contact, expected.colliding_pairs, expected.met_on_the_way), k
        contacts += got.contact
        target = random_configurations(two.checker, 1, int(rng.integers(1000)))[0]
        result, reason = two.check_trajectory(arm, [
            TrajectoryPoint(1.0, target[:7], [0.0] * 7), TrajectoryPoint(2.0, q[:7], [0.0] * 7)])
        assert result is not None, reason
    assert contacts >= 5
