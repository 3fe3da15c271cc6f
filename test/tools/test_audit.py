"""collision_sensor_check on many recordings: units found, every report line against python-fcl,
the same lines serially and in local workers, failing units reported, resume, killed workers,
worker memory, the extras' messages. (Ray: ``test_audit_ray.py``.)"""
import collections
import contextlib
import dataclasses
import json
import os
import signal
import sys

import numpy as np
import pytest

pytest.importorskip('pyarrow')

from collision_sensor.errors import ConfigError  # noqa: E402
from collision_sensor.tools import frame_check, offline_check  # noqa: E402
from collision_sensor.tools.audit import batch, report, scheduling, shipping  # noqa: E402
from collision_sensor.tools.audit.local_pool import LocalPool  # noqa: E402
from collision_sensor.tools.audit.unit_check import (  # noqa: E402
    CheckOptions, RobotSpec, UnitChecker, record_keys)
from collision_sensor.tools.audit.units import Unit, find_units  # noqa: E402
from collision_sensor.model.joint_map import load_joint_map  # noqa: E402
from collision_sensor.model.sequences import read_sequence  # noqa: E402
import audit_fleet  # noqa: E402
from test_demo_cell import CONFIG, FclCell  # noqa: E402


@pytest.fixture(scope='module')
def fleet(tmp_path_factory):
    root = str(tmp_path_factory.mktemp('fleet'))
    return root, audit_fleet.build(root)


@pytest.fixture(scope='module')
def spec():
    # The files collision_sensor_check takes without --urdf (config_path: the source tree, or
    # under colcon the install space), so that the report's settings digest is the command's.
    from collision_sensor.model.share import config_path
    return RobotSpec.load(config_path('demo_arm.urdf'), srdf=config_path('demo_arm.srdf'),
                          scene=config_path('demo_scene.yaml'), label='demo arm', demo=True)


@pytest.fixture(scope='module')
def options(fleet):
    return CheckOptions(joint_map=load_joint_map(os.path.join(fleet[0], 'joint_map.yaml')))


@pytest.fixture(scope='module')
def expected(fleet):
    """{source: contact keys} by python-fcl for every good unit but moving_part."""
    oracle = FclCell()
    out = {}
    for source, data in fleet[1]['good'].items():
        if data is not None:
            times, positions = data
            out[source] = audit_fleet.expected_keys(
                times, [oracle.colliding_pairs(q) for q in positions])
    return out


@pytest.fixture(scope='module')
def serial_records(fleet, spec, options):
    units = find_units([fleet[0]])
    return batch.run_batch(units, spec, options, batch.SerialRunner(spec, options),
                           progress='never')


def test_units_come_from_directories_globs_and_datasets_once_each(fleet):
    root, data = fleet
    sources = [unit.source for unit in find_units([root])]
    assert sorted(sources) == sorted(list(data['good']) + list(data['broken']))
    assert sources == [unit.source for unit in find_units([root])]      # a stable order
    assert not any('moving/' in s for s in sources)   # a bag directory is one unit
    globbed = find_units([os.path.join(root, '**', '*.csv'), os.path.join(root, 'a')])
    assert [u.source for u in globbed] == [os.path.join(root, 'a', 'paper_experiment.csv'),
                                           os.path.join(root, 'bad', 'nan_rows.csv'),
                                           os.path.join(root, 'bad', 'panda.csv'),
                                           os.path.join(root, 'a', 'random.mcap')]
    episodes = find_units([os.path.join(root, 'ds_v3')])
    assert [(u.kind, u.format, u.source) for u in episodes] == [
        ('lerobot', 'lerobot-v3.0', os.path.join(root, 'ds_v3') + f'#{i}') for i in (0, 1)]
    os.makedirs(os.path.join(root, 'empty'), exist_ok=True)
    for inputs, pattern in (([os.path.join(root, 'empty')], 'no recordings in it'),
                            ([os.path.join(root, 'nothing*.mcap')], 'no file matches'),
                            ([os.path.join(root, 'joint_map.yaml')], 'unknown recording'),
                            (['/no/such/bag.mcap'], 'no such file or directory')):
        with pytest.raises(ConfigError, match=pattern):
            find_units(inputs)


@pytest.mark.slow
def test_every_report_line_matches_python_fcl(fleet, serial_records, expected):
    lines = audit_fleet.by_source(serial_records.records)
    for source, keys in expected.items():
        line = lines[source]
        assert line['error'] is None, line
        for key in ('frames', 'frames_in_collision', 'pairs'):
            assert line[key] == keys[key], (source, key)
        assert line['time_in_collision'] == pytest.approx(keys['time_in_collision'], abs=1e-9)
    assert sum(keys['frames_in_collision'] > 0 for keys in expected.values()) >= 4
    assert any(keys['frames_in_collision'] == 0 for keys in expected.values())


def test_the_scene_changes_of_a_bag_are_replayed_as_the_single_check_does(
        fleet, serial_records):
    from collision_sensor import CollisionChecker
    source = os.path.join(fleet[0], 'b', 'moving')
    line = audit_fleet.by_source(serial_records.records)[source]
    checker = CollisionChecker.from_urdf(os.path.join(CONFIG, 'demo_arm.urdf'),
                                         srdf=os.path.join(CONFIG, 'demo_arm.srdf'),
                                         scene=os.path.join(CONFIG, 'demo_scene.yaml'))
    seq = read_sequence(source, joint_names=checker.joint_names)
    frames = frame_check.run_sequence(checker, seq)   # checked against python-fcl there
    assert line['scene_changes'] == len(seq.scene) > 0
    assert line['frames_in_collision'] == sum(f.in_collision for f in frames)
    assert {(p['link_a'], p['link_b']) for p in line['pairs']} == \
        {pair for f in frames for pair in f.pairs}
    assert any('crate' in (p['link_a'], p['link_b']) for p in line['pairs'])


def test_failing_units_are_reported_and_the_batch_goes_on(fleet, serial_records):
    lines = audit_fleet.by_source(serial_records.records)
    for source, reason in fleet[1]['broken'].items():
        assert lines[source]['error'] is not None and reason in lines[source]['error'], \
            lines[source]
        assert lines[source]['frames_in_collision'] is None and lines[source]['pairs'] == []
    assert 'bundled demo arm' in lines[os.path.join(fleet[0], 'bad', 'panda.csv')]['error']
    assert serial_records.status == batch.EXIT_FAILED
    keys = record_keys(CheckOptions())
    assert all(list(line) == keys + ['settings'] for line in serial_records.records)


def test_local_workers_give_the_serial_lines(fleet, spec, options, serial_records):
    units = find_units([fleet[0]])
    pooled = batch.run_batch(units, spec, options, LocalPool(spec, options, 2),
                             progress='never')
    assert pooled.records == serial_records.records     # sorted into the inputs' order
    assert pooled.stats.workers == 2 and pooled.stats.deaths == 0


def test_a_worker_reads_a_shipped_recording_without_its_path(fleet, spec, options,
                                                           serial_records, tmp_path):
    """What Ray workers do: the bytes travel, the path is only a name."""
    lines = audit_fleet.by_source(serial_records.records)
    checker = UnitChecker(spec, options)
    for unit in find_units([fleet[0]]):
        payload = shipping.pack(unit)
        moved = Unit(unit.source, unit.kind, unit.path, unit.episode)
        line = checker.check(moved, payload)
        expected = dict(lines[unit.source])
        expected.pop('settings')
        assert line == expected, unit.source


def _frame_keys(path) -> dict:
    """The report's contact keys, recomputed from the frames of ``--json`` FILE."""
    frames = [json.loads(line) for line in path.read_text().splitlines()]
    assert [frame['index'] for frame in frames] == list(range(len(frames)))
    return audit_fleet.expected_keys([frame['time'] for frame in frames],
                                     [[tuple(pair) for pair in frame['pairs']]
                                      for frame in frames])


def test_a_unit_the_report_names_is_checked_alone_frame_by_frame(fleet, serial_records,
                                                                expected, capsys, tmp_path):
    """An episode (``DATASET#N``) or a recording from a report line, checked alone: ``--json``
    gives its frames, which agree with python-fcl and with the report's line."""
    root = fleet[0]
    lines = audit_fleet.by_source(serial_records.records)
    path = tmp_path / 'frames.jsonl'
    for source in (os.path.join(root, 'ds_v21') + '#1', os.path.join(root, 'ds_v3') + '#0',
                   os.path.join(root, 'a', 'random.mcap')):
        status, out, err = _cli(capsys, [source, '--joint-map',
                                         os.path.join(root, 'joint_map.yaml'), '--json',
                                         str(path)])
        keys = _frame_keys(path)
        assert keys == expected[source], source
        assert {key: lines[source][key] for key in ('frames', 'frames_in_collision', 'pairs')} \
            == {key: keys[key] for key in ('frames', 'frames_in_collision', 'pairs')}
        assert status == (1 if keys['frames_in_collision'] else 0), err
        assert f'sequence:  {source} ({keys["frames"]} frames' in out
    assert any(expected[source]['frames_in_collision'] for source in (
        os.path.join(root, 'ds_v21') + '#1', os.path.join(root, 'ds_v3') + '#0'))
    status, _, err = _cli(capsys, [os.path.join(root, 'ds_v21') + '#7'])
    dataset = os.path.join(root, 'ds_v21')
    assert status == 2
    assert f'the dataset {dataset} has no episode 7; it has episodes 0 to 1 (2 in all)' in err
    status, _, err = _cli(capsys, [os.path.join(root, 'ds_v21'), '--json', str(path)])
    assert status == 2 and f'check the one the report names alone: collision_sensor_check ' \
        f'"{os.path.join(root, "ds_v21")}#0" --json FILE' in err


def test_a_dataset_in_normalised_units_maps_onto_the_joint_limits(fleet, capsys, tmp_path):
    """Body joints recorded -100..100 over their range (one counted the other way), mapped by
    ``range:`` onto the URDF's limits (read here from the file): every line and every frame
    agrees with python-fcl at the positions computed here."""
    limits = audit_fleet.urdf_limits(os.path.join(CONFIG, 'demo_arm.urdf'))
    good = audit_fleet.write_normalised(str(tmp_path), limits)
    oracle = FclCell()
    wanted = {source: audit_fleet.expected_keys(times, [oracle.colliding_pairs(q)
                                                        for q in positions])
              for source, (times, positions) in good.items()}
    assert any(keys['frames_in_collision'] for keys in wanted.values())
    joint_map = str(tmp_path / 'normalised.yaml')
    report = tmp_path / 'normalised.jsonl'
    status, _, err = _cli(capsys, [str(tmp_path / 'normalised'), '--joint-map', joint_map,
                                   '--report', str(report), '--jobs', '1'])
    assert status == 1, err
    for line in map(json.loads, report.read_text().splitlines()):
        keys = wanted[line['source']]
        assert {key: line[key] for key in ('frames', 'frames_in_collision', 'pairs')} == \
            {key: keys[key] for key in ('frames', 'frames_in_collision', 'pairs')}
    frames = tmp_path / 'frames.jsonl'
    source = str(tmp_path / 'normalised') + '#0'
    _cli(capsys, [source, '--joint-map', joint_map, '--json', str(frames)])
    assert _frame_keys(frames) == wanted[source]


def test_a_node_reads_in_place_only_the_very_files_the_driver_stamped(fleet, tmp_path):
    """Same path, size and modification time: read in place (a shared disk); any change, a
    missing file or no stamp at all: fetched."""
    unit = find_units([os.path.join(fleet[0], 'b', 'moving')])[0]      # a bag directory
    paths = shipping.files(unit)
    assert len(paths) > 1 and all(os.path.dirname(path) == unit.path for path in paths)
    stamped = shipping.stamp(paths)
    assert shipping.sees(stamped) and not shipping.sees(())
    copy = tmp_path / 'copy.csv'
    copy.write_text('time,a\n0,1\n')
    stamped = shipping.stamp([str(copy)])
    os.utime(copy, ns=(stamped[0][2] + 1, stamped[0][2] + 1))
    assert not shipping.sees(stamped)
    os.utime(copy, ns=(stamped[0][2], stamped[0][2]))
    assert shipping.sees(stamped)
    copy.write_text('time,a\n0,2\n0.1,3\n')
    os.utime(copy, ns=(stamped[0][2], stamped[0][2]))
    assert not shipping.sees(stamped)           # the size differs
    copy.unlink()
    assert not shipping.sees(stamped) and shipping.stamp([str(copy)])[0][1] == -1
    episode = find_units([os.path.join(fleet[0], 'ds_v3') + '#1'])[0]
    assert shipping.files(episode) == [os.path.join(episode.episode.root,
                                                    episode.episode.data_file)]


def _cli(capsys, argv):
    status = offline_check.main(argv + ['--progress', 'never'])
    out, err = capsys.readouterr()
    return status, out, err


def test_the_command_writes_the_report_summary_and_plot(fleet, serial_records, capsys,
                                                       tmp_path):
    root = fleet[0]
    path, png = tmp_path / 'audit.jsonl', tmp_path / 'audit.png'
    status, out, err = _cli(capsys, [root, '--joint-map', os.path.join(root, 'joint_map.yaml'),
                                     '--report', str(path), '--plot', str(png), '--jobs', '2'])
    assert status == 3, err
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert sorted(lines, key=lambda r: r['source']) == \
        sorted(serial_records.records, key=lambda r: r['source'])
    assert 'failed units (3):' in out and 'pairs most often in contact:' in out
    assert 'highest collision rate' in out and '2 local worker processes' in out
    assert out.rstrip().endswith('result: COLLISION and FAILED UNITS')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    status, _, err = _cli(capsys, [root, '--report', str(path)])
    assert status == 2 and 'exists already; pass --resume' in err


def test_resume_skips_what_the_report_holds_and_drops_a_torn_line(fleet, serial_records,
                                                                  capsys, tmp_path):
    root = fleet[0]
    whole = [json.dumps(r) for r in serial_records.records]
    path = tmp_path / 'cut.jsonl'
    path.write_text('\n'.join(whole[:4]) + '\n' + whole[4][:40])    # cut mid-line
    joint_map = ['--joint-map', os.path.join(root, 'joint_map.yaml')]
    status, out, err = _cli(capsys, [root, '--report', str(path), '--resume', '--jobs', '1']
                            + joint_map)
    assert status == 3, err
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert lines == serial_records.records[:4] + serial_records.records[4:]
    assert f'{len(whole) - 4} units' in out and '4 units resumed from the report' in out
    status, _, err = _cli(capsys, [root, '--report', str(path), '--resume', '--full']
                          + joint_map)
    assert status == 2 and 'written for another robot or other settings' in err


def _heavy(tmp_path, name='heavy', frames=150_000):
    """A long clear recording of the demo arm (a few tenths of a second to check)."""
    import numpy as np
    from collision_sensor.model.sequences import JointSequence, write_sequence
    rng = np.random.default_rng(5)
    walk = np.clip(np.cumsum(rng.normal(0, 0.001, (frames, 6)), axis=0), -0.3, 0.3)
    path = str(tmp_path / f'{name}.csv')
    write_sequence(JointSequence(audit_fleet.JOINTS, np.arange(frames) * 0.002, walk), path)
    return path


def check_kills(make_runner, fleet, spec, options, serial_records, tmp_path):
    """Kill the worker of one long unit once (it is checked on its retry) and of another on
    both attempts (it is reported); every other line as a serial run gives it."""
    # The long units first: each call then starts on an idle worker as it is announced, and the
    # kill lands while it runs (a call queued behind another may be finished by the time the
    # driver announces it).
    units = find_units([_heavy(tmp_path, 'once'), _heavy(tmp_path, 'twice'), fleet[0]])
    once, twice = 0, 1
    killed = []

    def kill(index, attempt, pid):
        if index == once and attempt == 1 or index == twice:
            killed.append((index, attempt))
            os.kill(pid, signal.SIGKILL)

    path = tmp_path / 'faults.jsonl'
    result = batch.run_batch(units, spec, options, make_runner(), report_path=str(path),
                             on_start=kill, progress='never')
    assert sorted(killed) == [(once, 1), (twice, 1), (twice, 2)]
    assert result.stats.deaths == 3 and result.stats.retried == 2
    lines = [json.loads(line) for line in path.read_text().splitlines()]   # valid JSON lines
    by_source = audit_fleet.by_source(lines)
    assert len(lines) == len(by_source) == len(units)
    for line in serial_records:
        assert by_source[line['source']] == line         # nothing else lost or changed
    assert by_source[units[once].source]['error'] is None
    assert by_source[units[once].source]['frames'] == 150_000
    failed = by_source[units[twice].source]
    assert failed['frames'] is None and 'died on each of 2 attempts (last: ' in failed['error']
    return failed['error']


@pytest.mark.slow
def test_a_killed_worker_costs_only_its_unit(fleet, spec, options, serial_records, tmp_path):
    error = check_kills(lambda: LocalPool(spec, options, 2), fleet, spec, options,
                        serial_records.records, tmp_path)
    assert '(last: killed by SIGKILL)' in error


def test_a_death_inside_a_call_of_several_units_charges_that_unit(fleet, spec, options,
                                                                   serial_records,
                                                                   monkeypatch):
    """Small units go several to a call; a worker dying in the middle of one charges the unit
    it was checking (its slot says which), not the call's first, and loses no other line:
    the units it had finished in that call are checked again."""
    path = os.path.join(fleet[0], 'a', 'paper_experiment.csv')
    units = [Unit(f'{path}?{k}', 'csv', path) for k in range(40)]
    weights = [scheduling.unit_weight(unit) for unit in units]
    assert len(scheduling.take_call(collections.deque(range(40)), weights, 16, set(),
                                    False)) == 16
    check = UnitChecker.check

    def crashing(self, unit, payload=None):    # the workers are forked: they inherit this
        if unit.source.endswith('?13'):
            os.kill(os.getpid(), signal.SIGKILL)
        return check(self, unit, payload)

    monkeypatch.setattr(UnitChecker, 'check', crashing)
    result = batch.run_batch(units, spec, options, LocalPool(spec, options, 2),
                             progress='never')
    assert result.stats.deaths == 2 and result.stats.retried == 1
    (expected,) = [line for line in serial_records.records if line['source'] == path]
    for k, line in enumerate(result.records):
        if k == 13:
            assert 'died on each of 2 attempts (last: killed by SIGKILL)' in line['error']
        else:
            assert line == {**expected, 'source': f'{path}?{k}'}


def test_a_unit_that_changes_the_scene_leaves_the_checker_as_loaded(fleet, spec, options,
                                                                   serial_records):
    """After a bag with scene arrays the same checker has the spec's scene again (not a new
    checker: forked workers keep sharing its trees), and the next units' lines are the
    serial run's (those the fleet's oracle checks come after this bag there too)."""
    checker = UnitChecker(spec, options)
    engine = checker.checker
    root = fleet[0]
    line = checker.check(find_units([os.path.join(root, 'b', 'moving')])[0])
    assert line['scene_changes'] > 0 and line['error'] is None
    assert checker.checker is engine
    assert engine.object_names == tuple(obj.name for obj in spec.scene)
    for obj, now in zip(spec.scene, engine.scene_objects):
        np.testing.assert_array_equal(obj.T_world_object, now.T_world_object)
    assert not engine.point_cloud_sources
    lines = audit_fleet.by_source(serial_records.records)
    for unit in find_units([os.path.join(root, 'a'), os.path.join(root, 'ds_v3')]):
        expected = dict(lines[unit.source])
        expected.pop('settings')
        assert checker.check(unit) == expected


@pytest.mark.slow
def test_forked_workers_share_the_so101_model_the_tool_built(erd_share, tmp_path):
    """The SO-101 (398,884 triangles) built once, by the process that forks the workers:
    each worker holds under a tenth of that process's memory as its own, and the lines of an
    SO-101 dataset in LeRobot's units are the serial ones and python-fcl's."""
    from engine_oracles import FclOracle
    from lerobot_writer import SO101_MAP, SO101_NAMES, so101_episodes, so101_positions, \
        write_v30
    from collision_sensor.model.joint_map import joint_map_from_mapping
    import yaml
    urdf = os.path.join(erd_share, 'robots', 'so_arm_description', 'urdf', 'so101.urdf')
    spec = RobotSpec.load(urdf, package_paths={'example-robot-data': erd_share},
                          label='so101')
    built = UnitChecker(spec, CheckOptions())
    joint_map = joint_map_from_mapping(yaml.safe_load(SO101_MAP), 'so101.yaml').for_robot(
        built.checker.joint_names, built.checker.joint_limits)
    options = CheckOptions(joint_map=joint_map)
    shared = UnitChecker(spec, options, built.checker)
    episodes = so101_episodes(6, 150, seed=4)
    write_v30(str(tmp_path / 'so101'), SO101_NAMES, episodes, fps=30, per_file=3)
    units = find_units([str(tmp_path / 'so101')])
    serial = batch.run_batch(units, spec, options, batch.SerialRunner(spec, options, shared),
                             progress='never')
    pooled = batch.run_batch(units, spec, options, LocalPool(spec, options, 2, shared),
                             progress='never')
    assert pooled.records == serial.records and pooled.stats.workers == 2
    driver = serial.stats.rss['driver'][1]
    for worker, (_, last) in pooled.stats.private.items():
        assert 0 < last < 0.1 * driver, (worker, last / 2 ** 20, driver / 2 ** 20)
    oracle = FclOracle(built.checker, urdf)
    order = [SO101_NAMES.index(name + '.pos') for name in built.checker.joint_names]
    for line, states in zip(serial.records, episodes):
        positions = so101_positions(states, built.checker.joint_limits)[:, order]
        times = (np.arange(len(states)) / 30).astype(np.float32).astype(float)
        keys = audit_fleet.expected_keys(times, [oracle.colliding_pairs(q) for q in positions])
        assert {key: line[key] for key in ('frames', 'frames_in_collision', 'pairs')} == \
            {key: keys[key] for key in ('frames', 'frames_in_collision', 'pairs')}
    assert any(line['frames_in_collision'] for line in serial.records)


@pytest.mark.slow
def test_worker_memory_does_not_grow_with_units(fleet, spec, options):
    path = os.path.join(fleet[0], 'a', 'paper_experiment.csv')
    units = [Unit(f'{path}?{k}', 'csv', path) for k in range(400)]
    stats = LocalPool(spec, options, 1).run(units, lambda index, record: None)
    (trace,) = stats.trace.values()
    assert len(trace) == 401
    grown = max(trace[50:]) - trace[50]
    assert grown < 4 * 2 ** 20, f'worker RSS grew by {grown / 2 ** 20:.1f} MiB over 350 units'


def test_without_urdf_a_mismatch_says_the_robot_is_the_demo_arm(fleet, capsys):
    status, _, err = _cli(capsys, [os.path.join(fleet[0], 'bad', 'panda.csv')])
    assert status == 2
    assert 'joints of the bundled demo arm' in err and 'pass --urdf YOUR_ROBOT.urdf' in err


@pytest.mark.parametrize('argv, pattern', [
    (['--ray', 'auto'], r'--ray needs Ray.*pip install "collision_sensor\[cluster\]"'),
    (['--json', 'x.jsonl'], 'for many recordings use --report FILE'),
    (['--resume'], '--resume continues a report: give --report FILE too'),
    (['--jobs', '0'], '--jobs 0: expected 1 or more'),
])
def test_option_errors_say_the_fix(fleet, capsys, monkeypatch, argv, pattern):
    import re
    monkeypatch.setitem(sys.modules, 'ray', None)
    status, _, err = _cli(capsys, [os.path.join(fleet[0], 'a'), os.path.join(fleet[0], 'b')]
                          + argv)
    assert status == 2 and re.search(pattern, err), err


def test_a_dataset_without_pyarrow_says_how_to_install(fleet, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, 'pyarrow', None)
    monkeypatch.setitem(sys.modules, 'pyarrow.parquet', None)
    status, _, err = _cli(capsys, [os.path.join(fleet[0], 'ds_v3')])
    assert status == 2 and 'pip install "collision_sensor[parquet]"' in err


def test_summary_and_plot_of_hand_made_lines(tmp_path):
    def line(source, frames, hit, pairs=(), error=None):
        return {'source': source, 'frames': frames, 'frames_in_collision': hit,
                'pairs': [{'link_a': a, 'link_b': b, 'first': 0.0, 'last': 1.0, 'frames': n}
                          for a, b, n in pairs], 'error': error}
    records = [line('x', 100, 50, [('a', 'b', 50)]), line('y', 10, 1, [('a', 'b', 1),
                                                                      ('a', 'c', 1)]),
               line('z', 10, 0), line('w', None, None, error='broken: fix it')]
    text = '\n'.join(report.summary_lines(records))
    assert 'units:               4 (3 checked, 1 failed)' in text
    assert 'units in collision:  2 of 3 (66.7 %)' in text
    assert '   50.0 %       100        50      1  x' in text
    assert '       2        51  a -- b' in text
    assert 'w: broken: fix it' in text
    report.plot_batch(records, str(tmp_path / 'b.png'))
    assert (tmp_path / 'b.png').read_bytes()[:4] == b'\x89PNG'


@contextlib.contextmanager
def _sigint_as_in_a_terminal():
    """Children started inside get SIGINT's default action, as a command typed in a terminal:
    a suite run as a script's background job (``make test &``) ignores SIGINT, the shell's rule
    for such jobs, and its children inherit that (Python then raises no KeyboardInterrupt)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # SIG_DFL after exec
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.slow
def test_ctrl_c_keeps_a_valid_report_that_resume_completes(fleet, serial_records, tmp_path):
    """Ctrl-C mid-run: exit 130, the report valid JSON lines of finished units, and --resume
    completes it with the lines of an uninterrupted run. The run is frozen (SIGSTOP, its whole
    process group) before the signal, so the units left are known, whatever the machine's
    speed or load; the signal goes to the group, as a terminal's Ctrl-C does (the workers
    ignore it)."""
    import shutil
    import subprocess
    import time
    root = fleet[0]
    # Long units (one written, the others copies: writing is the slow part), so that a worker
    # is seldom idle; what the test relies on is only that they outnumber what workers hold.
    heavy = [_heavy(tmp_path, 'long0')]
    heavy += [shutil.copy(heavy[0], tmp_path / f'long{k}.csv') for k in range(1, 16)]
    heavy = [str(path) for path in heavy]
    units = len(serial_records.records) + len(heavy)
    path = tmp_path / 'stopped.jsonl'
    jobs = 2
    argv = [sys.executable, '-m', 'collision_sensor.tools.offline_check', root, *heavy,
            '--joint-map', os.path.join(root, 'joint_map.yaml'), '--report', str(path),
            '--jobs', str(jobs), '--progress', 'never']
    # A session of its own, as a terminal's foreground job: its process group is the command
    # and its workers. Not in the source tree: under colcon test that has no engine.
    with _sigint_as_in_a_terminal():
        process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True, cwd=str(tmp_path), start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None and (
                not path.exists() or path.read_text().count('\n') < 1):
            time.sleep(0.02)
        assert process.poll() is None, f'ended before its first line: {process.stderr.read()}'
        os.killpg(process.pid, signal.SIGSTOP)
        # Frozen: the driver writes no line and the workers finish no unit until SIGCONT.
        # What can still be reported is what the workers hold (the unit each checks and the
        # next, scheduling.DEPTH); units never handed out are provably left to resume.
        before = [json.loads(line) for line in path.read_text().splitlines()]
        assert 1 <= len(before) and len(before) + jobs * scheduling.DEPTH < units, (
            f'{len(before)} of {units} units reported when the run was frozen: too few '
            f'left to interrupt (exit {process.poll()})')
        os.killpg(process.pid, signal.SIGINT)
    finally:
        with contextlib.suppress(ProcessLookupError):     # also when an assertion failed
            os.killpg(process.pid, signal.SIGCONT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, f'exit {process.returncode}: {err}'
    assert 'stopped; the report' in err and '--resume continues it' in err
    stopped = [json.loads(line) for line in path.read_text().splitlines()]   # valid JSON lines
    assert stopped[:len(before)] == before
    assert len(stopped) <= len(before) + jobs * scheduling.DEPTH < units
    # Under colcon test the source tree (the working directory) has no engine.
    done = subprocess.run(argv + ['--resume'], capture_output=True, text=True, timeout=300,
                          cwd=str(tmp_path))
    assert done.returncode == 3, done.stderr
    after = [json.loads(line) for line in path.read_text().splitlines()]
    assert after[:len(stopped)] == stopped
    lines = audit_fleet.by_source(after)
    assert len(lines) == len(after) == units
    for line in serial_records.records:
        assert lines[line['source']] == line


def test_closest_approach_is_the_single_checks(fleet, spec, capsys):
    """--max-distance in a batch: each unit's closest approach while clear is the one the
    single-recording check finds frame by frame (checked against fcl.distance there)."""
    from collision_sensor import CollisionChecker
    source = os.path.join(fleet[0], 'a', 'paper_experiment.csv')
    options = CheckOptions(max_distance=0.05)
    result = batch.run_batch(find_units([source, os.path.join(fleet[0], 'b')]), spec,
                             options, batch.SerialRunner(spec, options), progress='never')
    line = audit_fleet.by_source(result.records)[source]
    checker = CollisionChecker.from_urdf(os.path.join(CONFIG, 'demo_arm.urdf'),
                                         srdf=os.path.join(CONFIG, 'demo_arm.srdf'),
                                         scene=os.path.join(CONFIG, 'demo_scene.yaml'))
    seq = read_sequence(source, joint_names=checker.joint_names)
    frames = frame_check.run_sequence(checker, seq, max_distance=0.05)
    clear = [f for f in frames if not f.in_collision and f.min_distance is not None]
    best = min(clear, key=lambda f: f.min_distance)
    assert line['closest_approach'] == {'distance': best.min_distance,
                                        'link_a': best.nearest_pair[0],
                                        'link_b': best.nearest_pair[1], 'time': best.time}
    batch.print_summary(result, spec, checker, options, 'this process')
    nearest = min((r for r in result.records if r['closest_approach']),
                  key=lambda r: r['closest_approach']['distance'])
    c = nearest['closest_approach']
    assert (f'closest approach while clear: {c["distance"]:.6f} m ({c["link_a"]} -- '
            f'{c["link_b"]}) at {c["time"]:.3f} s in {nearest["source"]}; 3 units came within '
            '--max-distance') in capsys.readouterr().out


def test_the_settings_digest_is_the_files_contents_not_their_paths(erd_share, tmp_path,
                                                                   panda_urdf, panda_srdf):
    """The same Panda read from a copy elsewhere (URDF, SRDF, meshes) has the same digest, so
    --resume continues a report after a checkout moved; a changed mesh, SRDF, setting or option
    changes it."""
    import shutil
    from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec
    copy = tmp_path / 'elsewhere' / 'example-robot-data'
    shutil.copytree(os.path.join(erd_share, 'robots', 'panda_description'),
                    copy / 'robots' / 'panda_description')
    moved = copy / 'robots' / 'panda_description'
    options = CheckOptions()

    def digest(root, urdf='urdf/panda.urdf', srdf='srdf/panda.srdf', config=None,
               opts=options):
        spec = RobotSpec.load(os.path.join(root, urdf), os.path.join(root, srdf),
                              package_paths={'example-robot-data': str(root.parent.parent)},
                              config=config)
        return spec.digest(opts)

    import pathlib
    here = digest(pathlib.Path(erd_share) / 'robots' / 'panda_description')
    assert digest(moved) == here
    assert digest(moved, config={'padding': 0.01}) != here
    assert digest(moved, opts=CheckOptions(incremental=False)) != here
    text = (moved / 'srdf' / 'panda.srdf').read_text()
    line = '<disable_collisions link1="panda_link0" link2="panda_link2" reason="Never"/>'
    assert line in text
    (moved / 'srdf' / 'fewer.srdf').write_text(text.replace(line, '', 1))
    assert digest(moved, srdf='srdf/fewer.srdf') != here
    import trimesh
    mesh = str(moved / 'meshes' / 'collision' / 'link0.stl')
    shape = trimesh.load(mesh)
    shape.apply_scale(1.01)
    shape.export(mesh)
    assert digest(moved) != here


def test_a_unit_is_checked_on_one_core_whatever_the_threads_setting(spec, options):
    """Units run side by side (--jobs, Ray): each checker's batch calls on one thread, so
    --jobs N uses N cores; the robot's own settings are kept otherwise."""
    threaded = dataclasses.replace(spec, config={**(spec.config or {}), 'threads': 2})
    assert threaded.build().threads == 2
    for robot in (spec, threaded):
        assert UnitChecker(robot, options).checker.threads == 1
