"""Messages to and from YAML as ros2 topic echo prints them and ros2 topic pub takes them."""
import pytest
import yaml

pytest.importorskip('rclpy')

from builtin_interfaces.msg import Duration  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from collision_sensor import ConfigError  # noqa: E402
from collision_sensor.ros.message_yaml import (  # noqa: E402
    fill_message, message_to_yaml, message_type, to_plain)


def test_a_trajectory_round_trips():
    msg = JointTrajectory(joint_names=['a', 'b'], points=[
        JointTrajectoryPoint(positions=[0.5, -1.0], velocities=[0.0, 0.1],
                             time_from_start=Duration(sec=2, nanosec=5))])
    msg.header.frame_id = 'planner'
    text = message_to_yaml(msg)
    assert text.startswith('header:\n  stamp:\n')
    again = fill_message(JointTrajectory(), yaml.safe_load(text))
    assert again == msg


def test_integers_for_floats_and_errors_named_by_path():
    msg = fill_message(JointTrajectory(), {'joint_names': ['a'], 'points': [
        {'positions': [1], 'time_from_start': {'sec': 1}}]})
    assert list(msg.points[0].positions) == [1.0]
    for values, text in (
            ({'points': [{'position': [1.0]}]}, r'points\[0\]\.position: .*has no field'),
            ({'joint_names': 'a'}, 'one string'),
            ({'points': [{'positions': ['x']}]}, r'points\[0\]\.positions: .*sequence<double>'),
            ({'points': {'positions': [1.0]}}, 'expected a list of JointTrajectoryPoint'),
            ([1, 2], 'expected a mapping')):
        with pytest.raises(ConfigError, match=text):
            fill_message(JointTrajectory(), values)


def test_long_arrays_are_shown_by_their_length():
    msg = JointTrajectory(points=[JointTrajectoryPoint(positions=[0.0] * 200)])
    assert to_plain(msg)['points'][0]['positions'] == '<200 values>'
    assert len(to_plain(msg, None)['points'][0]['positions']) == 200


def test_message_types_by_name():
    assert message_type('trajectory_msgs/msg/JointTrajectory') is JointTrajectory
    assert message_type('trajectory_msgs/JointTrajectory') is JointTrajectory
    with pytest.raises(ConfigError, match='package/msg/Type'):
        message_type('JointTrajectory')
    with pytest.raises(ConfigError, match='not installed'):
        message_type('no_such_msgs/msg/Thing')
