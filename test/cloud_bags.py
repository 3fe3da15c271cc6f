"""Bags of joint states and PointCloud2 messages for the tests, written with ``rosbags``
directly (not with collision_sensor's writer), and the Panda scenario they share.

The scenario (:func:`panda_sweep`): the Panda swings its first joint through 2 rad in 2 s,
joint states at 10 Hz; ``/camera/points`` sees a box of points in the hand's way, in the frame
of ``panda_link1`` (which turns with joint 1) at the first frame, stamped then;
``/wrist/points`` sees the robot's own surfaces at a moment between two frames, in the world
frame ``panda_link0`` (the hand moves about 6 cm between frames there: a cloud filtered with
either frame's pose instead of the pose at its stamp keeps points); ``/bad/points`` holds
one cloud of each bad kind of issue 29 item 4 but one: the cloud whose every point is NaN comes
on ``/camera/points`` at 1.15 s (the box stays the obstacle); one more comes after the last
frame.
"""
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from engine_oracles import surface_points

NS = 1_000_000_000
FLOAT32, FLOAT64, INT32 = 7, 8, 5
OBJECT_TOPIC, SELF_TOPIC, BAD_TOPIC = '/camera/points', '/wrist/points', '/bad/points'
PANDA_JOINTS = tuple(f'panda_joint{i}' for i in range(1, 8)) + ('panda_finger_joint1',)
WORLD = 'panda_link0'


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def cloud_message(typestore, points, frame, stamp_ns, datatype=FLOAT32, point_step=None,
                  fields='xyz'):
    """A rosbags PointCloud2 of ``points`` (n, 3); ``datatype``, ``point_step`` and ``fields``
    may be made wrong on purpose."""
    t = typestore.types
    points = np.asarray(points, dtype=np.float64)
    kind = {FLOAT32: '<f4', FLOAT64: '<f8', INT32: '<i4'}[datatype]
    item = np.dtype(kind).itemsize
    data = np.ascontiguousarray(points.astype(kind)).view(np.uint8).reshape(-1)
    step = 3 * item if point_step is None else point_step
    sec, nanosec = divmod(stamp_ns, NS)
    return t['sensor_msgs/msg/PointCloud2'](
        header=t['std_msgs/msg/Header'](
            stamp=t['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id=frame),
        height=1, width=len(points),
        fields=[t['sensor_msgs/msg/PointField'](name=axis, offset=k * item, datatype=datatype,
                                                count=1) for k, axis in enumerate(fields)],
        is_bigendian=False, point_step=step, row_step=step * len(points),
        data=data, is_dense=False)


def write_bag(path, fmt, joint_names, times, positions, clouds):
    """Write a bag: JointState on /joint_states at ``times`` (s), and ``clouds``: a list of
    ``(topic, log_time_s, message)``. A path ending in .mcap or .db3 gets the bare storage file.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    typestore = _typestore()
    t = typestore.types
    bare = Path(path).suffix in ('.mcap', '.db3')
    scratch = tempfile.mkdtemp() if bare else None
    bag_dir = os.path.join(scratch, 'bag') if bare else str(path)
    writer = Writer(bag_dir, version=9, storage_plugin=(
        StoragePlugin.MCAP if fmt == 'mcap' else StoragePlugin.SQLITE3))
    writer.open()
    joints = writer.add_connection('/joint_states', 'sensor_msgs/msg/JointState',
                                   typestore=typestore)
    topics = {}
    entries = []
    for time, row in zip(times, positions):
        ns = int(round(time * NS))
        sec, nanosec = divmod(ns, NS)
        msg = t['sensor_msgs/msg/JointState'](
            header=t['std_msgs/msg/Header'](
                stamp=t['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id=''),
            name=list(joint_names), position=np.asarray(row, dtype=np.float64),
            velocity=np.zeros(0), effort=np.zeros(0))
        entries.append((ns, joints, typestore.serialize_cdr(msg, 'sensor_msgs/msg/JointState')))
    for topic, log_time, msg in clouds:
        if topic not in topics:
            topics[topic] = writer.add_connection(topic, 'sensor_msgs/msg/PointCloud2',
                                                  typestore=typestore)
        entries.append((int(round(log_time * NS)), topics[topic],
                        typestore.serialize_cdr(msg, 'sensor_msgs/msg/PointCloud2')))
    for ns, connection, raw in sorted(entries, key=lambda entry: entry[0]):
        writer.write(connection, ns, raw)
    writer.close()
    if bare:
        suffix = '.mcap' if fmt == 'mcap' else '.db3'
        shutil.move(os.path.join(bag_dir, 'bag' + suffix), str(path))
        shutil.rmtree(scratch)


def sweep_positions(times):
    """(n, 8) Panda joint values: joint 1 from -1 to 1 rad over 2 s, the arm reaching out."""
    times = np.asarray(times, dtype=np.float64)
    q = np.zeros((len(times), len(PANDA_JOINTS)))
    q[:, 0] = -1.0 + times
    q[:, 1] = 0.6
    q[:, 3] = -1.6
    q[:, 5] = 2.0
    q[:, 6] = 0.8
    q[:, 7:] = 0.02
    return q


def panda_sweep(checker, rng):
    """The scenario of the module docstring: ``(times, positions, clouds, facts)``; ``facts``
    holds the object's points (world), the self cloud's time and its points (world)."""
    typestore = _typestore()
    times = np.round(np.arange(21) * 0.1, 6)
    positions = sweep_positions(times)
    # The hand's position at t = 1.4 s: the object's centre, a 6 cm box of points.
    checker.check(sweep_positions([1.4])[0])
    hand = checker.link_poses()['panda_hand'][:3, 3]
    box = hand + rng.uniform(-0.03, 0.03, (600, 3))
    # The box in panda_link1's frame at the first frame (placed with that frame's pose).
    checker.check(positions[0])
    T_link1 = checker.link_poses()['panda_link1']
    box_in_link1 = (box - T_link1[:3, 3]) @ T_link1[:3, :3]
    # The robot's own surfaces half-way between frames 8 and 9 (world frame).
    t_self = 0.85
    checker.check(sweep_positions([t_self])[0])
    own = surface_points(checker, rng, per_element=150)
    nan = np.full((50, 3), np.nan)
    some = rng.uniform(-0.1, 0.1, (50, 3)) + [0.5, 0.5, 0.5]
    clouds = [
        (OBJECT_TOPIC, 0.0, cloud_message(typestore, box_in_link1, 'panda_link1', 0)),
        (SELF_TOPIC, t_self + 0.03, cloud_message(typestore, own, WORLD, int(t_self * NS))),
        (BAD_TOPIC, 0.31, cloud_message(typestore, some, WORLD, int(0.31 * NS),
                                        datatype=INT32)),
        (OBJECT_TOPIC, 1.15, cloud_message(typestore, nan, WORLD, int(1.15 * NS))),
        (BAD_TOPIC, 0.71, cloud_message(typestore, some, WORLD, int(0.71 * NS),
                                        point_step=8)),
        (BAD_TOPIC, 1.11, cloud_message(typestore, some, 'camera_optical_frame',
                                        int(1.11 * NS))),
        (BAD_TOPIC, 1.31, cloud_message(typestore, some, WORLD, int(1.31 * NS),
                                        fields='xyw')),
        (BAD_TOPIC, 2.5, cloud_message(typestore, some, WORLD, int(2.5 * NS))),
    ]
    return times, positions, clouds, {'box': box, 't_self': t_self, 'own': own}
