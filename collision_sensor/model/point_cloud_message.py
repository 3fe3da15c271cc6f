"""A ``sensor_msgs/PointCloud2``'s x, y, z as the engine reads them (issue 29, items 2 and 4).

Pure numpy, no rclpy: the message is read through its fields (``height``, ``width``,
``fields``, ``is_bigendian``, ``point_step``, ``row_step``, ``data``), so the same function
reads an rclpy message (the node's point cloud source) and a ``rosbags`` message read from a
bag (the offline checker, :mod:`collision_sensor.tools.recorded_clouds`). Everything in a
message is untrusted: each check below names what is wrong with the message and the fix, with
the message's own text escaped (:mod:`collision_sensor.untrusted_text`), and nothing is
allocated in proportion to what the message *claims* (only to the bytes it holds).

Accepted: x, y and z fields of one ``FLOAT32`` or ``FLOAT64`` element each (count 1), inside
``point_step``; ``row_step >= width * point_step``; ``len(data) == height * row_step``; either
byte order. The points are returned as an (n, 3) view of ``data`` when the three fields are
one contiguous triple of one type and rows are not padded (the usual case: no copy), else as
a float64 copy. Rows with NaN or inf (an organised cloud's holes) are left for the engine to
drop and count.

The node takes clouds serialized (a raw subscription) and reads them here
(:func:`cloud_from_cdr`): rclpy's own conversion of a 640 x 480 cloud into a Python message costs
about 6 ms of the interpreter's lock on the executor's thread (its ``data`` copied into an
``array.array``), time the joint states' verdicts would wait; here the points stay a view of
the received bytes. :func:`cdr_from_points` writes ``~/filtered_points`` the same way (rclpy
takes about 60 ms to serialize a cloud of that size from Python).
"""
import struct
from typing import NamedTuple, Optional

import numpy as np

from collision_sensor.errors import PointCloudError
from collision_sensor.untrusted_text import printable, quoted

#: ``sensor_msgs/PointField`` datatypes (the message's constants, without importing it).
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
_FLOAT_TYPES = {FLOAT32: 'f4', FLOAT64: 'f8'}
_TYPE_NAMES = {INT8: 'INT8', UINT8: 'UINT8', INT16: 'INT16', UINT16: 'UINT16', INT32: 'INT32',
               UINT32: 'UINT32', FLOAT32: 'FLOAT32', FLOAT64: 'FLOAT64'}
#: Fields listed in a message, at most (a message may claim any number).
MAX_FIELDS = 64


class CloudMessageError(PointCloudError):
    """A PointCloud2 whose layout cannot be read as points; the message says why and the fix.

    :ivar kind: a short key for throttling and counting (``empty``, ``fields``, ``layout``).
    """

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


class CloudRows(NamedTuple):
    """A message's points.

    :ivar points: (n, 3) float32 or float64, x y z per row (a view of the message's data, or a
        copy), n = height * width.
    :ivar frame: ``header.frame_id``, escaped for logs is the caller's business.
    """

    points: np.ndarray
    frame: str


class Stamp(NamedTuple):
    """``builtin_interfaces/Time``'s fields."""

    sec: int
    nanosec: int


class CloudHeader(NamedTuple):
    """``std_msgs/Header``'s fields."""

    stamp: Stamp
    frame_id: str


class Field(NamedTuple):
    """``sensor_msgs/PointField``'s fields."""

    name: str
    offset: int
    datatype: int
    count: int


class CloudMessage(NamedTuple):
    """A ``sensor_msgs/PointCloud2`` read from its serialized form (:func:`cloud_from_cdr`):
    the message's fields, ``data`` a view of the serialized bytes."""

    header: CloudHeader
    height: int
    width: int
    fields: tuple
    is_bigendian: bool
    point_step: int
    row_step: int
    data: memoryview
    is_dense: bool


class _Reader:
    """Reads CDR (XCDR1, as ROS 2's middlewares serialize; alignment counted from the end of
    the 4-byte encapsulation header), every read within the bytes given."""

    def __init__(self, data, topic: str):
        self.view = memoryview(data).cast('B')
        self.topic = topic
        if len(self.view) < 4 or self.view[1] not in (0, 1):
            raise self.error('not a serialized message (no CDR encapsulation header)')
        self.order = '<' if self.view[1] == 1 else '>'
        self.pos = 4

    def error(self, what: str) -> CloudMessageError:
        return CloudMessageError('layout', f'{self.topic}: {what}; the message is truncated or '
                                 'not a sensor_msgs/PointCloud2')

    def take(self, size: int, align: int = 1) -> int:
        """Return the offset of the next ``size`` bytes (aligned), and pass them."""
        at = 4 + (self.pos - 4 + align - 1) // align * align
        if size < 0 or at + size > len(self.view):
            raise self.error(f'{size} bytes wanted at byte {at} of {len(self.view)}')
        self.pos = at + size
        return at

    def u32(self) -> int:
        return struct.unpack_from(self.order + 'I', self.view, self.take(4, 4))[0]

    def i32(self) -> int:
        return struct.unpack_from(self.order + 'i', self.view, self.take(4, 4))[0]

    def u8(self) -> int:
        return self.view[self.take(1)]

    def string(self, limit: int) -> str:
        length = self.u32()
        at = self.take(length)
        text = bytes(self.view[at:at + min(length, limit + 1)]).split(b'\0', 1)[0]
        return text.decode('utf-8', 'replace')


def cloud_from_cdr(data, topic: str = 'point cloud') -> CloudMessage:
    """Read a serialized ``sensor_msgs/PointCloud2`` (as a raw subscription gives it) without
    copying its points.

    :raises CloudMessageError: the bytes do not hold a whole PointCloud2 (kind ``layout``), or
        it lists more than :data:`MAX_FIELDS` fields (kind ``fields``).
    """
    topic = printable(topic, 200)
    r = _Reader(data, topic)
    stamp = Stamp(r.i32(), r.u32())
    frame_id = r.string(256)
    height, width = r.u32(), r.u32()
    n_fields = r.u32()
    if n_fields > MAX_FIELDS:
        raise CloudMessageError('fields', f'{topic}: more than {MAX_FIELDS} fields; publish '
                                'a cloud with x, y and z FLOAT32 fields')
    fields = []
    for _ in range(n_fields):
        name = r.string(64)
        offset = r.u32()
        datatype = r.u8()
        fields.append(Field(name, offset, datatype, r.u32()))
    is_bigendian = bool(r.u8())
    point_step, row_step = r.u32(), r.u32()
    size = r.u32()
    at = r.take(size)
    points = r.view[at:at + size]
    is_dense = bool(r.u8())
    return CloudMessage(CloudHeader(stamp, frame_id), height, width, tuple(fields),
                        is_bigendian, point_step, row_step, points, is_dense)


_XYZ = b''.join(struct.pack('<I', 2) + axis + b'\0' + b'\0\0' + struct.pack('<IBxxxI', 4 * k,
                                                                            FLOAT32, 1)
                for k, axis in enumerate((b'x', b'y', b'z')))


def write_stamp(data: bytearray, sec: int, nanosec: int) -> None:
    """Write ``header.stamp`` into a serialized message that begins with a ``std_msgs/Header``
    (a PointCloud2, a DiagnosticArray ...), in place: the bytes after the 4-byte CDR
    encapsulation header, in the byte order it names."""
    struct.pack_into('<iI' if data[1] == 1 else '>iI', data, 4, sec, nanosec)


def cdr_from_points(points: np.ndarray, sec: int, nanosec: int, frame_id: str) -> bytes:
    """Serialize an unorganised ``sensor_msgs/PointCloud2`` of ``points`` (n, 3) float32: x,
    y, z FLOAT32, 12-byte points, dense, little-endian CDR; what rclpy would publish."""
    points = np.ascontiguousarray(points, dtype='<f4').reshape(-1, 3)
    frame = frame_id.encode('utf-8') + b'\0'
    head = struct.pack('<4siII', b'\0\1\0\0', sec, nanosec, len(frame)) + frame
    head += b'\0' * (-(len(head) - 4) % 4)
    n = len(points)
    head += struct.pack('<III', 1, n, 3) + _XYZ + struct.pack('<B3xIII', 0, 12, 12 * n, 12 * n)
    return b''.join((head, points.tobytes(), b'\1'))


def _field_layout(msg, topic: str):
    """Return ``{axis: (offset, numpy type)}`` of x, y, z."""
    fields = list(msg.fields[:MAX_FIELDS + 1])
    if len(fields) > MAX_FIELDS:
        raise CloudMessageError('fields', f'{topic}: more than {MAX_FIELDS} fields; publish '
                                'a cloud with x, y and z FLOAT32 fields')
    names = [f.name for f in fields]
    layout = {}
    for axis in 'xyz':
        found = [f for f in fields if f.name == axis]
        if not found:
            raise CloudMessageError(
                'fields', f'{topic}: no "{axis}" field (fields: '
                f'{", ".join(quoted(n, 40) for n in names) or "none"}); publish a cloud with '
                'x, y and z fields (e.g. depth_image_proc/point_cloud_xyz)')
        if len(found) > 1:
            raise CloudMessageError('fields', f'{topic}: field "{axis}" is listed '
                                    f'{len(found)} times; list each of x, y, z once')
        f = found[0]
        kind = _FLOAT_TYPES.get(f.datatype)
        if kind is None:
            type_name = _TYPE_NAMES.get(f.datatype, f'unknown ({printable(f.datatype, 20)})')
            raise CloudMessageError(
                'fields', f'{topic}: field "{axis}" is {type_name}; x, y and z must be '
                'FLOAT32 or FLOAT64 (metres)')
        if f.count != 1:
            raise CloudMessageError('fields', f'{topic}: field "{axis}" has count '
                                    f'{printable(f.count, 20)}; x, y and z must have count 1')
        size = int(kind[1])
        if f.offset < 0 or f.offset + size > msg.point_step:
            raise CloudMessageError(
                'layout', f'{topic}: field "{axis}" (offset {f.offset}, {size} bytes) does not '
                f'fit in point_step {msg.point_step}; fix point_step or the field\'s offset')
        layout[axis] = (int(f.offset), ('>' if msg.is_bigendian else '<') + kind)
    return layout


def cloud_rows(msg, topic: str = 'point cloud') -> CloudRows:
    """Return the points of PointCloud2 ``msg``.

    :param topic: names the input in messages (escaped here).
    :raises CloudMessageError: an empty cloud, missing or non-float x/y/z fields, or a layout
        (``point_step``, ``row_step``, data size) that does not add up; the message names the
        field or the step and the fix.
    """
    topic = printable(topic, 200)
    height, width = int(msg.height), int(msg.width)
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    data = msg.data
    size = len(data)
    if height == 0 or width == 0 or size == 0:
        raise CloudMessageError('empty', f'{topic}: empty cloud (height {height}, width {width}, '
                                f'{size} bytes of data); publish clouds with points')
    layout = _field_layout(msg, topic)
    if point_step <= 0 or row_step < width * point_step:
        raise CloudMessageError(
            'layout', f'{topic}: row_step {row_step} is less than width {width} x point_step '
            f'{point_step}; set row_step = width * point_step (plus any row padding)')
    if size != height * row_step:
        raise CloudMessageError(
            'layout', f'{topic}: {size} bytes of data, but height {height} x row_step '
            f'{row_step} = {height * row_step}; publish data of height * row_step bytes')
    raw = np.frombuffer(data, dtype=np.uint8)
    (ox, tx), (oy, ty), (oz, tz) = layout['x'], layout['y'], layout['z']
    item = int(tx[-1])
    rows = height * width
    if tx == ty == tz and oy == ox + item and oz == oy + item and row_step == width * point_step:
        # One strided view: row r's x at r * point_step + ox.
        points = np.ndarray((rows, 3), dtype=np.dtype(tx), buffer=raw, offset=ox,
                            strides=(point_step, item))
        return CloudRows(points, str(msg.header.frame_id))
    points = np.empty((rows, 3))
    for k, (offset, kind) in enumerate((layout['x'], layout['y'], layout['z'])):
        column = np.ndarray((height, width), dtype=np.dtype(kind), buffer=raw, offset=offset,
                            strides=(row_step, point_step))
        points[:, k] = column.reshape(-1)
    return CloudRows(points, str(msg.header.frame_id))


def cloud_frame(frame_id: str, link_names, world_frames, name: str) -> Optional[str]:
    """Return the frame a cloud's points are given in, as the checker takes it: a link's name,
    or None for the world frame.

    :param frame_id: the message's ``header.frame_id`` (untrusted).
    :param link_names: the robot's links; ``world_frames``: the names of its world frame.
    :param name: names the input in messages (``point cloud /camera/points``).
    :raises CloudMessageError: (kind ``frame``) any other frame, named, with the fix.
    """
    if frame_id in world_frames:
        return None
    if frame_id in link_names:
        return frame_id
    worlds = ' or '.join(quoted(world) for world in sorted(world_frames))
    raise CloudMessageError(
        'frame', f'{printable(name, 200)}: header.frame_id {quoted(frame_id, 100)} is no link '
        f'of the robot and not its world frame ({worlds}); publish the cloud in a frame of the '
        'URDF (add the camera\'s optical frame to the URDF as a link) or in the world frame '
        '(there is no tf2 here)')


def require_some_valid(stats, name: str) -> None:
    """Refuse a cloud whose every point has a NaN or infinite coordinate.

    :param stats: the cloud's ``PointCloudStats`` (``points``, ``invalid``).
    :raises CloudMessageError: (kind ``invalid``) saying so.
    """
    if stats.invalid == stats.points:
        raise CloudMessageError(
            'invalid', f'{printable(name, 200)}: every one of its {stats.points} points has a '
            'NaN or infinite coordinate; the last good cloud stays the obstacle')
