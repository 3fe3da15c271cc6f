"""Recorded joint-state sequences: read and write CSV files and rosbag2 bags.

A sequence is a list of frames, each a time and one position per joint
(:class:`JointSequence`). Two kinds of files hold one:

CSV (``*.csv``)
    The first row that is not blank and not a comment (``#`` in the first column) is the
    header: ``time`` and then one column per joint, named as in the URDF. Every following row
    is one frame: the time in seconds, then the joint positions (rad for revolute joints, m for
    prismatic ones). Times must strictly increase; every value must be a finite number::

        # paper experiment, 50 Hz
        time,shoulder_pan,shoulder_lift,elbow,wrist_roll,wrist_pitch,tool_roll
        0.0,0.0,0.0,0.0,0.0,0.0,0.0
        0.02,0.001,0.0,-0.002,0.0,0.0,0.0

rosbag2 (a bag directory with ``metadata.yaml``, or a bare ``*.mcap`` / ``*.db3`` file)
    ``sensor_msgs/msg/JointState`` messages on one topic (``/joint_states`` by default). The
    frame time is ``header.stamp`` (the bag's log time when the stamp is zero), with nanosecond
    resolution. A message may name only some joints: messages are merged into a running state,
    and each message yields a frame once every joint has been seen; a message stamped with the
    same time as the previous frame updates that frame. Joints that are not asked for are
    ignored.

    Scene changes: ``visualization_msgs/msg/MarkerArray`` messages on ``/scene`` (the node's
    ``scene`` topic, as ``ros2 bag record`` stores it; :data:`SCENE_TOPIC`), if the bag has
    that topic. Each becomes a :class:`SceneEvent` at its first marker's ``header.stamp`` (the
    log time when that is zero, or the array is empty); replaying, an array applies before the
    frames at or after its time, in the order recorded (the node's rules:
    :mod:`collision_sensor.engine.scene_markers`). A CSV file holds no scene changes: record a bag.

    Point clouds: ``sensor_msgs/msg/PointCloud2`` messages, on every topic of that type by
    default or on the topics asked for (``cloud_topics``). Each becomes a :class:`CloudEvent`
    at its ``header.stamp`` (the log time when that is zero), its frame ``header.frame_id``,
    its source the topic as recorded without the leading ``/`` (``/camera/points`` ->
    ``camera/points``: the relative name a node's ``point_cloud_topics`` gives and the player
    publishes on, so the obstacle is ``cloud/camera/points`` offline and in the node); the
    points stay in the bag until they are used
    (:func:`iter_cloud_messages` reads them again, one at a time, in time order), so a bag of
    gigabytes of clouds is read in the memory of a few. Whether a cloud's layout is readable is
    decided when it is used (:mod:`collision_sensor.model.point_cloud_message`), where a bad
    one is reported and the others go on.

Errors are :class:`~collision_sensor.errors.SequenceError` and name the file, the line (CSV) or
message (bag) and the fix.

This module is the front door: :func:`read_sequence` and :func:`write_sequence` pick the
format; the sequence in memory is :mod:`~collision_sensor.model.joint_sequence`'s, the formats
are :mod:`~collision_sensor.model.sequence_csv` and :mod:`~collision_sensor.model.sequence_bag`.
"""
import os
from pathlib import Path
from typing import Optional, Sequence

from collision_sensor.errors import SequenceError
from collision_sensor.model.joint_sequence import (  # noqa: F401 - the sequences' API
    CloudEvent, CloudSchedule, JointSequence, SceneEvent)
from collision_sensor.model.sequence_bag import (  # noqa: F401 - the sequences' API
    DEFAULT_TOPIC, MAX_READ_AHEAD, SCENE_TOPIC, cloud_source, iter_cloud_messages, read_bag,
    write_bag)
from collision_sensor.model.sequence_csv import (  # noqa: F401 - the sequences' API
    read_csv, use_number_table_parser, write_csv)

FORMATS = ('csv', 'mcap', 'sqlite3')


def _format_from_path(path: str) -> str:
    suffix = Path(path).suffix.lower()
    if suffix == '.csv':
        return 'csv'
    if suffix == '.db3':
        return 'sqlite3'
    if suffix == '.mcap' or suffix == '':
        return 'mcap'
    raise SequenceError(
        f'{path}: cannot tell the format from the extension "{suffix}"; use .csv, .mcap, '
        '.db3 or a bag directory, or pass fmt="csv"|"mcap"|"sqlite3"')


def read_sequence(path, topic: str = DEFAULT_TOPIC,
                  joint_names: Optional[Sequence[str]] = None,
                  scene_topic: str = SCENE_TOPIC,
                  cloud_topics: Optional[Sequence[str]] = None) -> JointSequence:
    """Read a sequence from a CSV file or a rosbag2 bag (see the module docstring).

    :param path: a ``.csv`` file, a bag directory holding ``metadata.yaml``, or a bare
        ``.mcap`` / ``.db3`` file.
    :param topic: the JointState topic in a bag (ignored for CSV).
    :param scene_topic: the MarkerArray topic of scene changes in a bag (none if absent).
    :param cloud_topics: the PointCloud2 topics of a bag to read clouds from: None for every
        topic of that type, ``()`` for none; a topic named must be in the bag.
    :param joint_names: the joints expected, in the order wanted for the columns. For CSV the
        columns must be exactly these; for a bag every one must appear (others are ignored).
        ``None`` takes the file's own joints in the order they first appear.
    :return: the sequence, ``source`` set to ``path``.
    :raises SequenceError: for anything unreadable or malformed.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        if not os.path.isfile(os.path.join(path, 'metadata.yaml')):
            raise SequenceError(
                f'{path}: a directory without metadata.yaml is not a rosbag2 bag; give a bag '
                'directory, a .mcap/.db3 file or a .csv file')
        return read_bag(path, topic, joint_names, scene_topic, cloud_topics)
    if not os.path.exists(path):
        raise SequenceError(f'{path}: no such file; check the path')
    suffix = Path(path).suffix.lower()
    if suffix == '.csv':
        return read_csv(path, joint_names)
    if suffix in ('.mcap', '.db3'):
        return read_bag(path, topic, joint_names, scene_topic, cloud_topics)
    raise SequenceError(
        f'{path}: unknown sequence format "{suffix}"; use a .csv file, a rosbag2 bag '
        'directory, or a .mcap/.db3 file')


def write_sequence(seq: JointSequence, path, fmt: Optional[str] = None,
                   topic: str = DEFAULT_TOPIC) -> None:
    """Write a sequence as CSV or as a rosbag2 bag of JointState messages.

    ``fmt`` defaults from the extension: ``.csv`` -> csv, ``.mcap`` -> mcap, ``.db3`` ->
    sqlite3, no extension -> mcap. Scene events go to a bag's :data:`SCENE_TOPIC`, each
    logged at its time. A path ending in ``.mcap`` or ``.db3`` receives a bare
    storage file (readable without ``metadata.yaml``); any other path for a bag receives a
    rosbag2 directory (``metadata.yaml`` and ``<name>.mcap`` or ``<name>.db3``).

    CSV values are written with Python's shortest round-trip ``repr``, so reading gives back
    the same floats. Bag times are stored in nanoseconds and must not be negative.

    :raises SequenceError: if the format is unknown, a bag target already exists, or the file
        cannot be written.
    """
    path = os.fspath(path)
    fmt = fmt or _format_from_path(path)
    if fmt not in FORMATS:
        raise SequenceError(f'{path}: unknown format "{fmt}"; use one of {list(FORMATS)}')
    if fmt == 'csv' and seq.scene:
        raise SequenceError(f'{path}: a CSV file holds no scene changes; write a bag (.mcap) '
                            f'to keep the {len(seq.scene)} scene events')
    try:
        if fmt == 'csv':
            write_csv(seq, path)
        else:
            write_bag(seq, path, fmt, topic)
    except OSError as err:
        raise SequenceError(f'{path}: cannot write: {err.strerror or err}; check the directory '
                            'exists and is writable') from None
