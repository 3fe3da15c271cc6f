"""collision_sensor_check on a real local Ray cluster (num_cpus=2, started once for the module):
the same report lines as a serial run, from the API and from the command line joining the
cluster; a killed actor costs only its unit. No Ray mock anywhere."""
import json
import os
import subprocess
import sys

import pytest

ray = pytest.importorskip('ray')
pytest.importorskip('pyarrow')

from collision_sensor.tools.audit import batch  # noqa: E402
from collision_sensor.tools.audit.ray_pool import RayPool  # noqa: E402
from collision_sensor.tools.audit.units import find_units  # noqa: E402
from test_audit import check_kills, fleet, options, spec  # noqa: E402,F401 (fixtures)

pytestmark = pytest.mark.ray


@pytest.fixture(scope='module', autouse=True)
def cluster(tmp_path_factory):
    """A local Ray cluster of 2 CPUs for the whole module (starting one takes ~10 s): a new
    one (``address='local'``), even where a ``ray start`` cluster runs, which a plain
    ``ray.init`` would join (and refuse the CPUs asked for)."""
    if ray.is_initialized():
        ray.shutdown()
    # Ray's workers start in the driver's working directory, which is the source tree under
    # colcon test (no engine there): the cluster starts elsewhere.
    here = os.getcwd()
    os.chdir(str(tmp_path_factory.mktemp('ray')))
    try:
        context = ray.init(address='local', num_cpus=2, include_dashboard=False,
                           log_to_driver=False, configure_logging=False)
    finally:
        os.chdir(here)
    yield context
    ray.shutdown()


@pytest.fixture(scope='module')
def serial(fleet, spec, options):
    units = find_units([fleet[0]])
    return batch.run_batch(units, spec, options, batch.SerialRunner(spec, options),
                           progress='never').records


@pytest.mark.parametrize('ship', [None, True])
def test_ray_actors_give_the_serial_lines(fleet, spec, options, serial, ship):
    """Actors on this machine read the files; shipped (as to another machine), the bytes
    travel through the object store and the lines are the same."""
    units = find_units([fleet[0]])
    result = batch.run_batch(units, spec, options, RayPool(spec, options, 'auto', ship=ship),
                             progress='never')
    assert result.records == serial
    assert result.stats.workers == 2 and result.stats.deaths == 0
    assert ray.is_initialized()           # a cluster it joined is left running


def test_the_command_joins_the_running_cluster(fleet, serial, tmp_path):
    """``--ray auto`` from another process, as a user runs it next to ``ray start``."""
    root = fleet[0]
    path = tmp_path / 'ray.jsonl'
    env = dict(os.environ, RAY_ADDRESS=ray.get_runtime_context().gcs_address)
    done = subprocess.run(
        [sys.executable, '-m', 'collision_sensor.tools.offline_check', root, '--joint-map',
         os.path.join(root, 'joint_map.yaml'), '--ray', 'auto', '--report', str(path),
         '--plot', str(tmp_path / 'ray.png'), '--progress', 'never'],
        capture_output=True, text=True, env=env, timeout=300,
        cwd=str(tmp_path))   # not the source tree: under colcon test it has no engine
    assert done.returncode == 3, done.stderr
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert sorted(lines, key=lambda r: r['source']) == sorted(serial, key=lambda r: r['source'])
    assert 'on Ray (auto)' in done.stdout and 'failed units (3):' in done.stdout


def test_a_killed_actor_costs_only_its_unit(fleet, spec, options, serial, tmp_path):
    error = check_kills(lambda: RayPool(spec, options, 'auto', ship=True), fleet, spec,
                        options, serial, tmp_path)
    assert '(last: the Ray actor died' in error


def test_a_death_in_a_call_of_several_units_names_the_unit_that_kills(fleet, spec, options,
                                                                       serial):
    """Small recordings go several to a call; an actor dying in such a call charges none of
    them: they are sent again one per call, and the one that kills again is charged, tried
    alone once more, then reported. Every other line is the serial one."""
    import signal
    from collision_sensor.tools.audit.units import Unit
    path = os.path.join(fleet[0], 'a', 'paper_experiment.csv')
    units = [Unit(f'{path}?{k}', 'csv', path) for k in range(40)]
    killed = []

    def kill(index, attempt, pid):
        if index == 10:
            killed.append(attempt)
            os.kill(pid, signal.SIGKILL)

    result = batch.run_batch(units, spec, options, RayPool(spec, options, 'auto'),
                             on_start=kill, progress='never')
    assert killed == [1, 1, 2] and result.stats.deaths == 3 and result.stats.retried == 1
    (expected,) = [line for line in serial if line['source'] == path]
    for k, line in enumerate(result.records):
        if k == 10:
            assert 'died on each of 2 attempts (last: the Ray actor died' in line['error']
        else:
            assert line == {**expected, 'source': f'{path}?{k}'}
