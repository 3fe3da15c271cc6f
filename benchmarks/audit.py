"""``python -m benchmarks audit``: checking many recordings, one core against two and Ray.

``python -m benchmarks audit [--recordings 1000] [--frames 1000] [--runs 3] [--no-ray]
[--markdown FILE]``

Generates ``--recordings`` CSV files of ``--frames`` Panda frames each (a random walk from a
random configuration within the joint limits, 100 Hz, N(0, 0.01) rad per joint per frame;
some walks touch themselves), then checks them all ``--runs`` times as
``collision_sensor_check`` does (:func:`~collision_sensor.tools.audit.batch.run_batch`, the
default incremental check): ``--jobs 1`` (this process), ``--jobs 2`` (two local workers) and
a local Ray cluster of 2 CPUs (started once, not timed; the actors' start is timed), in a
rotating order each round. It prints the wall time and frames per second of each (min, median
and max over the runs), the ratios of each round, frames per second per core next to one
``check_batch`` and one ``update_batch`` call on a recording's frames (what a unit costs
without reading, fan-out and report), how busy the machine was (load average, and the cores
busy during each run by ``/proc/stat``), and whether every run gave the same report lines.

Targets: ``--jobs 2`` >= 1.8x the throughput of ``--jobs 1``; Ray within 15 % of
``--jobs 2``. Throughput is judged end to end (start to last line, the workers' start
included); the steady rate after the first line is printed beside it.
"""
import argparse
import os
import statistics
import sys
import tempfile
import time
from typing import Dict, List, Optional, Sequence

import numpy as np

from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.model.example_robots import example_robot
from collision_sensor.model.sequences import read_sequence
from collision_sensor.tools.audit import batch
from collision_sensor.tools.audit.local_pool import LocalPool
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec
from collision_sensor.tools.audit.units import find_units

JOBS2_TARGET = 1.8
RAY_TARGET = 0.85


def write_recordings(directory: str, checker, count: int, frames: int, seed: int) -> None:
    """Write ``count`` CSV files of ``frames`` random-walk frames of ``checker``'s robot."""
    rng = np.random.default_rng(seed)
    lower, upper = sampling_bounds(checker)
    starts = random_configurations(checker, count, seed)
    header = 'time,' + ','.join(checker.joint_names)
    times = np.arange(frames) * 0.01
    for k in range(count):
        steps = rng.normal(0.0, 0.01, (frames, len(lower)))
        steps[0] = 0.0
        walk = np.clip(starts[k] + np.cumsum(steps, axis=0), lower, upper)
        np.savetxt(os.path.join(directory, f'rec_{k:05d}.csv'), np.column_stack([times, walk]),
                   delimiter=',', fmt='%.17g', header=header, comments='')


def busy_cores() -> Optional[tuple]:
    """Return the machine's (busy, total) CPU ticks so far (``/proc/stat``), or None."""
    try:
        with open('/proc/stat') as stream:
            values = [int(v) for v in stream.readline().split()[1:9]]
    except (OSError, ValueError):
        return None
    idle = values[3] + values[4]
    return sum(values) - idle, sum(values)


def cores_busy_between(before, after, cores: int) -> Optional[float]:
    if before is None or after is None or after[1] == before[1]:
        return None
    return cores * (after[0] - before[0]) / (after[1] - before[1])


def quiet_sample(seconds: float, cores: int) -> Optional[float]:
    """Cores busy while this process sleeps ``seconds``: the others' work."""
    before = busy_cores()
    time.sleep(seconds)
    return cores_busy_between(before, busy_cores(), cores)


def spread(values: Sequence[float], fmt: str = '{:.2f}') -> str:
    """``min / median / max`` of ``values``."""
    return ' / '.join(fmt.format(v) for v in (min(values), statistics.median(values),
                                               max(values)))


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ['cluster']:      # python -m benchmarks audit cluster --help
        from benchmarks import audit_cluster
        return audit_cluster.main(argv[1:])
    if argv[:1] == ['dataset']:      # python -m benchmarks audit dataset --help
        from benchmarks import audit_dataset
        return audit_dataset.main(argv[1:])
    parser = argparse.ArgumentParser(prog='python -m benchmarks audit',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--recordings', type=int, default=1000)
    parser.add_argument('--frames', type=int, default=1000)
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--seed', type=int, default=1998)
    parser.add_argument('--no-ray', action='store_true', help='leave Ray out')
    parser.add_argument('--markdown', metavar='FILE', help='also write the table here')
    args = parser.parse_args(argv)
    text = run(args.recordings, args.frames, args.runs, args.seed, not args.no_ray,
               log=lambda m: print(f'[python -m benchmarks audit] {m}', file=sys.stderr,
                                   flush=True))
    print(text)
    if args.markdown:
        with open(args.markdown, 'w', encoding='utf-8') as stream:
            stream.write(text)
    return 0


def run(recordings: int, frames: int, runs: int, seed: int, with_ray: bool, log) -> str:
    """Run the benchmark; return its markdown."""
    robot = example_robot('panda')
    spec = RobotSpec.load(robot.urdf, srdf=robot.srdf, package_paths=robot.package_paths,
                          label='panda')
    checker = spec.build()
    options = CheckOptions()
    cores = batch.default_jobs()
    lines = ['## Checking many recordings (python -m benchmarks audit)', '']
    with tempfile.TemporaryDirectory(prefix='collision_sensor_audit_bench_') as directory:
        log(f'writing {recordings} recordings of {frames} Panda frames ...')
        write_recordings(directory, checker, recordings, frames, seed)
        units = find_units([directory])
        others = quiet_sample(3.0, cores)
        load_before = os.getloadavg()
        modes = {'jobs 1': lambda: batch.SerialRunner(spec, options),
                 'jobs 2': lambda: LocalPool(spec, options, 2)}
        ray = None
        if with_ray:
            from collision_sensor.tools.audit.ray_pool import RayPool, require_ray
            ray = require_ray()
            log('starting a local Ray cluster of 2 CPUs (not timed) ...')
            # A cluster of its own, even where a `ray start` one runs (which a plain
            # ray.init would join, refusing num_cpus).
            ray.init(address='local', num_cpus=2, include_dashboard=False,
                     log_to_driver=False, configure_logging=False)
            modes['ray 2 CPUs'] = lambda: RayPool(spec, options, 'auto')
        names = list(modes)
        walls: Dict[str, List[float]] = {name: [] for name in names}
        steady: Dict[str, List[float]] = {name: [] for name in names}
        busy: Dict[str, List[float]] = {name: [] for name in names}
        rss: Dict[str, List[float]] = {name: [] for name in names}
        reference, same = None, True
        try:
            for round_index in range(runs):
                order = names[round_index % len(names):] + names[:round_index % len(names)]
                for name in order:
                    log(f'run {round_index + 1}/{runs}: {name} ...')
                    before = busy_cores()
                    result = batch.run_batch(units, spec, options, modes[name](),
                                             progress='never')
                    cores_busy = cores_busy_between(before, busy_cores(), cores)
                    walls[name].append(result.seconds)
                    rest = sum(r['frames'] for r in result.new) - result.new[0]['frames']
                    steady[name].append(rest / max(result.seconds - result.first_seconds,
                                                   1e-9))
                    busy[name].append(cores_busy if cores_busy is not None else float('nan'))
                    rss[name].append(max(v[1] - v[0] for v in result.stats.rss.values())
                                     / 2 ** 20)
                    if reference is None:
                        reference = result.records
                    same = same and result.records == reference
        finally:
            if ray is not None:
                ray.shutdown()
        load_after = os.getloadavg()

        Q = np.loadtxt(units[0].path, delimiter=',', skiprows=1)[:, 1:]
        batch_rates = {}
        for label, call in (('check_batch', checker.check_batch),
                            ('update_batch', checker.update_batch)):
            best = min(_timed(call, Q) for _ in range(5))
            batch_rates[label] = len(Q) / best
        read = min(_timed(read_sequence, units[0].path) for _ in range(5))
    total = sum(r['frames'] for r in reference)
    in_collision = sum(1 for r in reference if r['frames_in_collision'])
    ratio2 = [a / b for a, b in zip(walls['jobs 1'], walls['jobs 2'])]
    lines += [
        f'{recordings} CSV recordings of {frames} Panda frames ({total:,} frames; '
        f'{in_collision} recordings touch themselves), {runs} runs, incremental check (the '
        f'default). Machine: {cores} '
        + (f'cores; before the runs {others:.2f} cores were busy with others\' work (3 s '
           'sample) and ' if others is not None else 'cores; before the runs ')
        + f'the load average was {load_before[0]:.2f}; after, {load_after[0]:.2f}.', '',
        '| run | wall s (min / median / max) | frames/s (median) | frames/s per core | '
        'steady frames/s after the first line (median) | cores busy during the run '
        '(median) | RSS growth of a worker (jobs 1: this process, holding the lines), MiB '
        '(max) |',
        '|---|---|---|---|---|---|---|']
    for name in names:
        per_core = 1 if name == 'jobs 1' else 2
        rate = total / statistics.median(walls[name])
        lines.append(f'| {name} | {spread(walls[name])} | {rate:,.0f} | {rate / per_core:,.0f} '
                     f'| {statistics.median(steady[name]):,.0f} | '
                     f'{statistics.median(busy[name]):.2f} | {max(rss[name]):.1f} |')
    lines += ['', f'One call on one recording\'s {len(Q)} frames, this process: check_batch '
              f'{batch_rates["check_batch"]:,.0f} frames/s, update_batch '
              f'{batch_rates["update_batch"]:,.0f} frames/s; reading the CSV file '
              f'{read * 1e3:.1f} ms ({len(Q) / read:,.0f} frames/s). Every run gave the same '
              f'report lines: {"yes" if same else "NO"}.', '',
              '| target | measured (min / median / max over rounds) | verdict |', '|---|---|---|',
              f'| --jobs 2 >= {JOBS2_TARGET}x --jobs 1 | {spread(ratio2)}x | '
              f'**{"PASS" if statistics.median(ratio2) >= JOBS2_TARGET else "MISS"}** |']
    if with_ray:
        ratio_ray = [a / b for a, b in zip(walls['jobs 2'], walls['ray 2 CPUs'])]
        lines.append(f'| Ray (2 CPUs) >= {RAY_TARGET}x the throughput of --jobs 2 | '
                     f'{spread(ratio_ray)}x | '
                     f'**{"PASS" if statistics.median(ratio_ray) >= RAY_TARGET else "MISS"}** |')
    return '\n'.join(lines) + '\n'


def _timed(call, *args) -> float:
    start = time.perf_counter()
    call(*args)
    return time.perf_counter() - start
