"""Sequences: CSV and rosbag2 (mcap, sqlite3) round trips, and every bad-input rule."""
import numpy as np
import pytest

from collision_sensor.errors import SequenceError
from collision_sensor.model.sequences import JointSequence, read_sequence, write_sequence

JOINTS = ('shoulder_pan', 'shoulder_lift', 'elbow')


@pytest.fixture
def seq():
    rng = np.random.default_rng(7)
    times = np.round(np.arange(40) * 0.02 + 0.5, 6)   # whole nanoseconds: exact in a bag
    return JointSequence(JOINTS, times, rng.uniform(-3.0, 3.0, (40, 3)), 'seeded')


def _csv(tmp_path, text, name='s.csv'):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize('name, fmt', [('s.csv', None), ('s.mcap', None), ('s.db3', None),
                                       ('bag_mcap', 'mcap'), ('bag_sqlite', 'sqlite3')])
def test_round_trip_gives_the_same_sequence(tmp_path, seq, name, fmt):
    path = tmp_path / name
    write_sequence(seq, path, fmt=fmt)
    back = read_sequence(path)
    assert back.joint_names == seq.joint_names
    assert np.array_equal(back.times, seq.times)
    assert np.array_equal(back.positions, seq.positions)   # bit for bit


def test_bag_directory_has_metadata_and_storage(tmp_path, seq):
    write_sequence(seq, tmp_path / 'bag', fmt='mcap')
    assert sorted(p.name for p in (tmp_path / 'bag').iterdir()) == ['bag.mcap', 'metadata.yaml']


def test_joint_names_reorder_columns(tmp_path, seq):
    write_sequence(seq, tmp_path / 's.csv')
    back = read_sequence(tmp_path / 's.csv', joint_names=['elbow', 'shoulder_pan',
                                                           'shoulder_lift'])
    assert back.joint_names == ('elbow', 'shoulder_pan', 'shoulder_lift')
    assert np.array_equal(back.positions, seq.positions[:, [2, 0, 1]])


def test_csv_comments_and_blank_lines_are_skipped(tmp_path):
    path = _csv(tmp_path, '# note\n\ntime,a,b\n0.0,1,2\n# mid\n0.5,3,4\n\n')
    back = read_sequence(path)
    assert back.joint_names == ('a', 'b')
    assert back.times.tolist() == [0.0, 0.5]
    assert back.positions.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def _bag_from_messages(path, messages):
    """Write JointState messages (stamp_ns, names, positions) to an mcap bag directory.

    The bag's log times increase by 1 ms per message whatever the header stamps say.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    JS = store.types['sensor_msgs/msg/JointState']
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    connection = writer.add_connection('/joint_states', JS.__msgtype__, typestore=store)
    empty = np.zeros(0)
    for index, (stamp, names, positions) in enumerate(messages):
        msg = JS(header=Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9),
                               frame_id=''),
                 name=list(names), position=np.array(positions, dtype=float),
                 velocity=empty, effort=empty)
        writer.write(connection, (index + 1) * 10**6, store.serialize_cdr(msg, JS.__msgtype__))
    writer.close()


def test_partial_joint_states_merge_into_frames(tmp_path):
    path = tmp_path / 'bag'
    _bag_from_messages(path, [
        (10**9, ['a'], [1.0]),                 # b not seen yet: no frame
        (2 * 10**9, ['b', 'gripper'], [2.0, 9.0]),   # first frame (a=1, b=2); gripper ignored
        (3 * 10**9, ['a'], [3.0]),             # a=3, b carried
        (3 * 10**9, ['b'], [4.0]),             # same stamp: updates that frame
    ])
    back = read_sequence(path, joint_names=['a', 'b'])
    assert back.times.tolist() == [2.0, 3.0]
    assert back.positions.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_bag_missing_joint_is_an_error(tmp_path):
    path = tmp_path / 'bag'
    _bag_from_messages(path, [(10**9, ['a'], [1.0])])
    with pytest.raises(SequenceError, match=r'never names joint\(s\) \[.b.\]'):
        read_sequence(path, joint_names=['a', 'b'])


def test_bag_stamps_going_back_are_an_error(tmp_path):
    path = tmp_path / 'bag'
    _bag_from_messages(path, [(2 * 10**9, ['a'], [1.0]), (1 * 10**9, ['a'], [2.0])])
    with pytest.raises(SequenceError, match='message 1: .* earlier than'):
        read_sequence(path)


def test_bag_unknown_topic_names_the_topics_it_has(tmp_path, seq):
    write_sequence(seq, tmp_path / 'bag', fmt='mcap')
    with pytest.raises(SequenceError, match=r'no topic "/other".*/joint_states'):
        read_sequence(tmp_path / 'bag', topic='/other')


# --- the bad-input rules: each names the file, the place and the fix ---------------------------

@pytest.mark.parametrize('text, pattern', [
    ('', r'empty file; expected a header "time,<joint>'),
    ('# only a comment\n', 'empty file'),
    ('time,a,b\n', 'no frames after the header'),
    ('t,a\n0,1\n', r'line 1: the first column is "t", expected "time"'),
    ('time,a,a\n0,1,2\n', r"line 1: column\(s\) \['a'\] appear more than once"),
    ('time,a,b\n0,1\n', r'line 2: 2 values, expected 3'),
    ('time,a,b\n0,1,x\n', r'line 2, column "b": "x" is not a number'),
    ('time,a,b\n0,1,nan\n', r'line 2, column "b": nan is not a finite number'),
    ('time,a,b\n0,1,2\n0,1,2\n', r'line 3: time 0 is not after .* strictly increase'),
    ('time,a,b\n1,1,2\n0.5,1,2\n', r'line 3: time 0.5 is not after'),
])
def test_bad_csv_is_reported_with_file_line_and_fix(tmp_path, text, pattern):
    path = _csv(tmp_path, text)
    with pytest.raises(SequenceError, match=pattern) as info:
        read_sequence(path)
    assert path in str(info.value)


def test_unknown_column_names_the_robots_joints(tmp_path):
    path = _csv(tmp_path, 'time,a,elbw\n0,1,2\n')
    with pytest.raises(SequenceError, match=r"line 1: unknown joint column\(s\) \['elbw'\]; "
                                            r"the robot's joints are \['a', 'elbow'\]"):
        read_sequence(path, joint_names=['a', 'elbow'])


def test_missing_column_is_reported(tmp_path):
    path = _csv(tmp_path, 'time,a\n0,1\n')
    with pytest.raises(SequenceError, match=r"line 1: no column for joint\(s\) \['b'\]"):
        read_sequence(path, joint_names=['a', 'b'])


def test_unreadable_files_are_reported(tmp_path):
    with pytest.raises(SequenceError, match='no such file'):
        read_sequence(tmp_path / 'missing.csv')
    (tmp_path / 'plain_dir').mkdir()
    with pytest.raises(SequenceError, match='without metadata.yaml is not a rosbag2 bag'):
        read_sequence(tmp_path / 'plain_dir')
    (tmp_path / 'binary.csv').write_bytes(b'\xff\xfe\x00time')
    with pytest.raises(SequenceError, match='cannot read'):
        read_sequence(tmp_path / 'binary.csv')
    (tmp_path / 'broken.mcap').write_bytes(b'not an mcap file at all')
    with pytest.raises(SequenceError, match='broken.mcap: cannot read the bag'):
        read_sequence(tmp_path / 'broken.mcap')
    (tmp_path / 's.txt').write_text('time,a\n0,1\n')
    with pytest.raises(SequenceError, match='unknown sequence format ".txt"'):
        read_sequence(tmp_path / 's.txt')


def test_writing_a_bag_over_an_existing_path_is_refused(tmp_path, seq):
    write_sequence(seq, tmp_path / 'bag', fmt='mcap')
    with pytest.raises(SequenceError, match='exists already'):
        write_sequence(seq, tmp_path / 'bag', fmt='mcap')


def test_sequence_rejects_non_increasing_times_and_nan():
    with pytest.raises(SequenceError, match='frame 1: .* strictly increase'):
        JointSequence(('a',), np.array([0.0, 0.0]), np.zeros((2, 1)))
    with pytest.raises(SequenceError, match='finite'):
        JointSequence(('a',), np.array([0.0, 1.0]), np.array([[0.0], [np.nan]]))
    with pytest.raises(SequenceError, match='shape'):
        JointSequence(('a', 'b'), np.array([0.0, 1.0]), np.zeros((2, 1)))


# --- scene changes in bags --------------------------------------------------------------------

def _cube(ns, x, frame=''):
    from types import SimpleNamespace as Fields
    return Fields(header=Fields(frame_id=frame), ns=ns, id=0, type=1, action=0,
                  pose=Fields(position=Fields(x=x, y=0.0, z=0.5),
                              orientation=Fields(x=0.0, y=0.0, z=0.0, w=1.0)),
                  scale=Fields(x=0.1, y=0.2, z=0.3), points=(), mesh_resource='', text='b c')


@pytest.mark.parametrize('name', ['s.mcap', 's.db3'])
def test_scene_events_round_trip_through_a_bag(tmp_path, seq, name):
    from collision_sensor.model.sequences import SceneEvent
    events = (SceneEvent(0.5, (_cube('crate', 0.25),)),
              SceneEvent(0.7, (_cube('crate', 0.5, frame='tool'), _cube('post', -1.0))),
              SceneEvent(2.0, (_cube('post', 1.0),)))     # after the last frame (1.28 s)
    with_scene = JointSequence(seq.joint_names, seq.times, seq.positions, 'seeded', events)
    write_sequence(with_scene, tmp_path / name)
    back = read_sequence(tmp_path / name)
    assert [event.time for event in back.scene] == [0.5, 0.7, 2.0]
    markers = [m for event in back.scene for m in event.markers]
    assert [(m.ns, m.header.frame_id, m.pose.position.x, m.text) for m in markers] == [
        ('crate', '', 0.25, 'b c'), ('crate', 'tool', 0.5, 'b c'), ('post', '', -1.0, 'b c'),
        ('post', '', 1.0, 'b c')]
    assert (markers[0].scale.x, markers[0].scale.y, markers[0].scale.z) == (0.1, 0.2, 0.3)
    # Each event goes before the first frame at or after its time; the late one with the last.
    before = back.scene_before()
    assert [len(events) for events in before] == [1] + [0] * 9 + [1] + [0] * 28 + [1]
    assert back.select(['elbow']).scene == back.scene


def test_a_csv_file_holds_no_scene_changes(tmp_path, seq):
    from collision_sensor.model.sequences import SceneEvent
    with_scene = JointSequence(seq.joint_names, seq.times, seq.positions, 'seeded',
                               (SceneEvent(0.5, (_cube('crate', 0.0),)),))
    with pytest.raises(SequenceError, match='a CSV file holds no scene changes; write a bag'):
        write_sequence(with_scene, tmp_path / 's.csv')


def test_scene_events_out_of_order_are_refused(seq):
    from collision_sensor.model.sequences import SceneEvent
    with pytest.raises(SequenceError, match='scene event times must be finite and in order'):
        JointSequence(seq.joint_names, seq.times, seq.positions, 'seeded',
                      (SceneEvent(1.0, ()), SceneEvent(0.5, ())))


def test_a_scene_topic_of_another_type_is_named(tmp_path, seq):
    write_sequence(seq, tmp_path / 's.mcap')
    with pytest.raises(SequenceError, match='topic "/joint_states" has type '
                                            'sensor_msgs/msg/JointState, expected '
                                            'visualization_msgs/msg/MarkerArray'):
        read_sequence(tmp_path / 's.mcap', scene_topic='/joint_states')


@pytest.fixture(params=['engine', 'loadtxt'])
def fast_parser(request):
    """The fast path's parser: the engine's (registered when it loads), or numpy's loadtxt
    (before it does)."""
    from collision_sensor.engine.compiled import engine
    from collision_sensor.model import sequences
    sequences.use_number_table_parser(
        engine.parse_number_table if request.param == 'engine' else None)
    yield request.param
    sequences.use_number_table_parser(engine.parse_number_table)


def test_the_engine_registers_its_number_parser():
    from collision_sensor.engine.compiled import engine
    from collision_sensor.model import sequence_csv
    assert sequence_csv._number_table_parser is engine.parse_number_table


def test_the_fast_csv_reader_gives_the_exact_readers_floats(tmp_path, fast_parser):
    """The fast path (the engine's parser, or numpy's) against Python's float (the exact path)
    on values of every magnitude, subnormal and largest included, written as repr and as
    people write them."""
    from collision_sensor.model import sequence_csv
    rng = np.random.default_rng(7)
    values = np.concatenate([rng.normal(0, 1, 3000), rng.normal(0, 1e-9, 300),
                             rng.uniform(-1e6, 1e6, 300), [0.0, -0.0, 5e-324, 1e308]])
    texts = [repr(float(v)) for v in values] + ['.5', '5.', '1E3', '+2', ' 0.25 ', '-0']
    rows = [texts[i:i + 3] for i in range(0, len(texts) - len(texts) % 3, 3)]
    body = '\n'.join(f'{k * 0.01!r},{a},{b},{c}' for k, (a, b, c) in enumerate(rows))
    path = tmp_path / 'mixed.csv'
    path.write_text('# header comment\n\ntime,a,b,c\n' + body + '\n\n')
    fast = sequence_csv.read_csv_fast(str(path), path.read_text(), None)
    assert fast is not None
    exact = np.array([[float(x) for x in row] for row in rows])
    np.testing.assert_array_equal(fast.positions, exact)
    assert np.array_equal(np.signbit(fast.positions), np.signbit(exact))
    assert read_sequence(path) == fast


@pytest.mark.parametrize('body', ['0,1\n1,2 # late\n', '0,1\n1,"2"\n', '0,1\n1,nan\n',
                                  '0,1\n0,2\n', '0,1\n,,\n1,2\n', '0,1\n1,2,3\n',
                                  '0,1\n1,0x1p3\n', '0,1\n1,1_000\n', '0,1\n1,inf\n',
                                  '0,1\n1,1e999\n', '0,1\n1,+-2\n', '0,1\n1,2e\n',
                                  '0,1\n1,.\n', '0,1\n1,2\xa0\n', '0,1\n1\n'])
def test_what_the_fast_reader_refuses_the_exact_reader_judges(tmp_path, body, fast_parser):
    """The engine's parser refuses every one of these bodies; numpy's refuses them or reads
    what the exact reader reads (it takes a non-breaking space for a blank, as Python does)."""
    from collision_sensor.model import sequence_csv
    path = tmp_path / 'odd.csv'
    path.write_text('time,a\n' + body)
    fast = sequence_csv.read_csv_fast(str(path), path.read_text(), None)
    if fast_parser == 'engine':
        assert fast is None
    elif fast is not None:
        assert fast == sequence_csv.read_csv(str(path), None)
    try:
        exact = sequence_csv.read_csv(str(path), None)
    except SequenceError as err:
        assert 'line' in str(err)     # the exact reader names the line
    else:  # quoted and empty rows are fine, and what Python's float reads
        accepted = {'0,1\n1,"2"\n': 2.0, '0,1\n,,\n1,2\n': 2.0, '0,1\n1,1_000\n': 1000.0,
                    '0,1\n1,2\xa0\n': 2.0}
        assert body in accepted
        assert exact.positions.tolist() == [[1.0], [accepted[body]]]


# --- point clouds in bags ----------------------------------------------------------------------

@pytest.mark.parametrize('fmt', ['mcap', 'sqlite3'])
def test_clouds_are_read_in_stamp_order_and_scheduled_by_the_frames(tmp_path, fmt):
    """Two cameras with different delays: the bag's order (log time) is not the stamps'; the
    messages come back in stamp order, each its own, and each cloud goes before the first frame
    at or after its stamp (earlier ones dropped, later ones after the last frame)."""
    from cloud_bags import _typestore, cloud_message, write_bag
    typestore = _typestore()
    times = np.array([1.0, 1.1, 1.2, 1.3])
    positions = np.column_stack([times, -times, 2 * times])
    point = np.array([[0.1, 0.2, 0.3]])
    # (topic, log time, stamp, frame)
    recorded = [('/a', 0.50, 0.50, 'a0'), ('/a', 1.12, 1.10, 'a1'), ('/b', 1.16, 1.05, 'b1'),
                ('/a', 1.22, 1.20, 'a2'), ('/b', 1.26, 1.15, 'b2'), ('/b', 1.50, 1.45, 'b3')]
    clouds = [(topic, log, cloud_message(typestore, point * (k + 1), frame, int(stamp * 1e9)))
              for k, (topic, log, stamp, frame) in enumerate(recorded)]
    path = tmp_path / ('c.mcap' if fmt == 'mcap' else 'c.db3')
    write_bag(path, fmt, JOINTS, times, positions, clouds)
    seq = read_sequence(path)
    by_stamp = sorted(recorded, key=lambda r: r[2])
    assert [(e.source, e.time, e.frame) for e in seq.clouds] == [
        (topic[1:], stamp, frame) for topic, _, stamp, frame in by_stamp]
    from collision_sensor.model.sequences import iter_cloud_messages
    got = [(event.frame, msg.header.frame_id, np.frombuffer(msg.data, '<f4')[0])
           for event, msg in iter_cloud_messages(seq.clouds)]
    scale = {frame: k + 1 for k, (_, _, _, frame) in enumerate(recorded)}
    assert got == [(f, f, pytest.approx(0.1 * scale[f])) for _, _, _, f in by_stamp]
    schedule = seq.cloud_schedule()
    assert [e.frame for e in schedule.before_first] == ['a0']
    assert [[e.frame for e in events] for events in schedule.per_frame] == [
        [], ['b1', 'a1'], ['b2', 'a2'], []]
    assert [e.frame for e in schedule.after_last] == ['b3']
    assert read_sequence(path, cloud_topics=['b']).clouds[0].frame == 'b1'
    # Memory is bounded: clouds read ahead of their turn are kept up to a limit.
    from collision_sensor.model import sequence_bag
    limit, sequence_bag.MAX_READ_AHEAD = sequence_bag.MAX_READ_AHEAD, 10
    try:
        with pytest.raises(SequenceError, match='the cloud of b stamped 1.050 s was recorded '
                           'after more than 0 MiB of clouds stamped later'):
            list(iter_cloud_messages(seq.clouds))
    finally:
        sequence_bag.MAX_READ_AHEAD = limit
    # The state at a cloud's stamp: linear between the frames around it.
    assert seq.positions_at(1.05) == pytest.approx([1.05, -1.05, 2.1])
    assert seq.positions_at(0.5) == pytest.approx(positions[0])
    assert seq.positions_at(9.0) == pytest.approx(positions[-1])


def test_a_cloud_topic_that_is_missing_or_not_a_cloud_is_named(tmp_path, seq):
    path = tmp_path / 's.mcap'
    write_sequence(seq, path)
    with pytest.raises(SequenceError, match='no topic "/cam" in the bag; its PointCloud2 '
                       'topics are none'):
        read_sequence(path, cloud_topics=['/cam'])
    with pytest.raises(SequenceError, match='has type sensor_msgs/msg/JointState, expected '
                       'sensor_msgs/msg/PointCloud2'):
        read_sequence(path, cloud_topics=['joint_states'])
    assert read_sequence(path).clouds == ()
