"""collision_sensor_play: timing helpers (pure), bad input (no ROS), and playback with real
rclpy in this process: the player runs ``main`` in a thread with a Context of its own, a probe
node of the test's harness records what arrives, in a namespace per test.
"""
import os

import numpy as np
import pytest

from collision_sensor.model.sequences import JointSequence, read_sequence, write_sequence
from collision_sensor.ros import player

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUNDLED = os.path.join(REPO, 'config', 'sequences')
PAPER = os.path.join(BUNDLED, 'paper_experiment.csv')


# --- pure --------------------------------------------------------------------------------------

def test_frame_offsets_follow_recorded_times_or_the_rate():
    times = np.array([10.0, 10.5, 11.75])
    assert player.frame_offsets(times).tolist() == [0.0, 0.5, 1.75]
    assert player.frame_offsets(times, rate=4.0).tolist() == [0.0, 0.25, 0.5]


def test_loop_period_adds_one_typical_gap():
    assert player.loop_period(np.array([0.0, 0.1, 0.2, 0.6])) == pytest.approx(0.7)


# --- bad input fails before ROS starts ---------------------------------------------------------

@pytest.mark.parametrize('text, args, pattern', [
    (None, [], 'no such file'),
    ('time,a,b\n0,1,2\n', ['--joints', 'a,c'], r"unknown joint column\(s\) \['b'\]"),
    ('time,a\n0,1\n0,2\n', [], 'line 3: time 0 is not after'),
    ('time,a\n0,1\n', ['--rate', '0'], '--rate 0.0: must be a positive'),
])
def test_bad_input_is_one_error_line_and_status_2(tmp_path, capsys, text, args, pattern):
    import re
    path = tmp_path / 's.csv'
    if text is not None:
        path.write_text(text)
    assert player.main([str(path)] + args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('collision_sensor_play: error: ')
    assert re.search(pattern, err[0])


# --- with ROS ----------------------------------------------------------------------------------

@pytest.fixture
def ros(request):
    from ros_helpers import RosHarness
    harness = RosHarness(request.node.name)
    yield harness
    harness.close()


def PlayerThread(argv):  # noqa: N802 (stands for the class, imported late: rclpy)
    from ros_helpers import PlayerThread as player_thread
    return player_thread(argv)


def _keep_all():
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


def test_as_fast_as_possible_delivers_every_frame_in_order(ros):
    seq = read_sequence(PAPER)
    received = ros.record(player.JointState, 'joint_states', _keep_all())
    play = PlayerThread([PAPER, '--as-fast-as-possible', '--progress', 'never',
                         '--ros-args', '-r', f'__ns:={ros.namespace}'])
    try:
        assert ros.spin_until(lambda: len(received) >= len(seq), timeout=30.0)
        assert play.join() == 0
        ros.spin_for(0.2)
    finally:
        play.stop()
    assert len(received) == len(seq)
    assert all(tuple(msg.name) == seq.joint_names for msg in received.messages)
    positions = np.array([msg.position for msg in received.messages])
    assert np.array_equal(positions, seq.positions)


def test_remapped_topic_rate_and_recorded_stamps(ros, tmp_path):
    seq = JointSequence(('a', 'b'), np.array([100.0, 100.25, 101.5]),
                        np.array([[0.0, 1.0], [0.5, 1.5], [1.0, 2.0]]), 'three')
    path = tmp_path / 'three.csv'
    write_sequence(seq, path)
    received = ros.record(player.JointState, 'remapped', _keep_all())
    play = PlayerThread([str(path), '--rate', '50', '--stamp', 'recorded',
                         '--wait-for-subscribers', '1', '--joints', 'b,a',
                         '--ros-args', '-r', f'__ns:={ros.namespace}',
                         '-r', 'joint_states:=remapped'])
    try:
        assert ros.spin_until(lambda: len(received) >= 3, timeout=15.0)
        assert play.join() == 0
    finally:
        play.stop()
    assert [tuple(msg.name) for msg in received.messages] == [('b', 'a')] * 3
    assert [list(msg.position) for msg in received.messages] == [[1.0, 0.0], [1.5, 0.5],
                                                                  [2.0, 1.0]]
    stamps = [msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
              for msg in received.messages]
    assert stamps == pytest.approx([100.0, 100.25, 101.5], abs=1e-9)


def test_loop_runs_until_shutdown(ros, tmp_path):
    seq = JointSequence(('a',), np.array([0.0, 0.01, 0.02]), np.array([[1.0], [2.0], [3.0]]))
    path = tmp_path / 'short.csv'
    write_sequence(seq, path)
    received = ros.record(player.JointState, 'joint_states', _keep_all())
    play = PlayerThread([str(path), '--loop', '--wait-for-subscribers', '1',
                         '--ros-args', '-r', f'__ns:={ros.namespace}'])
    try:
        assert ros.spin_until(lambda: len(received) >= 7, timeout=15.0)
    finally:
        status = play.stop()
    assert status == 0
    values = [msg.position[0] for msg in received.messages[:7]]
    assert values == [1.0, 2.0, 3.0, 1.0, 2.0, 3.0, 1.0]
