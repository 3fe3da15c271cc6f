"""The sensor core's merge of partial joint states, without ROS, against the Python statement
of its rules (benchmarks/joint_state_oracle.py: a merger written from the rules alone, one message at a
time), on the Panda's joints: what each message is answered with, why, and the state after."""
import math
import random

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.sensor import Sensor
from benchmarks.joint_state_oracle import JointStateMerger, Verdict

GHOSTS = ('ghost', 'wheel_left', 'j1\n[ERROR] forged')


@pytest.fixture(scope='module')
def panda(panda_urdf, panda_srdf, erd_package_paths):
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths)


def limits_of(checker):
    return {name: checker.joint_limits[name] for name in checker.joint_names}


def oracle_for(checker, policy='reject', tolerance=0.01, max_unknown=100):
    derived = {joint.name for joint in checker.model.joints if joint.mimic is not None}
    return JointStateMerger(checker.joint_names, derived, limits=limits_of(checker),
                            limit_policy=policy, limit_tolerance=tolerance,
                            max_unknown_names=max_unknown)


def merged(sensor, names):
    return {name: float(v) for name, v in zip(names, sensor.merged_positions())
            if not math.isnan(v)}


def random_message(rng, checker):
    pool = list(checker.joint_names) + ['panda_finger_joint2'] + list(GHOSTS)
    names = [rng.choice(pool) for _ in range(rng.randint(0, 6))]
    if rng.random() < 0.5:      # a whole state, in a shuffled order: most messages of a driver
        names = list(checker.joint_names)
        rng.shuffle(names)
    positions = []
    for name in names:
        lower, upper = checker.joint_limits.get(name, (-3.0, 3.0))
        r = rng.random()
        if r < 0.04:
            positions.append(rng.choice([math.nan, math.inf, -math.inf]))
        elif r < 0.12:          # beyond a limit: by less or more than the tolerance
            positions.append(upper + rng.choice([0.005, 0.3]))
        else:
            positions.append(rng.uniform(lower, upper))
    extra = rng.choice([0, 0, 0, 0, 0, 0, -1, 1])
    if extra < 0 and positions:
        positions.pop()
    elif extra > 0:
        positions.append(0.0)
    if rng.random() < 0.03:
        positions = []
    return names, positions


@pytest.mark.parametrize('policy', ['reject', 'clamp', 'accept'])
def test_every_message_answered_as_the_rules_say(panda, policy):
    """2,000 seeded messages: the answer's kind and reason, and the merged state after each,
    are the oracle's; an accepted complete state gets a verdict, nothing else does."""
    sensor = Sensor(panda, {'joint_limit_policy': policy, 'check_motion': False})
    oracle = oracle_for(panda, policy)
    rng = random.Random({'reject': 1, 'clamp': 2, 'accept': 3}[policy])
    names = panda.joint_names
    held = False
    for k in range(2000):
        message_names, positions = random_message(rng, panda)
        outcome = oracle.merge(message_names, positions)
        verdict = sensor.step(message_names, positions, stamp=(k, 0))
        context = (message_names, positions)
        if outcome.verdict is Verdict.REJECTED:
            assert verdict.failure is not None and verdict.failure.kind == 'joint_state_rejected'
            assert verdict.failure.reason == 'joint state rejected: ' + outcome.reason, context
            assert verdict.contact        # on_rejected_input contact: the node cannot say
        elif outcome.verdict is Verdict.IGNORED:
            if held:   # the state checked last, again
                assert verdict.failure is None, context
            else:
                assert verdict.failure.kind == 'waiting_for_joints', context
        elif oracle.complete:
            assert verdict.failure is None, context
            held = True
        else:
            assert verdict.failure.kind == 'waiting_for_joints', context
        assert merged(sensor, names) == oracle.positions, context
        assert verdict.stamp == (k, 0)
    snapshot = sensor.snapshot()
    assert set(snapshot['unknown']) == oracle.unknown_names
    assert snapshot['totals']['received'] == 2000


def test_partial_states_merge_and_the_mimic_joint_is_skipped(panda):
    sensor = Sensor(panda)
    arm = [f'panda_joint{i}' for i in range(1, 8)]
    q_arm = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0]
    verdict = sensor.step(arm, q_arm)
    assert verdict.failure.kind == 'waiting_for_joints'
    assert 'panda_finger_joint1' in verdict.failure.reason
    verdict = sensor.step(['panda_finger_joint1', 'panda_finger_joint2'], [0.02, 0.5])
    assert verdict.failure is None and not verdict.contact
    assert sensor.merged_positions()[-1] == 0.02
    assert sensor.snapshot()['unknown'] == []      # the mimic joint is no unknown name


def test_unknown_names_are_remembered_up_to_the_cap_then_counted(panda):
    sensor = Sensor(panda, {'max_unknown_joints': 3})
    for k in range(10):
        sensor.step([f'extra_{k}', 'panda_joint1'], [0.0, 0.1])
    snapshot = sensor.snapshot()
    assert snapshot['unknown'] == ['extra_0', 'extra_1', 'extra_2']
    assert snapshot['unknown_overflow'] == 7
    warnings = [text for level, kind, text in sensor.notes() if kind == 'unknown']
    assert len(warnings) == 10 and 'at most 3' in warnings[-1]


def test_reasons_and_notes_escape_names_that_could_forge_log_lines(panda):
    sensor = Sensor(panda)
    verdict = sensor.step(['j1\n[ERROR] forged', 'j1\n[ERROR] forged'], [0.0, 1.0])
    assert '\n' not in verdict.failure.reason
    assert '"j1\\n[ERROR] forged"' in verdict.failure.reason
    huge = 'x' * 100_000
    verdict = sensor.step([huge], [math.nan])
    assert len(verdict.failure.reason) < 400 and '(+99' in verdict.failure.reason
    for _, _, text in sensor.notes():
        assert '\n' not in text and len(text) < 2000


def test_a_message_of_ten_thousand_names_costs_memory_in_bounds(panda):
    sensor = Sensor(panda, {'max_unknown_joints': 100})
    names = [f'n{k}' for k in range(10_000)]
    sensor.step(names, np.zeros(len(names)))
    snapshot = sensor.snapshot()
    assert len(snapshot['unknown']) == 100 and snapshot['unknown_overflow'] == 9_900


def test_serialized_messages_the_middleware_hands_over(panda):
    """Bytes as rmw hands them: read without rclpy, the same answers as the fields; malformed,
    truncated and oversized ones answered with their reason."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    sensor = Sensor(panda, {'max_joint_state_bytes': 2048, 'check_motion': False})
    q = [0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0, 0.02]
    message = JointState(name=list(panda.joint_names), position=q)
    message.header.stamp.sec, message.header.stamp.nanosec = 12, 345
    message.header.frame_id = 'base'
    data = serialize_message(message)
    verdict = sensor.take(data)
    assert verdict.failure is None and verdict.stamp == (12, 345) and verdict.frame_id == b'base'
    # (rclpy's buffer may end in a few bytes past the message: cuts well inside it)
    for cut in (3, 9, 20, len(data) // 2, len(data) - 40):
        verdict = sensor.take(data[:cut])
        assert verdict.failure.kind == 'joint_state_rejected'
        assert 'not a sensor_msgs/JointState' in verdict.failure.reason
    big = JointState(name=[f'joint_{k}' for k in range(200)], position=[0.0] * 200)
    verdict = sensor.take(serialize_message(big))
    assert 'above max_joint_state_bytes (2048)' in verdict.failure.reason
    assert sensor.snapshot()['totals']['rejected_oversized'] == 1
    assert sensor.snapshot()['totals']['rejected_malformed'] == 5
    # Nothing known was lost: the state is the first message's.
    assert list(sensor.merged_positions()) == q
