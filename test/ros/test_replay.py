"""Replay through ROS equals the offline check, frame for frame, for every bundled sequence.

The node (``CollisionSensorNode`` on the demo cell, ``joint_states_qos: reliable``) runs in
this process with a Context of its own (``ros_helpers.RosHarness``); the player
(``collision_sensor_play --as-fast-as-possible --stamp recorded``) runs its ``main`` in a
thread with another Context, so every frame crosses real DDS (shared memory). The reference is
``collision_sensor_check SEQUENCE --json``. Verdicts are matched to frames by header stamp (the
recorded time), so a lost, repeated or reordered frame shows as a mismatch at that frame.
A bag with scene changes (``moving_part``) also makes the node answer each applied array at
once: those verdicts carry the root frame in their header and are told apart so; every array
after the first frame gets one.
"""
import json

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from std_msgs.msg import Bool  # noqa: E402

from collision_sensor.model.sequences import read_sequence  # noqa: E402
from collision_sensor.ros import playback_messages  # noqa: E402
from collision_sensor.ros.demo_node_process import demo_cell_parameters  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from collision_sensor.tools import offline_check
from ros_helpers import PlayerThread, RosHarness  # noqa: E402

#: Every verdict, including one published before the probe matched (transient local).
EVERY_VERDICT = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture
def ros(request):
    harness = RosHarness(request.node.name)
    yield harness
    harness.close()


def offline_frames(name, tmp_path, capsys):
    """Return ``collision_sensor_check NAME --json`` as a list of dicts, one per frame."""
    path = tmp_path / f'{name}.jsonl'
    status = offline_check.main([name, '--json', str(path), '--progress', 'never'])
    capsys.readouterr()    # the summary
    assert status in (offline_check.EXIT_CLEAR, offline_check.EXIT_COLLISION)
    return [json.loads(line) for line in path.read_text().splitlines()]


def stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def pairs_of(msg: DiagnosticArray):
    return [status.name.split(':', 1) for status in msg.status]


@pytest.mark.slow
@pytest.mark.parametrize('name', offline_check.BUNDLED_SEQUENCES)
def test_node_verdicts_equal_the_offline_check(ros, tmp_path, capsys, name):
    expected = offline_frames(name, tmp_path, capsys)
    # One verdict per frame at any pace: the node checks every state in order.
    # (stale_timeout 0: the player's last acknowledgements may take longer than the default
    # timeout on a loaded machine, and a stale answer is not what this test counts)
    values = dict(demo_cell_parameters(), overload_policy='every', stale_timeout=0.0)
    parameters = [Parameter(key, value=value) for key, value in values.items()]
    ros.add(CollisionSensorNode(namespace=ros.namespace, context=ros.context,
                                parameter_overrides=parameters))
    contact = ros.record(Bool, 'contact', EVERY_VERDICT)
    pairs = ros.record(DiagnosticArray, 'colliding_pairs', EVERY_VERDICT)
    assert ros.spin_until(lambda: ros.probe.count_subscribers(
        f'{ros.namespace}/joint_states') > 0, 60.0), 'the node never subscribed'

    play = PlayerThread([offline_check.bundled_sequence_path(name), '--as-fast-as-possible',
                         '--stamp', 'recorded', '--progress', 'never',
                         '--ros-args', '-r', f'__ns:={ros.namespace}'])
    try:
        # The first check may compile kernels on a cold cache: a generous timeout.
        seq = read_sequence(offline_check.bundled_sequence_path(name))
        answered_scene = sum(len(events) for events in seq.scene_before()[1:])
        total = len(expected) + answered_scene
        done = ros.spin_until(lambda: len(pairs) >= total and len(contact) >= total, 120.0)
        assert play.join() == 0
        ros.spin_for(0.2)    # anything beyond the last frame would arrive now
    finally:
        play.stop()
    assert done, f'{len(pairs)} verdicts for {len(expected)} frames'

    want = [(playback_messages.stamp_from_seconds(frame['time']), frame['pairs'])
            for frame in expected]
    assert len(contact.messages) == len(pairs.messages) == total
    on_frames = [(msg, bool_msg.data) for msg, bool_msg in zip(pairs.messages, contact.messages)
                 if not msg.header.frame_id]     # not the answers to scene arrays
    got = [(msg.header.stamp, pairs_of(msg)) for msg, _ in on_frames]
    for index, (frame, (stamp, verdict)) in enumerate(zip(want, got)):
        assert (stamp_ns(stamp), verdict) == (stamp_ns(frame[0]), frame[1]), \
            f'{name} frame {index} (t = {expected[index]["time"]} s)'
    assert len(got) == len(want)
    assert [data for _, data in on_frames] == [f['in_collision'] for f in expected]
    # into_drum_clear is clear throughout; guard_rail_5hz only between its frames.
    assert any(f['in_collision'] for f in expected) == (
        name not in ('into_drum_clear', 'guard_rail_5hz'))
