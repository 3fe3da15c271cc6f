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
    :mod:`collision_sensor.scene_markers`). A CSV file holds no scene changes: record a bag.

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
"""
import csv
import io
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.errors import SequenceError

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
POINT_CLOUD_TYPE = 'sensor_msgs/msg/PointCloud2'
DEFAULT_TOPIC = '/joint_states'
SCENE_TOPIC = '/scene'
FORMATS = ('csv', 'mcap', 'sqlite3')
_NS_PER_S = 1_000_000_000
#: Bytes of clouds read ahead of their turn that :func:`iter_cloud_messages` keeps at most.
MAX_READ_AHEAD = 1 << 30


@dataclass(frozen=True)
class SceneEvent:
    """One recorded change of the scene: a ``scene`` array, applied before the frames at or
    after ``time``.

    :ivar time: seconds, on the frames' clock.
    :ivar markers: the array's markers (objects with the fields of visualization_msgs/Marker).
    """

    time: float
    markers: tuple


@dataclass(frozen=True)
class CloudEvent:
    """One recorded point cloud, its points left in the bag (:func:`iter_cloud_messages`).

    :ivar time: seconds on the frames' clock: ``header.stamp``, or the log time when that is
        zero.
    :ivar source: the topic as recorded without its leading ``/`` (the source's name as the
        node's ``point_cloud_topics`` gives it; the obstacle is ``cloud/<source>``).
    :ivar frame: ``header.frame_id`` (untrusted text: escape it before printing).
    :ivar bag: the bag it is read from.
    :ivar ordinal: its place among the bag's cloud messages as the bag yields them.
    :ivar size: bytes of the serialized message.
    :ivar error: why the message could not be deserialized ('' when it could).
    :ivar log_time: seconds, when the bag received it (the player publishes it then).
    """

    time: float
    source: str
    frame: str
    bag: str
    ordinal: int
    size: int = 0
    error: str = ''
    log_time: float = 0.0


@dataclass(frozen=True)
class CloudSchedule:
    """When a sequence's clouds apply (:meth:`JointSequence.cloud_schedule`).

    :ivar before_first: clouds stamped before the first frame (the node drops them: no joint
        state to self-filter them with yet).
    :ivar per_frame: n lists: the clouds applied before frame i, those with a time in
        ``(times[i - 1], times[i]]`` (for frame 0, at its time).
    :ivar after_last: clouds stamped after the last frame (no frame checks them).
    """

    before_first: tuple
    per_frame: tuple
    after_last: tuple


@dataclass(frozen=True)
class JointSequence:
    """Joint positions over time, and the scene's changes meanwhile.

    :ivar joint_names: (J,) joint names, the column order of ``positions``.
    :ivar times: (n,) float64 seconds, strictly increasing.
    :ivar positions: (n, J) float64 joint positions.
    :ivar source: where the sequence came from (a file name), for messages.
    :ivar scene: :class:`SceneEvent` in time order (equal times in recorded order).
    :ivar clouds: :class:`CloudEvent` in time order (equal times in recorded order).
    """

    joint_names: tuple
    times: np.ndarray
    positions: np.ndarray
    source: str = ''
    scene: tuple = ()
    clouds: tuple = ()

    def __post_init__(self):
        names = tuple(str(name) for name in self.joint_names)
        times = np.ascontiguousarray(self.times, dtype=np.float64)
        positions = np.ascontiguousarray(self.positions, dtype=np.float64)
        if positions.ndim == 1 and len(names) == 0:
            positions = positions.reshape(len(times), 0)
        where = self.source or 'sequence'
        if times.ndim != 1 or positions.shape != (len(times), len(names)):
            raise SequenceError(
                f'{where}: positions have shape {positions.shape}, expected '
                f'({len(times)}, {len(names)}) for {len(times)} times and {len(names)} joints')
        if len(set(names)) != len(names):
            raise SequenceError(f'{where}: joint names repeat: {list(names)}')
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(positions))):
            raise SequenceError(f'{where}: times and positions must be finite numbers')
        if np.any(np.diff(times) <= 0.0):
            row = int(np.argmax(np.diff(times) <= 0.0)) + 1
            raise SequenceError(
                f'{where}: frame {row}: time {times[row]!r} is not after {times[row - 1]!r}; '
                'times must strictly increase')
        event_times = [event.time for event in self.scene]
        if not all(math.isfinite(t) for t in event_times) or event_times != sorted(event_times):
            raise SequenceError(f'{where}: scene event times must be finite and in order')
        cloud_times = [event.time for event in self.clouds]
        if not all(math.isfinite(t) for t in cloud_times) or cloud_times != sorted(cloud_times):
            raise SequenceError(f'{where}: cloud times must be finite and in order')
        times.setflags(write=False)
        positions.setflags(write=False)
        object.__setattr__(self, 'joint_names', names)
        object.__setattr__(self, 'times', times)
        object.__setattr__(self, 'positions', positions)
        object.__setattr__(self, 'scene', tuple(self.scene))
        object.__setattr__(self, 'clouds', tuple(self.clouds))

    def __len__(self) -> int:
        return len(self.times)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame (0 for fewer than two frames)."""
        return float(self.times[-1] - self.times[0]) if len(self.times) else 0.0

    def select(self, joint_names: Sequence[str]) -> 'JointSequence':
        """Return the sequence with columns reordered to ``joint_names``.

        :raises SequenceError: if a name is not a column of this sequence.
        """
        missing = [name for name in joint_names if name not in self.joint_names]
        if missing:
            raise SequenceError(
                f'{self.source or "sequence"}: no column for joint(s) {missing}; '
                f'it has {list(self.joint_names)}')
        columns = [self.joint_names.index(name) for name in joint_names]
        return JointSequence(tuple(joint_names), self.times, self.positions[:, columns],
                             self.source, self.scene, self.clouds)

    def scene_before(self) -> list:
        """Return, for each frame i, the scene events to apply before it: those with a time
        up to ``times[i]`` not yet applied; the events after the last frame go with it.

        :return: n lists of :class:`SceneEvent`.
        """
        out, k = [], 0
        for i, t in enumerate(self.times.tolist()):
            start = k
            while k < len(self.scene) and (self.scene[k].time <= t or i == len(self) - 1):
                k += 1
            out.append(list(self.scene[start:k]))
        return out

    def cloud_schedule(self) -> CloudSchedule:
        """Return when each cloud applies: before the first frame at or after its time (as a
        scene array), the robot's state at its time known then (:meth:`positions_at`)."""
        times = self.times
        if not self.clouds:
            return CloudSchedule((), ((),) * len(times), ())
        cloud_times = np.array([event.time for event in self.clouds], dtype=np.float64)
        # frame index of the first frame at or after each cloud's time (n: after the last)
        frame = np.searchsorted(times, cloud_times, side='left')
        early = cloud_times < times[0] if len(times) else np.ones(len(cloud_times), bool)
        per_frame = [[] for _ in range(len(times))]
        before, after = [], []
        for event, i, is_early in zip(self.clouds, frame.tolist(), early.tolist()):
            if is_early:
                before.append(event)
            elif i >= len(times):
                after.append(event)
            else:
                per_frame[i].append(event)
        return CloudSchedule(tuple(before), tuple(tuple(f) for f in per_frame), tuple(after))

    def positions_at(self, t: float) -> np.ndarray:
        """Return the joint positions at time ``t``: linear between the two frames around it
        (the node's joint-state window, :mod:`collision_sensor.ros.joint_state_window`, with
        every frame kept); the first or last frame outside them.

        :return: (J,) float64.
        """
        times = self.times
        k = int(np.searchsorted(times, t, side='right'))     # times[k - 1] <= t < times[k]
        if k == 0:
            return self.positions[0].copy()
        if k >= len(times):
            return self.positions[-1].copy()
        t0, t1 = float(times[k - 1]), float(times[k])
        s = (t - t0) / (t1 - t0)
        return (1.0 - s) * self.positions[k - 1] + s * self.positions[k]

    def __eq__(self, other):
        if not isinstance(other, JointSequence):
            return NotImplemented
        return (self.joint_names == other.joint_names
                and np.array_equal(self.times, other.times)
                and np.array_equal(self.positions, other.positions))

    __hash__ = None


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
        return _read_bag(path, topic, joint_names, scene_topic, cloud_topics)
    if not os.path.exists(path):
        raise SequenceError(f'{path}: no such file; check the path')
    suffix = Path(path).suffix.lower()
    if suffix == '.csv':
        return _read_csv(path, joint_names)
    if suffix in ('.mcap', '.db3'):
        return _read_bag(path, topic, joint_names, scene_topic, cloud_topics)
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
            _write_csv(seq, path)
        else:
            _write_bag(seq, path, fmt, topic)
    except OSError as err:
        raise SequenceError(f'{path}: cannot write: {err.strerror or err}; check the directory '
                            'exists and is writable') from None


# --- CSV ---------------------------------------------------------------------------------------

def _write_csv(seq: JointSequence, path: str) -> None:
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        stream.write(','.join(('time',) + seq.joint_names) + '\n')
        for time, row in zip(seq.times.tolist(), seq.positions.tolist()):
            stream.write(','.join(repr(float(value)) for value in [time] + row) + '\n')


def _data_rows(reader) -> Iterable:
    """Yield (line number, fields) for rows that are neither blank nor comments."""
    for fields in reader:
        if not fields or all(not field.strip() for field in fields):
            continue
        if fields[0].lstrip().startswith('#'):
            continue
        yield reader.line_num, [field.strip() for field in fields]


#: The fast path's parser of a CSV file's body: (bytes, columns) -> (rows, columns) float64,
#: or None for anything but lines of plain decimal numbers. The compiled engine registers its
#: own when it loads (``cpp/number_table.hpp``, by :func:`use_number_table_parser`, from
#: ``collision_sensor/engine/compiled.py``): this layer does not import the engine. Until
#: then numpy's ``loadtxt`` reads the file, four to seven times slower.
_number_table_parser = None


def use_number_table_parser(parse) -> None:
    """Read CSV bodies with ``parse(text: bytes, columns: int)`` (see above; None: numpy's
    ``loadtxt``)."""
    global _number_table_parser
    _number_table_parser = parse


def _number_table(body: str, columns: int) -> Optional[np.ndarray]:
    """The (rows, columns) float64 values of a CSV body, or None where the fast path does not
    read it."""
    if _number_table_parser is not None:
        try:
            return _number_table_parser(body.encode('ascii'), columns)
        except UnicodeEncodeError:
            return None
    if '#' in body or '"' in body:
        return None
    try:
        values = np.loadtxt(io.StringIO(body), delimiter=',', dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    return values if values.shape[1] == columns else None


def _read_csv_fast(path: str, text: str, joint_names: Optional[Sequence[str]]
                   ) -> Optional[JointSequence]:
    """Read a plain CSV file (no quotes, no comments after the header, plain decimal numbers)
    with the fast parser (:func:`use_number_table_parser`); return None for anything else or
    anything wrong, which the exact reader below then reads again and reports line by line.
    Both fast parsers give the floats Python's ``float`` gives (checked by the tests); the
    engine's reads a 1000-frame file in about a millisecond, numpy's ``loadtxt`` in 4 to 7,
    which was most of the work of checking it (``collision_sensor_check --jobs``)."""
    start = 0
    while True:  # the header: the first line neither blank nor a comment
        end = text.find('\n', start)
        line = text[start:] if end < 0 else text[start:end]
        if line.strip() and not line.lstrip().startswith('#'):
            break
        if end < 0:
            return None
        start = end + 1
    if '"' in line:
        return None
    columns = [name.strip() for name in line.split(',')]
    body = '' if end < 0 else text[end + 1:]
    if columns[0] != 'time' or len(columns) < 2 or not all(columns) \
            or len(set(columns)) != len(columns) or not body.strip():
        return None
    if joint_names is not None and set(columns[1:]) != set(joint_names):
        return None
    values = _number_table(body, len(columns))
    if values is None or not len(values) or not np.all(np.isfinite(values)) \
            or np.any(np.diff(values[:, 0]) <= 0.0):
        return None
    seq = JointSequence(tuple(columns[1:]), values[:, 0], values[:, 1:], path)
    return seq.select(joint_names) if joint_names is not None else seq


def _read_csv(path: str, joint_names: Optional[Sequence[str]]) -> JointSequence:
    try:
        with open(path, newline='', encoding='utf-8') as stream:
            text = stream.read()
        fast = _read_csv_fast(path, text, joint_names)
        if fast is not None:
            return fast
        rows = list(_data_rows(csv.reader(io.StringIO(text, newline=''))))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        reason = getattr(err, 'strerror', None) or err
        raise SequenceError(f'{path}: cannot read: {reason}; give a readable UTF-8 CSV file') \
            from None
    if not rows:
        raise SequenceError(
            f'{path}: empty file; expected a header "time,<joint>,<joint>,..." and one row per '
            'frame')
    header_line, header = rows[0]
    if header[0] != 'time':
        raise SequenceError(
            f'{path}: line {header_line}: the first column is "{header[0]}", expected "time"; '
            'the header must read "time,<joint>,<joint>,..."')
    columns = header[1:]
    if not columns or any(not name for name in columns):
        raise SequenceError(
            f'{path}: line {header_line}: empty joint name in the header; name every column')
    repeated = sorted({name for name in columns if columns.count(name) > 1})
    if repeated:
        raise SequenceError(
            f'{path}: line {header_line}: column(s) {repeated} appear more than once; keep one')
    if joint_names is not None:
        unknown = [name for name in columns if name not in joint_names]
        missing = [name for name in joint_names if name not in columns]
        if unknown:
            raise SequenceError(
                f'{path}: line {header_line}: unknown joint column(s) {unknown}; the robot\'s '
                f'joints are {list(joint_names)}; rename or remove the column(s)')
        if missing:
            raise SequenceError(
                f'{path}: line {header_line}: no column for joint(s) {missing}; add a column '
                'per joint')
    if len(rows) == 1:
        raise SequenceError(f'{path}: no frames after the header; add one row per frame')

    names = ['time'] + columns
    values = np.empty((len(rows) - 1, len(names)))
    for row_index, (line, fields) in enumerate(rows[1:]):
        if len(fields) != len(names):
            raise SequenceError(
                f'{path}: line {line}: {len(fields)} values, expected {len(names)} (time and '
                f'{len(columns)} joints as in the header)')
        for column, (name, text) in enumerate(zip(names, fields)):
            try:
                value = float(text)
            except ValueError:
                raise SequenceError(
                    f'{path}: line {line}, column "{name}": "{text}" is not a number; write a '
                    'decimal number such as 0.25') from None
            if not math.isfinite(value):
                raise SequenceError(
                    f'{path}: line {line}, column "{name}": {text} is not a finite number; '
                    'fill in the value or drop the row')
            values[row_index, column] = value
        if row_index and values[row_index, 0] <= values[row_index - 1, 0]:
            raise SequenceError(
                f'{path}: line {line}: time {fields[0]} is not after the previous row\'s time '
                f'{values[row_index - 1, 0]!r}; times must strictly increase (sort the rows, '
                'drop repeated ones)')
    seq = JointSequence(tuple(columns), values[:, 0], values[:, 1:], path)
    return seq.select(joint_names) if joint_names is not None else seq


# --- rosbag2 -----------------------------------------------------------------------------------

def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _write_bag(seq: JointSequence, path: str, fmt: str, topic: str) -> None:
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


def _read_bag(path: str, topic: str, joint_names: Optional[Sequence[str]],
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
