"""Joint sequences in rosbag2 bags (mcap or sqlite3): ``sensor_msgs/JointState`` frames, the
``scene`` topic's arrays and the point clouds recorded beside them (the rules:
:mod:`collision_sensor.model.sequences`). Read and written with ``rosbags``, without ROS.
"""
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.errors import SequenceError
from collision_sensor.model.joint_sequence import CloudEvent, JointSequence, SceneEvent

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
POINT_CLOUD_TYPE = 'sensor_msgs/msg/PointCloud2'
DEFAULT_TOPIC = '/joint_states'
SCENE_TOPIC = '/scene'
_NS_PER_S = 1_000_000_000
#: Bytes of clouds read ahead of their turn that :func:`iter_cloud_messages` keeps at most.
MAX_READ_AHEAD = 1 << 30


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def write_bag(seq: JointSequence, path: str, fmt: str, topic: str) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.errors import WriterError

    if np.any(seq.times < 0.0):
        raise SequenceError(f'{path}: a bag cannot hold negative times; shift the times so the '
                            'first one is >= 0')
    bare_file = Path(path).suffix.lower() in ('.mcap', '.db3')
    if os.path.exists(path):
        raise SequenceError(f'{path}: exists already; remove it or choose another name')
    plugin = StoragePlugin.MCAP if fmt == 'mcap' else StoragePlugin.SQLITE3
    typestore = _typestore()
    msg_type = typestore.types[JOINT_STATE_TYPE]
    header_type = typestore.types['std_msgs/msg/Header']
    time_type = typestore.types['builtin_interfaces/msg/Time']
    empty = np.zeros(0, dtype=np.float64)

    scratch = tempfile.mkdtemp(prefix='collision_sensor_bag_') if bare_file else None
    bag_dir = os.path.join(scratch, Path(path).stem) if bare_file else path
    try:
        writer = Writer(bag_dir, version=9, storage_plugin=plugin)
        try:
            writer.open()
            connection = writer.add_connection(topic, JOINT_STATE_TYPE, typestore=typestore)
            names = list(seq.joint_names)
            for time, row in zip(seq.times.tolist(), seq.positions):
                stamp_ns = int(round(time * _NS_PER_S))
                sec, nanosec = divmod(stamp_ns, _NS_PER_S)
                message = msg_type(
                    header=header_type(stamp=time_type(sec=sec, nanosec=nanosec), frame_id=''),
                    name=names, position=np.array(row, dtype=np.float64),
                    velocity=empty, effort=empty)
                writer.write(connection, stamp_ns,
                             typestore.serialize_cdr(message, JOINT_STATE_TYPE))
            if seq.scene:
                scene = writer.add_connection(SCENE_TOPIC, MARKER_ARRAY_TYPE,
                                              typestore=typestore)
                for event in seq.scene:
                    stamp_ns = int(round(event.time * _NS_PER_S))
                    array = typestore.types[MARKER_ARRAY_TYPE](markers=[
                        _bag_marker(typestore, marker, stamp_ns) for marker in event.markers])
                    writer.write(scene, stamp_ns,
                                 typestore.serialize_cdr(array, MARKER_ARRAY_TYPE))
        finally:
            writer.close()
        if bare_file:
            storage = Path(bag_dir) / (Path(bag_dir).name + ('.mcap' if fmt == 'mcap' else '.db3'))
            shutil.move(str(storage), path)
    except WriterError as err:
        raise SequenceError(f'{path}: cannot write the bag: {err}') from None
    finally:
        if scratch:
            shutil.rmtree(scratch, ignore_errors=True)


def _bag_marker(typestore, marker, stamp_ns: int):
    """A rosbags visualization_msgs/Marker from ``marker``'s fields, stamped ``stamp_ns``."""
    t = typestore.types
    vector = t['geometry_msgs/msg/Vector3']
    point = t['geometry_msgs/msg/Point']
    pose = marker.pose
    sec, nanosec = divmod(stamp_ns, _NS_PER_S)
    return t['visualization_msgs/msg/Marker'](
        header=t['std_msgs/msg/Header'](
            stamp=t['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec),
            frame_id=marker.header.frame_id),
        ns=marker.ns, id=int(marker.id), type=int(marker.type), action=int(marker.action),
        pose=t['geometry_msgs/msg/Pose'](
            position=point(x=float(pose.position.x), y=float(pose.position.y),
                           z=float(pose.position.z)),
            orientation=t['geometry_msgs/msg/Quaternion'](
                x=float(pose.orientation.x), y=float(pose.orientation.y),
                z=float(pose.orientation.z), w=float(pose.orientation.w))),
        scale=vector(x=float(marker.scale.x), y=float(marker.scale.y),
                     z=float(marker.scale.z)),
        color=t['std_msgs/msg/ColorRGBA'](r=0.6, g=0.6, b=0.65, a=1.0),
        lifetime=t['builtin_interfaces/msg/Duration'](sec=0, nanosec=0), frame_locked=False,
        points=[point(x=float(p.x), y=float(p.y), z=float(p.z))
                for p in getattr(marker, 'points', ())],
        colors=[], texture_resource='',
        texture=t['sensor_msgs/msg/CompressedImage'](
            header=t['std_msgs/msg/Header'](
                stamp=t['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=''),
            format='', data=np.zeros(0, dtype=np.uint8)),
        uv_coordinates=[], text=getattr(marker, 'text', ''),
        mesh_resource=getattr(marker, 'mesh_resource', ''),
        mesh_file=t['visualization_msgs/msg/MeshFile'](filename='',
                                                        data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False)


def read_bag(path: str, topic: str, joint_names: Optional[Sequence[str]],
              scene_topic: str = SCENE_TOPIC,
              cloud_topics: Optional[Sequence[str]] = None) -> JointSequence:
    from rosbags.rosbag2 import Reader

    typestore = _typestore()
    try:
        with Reader(Path(path)) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                topics = sorted({f'{c.topic} ({c.msgtype})' for c in reader.connections})
                raise SequenceError(
                    f'{path}: no topic "{topic}" in the bag; it has {topics or "no topics"}; '
                    'pass the JointState topic (--topic)')
            wrong = [c.msgtype for c in connections if c.msgtype != JOINT_STATE_TYPE]
            if wrong:
                raise SequenceError(
                    f'{path}: topic "{topic}" has type {wrong[0]}, expected {JOINT_STATE_TYPE}')
            messages = []
            for index, (_, log_time, raw) in enumerate(reader.messages(connections=connections)):
                msg = typestore.deserialize_cdr(raw, JOINT_STATE_TYPE)
                stamp = msg.header.stamp.sec * _NS_PER_S + msg.header.stamp.nanosec
                messages.append((index, stamp or log_time, list(msg.name),
                                 np.asarray(msg.position, dtype=np.float64)))
            scene = _read_scene(path, reader, typestore, scene_topic)
            clouds = _read_clouds(path, reader, typestore, cloud_topics)
    except SequenceError:
        raise
    except Exception as err:  # rosbags raises several families for broken bags
        raise SequenceError(f'{path}: cannot read the bag: {err}; check it is a rosbag2 bag '
                            '(mcap or sqlite3) and not truncated') from None
    if not messages:
        raise SequenceError(f'{path}: topic "{topic}" has no messages; record some first')
    seq = _merge_joint_states(path, topic, messages, joint_names)
    return JointSequence(seq.joint_names, seq.times, seq.positions, seq.source, scene, clouds)


def _read_scene(path, reader, typestore, scene_topic) -> tuple:
    """The bag's scene arrays as :class:`SceneEvent`, in time order (see the module doc)."""
    connections = [c for c in reader.connections if c.topic == scene_topic]
    wrong = [c.msgtype for c in connections if c.msgtype != MARKER_ARRAY_TYPE]
    if wrong:
        raise SequenceError(f'{path}: topic "{scene_topic}" has type {wrong[0]}, expected '
                            f'{MARKER_ARRAY_TYPE}; pass another scene topic')
    if not connections:
        return ()       # (an empty list would make rosbags read every topic)
    events = []
    for _, log_time, raw in reader.messages(connections=connections):
        markers = tuple(typestore.deserialize_cdr(raw, MARKER_ARRAY_TYPE).markers)
        stamp = (markers[0].header.stamp.sec * _NS_PER_S + markers[0].header.stamp.nanosec
                 if markers else 0)
        events.append(SceneEvent((stamp or log_time) / _NS_PER_S, markers))
    events.sort(key=lambda event: event.time)    # stable: equal times keep the bag's order
    return tuple(events)


def cloud_source(topic: str) -> str:
    """Return the source name of a recorded cloud topic: without its leading ``/``."""
    return topic[1:] if topic.startswith('/') else topic


def _cloud_connections(path, reader, cloud_topics) -> list:
    """The bag's connections of the cloud topics asked for (module docstring); a topic asked
    for matches with or without its leading ``/``."""
    if cloud_topics is None:
        return [c for c in reader.connections if c.msgtype == POINT_CLOUD_TYPE]
    connections = []
    for name in cloud_topics:
        found = [c for c in reader.connections if cloud_source(c.topic) == cloud_source(name)]
        if not found:
            clouds = sorted({c.topic for c in reader.connections
                             if c.msgtype == POINT_CLOUD_TYPE})
            raise SequenceError(
                f'{path}: no topic "{name}" in the bag; its PointCloud2 topics are '
                f'{clouds or "none"}; pass one of them (--cloud-topic) or none')
        wrong = [c.msgtype for c in found if c.msgtype != POINT_CLOUD_TYPE]
        if wrong:
            raise SequenceError(f'{path}: topic "{name}" has type {wrong[0]}, expected '
                                f'{POINT_CLOUD_TYPE}; pass a PointCloud2 topic (--cloud-topic)')
        connections += found
    return connections


def _read_clouds(path, reader, typestore, cloud_topics) -> tuple:
    """The bag's clouds as :class:`CloudEvent` in time order, their points left in the bag."""
    connections = _cloud_connections(path, reader, cloud_topics)
    if not connections:
        return ()       # (an empty list would make rosbags read every topic)
    events = []
    for ordinal, (connection, log_time, raw) in enumerate(
            reader.messages(connections=connections)):
        try:
            header = typestore.deserialize_cdr(raw, POINT_CLOUD_TYPE).header
            stamp = header.stamp.sec * _NS_PER_S + header.stamp.nanosec
            frame, error = str(header.frame_id), ''
        except Exception as err:   # noqa: B902 - rosbags raises several kinds for bad bytes
            stamp, frame = 0, ''
            error = f'cannot deserialize the message: {type(err).__name__}: {err}'
        events.append(CloudEvent((stamp or log_time) / _NS_PER_S,
                                 cloud_source(connection.topic), frame, path, ordinal, len(raw),
                                 error[:500], log_time / _NS_PER_S))
    events.sort(key=lambda event: event.time)    # stable: equal times keep the bag's order
    return tuple(events)


def iter_cloud_messages(clouds: Sequence[CloudEvent], path: Optional[str] = None
                        ) -> Iterator[Tuple[CloudEvent, object]]:
    """Yield ``(event, message)`` for ``clouds`` (events of one bag, in the order given:
    time order), reading the messages again from the bag, one pass in the bag's order.

    Memory: a message read before its turn (recorded earlier than a cloud with an earlier
    stamp, e.g. two cameras with different delays) is kept, serialized, until its turn, up to
    :data:`MAX_READ_AHEAD` bytes; the others are deserialized when yielded and dropped by the
    caller.

    :param path: the bag to read (default: the events' own ``bag``; a worker that unpacked a
        shipped bag elsewhere passes that).
    :return: messages are ``rosbags`` PointCloud2 dataclasses, or None for an event whose
        ``error`` says why it could not be deserialized.
    :raises SequenceError: the bag cannot be read again, or its clouds' stamps are so far
        out of the order it recorded them in that more than :data:`MAX_READ_AHEAD` bytes would
        wait.
    """
    from rosbags.rosbag2 import Reader

    if not clouds:
        return
    path = path or clouds[0].bag
    wanted = {event.ordinal for event in clouds}
    topics = sorted({event.source for event in clouds})
    typestore = _typestore()
    waiting, held = {}, 0
    reader = Reader(Path(path))
    try:
        reader.open()
        connections = [c for c in reader.connections
                       if cloud_source(c.topic) in topics and c.msgtype == POINT_CLOUD_TYPE]
        messages = reader.messages(connections=connections)
        stream = enumerate(messages)
    except Exception as err:   # noqa: B902 - rosbags raises several families for broken bags
        _close_quietly(reader)
        raise SequenceError(f'{path}: cannot read the bag\'s clouds again: {err}') from None
    try:
        for number, event in enumerate(clouds):
            try:
                while event.ordinal not in waiting:
                    ordinal, (_, _, raw) = next(stream)
                    if ordinal in wanted:
                        waiting[ordinal] = raw
                        held += len(raw)
                    if held > MAX_READ_AHEAD and event.ordinal not in waiting:
                        raise SequenceError(
                            f'{path}: the cloud of {event.source} stamped {event.time:.3f} s '
                            f'was recorded after more than {MAX_READ_AHEAD >> 20} MiB of clouds '
                            'stamped later; are the stamps of one topic on another clock? '
                            'Check each topic alone (--cloud-topic)')
                raw = waiting.pop(event.ordinal)
                held -= len(raw)
                msg = None if event.error else typestore.deserialize_cdr(raw, POINT_CLOUD_TYPE)
            except StopIteration:
                raise SequenceError(f'{path}: the bag holds fewer clouds than when it was read '
                                    'first; was it changed meanwhile?') from None
            except SequenceError:
                raise
            except Exception as err:   # noqa: B902 - rosbags raises several families
                raise SequenceError(f'{path}: cannot read the bag\'s clouds again: {err}') \
                    from None
            if number == len(clouds) - 1:
                _close_quietly(reader, messages)   # the last: not left open until let go
            yield event, msg
    finally:
        _close_quietly(reader, messages)


def _close_quietly(reader, messages=None) -> None:
    """Close a bag reader that was only read from, and its message stream (twice is
    harmless; errors say nothing the reading did not)."""
    for close in ((messages.close,) if messages is not None else ()) + (reader.close,):
        try:
            close()
        except Exception:   # noqa: B902
            pass


def _merge_joint_states(path, topic, messages, joint_names) -> JointSequence:
    """Turn (index, stamp_ns, names, positions) messages into frames (module docstring)."""
    if joint_names is None:
        seen = {}
        for _, _, names, _ in messages:
            for name in names:
                seen.setdefault(name, None)
        joint_names = tuple(seen)
    else:
        joint_names = tuple(joint_names)
        present = {name for _, _, names, _ in messages for name in names}
        missing = [name for name in joint_names if name not in present]
        if missing:
            raise SequenceError(
                f'{path}: topic "{topic}" never names joint(s) {missing}; record them or pass '
                'the robot that matches this bag')
    column = {name: index for index, name in enumerate(joint_names)}
    state = np.full(len(joint_names), np.nan)
    times, rows = [], []
    for index, stamp, names, positions in messages:
        if len(positions) != len(names):
            raise SequenceError(
                f'{path}: message {index}: {len(names)} names but {len(positions)} positions; '
                'every named joint needs a position')
        for name, value in zip(names, positions.tolist()):
            if name not in column:
                continue
            if not math.isfinite(value):
                raise SequenceError(
                    f'{path}: message {index}: joint "{name}" position {value} is not finite')
            state[column[name]] = value
        if np.isnan(state).any():
            continue  # not every joint seen yet
        if times and stamp < times[-1]:
            raise SequenceError(
                f'{path}: message {index}: stamp {stamp / _NS_PER_S!r} s is earlier than the '
                f'previous frame\'s {times[-1] / _NS_PER_S!r} s; times must not go backwards '
                '(re-stamp the messages or use --topic with a single publisher)')
        if times and stamp == times[-1]:
            rows[-1] = state.copy()
        else:
            times.append(stamp)
            rows.append(state.copy())
    if not times:
        raise SequenceError(f'{path}: topic "{topic}" never gives every joint a position')
    return JointSequence(joint_names, np.array(times, dtype=np.float64) / _NS_PER_S,
                         np.array(rows), path)
