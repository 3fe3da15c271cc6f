"""PointCloud2 messages read as points (collision_sensor.model.point_cloud_message), on real
``sensor_msgs`` messages (no node): every layout a driver publishes is read as numpy would
decode it field by field, and every bad input of issue 29 item 4 is refused with a message
naming the field or step and the fix."""
import numpy as np
import pytest

pytest.importorskip('sensor_msgs.msg')

from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from std_msgs.msg import Header  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.model.point_cloud_message import CloudMessageError, cloud_rows  # noqa: E402


def _message(points, dtype='<f4', extra=0, row_pad=0, height=1, order='xyz', frame='cam',
             datatype=None):
    """A cloud of ``points`` (n, 3) with fields in ``order``, ``extra`` padding bytes per
    point and ``row_pad`` per row; returns the message."""
    points = np.asarray(points, dtype=np.float64)
    item = np.dtype(dtype).itemsize
    point_step = 3 * item + extra
    width = len(points) // height
    row_step = width * point_step + row_pad
    data = bytearray(height * row_step)
    raw = np.frombuffer(data, dtype=np.uint8)
    fields = []
    for k, axis in enumerate(order):
        column = np.ndarray((height, width), dtype=dtype, buffer=raw, offset=k * item,
                            strides=(row_step, point_step))
        column[...] = points[:, 'xyz'.index(axis)].reshape(height, width)
        fields.append(PointField(name=axis, offset=k * item, count=1, datatype=datatype or (
            PointField.FLOAT32 if item == 4 else PointField.FLOAT64)))
    return PointCloud2(header=Header(frame_id=frame), height=height, width=width, fields=fields,
                       is_bigendian=dtype.startswith('>'), point_step=point_step,
                       row_step=row_step, data=bytes(data), is_dense=False)


POINTS = np.random.default_rng(1).uniform(-2.0, 2.0, (48, 3))


@pytest.mark.parametrize('dtype,extra,row_pad,height,order', [
    ('<f4', 4, 0, 1, 'xyz'),     # the usual: x y z padding
    ('<f4', 4, 0, 6, 'xyz'),     # organised
    ('<f8', 0, 0, 4, 'xyz'),
    ('>f4', 0, 0, 2, 'xyz'),     # big endian
    ('<f4', 12, 8, 4, 'xyz'),    # padded rows
    ('<f4', 0, 0, 3, 'zyx'),     # fields in another order
])
def test_layouts_read_as_their_points(dtype, extra, row_pad, height, order):
    rows = cloud_rows(_message(POINTS, dtype, extra, row_pad, height, order), 'cam/points')
    assert rows.points.shape == (len(POINTS), 3)
    expected = POINTS.astype(np.dtype(dtype).newbyteorder('=')).astype(np.float64)
    np.testing.assert_array_equal(rows.points.astype(np.float64), expected)
    assert rows.frame == 'cam'


def test_usual_layout_is_a_view_and_the_checker_reads_it(erd_share, erd_package_paths):
    msg = _message(POINTS, '<f4', 4)
    rows = cloud_rows(msg)
    assert not rows.points.flags.owndata     # no copy of a camera's 307,200 rows
    import os
    checker = CollisionChecker.from_urdf(
        os.path.join(erd_share, 'robots', 'ur_description', 'urdf', 'ur5_robot.urdf'),
        package_paths=erd_package_paths)
    a = checker.set_points('cam', rows.points)
    b = checker.set_points('copy', np.array(rows.points, dtype=np.float64))
    assert a == b and a > 0


@pytest.mark.parametrize('change,kind,words', [
    (dict(width=0), 'empty', 'empty cloud'),
    (dict(data=b''), 'empty', 'empty cloud'),
    (dict(fields=[]), 'fields', 'no "x" field'),
    (dict(point_step=8), 'layout', 'does not fit in point_step 8'),
    (dict(row_step=4), 'layout', 'row_step 4 is less than'),
    (dict(row_step=1000), 'layout', 'bytes of data, but height'),
    (dict(height=2), 'layout', 'bytes of data, but height'),
])
def test_bad_layouts_are_refused_with_the_fix(change, kind, words):
    msg = _message(POINTS, '<f4', 4)
    for key, value in change.items():
        setattr(msg, key, value)
    with pytest.raises(CloudMessageError, match=words) as caught:
        cloud_rows(msg, 'cam/points')
    assert caught.value.kind == kind
    assert 'cam/points' in str(caught.value)


@pytest.mark.parametrize('datatype,name', [(PointField.INT16, 'INT16'),
                                           (PointField.UINT8, 'UINT8'), (42, 'unknown')])
def test_non_float_fields_are_refused(datatype, name):
    msg = _message(POINTS, '<f4', datatype=datatype)
    with pytest.raises(CloudMessageError, match=f'field "x" is {name}.*FLOAT32 or FLOAT64'):
        cloud_rows(msg)


def test_missing_duplicate_and_counted_fields():
    msg = _message(POINTS, '<f4')
    msg.fields = msg.fields[:2]
    with pytest.raises(CloudMessageError, match='no "z" field.*"x", "y"'):
        cloud_rows(msg)
    msg = _message(POINTS, '<f4')
    msg.fields = list(msg.fields) + [PointField(name='x', offset=0, datatype=7, count=1)]
    with pytest.raises(CloudMessageError, match='listed 2 times'):
        cloud_rows(msg)
    msg = _message(POINTS, '<f4')
    msg.fields[1].count = 3
    with pytest.raises(CloudMessageError, match='count 3'):
        cloud_rows(msg)


def test_untrusted_text_is_escaped():
    msg = _message(POINTS, '<f4')
    msg.fields[2].name = 'z\x1b[31m\n'
    with pytest.raises(CloudMessageError) as caught:
        cloud_rows(msg, 'cam\n/points')
    text = str(caught.value)
    assert '\x1b' not in text and '\n' not in text


def test_all_nan_cloud_is_read_and_left_to_the_engine_to_count():
    rows = cloud_rows(_message(np.full((12, 3), np.nan), '<f4', 4, height=3))
    assert np.isnan(rows.points).all()


# -- the serialized form: what the node's raw subscription reads --------------------------------

@pytest.mark.parametrize('dtype,extra,row_pad,height,order', [
    ('<f4', 4, 0, 6, 'xyz'), ('<f8', 0, 0, 4, 'xyz'), ('>f4', 0, 0, 2, 'xyz'),
    ('<f4', 12, 8, 4, 'zyx')])
@pytest.mark.parametrize('frame', ['', 'c', 'cam', 'camera_depth_optical_frame'])
def test_serialized_clouds_read_as_rclpy_reads_them(dtype, extra, row_pad, height, order, frame):
    """cloud_from_cdr against rclpy's own deserializer (every field), on frame names of every
    length modulo 4 (CDR's alignment); the points are a view of the bytes."""
    serialization = pytest.importorskip('rclpy.serialization')
    deserialize_message = serialization.deserialize_message
    serialize_message = serialization.serialize_message
    from collision_sensor.model.point_cloud_message import cloud_from_cdr
    msg = _message(POINTS, dtype, extra, row_pad, height, order, frame)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1764115200, 123456789
    data = serialize_message(msg)
    mine, theirs = cloud_from_cdr(data, 'cam/points'), deserialize_message(data, PointCloud2)
    assert mine.header.frame_id == theirs.header.frame_id == frame
    assert (mine.header.stamp.sec, mine.header.stamp.nanosec) == (1764115200, 123456789)
    assert [tuple(f) for f in mine.fields] == [
        (f.name, f.offset, f.datatype, f.count) for f in theirs.fields]
    for key in ('height', 'width', 'is_bigendian', 'point_step', 'row_step', 'is_dense'):
        assert getattr(mine, key) == getattr(theirs, key), key
    assert bytes(mine.data) == bytes(theirs.data)
    rows = cloud_rows(mine, 'cam/points')
    np.testing.assert_array_equal(rows.points, cloud_rows(theirs).points)
    if extra == 4 and row_pad == 0:
        assert not rows.points.flags.owndata


def test_truncated_or_foreign_bytes_are_refused_as_a_layout_error():
    """Every prefix of a serialized cloud, and bytes of another message type, give a
    CloudMessageError (never an IndexError or a read past the end)."""
    serialize_message = pytest.importorskip('rclpy.serialization').serialize_message
    from sensor_msgs.msg import JointState
    from collision_sensor.model.point_cloud_message import cloud_from_cdr
    data = serialize_message(_message(POINTS[:8], '<f4', 4, 0, 2, 'xyz', 'cam'))
    for end in range(len(data) - 1):     # the last byte (is_dense) is the only one optional
        with pytest.raises(CloudMessageError) as error:
            cloud_from_cdr(data[:end], 'cam/points')
        assert 'cam/points' in str(error.value)
    names = serialize_message(JointState(name=['a' * 40] * 3, position=[1.0, 2.0, 3.0]))
    with pytest.raises(CloudMessageError):
        rows = cloud_from_cdr(names, 'cam/points')
        cloud_rows(rows, 'cam/points')
    with pytest.raises(CloudMessageError, match='more than 64 fields'):
        msg = _message(POINTS[:4])
        msg.fields = [PointField(name=f'f{k}', offset=0, datatype=7, count=1)
                      for k in range(65)]
        cloud_from_cdr(serialize_message(msg), 'cam/points')


def test_filtered_points_serialize_as_rclpy_serializes_them():
    """cdr_from_points writes what rclpy reads back as the same PointCloud2 (and as long as
    rclpy's own serialization: CDR's padding bytes are unspecified, so not byte for byte)."""
    serialization = pytest.importorskip('rclpy.serialization')
    deserialize_message = serialization.deserialize_message
    serialize_message = serialization.serialize_message
    from collision_sensor.model.point_cloud_message import cdr_from_points
    for n, frame in [(0, 'world'), (1, 'map'), (37, 'panda_link0'), (5, '')]:
        points = np.random.default_rng(n).normal(size=(n, 3)).astype(np.float32)
        msg = PointCloud2(header=Header(frame_id=frame), height=1, width=n, fields=[
            PointField(name=axis, offset=4 * k, datatype=PointField.FLOAT32, count=1)
            for k, axis in enumerate('xyz')], is_bigendian=False, point_step=12,
            row_step=12 * n, data=points.tobytes(), is_dense=True)
        msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 8
        data = cdr_from_points(points, 7, 8, frame)
        assert len(data) == len(serialize_message(msg))
        back = deserialize_message(data, PointCloud2)
        assert back == msg
        assert bytes(back.data) == points.tobytes()
