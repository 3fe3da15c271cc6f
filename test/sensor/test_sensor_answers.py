"""What the sensor hands the node, without ROS running: the answers serialized as the messages
rclpy would make (decoded by rclpy's own deserializer), the fail-safe policies, staleness, the
window of recent states a cloud is placed with, and text from the network escaped."""
import math

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.motion import interpolate
from collision_sensor.sensor import Failure, Sensor
from collision_sensor.untrusted_text import printable
from small_robot import SMALL_ROBOT, SMALL_SCENE

rclpy_serialization = pytest.importorskip('rclpy.serialization')


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def decoded(verdict):
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import Bool, Float64
    types = {'contact': Bool, 'colliding_pairs': DiagnosticArray, 'near': Bool,
             'min_distance': Float64, 'near_pairs': DiagnosticArray}
    return [(topic, rclpy_serialization.deserialize_message(data, types[topic]))
            for topic, data in verdict.messages]


@pytest.fixture()
def small():
    return CollisionChecker.from_urdf(SMALL_ROBOT, scene=SMALL_SCENE)


def colliding_state(checker):
    """A state of the small robot in contact with the pillar."""
    for shoulder in np.linspace(-2.4, 2.4, 97):
        q = np.array([shoulder, 0.0, 0.0, 0.0])
        if checker.check(q).in_collision:
            return q
    raise AssertionError('no state in contact')


def test_messages_are_the_ones_rclpy_reads(small):
    sensor = Sensor(small, {'warning_distance': 0.3})
    names = small.joint_names
    q = colliding_state(small)
    verdict = sensor.step(names, q, stamp=(7, 8), frame_id='odom')
    messages = decoded(verdict)
    assert [topic for topic, _ in messages] == ['contact', 'colliding_pairs', 'near',
                                                'min_distance', 'near_pairs']
    contact, pairs, near, minimum, near_pairs = (m for _, m in messages)
    assert contact.data is True and near.data is True
    assert (pairs.header.stamp.sec, pairs.header.stamp.nanosec) == (7, 8)
    assert pairs.header.frame_id == 'odom'
    from diagnostic_msgs.msg import DiagnosticStatus
    assert [(s.name, s.level, s.hardware_id) for s in pairs.status] == [
        (f'{a}:{b}', DiagnosticStatus.ERROR, 'base') for a, b in verdict.colliding_pairs]
    for status, (a, b) in zip(pairs.status, verdict.colliding_pairs):
        assert status.message == f'{a} collides with {b}'
        assert [(kv.key, kv.value) for kv in status.values] == [('link_a', a), ('link_b', b)]
    assert minimum.data == verdict.zone.min_distance <= 0.0
    for status, near_pair in zip(near_pairs.status, verdict.zone.pairs):
        values = {kv.key: kv.value for kv in status.values}
        assert float(values['distance']) == near_pair.distance
        assert np.allclose([float(v) for v in values['point_a'].split()], near_pair.point_a)
        assert status.level == (DiagnosticStatus.ERROR if near_pair.distance <= 0
                                else DiagnosticStatus.WARN)
    # The same pairs again: the message is the last one with the new stamp.
    again = decoded(sensor.step(names, q, stamp=(9, 0)))
    assert again[1][1].header.stamp.sec == 9 and again[1][1].status == pairs.status


@pytest.mark.parametrize('policy', ['contact', 'hold'])
def test_fail_safe_policies(small, policy):
    """A rejected joint state, an engine error and a stale stream: with contact, contact true
    and the failure alone; with hold, the held verdict's contact and pairs after the failure;
    the zone follows."""
    clock = Clock()
    sensor = Sensor(small, {'on_rejected_input': policy, 'on_engine_error': policy,
                            'stale_policy': policy, 'stale_timeout': 0.5,
                            'warning_distance': 0.3}, clock=clock)
    names = small.joint_names
    # Nothing held yet: as contact whatever the policy.
    verdict = sensor.step(names, [math.nan] * 4)
    assert verdict.contact and verdict.failure.policy == policy
    assert verdict.colliding_pairs == () and verdict.zone.min_distance == -math.inf
    held = sensor.step(names, colliding_state(small))
    assert held.contact and held.colliding_pairs
    verdict = sensor.step(names, [math.nan] * 4)
    messages = dict(decoded(verdict))
    statuses = [s.name for s in messages['colliding_pairs'].status]
    assert statuses[0] == 'joint_state_rejected'
    zone_statuses = [s.name for s in messages['near_pairs'].status]
    assert zone_statuses[0] == 'joint_state_rejected'
    if policy == 'hold':
        assert verdict.contact == held.contact
        assert verdict.colliding_pairs == held.colliding_pairs
        assert statuses[1:] == [f'{a}:{b}' for a, b in held.colliding_pairs]
        assert verdict.zone.min_distance == held.zone.min_distance
    else:
        assert verdict.contact and statuses == ['joint_state_rejected']
        assert verdict.zone.near and verdict.zone.min_distance == -math.inf
    # An engine error (injected): answered by on_engine_error, the state unchanged.
    before = sensor.merged_positions().copy()
    sensor.core.inject_fault(0, 0.25, 'engine fault injected by the test', False)
    verdict = sensor.step(names, [0.25, 0.0, 0.0, 0.0])
    assert verdict.failure.kind == 'engine_error' and verdict.failure.policy == policy
    assert 'engine fault injected by the test' in verdict.failure.reason
    assert list(sensor.merged_positions()) == list(before)
    assert verdict.contact == (True if policy == 'contact' else held.contact)
    # Staleness: the first poll after stale_timeout starts an episode; contact answers it.
    clock.now = 0.4
    assert sensor.poll() is None
    clock.now = 1.0
    verdict = sensor.poll()
    assert sensor.snapshot()['stale']
    if policy == 'contact':
        assert verdict.contact and verdict.failure.kind == 'joint_states_stale'
    else:
        assert verdict is None      # hold: contact keeps the last verdict
    assert sensor.poll() is None    # once per episode
    sensor.step(names, before)
    assert not sensor.snapshot()['stale']
    assert any(kind == 'resumed' for _, kind, _ in sensor.notes())


def test_a_failing_source_answers_every_verdict_until_it_recovers(small):
    sensor = Sensor(small)
    names = small.joint_names
    sensor.step(names, [0.0] * 4)
    failure = Failure('point_cloud_timeout', 'camera: no cloud', 'contact')
    sensor.fail_source('camera', failure)
    verdict = sensor.step(names, [0.1, 0.0, 0.0, 0.0])
    assert verdict.failure == failure and verdict.contact
    sensor.recover_source('camera')
    assert sensor.step(names, [0.1, 0.0, 0.0, 0.0]).failure is None


def test_the_window_places_a_stamp_as_the_motion_does(small):
    """Interpolated between the two complete states around a stamp, by the motion's rules (a
    continuous joint the shorter way round); the newest after; 'old' before the window."""
    sensor = Sensor(small, {'point_cloud_state_window': 1.0})
    names = small.joint_names
    kinds = small.motion_kinds
    assert sensor.positions_at(5.0) is None
    states = [np.array([0.1 * k, 3.0 if k % 2 else -3.0, -0.1, 0.2]) for k in range(5)]
    for k, q in enumerate(states):
        sensor.step(names, q, stamp=10.0 + 0.25 * k)
    for t in (10.3, 10.5, 10.99):
        k = int((t - 10.0) / 0.25)
        s = (t - 10.0 - 0.25 * k) / 0.25
        expected = interpolate(kinds, states[k], states[k + 1], [s])[0]
        assert np.allclose(sensor.positions_at(t), expected)
    assert np.array_equal(sensor.positions_at(20.0), states[-1])
    sensor.step(names, states[0], stamp=12.5)      # the window keeps 1 s before the newest
    assert sensor.positions_at(10.6) == 'old'


@pytest.mark.parametrize('text', ['plain_joint', 'tab\there', 'back\\slash', 'bell\x07',
                                  'x' * 500, 'quote"and\'', 'ctrl\x1b[31mred'])
def test_names_are_escaped_as_the_python_side_escapes_them(small, text):
    sensor = Sensor(small)
    verdict = sensor.step([text, text], [1.0, 2.0])
    assert verdict.failure.reason == ('joint state rejected: joint names given more than once: '
                                      f'"{printable(text)}"')


def test_beyond_ascii_every_character_is_escaped(small):
    sensor = Sensor(small)
    name = 'gelenk_\u00e4\u202e\U0001f600'
    verdict = sensor.step([name, name], [1.0, 2.0])
    assert '"gelenk_\\xe4\\u202e\\U0001f600"' in verdict.failure.reason
    bad = b'bad\xff\xfe'.decode('latin-1')     # as a str, its own code points
    verdict = sensor.step([bad, bad], [1.0, 2.0])
    assert '\\xff\\xfe' in verdict.failure.reason


def test_importing_the_sensor_imports_no_ros():
    import subprocess
    import sys
    code = ('import sys, collision_sensor.sensor; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "sensor_msgs", "std_msgs", "diagnostic_msgs")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == '[]'


def test_the_docs_example_runs_and_says_what_it_prints(monkeypatch):
    """docs/node.md's example of the sensor without ROS, against what the calls return."""
    import os
    import re
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    text = open(os.path.join(here, 'docs', 'node.md')).read()
    section = text[text.index('## The sensor without ROS'):]
    code, = re.findall(r'^```python\n(.*?)^```', section, re.M | re.S)
    monkeypatch.chdir(here)
    scope = {}
    exec(compile(code, 'docs/node.md', 'exec'), scope)
    sensor, verdict = scope['sensor'], scope['verdict']
    assert verdict.contact and ('tool_link', 'washer_cabinet') in verdict.colliding_pairs
    assert [topic for topic, _ in verdict.messages] == ['contact', 'colliding_pairs']
    rejected = sensor.step(['elbow'], [float('nan')], stamp=1.3)
    assert rejected.failure.reason == ('joint state rejected: positions that are not finite: '
                                       '"elbow"=nan') and rejected.contact
