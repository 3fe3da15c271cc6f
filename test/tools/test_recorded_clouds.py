"""Bags with PointCloud2 topics through the offline checker
(collision_sensor.tools.recorded_clouds, ``collision_sensor_check``, the batch audit's unit), on
the Panda (example-robot-data), mcap and sqlite3 (the scenario: test/cloud_bags.py).

Oracles: the box's contacts, frame by frame, are python-fcl's (one fcl.Box per voxel of the
test's own voxelisation of the points, against each link's BVH models and primitives at
pinocchio's poses); the robot's own surfaces, seen between two frames in the hand's frame, are
filtered whole with the pose at the cloud's stamp (and not with either frame's pose: the test
shows both would keep voxels); each bad cloud is refused with its reason, counted, and the check
goes on with the last good cloud of its topic.
"""
import json
import os

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.model.sequences import read_sequence
from collision_sensor.tools import offline_check
from cloud_bags import OBJECT_TOPIC, PANDA_JOINTS, SELF_TOPIC, panda_sweep, write_bag
from engine_oracles import FclOracle, voxel_links_in_contact

OBJECT, OWN = 'cloud/' + OBJECT_TOPIC[1:], 'cloud/' + SELF_TOPIC[1:]
VOXEL = 0.02


@pytest.fixture(scope='module')
def panda_files(erd_share):
    base = os.path.join(erd_share, 'robots', 'panda_description')
    return (os.path.join(base, 'urdf', 'panda.urdf'), os.path.join(base, 'srdf', 'panda.srdf'),
            f'example-robot-data={erd_share}')


@pytest.fixture(scope='module')
def panda(panda_files, erd_package_paths):
    urdf, srdf, _ = panda_files
    return CollisionChecker.from_urdf(urdf, srdf, package_paths=erd_package_paths)


@pytest.fixture(scope='module')
def scenario(panda):
    return panda_sweep(panda, np.random.default_rng(29))


@pytest.fixture(scope='module', params=['mcap', 'sqlite3'])
def bag(request, scenario, tmp_path_factory):
    times, positions, clouds, _ = scenario
    path = tmp_path_factory.mktemp(request.param) / ('sweep.mcap' if request.param == 'mcap'
                                                     else 'sweep.db3')
    write_bag(path, request.param, PANDA_JOINTS, times, positions, clouds)
    return str(path)


def _check(bag, panda_files, tmp_path, capsys, *extra):
    urdf, srdf, package = panda_files
    out = tmp_path / 'frames.jsonl'
    status = offline_check.main([bag, '--urdf', urdf, '--srdf', srdf, '--package-path', package,
                                 '--json', str(out), '--progress', 'never', *extra])
    text = capsys.readouterr().out
    return status, [json.loads(line) for line in out.read_text().splitlines()], text


def _voxel_centres(points, size):
    """The test's own voxelisation: the cubes of a world-aligned grid holding a point."""
    cells = np.unique(np.floor(points / size).astype(np.int64), axis=0)
    return (cells + 0.5) * size


def test_reading_keeps_the_points_in_the_bag_and_orders_by_stamp(bag, scenario):
    seq = read_sequence(bag, joint_names=PANDA_JOINTS)
    times, _, clouds, _ = scenario
    assert len(seq) == len(times)
    assert [(e.source, e.time) for e in seq.clouds] == sorted(
        [(topic[1:], (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec) / 1e9)
         for topic, _, msg in clouds], key=lambda item: item[1])
    assert all(not hasattr(event, 'points') for event in seq.clouds)
    assert read_sequence(bag, cloud_topics=[SELF_TOPIC]).clouds[0].source == SELF_TOPIC[1:]
    assert read_sequence(bag, cloud_topics=['camera/points']).clouds[0].frame == 'panda_link1'
    assert read_sequence(bag, cloud_topics=()).clouds == ()


def test_box_contacts_equal_fcl_on_the_voxels_and_own_points_are_filtered(
        bag, scenario, panda, panda_files, tmp_path, capsys):
    times, positions, _, facts = scenario
    status, frames, text = _check(bag, panda_files, tmp_path, capsys)
    assert status == offline_check.EXIT_COLLISION
    # The oracle: the box's voxels (nothing of it is near the robot at its stamp, t = 0).
    centres = _voxel_centres(facts['box'], VOXEL)
    reference = CollisionChecker.from_urdf(panda_files[0], panda_files[1], package_paths={
        'example-robot-data': panda_files[2].split('=', 1)[1]})
    reference.set_points(OBJECT_TOPIC[1:], facts['box'], positions=positions[0])
    # (the bag holds it in panda_link1's frame at the first frame: placed with that pose)
    engine_centres, size = reference.cloud_voxels(OBJECT_TOPIC[1:])
    assert size == VOXEL
    assert sorted(map(tuple, np.round(engine_centres, 9))) == sorted(
        map(tuple, np.round(centres, 9)))
    links = [a if b == OBJECT else b for a, b in reference.checked_pairs if OBJECT in (a, b)]
    oracle = FclOracle(panda, panda_files[0])
    seen = 0
    for frame, q in zip(frames, positions):
        want = voxel_links_in_contact(oracle, q, centres, VOXEL, links)
        got = {a if b == OBJECT else b for a, b in frame['pairs'] if OBJECT in (a, b)}
        assert got == want, frame['time']
        assert not any(OWN in pair for pair in frame['pairs']), frame['time']
        seen += bool(want)
    assert 3 <= seen < len(frames)
    # Every pair in contact is with the box: the arm alone is clear throughout.
    assert all(OBJECT in pair for frame in frames for pair in frame['pairs'])
    # The robot's own points: applied before frame 9, every one filtered out.
    own = [c for frame in frames for c in frame['clouds'] if c['source'] == SELF_TOPIC[1:]]
    assert own == [{'source': SELF_TOPIC[1:], 'time': facts['t_self'], 'frame': 'panda_link0',
                    'voxels': 0}]
    assert any(c['source'] == SELF_TOPIC[1:] for c in frames[9]['clouds'])
    # ... which takes the pose at the cloud's stamp: either frame's pose keeps voxels.
    for q in (positions[8], positions[9]):
        assert reference.set_points('probe', facts['own'], positions=q) > 0
    assert reference.set_points('probe', facts['own'],
                                positions=_halfway(positions[8], positions[9])) == 0
    assert 'point clouds:        2 of 8 applied (bad/points, camera/points, wrist/points)' in text


def _halfway(a, b):
    return 0.5 * (np.asarray(a) + np.asarray(b))


def test_bad_clouds_are_counted_named_and_the_check_goes_on(bag, panda_files, tmp_path,
                                                            capsys):
    status, frames, text = _check(bag, panda_files, tmp_path, capsys)
    refused = {c['time']: c['error'] for frame in frames for c in frame['clouds']
               if c['voxels'] is None}
    assert sorted(refused) == [0.31, 0.71, 1.11, 1.15, 1.31]
    assert 'field "x" is INT32; x, y and z must be FLOAT32 or FLOAT64' in refused[0.31]
    assert 'does not fit in point_step 8' in refused[0.71]
    assert ('header.frame_id "camera_optical_frame" is no link of the robot and not its '
            'world frame ("panda_link0")') in refused[1.11]
    assert 'add the camera\'s optical frame to the URDF as a link' in refused[1.11]
    assert 'every one of its 50 points has a NaN' in refused[1.15]
    assert 'no "z" field (fields: "x", "y", "w")' in refused[1.31]
    assert all(message.startswith('point cloud ') and message.endswith(f'at {t:.3f} s)')
               for t, message in refused.items())
    # The box (camera/points' last good cloud) stays the obstacle after its NaN cloud.
    assert any(OBJECT in pair for frame in frames if frame['time'] > 1.15
               for pair in frame['pairs'])
    assert ('not applied: 1 after_last_frame, 2 fields, 1 frame, 1 invalid, 1 layout'
            in text)
    assert 'result: COLLISION (6 of 8 point clouds not applied: see above)' in text


def test_options_reach_the_filter(bag, panda_files, tmp_path, capsys):
    # The box is about 1 m from the base: a 0.5 m range drops it; no contact is left.
    status, frames, _ = _check(bag, panda_files, tmp_path, capsys, '--cloud-max-range', '0.5')
    assert status == offline_check.EXIT_CLEAR
    # Only the chosen topic is read; a larger voxel keeps fewer, larger cubes.
    status, frames, _ = _check(bag, panda_files, tmp_path, capsys, '--cloud-topic',
                               'camera/points', '--cloud-voxel-size', '0.05')
    clouds = [c for frame in frames for c in frame['clouds']]
    assert {c['source'] for c in clouds} == {'camera/points'}
    assert clouds[0]['voxels'] < 64 and status == offline_check.EXIT_COLLISION
    # Checked from scratch at every frame: the same answers as the incremental updates.
    _, incremental, _ = _check(bag, panda_files, tmp_path, capsys)
    _, full, _ = _check(bag, panda_files, tmp_path, capsys, '--full')
    assert [f['pairs'] for f in full] == [f['pairs'] for f in incremental]
    status, frames, _ = _check(bag, panda_files, tmp_path, capsys, '--no-clouds')
    assert status == offline_check.EXIT_CLEAR and 'clouds' not in frames[0]


@pytest.mark.parametrize('args, message', [
    (['--cloud-voxel-size', '0'], '--cloud-voxel-size'),
    (['--cloud-max-range', '-1'], '--cloud-max-range -1.0: expected a finite distance'),
    (['--cloud-persistence', 'nan'], '--cloud-persistence nan'),
    (['--cloud-topic', '/joint_states'], 'topic "/joint_states" has type '
     'sensor_msgs/msg/JointState, expected sensor_msgs/msg/PointCloud2'),
    (['--cloud-topic', '/nothing'], 'no topic "/nothing" in the bag; its PointCloud2 topics'),
    (['--no-clouds', '--cloud-topic', 'x'], '--no-clouds and --cloud-topic contradict'),
])
def test_bad_cloud_options_are_one_error_line(bag, panda_files, capsys, args, message):
    urdf, srdf, package = panda_files
    status = offline_check.main([bag, '--urdf', urdf, '--srdf', srdf, '--package-path', package,
                                 '--progress', 'never', *args])
    err = capsys.readouterr().err
    assert status == offline_check.EXIT_ERROR and message in err, err


def test_the_audit_unit_reports_the_same_pairs_and_counts(bag, panda_files, tmp_path, capsys):
    _, frames, _ = _check(bag, panda_files, tmp_path, capsys)
    urdf, srdf, package = panda_files
    report = tmp_path / 'audit.jsonl'
    status = offline_check.main([bag, '--urdf', urdf, '--srdf', srdf, '--package-path', package,
                                 '--report', str(report), '--jobs', '1', '--progress', 'never'])
    text = capsys.readouterr().out
    assert ('point clouds: 2 of 8 applied in 1 units\n  not applied in 1 units: '
            '1 after_last_frame, 2 fields, 1 frame, 1 invalid, 1 layout') in text, text
    assert status == offline_check.EXIT_COLLISION
    line = json.loads(report.read_text().splitlines()[0])
    assert line['error'] is None
    spans = {}
    for frame in frames:
        for a, b in frame['pairs']:
            spans.setdefault((a, b), []).append(frame['time'])
    assert {(p['link_a'], p['link_b']): (p['first'], p['last'], p['frames'])
            for p in line['pairs']} == {
        pair: (pytest.approx(t[0]), pytest.approx(t[-1]), len(t)) for pair, t in spans.items()}
    counts = line['point_clouds']
    assert (counts['clouds'], counts['applied']) == (8, 2)
    assert counts['rejected'] == {'after_last_frame': 1, 'fields': 2, 'frame': 1, 'invalid': 1,
                                  'layout': 1}
    assert counts['sources'] == ['bad/points', 'camera/points', 'wrist/points']
