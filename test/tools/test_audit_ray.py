"""collision_sensor_check on a multi-node Ray cluster on this machine (``ray.cluster_utils``:
a head without CPUs beside the driver and one-CPU worker nodes, started once for the module):
a few hundred recordings and LeRobot episodes in a folder only the driver reads (given by
paths relative to its working directory), the same lines as a serial run; a node lost
mid-run; a worker that dies; the command, Ctrl-C and --resume with nodes joining and leaving
between the runs. No Ray mock anywhere. The cluster tests are the ``cluster`` tier."""
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

ray = pytest.importorskip('ray', reason='the cluster tests need Ray: pip install '
                                        '"collision_sensor[cluster]"')
pytest.importorskip('pyarrow', reason='the cluster tests read LeRobot datasets: pip install '
                                      '"collision_sensor[parquet]"')

from collision_sensor.tools.audit import batch  # noqa: E402
from collision_sensor.tools.audit.ray_pool import RayPool  # noqa: E402
from collision_sensor.tools.audit.units import Unit, find_units  # noqa: E402
import audit_fleet  # noqa: E402
from lerobot_writer import write_v21, write_v30  # noqa: E402
from collision_sensor.model.joint_map import load_joint_map  # noqa: E402
from collision_sensor.tools.audit.unit_check import CheckOptions  # noqa: E402
from test_audit import spec  # noqa: E402,F401 (a fixture)

pytestmark = [pytest.mark.ray, pytest.mark.cluster]
#: Recordings, and episodes of each of two datasets, in the module's fleet.
RECORDINGS, EPISODES = 200, 50


@pytest.fixture(scope='module')
def crashed(tmp_path_factory):
    """Where the workers' fault injection marks a unit that crashed once."""
    return str(tmp_path_factory.mktemp('crashed'))


@pytest.fixture(scope='module')
def hidden(tmp_path_factory):
    """The folder of the recordings, which the nodes do not see."""
    return str(tmp_path_factory.mktemp('driver'))


@pytest.fixture(scope='module')
def cluster(tmp_path_factory, crashed, hidden):
    """A head node without CPUs (the driver's) and two one-CPU worker nodes, their processes
    started in a directory of their own. Injected into Ray's worker processes, as a
    monkeypatch would be: the nodes do not see the files under ``hidden`` (they are on
    another machine's disk), and a worker that reads one in place fails its unit; a worker
    checking a unit whose source ends in ``?crash`` (every time) or ``?crash-once`` (the first
    time) is killed, as a recording that crashes the engine would."""
    from ray.cluster_utils import Cluster

    def inject_faults():
        import os
        import signal
        from collision_sensor.tools.audit import shipping
        from collision_sensor.tools.audit.unit_check import UnitChecker
        check, sees = UnitChecker.check, shipping.sees

        def crashing(self, unit, payload=None):
            if payload is None and unit.path.startswith(hidden):
                raise OSError(f'{unit.path}: read in place on a node that cannot see it')
            mark = os.path.join(crashed, os.path.basename(unit.source))
            if unit.source.endswith('?crash') or (unit.source.endswith('?crash-once')
                                                  and not os.path.exists(mark)):
                open(mark, 'w').close()
                os.kill(os.getpid(), signal.SIGKILL)
            return check(self, unit, payload)

        UnitChecker.check = crashing
        shipping.sees = lambda stamped: sees(stamped) and not any(
            path.startswith(hidden) for path, _, _ in stamped)

    if ray.is_initialized():
        ray.shutdown()
    here = os.getcwd()
    os.chdir(str(tmp_path_factory.mktemp('raylets')))
    try:
        cluster = Cluster(initialize_head=True, head_node_args={'num_cpus': 0})
        nodes = [cluster.add_node(num_cpus=1) for _ in range(2)]
        cluster.wait_for_nodes()
        ray.init(address=cluster.address, log_to_driver=False, configure_logging=False,
                 runtime_env={'worker_process_setup_hook': inject_faults})
    finally:
        os.chdir(here)
    yield cluster, nodes
    ray.shutdown()
    cluster.shutdown()


@pytest.fixture(scope='module')
def driver_only(hidden):
    """``(folder, inputs)``: the fleet of test_audit, 200 CSV recordings (stretches of the
    bundled paths) and two datasets of 50 episodes each (v2.1, and v3.0 with 25 episodes a
    file), under ``folder``, which the nodes do not see; ``inputs`` relative to it."""
    folder = hidden
    root = os.path.join(folder, 'fleet')
    os.makedirs(root)
    audit_fleet.build(root)
    paths = [audit_fleet.bundled(name) for name in ('paper_experiment', 'random')]
    os.makedirs(os.path.join(root, 'many'))
    from collision_sensor.model.sequences import JointSequence, write_sequence
    rng = np.random.default_rng(46)
    episodes = []
    for k in range(RECORDINGS + 2 * EPISODES):
        seq = paths[k % 2]
        start = int(rng.integers(0, len(seq) - 60))
        stop = start + int(rng.integers(40, 60))
        piece = JointSequence(seq.joint_names, seq.times[start:stop],
                              seq.positions[start:stop])
        if k < RECORDINGS:
            write_sequence(piece, os.path.join(root, 'many', f'r{k:03d}.csv'))
        else:
            episodes.append(audit_fleet.dataset_states(piece))
    write_v21(os.path.join(root, 'many_v21'), audit_fleet.STATE_NAMES, episodes[:EPISODES])
    write_v30(os.path.join(root, 'many_v3'), audit_fleet.STATE_NAMES, episodes[EPISODES:],
              per_file=25)
    return folder, ['fleet']


@pytest.fixture(scope='module')
def joint_map(driver_only):
    return os.path.join(driver_only[0], 'fleet', 'joint_map.yaml')


@pytest.fixture(scope='module')
def options(joint_map):
    return CheckOptions(joint_map=load_joint_map(joint_map))


@pytest.fixture(scope='module')
def serial(driver_only, spec, options):
    here = os.getcwd()
    os.chdir(driver_only[0])
    try:
        units = find_units(driver_only[1])
        result = batch.run_batch(units, spec, options, batch.SerialRunner(spec, options),
                                 progress='never')
    finally:
        os.chdir(here)
    assert len(result.records) >= RECORDINGS + 2 * EPISODES
    return result.records


@pytest.fixture(scope='module')
def heavy(tmp_path_factory, spec, options):
    """``(path, line)``: a long recording (60,000 frames, a tenth of a second or two to check)
    the nodes see, and its serial line."""
    from collision_sensor.model.sequences import JointSequence, write_sequence
    from collision_sensor.tools.audit.unit_check import UnitChecker
    rng = np.random.default_rng(5)
    frames = 60_000
    walk = np.clip(np.cumsum(rng.normal(0, 0.001, (frames, 6)), axis=0), -0.3, 0.3)
    path = str(tmp_path_factory.mktemp('heavy') / 'long.csv')
    write_sequence(JointSequence(audit_fleet.JOINTS, np.arange(frames) * 0.002, walk), path)
    line = UnitChecker(spec, options).check(find_units([path])[0])
    line['settings'] = spec.digest(options)
    return path, line


def _audit(driver_only, spec, options, monkeypatch, units=None, pool=None, **kwargs):
    monkeypatch.chdir(driver_only[0])
    units = units or find_units(driver_only[1])
    return batch.run_batch(units, spec, options, RayPool(spec, options, 'auto', **(pool or {})),
                           progress='never', **kwargs)


def test_the_cluster_gives_the_serial_lines_reading_every_file_through_the_driver(
        cluster, driver_only, spec, options, serial, monkeypatch):
    """No node sees the folder: every unit's files are fetched from the driver's machine, and
    every line is the serial run's, unit for unit."""
    result = _audit(driver_only, spec, options, monkeypatch)
    assert result.records == serial
    assert result.stats.nodes == 2 and result.stats.workers == 2
    assert result.stats.deaths == result.stats.lost_nodes == 0
    assert ray.is_initialized()           # a cluster it joined is left running


def test_a_node_lost_mid_run_costs_no_unit(cluster, driver_only, spec, options, serial, heavy,
                                           monkeypatch, tmp_path):
    """A third node joins; its raylet is killed once each of the three nodes holds units (long
    ones wait in the queue). The audit ends; every unit is reported once, with the serial
    line; none is charged, and the summary says how many were checked again and why."""
    cluster, _ = cluster
    node = cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    monkeypatch.chdir(driver_only[0])
    long = [Unit(f'{heavy[0]}?{k}', 'csv', heavy[0]) for k in range(12)]
    units = find_units(driver_only[1]) + long
    expected = serial + [{**heavy[1], 'source': unit.source} for unit in long]
    report = tmp_path / 'lost.jsonl'
    workers, removed = set(), []

    def remove_later():
        while len(workers) < 3:        # a worker of each node has a call (on_start's pids)
            time.sleep(0.01)
        cluster.remove_node(node, allow_graceful=False)
        removed.append(report.read_text().count('\n') if report.exists() else 0)

    killer = threading.Thread(target=remove_later, daemon=True)
    killer.start()
    result = _audit(driver_only, spec, options, monkeypatch, units=units,
                    pool={'call_units': 4}, report_path=str(report),
                    on_start=lambda index, attempt, pid: workers.add(pid))
    killer.join(timeout=60)
    assert removed and removed[0] < len(units), 'the node was removed after the run'
    assert result.records == expected
    lines = [json.loads(line) for line in report.read_text().splitlines()]
    assert len(lines) == len({line['source'] for line in lines}) == len(units)
    stats = result.stats
    assert stats.lost_nodes == 1 and stats.rerun >= 1 and stats.deaths == 0
    assert stats.nodes == 3
    text = '\n'.join(batch.run_lines(stats, len(result.new)))
    assert f'nodes:     1 lost; {stats.rerun} units they held checked again on the others ' \
        '(none charged)' in text


def test_a_worker_that_dies_costs_only_its_unit(cluster, driver_only, spec, options, serial,
                                                monkeypatch, crashed):
    """A unit that kills its worker every time is reported after its retry; one that kills it
    once is checked on its retry; the node's host forks a new worker each time and no other
    unit is touched."""
    monkeypatch.chdir(driver_only[0])
    units = find_units(driver_only[1])[:60]
    path = os.path.join('fleet', 'a', 'paper_experiment.csv')
    units[10] = Unit(f'{path}?crash-once', 'csv', path)
    units[40] = Unit(f'{path}?crash', 'csv', path)
    result = batch.run_batch(units, spec, options, RayPool(spec, options, 'auto'),
                             progress='never')
    assert result.stats.deaths == 3 and result.stats.retried == 2
    assert result.stats.lost_nodes == 0
    lines = audit_fleet.by_source(serial)
    for unit, line in zip(units, result.records):
        if unit.source.endswith('?crash'):
            assert line['frames'] is None and 'died on each of 2 attempts (last: killed by ' \
                'SIGKILL)' in line['error']
        elif unit.source.endswith('?crash-once'):
            assert line == {**lines[unit.path], 'source': unit.source}
        else:
            assert line == lines[unit.source]


def test_the_command_stops_on_ctrl_c_and_resumes_on_other_nodes(
        cluster, driver_only, serial, joint_map, heavy, tmp_path):
    """``--ray auto`` from another process, as a user runs it beside ``ray start``: Ctrl-C
    stops it (exit 130, whole lines); a node joins and another leaves; --resume completes the
    report with the serial lines."""
    cluster, nodes = cluster
    folder, inputs = driver_only
    report = tmp_path / 'cluster.jsonl'
    long = [str(tmp_path / f'long{k}.csv') for k in range(8)]   # in the queue after the rest
    for path in long:
        shutil.copy(heavy[0], path)
    expected = serial + [{**heavy[1], 'source': path} for path in long]
    argv = [sys.executable, '-m', 'collision_sensor.tools.offline_check', *inputs, *long,
            '--joint-map', joint_map, '--ray', 'auto',
            '--report', str(report), '--progress', 'never']
    env = dict(os.environ, RAY_ADDRESS=cluster.address)
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=folder, env=env)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None and (
                not report.exists() or report.read_text().count('\n') < 20):
            time.sleep(0.01)
        assert process.poll() is None, f'ended before 20 lines: {process.stderr.read()}'
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert 'stopped; the report' in err and '--resume continues it' in err
    stopped = [json.loads(line) for line in report.read_text().splitlines()]
    assert 20 <= len(stopped) < len(expected)
    joined = cluster.add_node(num_cpus=1)
    cluster.remove_node(nodes[0], allow_graceful=True)
    cluster.wait_for_nodes()
    nodes[0] = joined
    done = subprocess.run(argv + ['--resume'], capture_output=True, text=True, timeout=300,
                          cwd=folder, env=env)
    assert done.returncode == 3, done.stderr
    assert 'on Ray (auto)' in done.stdout and 'failed units (3):' in done.stdout
    after = [json.loads(line) for line in report.read_text().splitlines()]
    assert after[:len(stopped)] == stopped
    assert sorted(after, key=lambda r: r['source']) == \
        sorted(expected, key=lambda r: r['source'])


def test_ray_local_starts_a_cluster_of_its_own_for_the_run(driver_only, serial, joint_map,
                                                           tmp_path):
    """``--ray local``: a one-machine cluster started for the run and stopped after it (its
    node's host reads the files in place); the lines of the demo fleet's first folder are the
    serial run's."""
    folder = driver_only[0]
    report = tmp_path / 'local.jsonl'
    env = {key: value for key, value in os.environ.items() if key != 'RAY_ADDRESS'}
    done = subprocess.run(
        [sys.executable, '-m', 'collision_sensor.tools.offline_check',
         os.path.join('fleet', 'a'), os.path.join('fleet', 'ds_v3'), '--joint-map', joint_map,
         '--ray', 'local', '--jobs', '2', '--report', str(report), '--progress', 'never'],
        capture_output=True, text=True, timeout=300, cwd=folder, env=env)
    assert done.returncode == 1, done.stderr
    assert 'on Ray (local)' in done.stdout
    lines = audit_fleet.by_source(serial)
    for line in map(json.loads, report.read_text().splitlines()):
        assert line == lines[line['source']]
    assert len(report.read_text().splitlines()) == 4
