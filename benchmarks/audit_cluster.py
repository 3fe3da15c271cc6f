"""``python -m benchmarks audit cluster``: the audit on a simulated multi-node Ray cluster.

``python -m benchmarks audit cluster [--runs 3] [--units 2000] [--kills 10]
[--markdown FILE]``

A ``ray.cluster_utils.Cluster`` on this machine: a head without CPUs (the driver's node) and two
one-CPU worker nodes, started once (not timed). Three parts:

1. **Throughput**: ``--units`` Panda units of 1,000 frames (CSV files, a random walk; each file
   named by several units) checked by ``--jobs 2`` and by the cluster, files read in place (the
   nodes see them, as on a shared file system) and shipped (every file fetched from the
   driver's machine), in a rotating order each round. Steady throughput is the frames over the
   time after the workers are up; the start-up (the nodes' hosts started, the model built) is
   reported beside it.
2. **The driver's CPU per unit** (the driver process's CPU time after its first line, over the
   units after it) for units of 1,000 and 100,000 frames, each a CSV file of its own or a
   LeRobot v3.0 episode (many to a large parquet file), read in place and shipped; with the
   workers' seconds per unit and the cost of one ``ray.wait`` over many calls, the largest
   cluster one driver feeds is projected (its arithmetic printed).
3. **A node lost**: ``--kills`` runs, each with a third one-CPU node that joins and is killed
   (its raylet) at a random moment of the run; every run's lines against a serial run's: lost,
   wrong and charged units.

Targets (issue 46): steady throughput on the cluster within 20 % of ``--jobs 2``'s; driver CPU
per unit at most 0.2 ms for calls of small units; the projection at least 1,000 workers fed for
100,000-frame units; 0 lost, 0 wrong, 0 charged units over the runs with a node killed.
"""
import argparse
import os
import random
import statistics
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional, Sequence

import numpy as np

from benchmarks.audit import busy_cores, cores_busy_between, quiet_sample, spread, \
    write_recordings
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.model.example_robots import example_robot
from collision_sensor.tools.audit import batch
from collision_sensor.tools.audit.local_pool import LocalPool
from collision_sensor.tools.audit.scheduling import DEPTH
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec
from collision_sensor.tools.audit.units import Unit, find_units

THROUGHPUT_TARGET = 0.8
DRIVER_TARGET_MS = 0.2
WORKERS_TARGET = 1000
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def lerobot_writer():
    """The test suite's LeRobot writer (``test/lerobot_writer.py``: datasets as LeRobot writes
    them), imported from the source tree."""
    sys.path.insert(0, os.path.join(REPO, 'test'))
    try:
        import lerobot_writer as writer
    finally:
        sys.path.pop(0)
    return writer


def walks(checker, count: int, frames: int, seed: int) -> List[np.ndarray]:
    """``count`` random walks of ``frames`` states (float32), as write_recordings draws them."""
    rng = np.random.default_rng(seed)
    lower, upper = sampling_bounds(checker)
    starts = random_configurations(checker, count, seed)
    out = []
    for k in range(count):
        steps = rng.normal(0.0, 0.01, (frames, len(lower)))
        steps[0] = 0.0
        out.append(np.clip(starts[k] + np.cumsum(steps, axis=0), lower, upper)
                   .astype(np.float32))
    return out


def start_cluster(log, nodes: int = 2):
    """A head without CPUs and ``nodes`` one-CPU nodes, joined by this process."""
    import ray
    from ray.cluster_utils import Cluster
    log(f'starting a cluster: a head without CPUs and {nodes} one-CPU nodes (not timed) ...')
    here = os.getcwd()
    os.chdir(tempfile.mkdtemp(prefix='collision_sensor_raylets_'))
    try:
        cluster = Cluster(initialize_head=True, head_node_args={'num_cpus': 0})
        for _ in range(nodes):
            cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        ray.init(address=cluster.address, log_to_driver=False, configure_logging=False)
    finally:
        os.chdir(here)
    return cluster


def throughput(spec, options, units, runs: int, log) -> dict:
    """Part 1: wall, start-up and steady frames/s of each mode, by round."""
    from collision_sensor.tools.audit.ray_pool import RayPool
    modes = {'jobs 2': lambda: LocalPool(spec, options, 2),
             'cluster, read in place': lambda: RayPool(spec, options, 'auto'),
             'cluster, shipped': lambda: RayPool(spec, options, 'auto', ship=True)}
    names = list(modes)
    out = {name: {'wall': [], 'start': [], 'steady': [], 'busy': []} for name in names}
    reference, same = None, True
    for round_index in range(runs):
        for name in names[round_index % 3:] + names[:round_index % 3]:
            log(f'throughput {round_index + 1}/{runs}: {name} ...')
            before = busy_cores()
            result = batch.run_batch(units, spec, options, modes[name](), progress='never')
            busy = cores_busy_between(before, busy_cores(), os.cpu_count() or 1)
            frames = sum(r['frames'] for r in result.new)
            up = result.stats.start_seconds
            row = out[name]
            row['wall'].append(result.seconds)
            row['start'].append(up)
            row['steady'].append(frames / max(result.seconds - up, 1e-9))
            row['busy'].append(busy if busy is not None else float('nan'))
            reference = reference or result.records
            same = same and result.records == reference
    out['same'] = same
    out['frames'] = sum(r['frames'] for r in reference)
    return out


#: (frames, files, units) of the driver-cost workloads: small units and long ones.
WORKLOADS = ((1000, 600, 600), (100_000, 10, 40))
QUICK_WORKLOADS = ((1000, 20, 60), (10_000, 4, 8))


def driver_cost(spec, options, checker, directory: str, runs: int, log,
                workloads_sizes=WORKLOADS) -> dict:
    """Part 2: each workload's runs (the driver's CPU after its first line, that window's
    seconds, calls and units, and a worker's seconds per unit), and the fit of the driver's
    CPU to ``r T + c_call calls + c_unit units`` (:func:`fit`), the small CSV units also sent
    one to a call so that calls and units part."""
    from collision_sensor.tools.audit.ray_pool import CALL_UNITS, RayPool
    writer = lerobot_writer()
    workloads = []
    for frames, files, count in workloads_sizes:
        folder = os.path.join(directory, f'csv_{frames}')
        os.makedirs(folder)
        log(f'writing {files} CSV recordings of {frames:,} frames ...')
        write_recordings(folder, checker, files, frames, seed=frames)
        base = find_units([folder])
        workloads.append((frames, 'CSV', 'a CSV file each',
                          [Unit(f'{base[k % files].source}?{k}', 'csv', base[k % files].path)
                           for k in range(count)]))
        dataset = os.path.join(directory, f'lerobot_{frames}')
        per_file = max(files // 4, 1)
        log(f'writing a LeRobot v3.0 dataset of {files} episodes of {frames:,} frames ...')
        writer.write_v30(dataset, checker.joint_names, walks(checker, files, frames, frames + 1),
                         fps=100, per_file=per_file)
        base = find_units([dataset])
        workloads.append((frames, 'LeRobot', f'LeRobot v3.0 episodes, {per_file} to a file',
                          [Unit(f'{base[k % files].source}?{k}', 'lerobot', base[k % files].path,
                                base[k % files].episode) for k in range(count)]))

    def measure(units, shipped: bool, call_units: int = CALL_UNITS) -> dict:
        result = batch.run_batch(units, spec, options,
                                 RayPool(spec, options, 'auto', ship=shipped,
                                         call_units=call_units), progress='never')
        workers = max(result.stats.workers, 1)
        return {'cpu': result.stats.steady_cpu, 'seconds': result.seconds - result.first_seconds,
                'calls': result.stats.calls - 1, 'units': len(result.new) - 1,
                'per_call': len(units) / result.stats.calls,
                'unit_s': (result.seconds - result.stats.start_seconds) * workers / len(units)}

    samples = []         # (group, measurement)
    rows = []
    for k in range(runs):
        log(f'driver cost {k + 1}/{runs}: small CSV units, one to a call ...')
        samples.append((('CSV', False), measure(workloads[0][3], False, call_units=1)))
    for frames, kind, label, units in workloads:
        paths = {os.path.join(u.episode.root, u.episode.data_file) if u.kind == 'lerobot'
                 else u.path for u in units}
        size = sum(os.path.getsize(path) for path in paths) / len(paths)
        for shipped in (False, True):
            measured = []
            for k in range(runs):
                log(f'driver cost {k + 1}/{runs}: {frames:,} frames, {label}, '
                    f'{"shipped" if shipped else "read in place"} ...')
                measured.append(measure(units, shipped))
                samples.append(((kind, shipped), measured[-1]))
            rows.append({'frames': frames, 'kind': kind, 'label': label, 'shipped': shipped,
                         'bytes': size, 'weight': units[0].episode.length * 64
                         if units[0].kind == 'lerobot' else size, 'measured': measured})
    return {'rows': rows, 'fit': fit(samples)}


def fit(samples) -> dict:
    """Least squares of the driver's CPU in each sample's window to ``r * seconds + c_call *
    calls + c_unit[group] * units``: ``r`` its CPU per second whatever it does (Ray's threads,
    its look at the cluster every few seconds), ``c_call`` per call, ``c_unit`` per unit of
    each group (file kind, shipped or not). Negative estimates (noise) are taken as 0."""
    groups = sorted({group for group, _ in samples})
    matrix = np.array([[m['seconds'], m['calls']] + [m['units'] if g == group else 0
                                                     for g in groups] for group, m in samples])
    cpu = np.array([m['cpu'] for _, m in samples])
    solution = np.linalg.lstsq(matrix, cpu, rcond=None)[0]
    residual = cpu - matrix @ solution
    return {'r': max(solution[0], 0.0), 'c_call': max(solution[1], 0.0),
            'c_unit': {g: max(v, 0.0) for g, v in zip(groups, solution[2:])},
            'rms_ms': 1e3 * float(np.sqrt(np.mean(residual ** 2)))}


def holding(count: int):
    """Return an actor whose calls wait until released, and ``count`` of its calls
    outstanding (the class is made here: Ray's workers cannot import this module, so it
    travels by value)."""
    import ray

    class Hold:
        def __init__(self):
            self.go = threading.Event()

        def wait(self):
            self.go.wait(120)

        def release(self):
            self.go.set()

    holder = ray.remote(Hold).options(num_cpus=0, max_concurrency=count + 2).remote()
    return holder, [holder.wait.remote() for _ in range(count)]


def release(holder, refs) -> None:
    import ray
    ray.get(holder.release.remote())
    ray.get(refs)
    ray.kill(holder)


def wait_cost(log, calls: Sequence[int] = (100, 1000, 4000)) -> Dict[int, float]:
    """Seconds of this process's CPU for one ``ray.wait`` over ``n`` outstanding calls (none
    ready), for each ``n`` of ``calls``: the driver's cost per wake-up that grows with the
    cluster (DEPTH calls per worker)."""
    import ray
    holder, refs = holding(max(calls))
    out = {}
    for n in calls:
        log(f'ray.wait over {n} outstanding calls ...')
        ray.wait(refs[:n], num_returns=1, timeout=0)
        start = time.process_time()
        for _ in range(20):
            ray.wait(refs[:n], num_returns=1, timeout=0)
        out[n] = (time.process_time() - start) / 20
    release(holder, refs)
    return out


def node_losses(cluster, spec, options, units, serial, kills: int, seed: int, log) -> dict:
    """Part 3: runs with a third node killed at a random moment; lost, wrong, charged units."""
    from collision_sensor.tools.audit.ray_pool import RayPool
    rng = random.Random(seed)
    outcome = {'lost': 0, 'wrong': 0, 'charged': 0, 'rerun': [], 'lost_nodes': 0, 'during': 0,
               'at': [],
               'seconds': []}
    expected = {record['source']: record for record in serial}
    node = cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    log('node loss: a run on three nodes, none killed, for its start-up and duration ...')
    baseline = batch.run_batch(units, spec, options, RayPool(spec, options, 'auto'),
                               progress='never')
    steady = baseline.seconds - baseline.stats.start_seconds
    for k in range(kills):
        if k:
            node = cluster.add_node(num_cpus=1)
            cluster.wait_for_nodes()
        # A random moment while every node holds units: from the first call of the third
        # node's workers on (the three hosts start in their own time), before the tail.
        delay = rng.uniform(0.0, 0.5) * steady
        log(f'node loss {k + 1}/{kills}: killing the third node {delay:.1f} s after all three '
            'hold units ...')
        workers, timers = set(), []
        start = time.perf_counter()

        def arm(index, attempt, pid, n=node, delay=delay):
            workers.add(pid)
            if len(workers) == 3 and not timers:
                timers.append((time.perf_counter() - start + delay, threading.Timer(
                    delay, lambda: cluster.remove_node(n, allow_graceful=False))))
                timers[0][1].start()

        result = batch.run_batch(units, spec, options, RayPool(spec, options, 'auto'),
                                 progress='never', on_start=arm)
        seconds = time.perf_counter() - start
        if timers:
            when = timers[0][0]
            timers[0][1].join()
        else:
            when = float('nan')
            cluster.remove_node(node, allow_graceful=False)
        got = {}
        for record in result.new:
            got.setdefault(record['source'], []).append(record)
        outcome['lost'] += sum(1 for source in expected if source not in got)
        outcome['wrong'] += sum(1 for source, records in got.items()
                                if len(records) != 1 or records[0] != expected.get(source))
        outcome['charged'] += result.stats.retried + sum(
            1 for record in result.new if record['error'] is not None
            and expected[record['source']]['error'] is None)
        outcome['rerun'].append(result.stats.rerun)
        outcome['lost_nodes'] += result.stats.lost_nodes
        outcome['at'].append(when)
        outcome['seconds'].append(seconds)
        outcome['during'] += when < seconds      # the node killed while the run went on
    return outcome


def projection(c_unit: float, c_call: float, k: float, unit_s: float, b: float,
               r: float) -> float:
    """The most workers one driver core feeds: W workers each finishing a unit every
    ``unit_s`` seconds cost it ``W / unit_s * c(W)`` of a core beside ``r``, a unit ``c(W) =
    c_unit + (c_call + b * DEPTH * W) / k`` (k units a call, b per call outstanding scanned
    once per answer); W solves ``W * c(W) = unit_s * (1 - r)``."""
    linear = c_unit + c_call / k
    quadratic = b * DEPTH / k
    budget = unit_s * (1.0 - r)
    if quadratic <= 0:
        return budget / linear
    return (-linear + (linear * linear + 4 * quadratic * budget) ** 0.5) / (2 * quadratic)


def units_per_call(weight: float) -> int:
    """Units of ``weight`` bytes a call takes at scale (take_call's limits for Ray)."""
    from collision_sensor.tools.audit.ray_pool import CALL_BYTES, CALL_UNITS
    return max(1, min(CALL_UNITS, int(CALL_BYTES // max(weight, 1))))


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m benchmarks audit cluster',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--units', type=int, default=2000)
    parser.add_argument('--kills', type=int, default=10)
    parser.add_argument('--seed', type=int, default=46)
    parser.add_argument('--quick', action='store_true',
                        help='small workloads, one node loss (a smoke run: figures say little)')
    parser.add_argument('--markdown', metavar='FILE', help='also write the tables here')
    args = parser.parse_args(argv)
    if args.quick:
        args.units, args.kills = min(args.units, 300), min(args.kills, 1)
    text = run(args.runs, args.units, args.kills, args.seed, args.quick,
               log=lambda m: print(f'[python -m benchmarks audit cluster] {m}',
                                   file=sys.stderr, flush=True))
    print(text)
    if args.markdown:
        with open(args.markdown, 'w', encoding='utf-8') as stream:
            stream.write(text)
    return 0


def run(runs: int, count: int, kills: int, seed: int, quick: bool, log) -> str:
    import ray
    robot = example_robot('panda')
    spec = RobotSpec.load(robot.urdf, srdf=robot.srdf, package_paths=robot.package_paths,
                          label='panda')
    checker = spec.build()
    options = CheckOptions()
    cores = os.cpu_count() or 1
    others = quiet_sample(3.0, cores)
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix='collision_sensor_cluster_bench_') as directory:
        files = os.path.join(directory, 'files')
        os.makedirs(files)
        log(f'writing {min(count, 200)} recordings of 1,000 Panda frames ...')
        write_recordings(files, checker, min(count, 200), 1000, seed)
        base = find_units([files])
        units = [Unit(f'{base[k % len(base)].path}?{k}', 'csv', base[k % len(base)].path)
                 for k in range(count)]
        cluster = start_cluster(log)
        try:
            flow = throughput(spec, options, units, runs, log)
            costs = driver_cost(spec, options, checker, directory, runs, log,
                                QUICK_WORKLOADS if quick else WORKLOADS)
            wait = wait_cost(log)
            lost_units = units[:max(count * 3 // 4, 300)]
            serial = batch.run_batch(lost_units, spec, options,
                                     batch.SerialRunner(spec, options), progress='never').records
            losses = node_losses(cluster, spec, options, lost_units, serial, kills, seed, log)
        finally:
            ray.shutdown()
            cluster.shutdown()
    load_after = os.getloadavg()
    return report(flow, costs, wait, losses, runs, count, kills, cores, others, load_before,
                  load_after)


def report(flow, costs, wait, losses, runs, count, kills, cores, others, load_before,
           load_after) -> str:
    lines = ['## The audit on a simulated cluster (python -m benchmarks audit cluster)', '',
             'A head without CPUs (the driver\'s node) and two one-CPU worker nodes on this '
             f'machine ({cores} cores'
             + (f'; {others:.2f} cores busy with others\' work before the runs'
                if others is not None else '')
             + f'; load average {load_before[0]:.2f} before, {load_after[0]:.2f} after).', '',
             f'### Throughput: {count:,} Panda units of 1,000 frames ({flow["frames"]:,} '
             f'frames), {runs} rounds in a rotating order', '',
             '| run | wall s | start-up s (workers up) | steady frames/s after the start-up | '
             'cores busy (median) |', '|---|---|---|---|---|']
    for name in ('jobs 2', 'cluster, read in place', 'cluster, shipped'):
        row = flow[name]
        lines.append(f'| {name} | {spread(row["wall"])} | {spread(row["start"])} | '
                     f'{spread(row["steady"], "{:,.0f}")} | '
                     f'{statistics.median(row["busy"]):.2f} |')
    ratios = {name: [a / b for a, b in zip(flow[name]['steady'], flow['jobs 2']['steady'])]
              for name in ('cluster, read in place', 'cluster, shipped')}
    lines += ['', f'Every run gave the same report lines: {"yes" if flow["same"] else "NO"}. '
              'Steady throughput over --jobs 2\'s in the same round: read in place '
              f'{spread(ratios["cluster, read in place"])}x; shipped '
              f'{spread(ratios["cluster, shipped"])}x (every file fetched from the driver\'s '
              'machine through the object store, on the same two cores as the checking).']
    ns = sorted(wait)
    b = (wait[ns[-1]] - wait[ns[0]]) / (ns[-1] - ns[0])
    model = costs['fit']
    lines += ['', '### The driver\'s CPU per unit', '',
              'Each workload run three times on the cluster; the driver\'s CPU time from its '
              'first line to its last, over the units after the first (nothing taken out).', '',
              '| units | files | MiB a file | driver CPU ms per unit (units a call) | worker s '
              'per unit | units a call at scale | workers one driver core feeds |',
              '|---|---|---|---|---|---|---|']
    projections = {}
    for row in costs['rows']:
        measured = row['measured']
        per_unit = [1e3 * m['cpu'] / max(m['units'], 1) for m in measured]
        k = statistics.median(m['per_call'] for m in measured)
        unit_s = statistics.median(m['unit_s'] for m in measured)
        at_scale = units_per_call(row['weight'])
        workers = projection(model['c_unit'][(row['kind'], row['shipped'])], model['c_call'],
                             at_scale, unit_s, b, model['r'])
        projections[(row['frames'], row['kind'], row['shipped'])] = workers
        row['per_unit'] = per_unit
        lines.append(f'| {row["frames"]:,} frames, {row["label"]} | '
                     f'{"shipped" if row["shipped"] else "in place"} | '
                     f'{row["bytes"] / 2 ** 20:.2f} | {spread(per_unit, "{:.3f}")} '
                     f'({k:.0f}) | {spread([m["unit_s"] for m in measured], "{:.4f}")} | '
                     f'{at_scale} | {workers:,.0f} |')
    units_text = ', '.join(f'{kind} {"shipped" if shipped else "in place"} '
                           f'{1e3 * value:.3f} ms' for (kind, shipped), value
                           in sorted(model['c_unit'].items()))
    lines += ['', 'The projection. The driver\'s CPU over every run above (and the small CSV '
              'units sent one to a call, so that calls and units part) fits r x T + c_call x '
              f'calls + c_unit x units: r = {model["r"]:.4f} of a core whatever it does (Ray\'s '
              f'threads, its look at the cluster every few seconds), c_call = '
              f'{1e3 * model["c_call"]:.3f} ms a call (Ray\'s submission, wait and answer), '
              f'c_unit = {units_text} (rms of the fit {model["rms_ms"]:.1f} ms a run). One '
              '`ray.wait` over n outstanding calls costs '
              + ', '.join(f'{wait[n] * 1e3:.2f} ms (n = {n:,})' for n in ns)
              + f': b = {b * 1e6:.2f} us per call outstanding, scanned once per answer (the '
              'worst case: one answer a wake-up). W workers, each finishing a unit every t s '
              '(the worker s per unit), cost the driver W / t x c(W) of a core beside r, where '
              f'c(W) = c_unit + (c_call + b x {DEPTH} x W) / k with k the units a call at scale '
              f'(the call limits: 128 units, 128 MiB); one core is saturated at W = '
              f'(-(c_unit + c_call/k) + sqrt((c_unit + c_call/k)^2 + 4 (b x {DEPTH} / k) t (1 - '
              f'r))) / (2 b x {DEPTH} / k). It assumes r does not grow with the nodes (Ray\'s '
              'own per-node costs are the raylets\', not the driver\'s) and the wait scan is '
              'the only cost that grows with W.']
    loss_ok = losses['lost'] == losses['wrong'] == losses['charged'] == 0
    small = [statistics.median(row['per_unit']) for row in costs['rows']
             if row['frames'] == 1000]
    large = [workers for (frames, _, _), workers in projections.items() if frames != 1000]
    lines += ['', f'### A node lost, {kills} runs', '',
              f'Each run: {max(count * 3 // 4, 300)} units, a third one-CPU node joined and '
              f'killed (its raylet) at {", ".join(f"{t:.1f}" for t in losses["at"])} s; runs took '
              f'{spread(losses["seconds"])} s. The node was killed while the run went on in '
              f'{losses["during"]} of {kills} runs; the run noticed the loss in '
              f'{losses["lost_nodes"]} (in any other, the node had handed back all it held '
              'before Ray told of its death) and checked again '
              f'{spread(losses["rerun"], "{:.0f}")} units. Lost units: {losses["lost"]}, wrong: '
              f'{losses["wrong"]}, charged: {losses["charged"]}.', '',
              '| target | measured (min / median / max) | verdict |', '|---|---|---|']
    ratio = ratios['cluster, read in place']
    lines.append(f'| the cluster (its nodes see the files): steady >= {THROUGHPUT_TARGET}x '
                 f'--jobs 2\'s | {spread(ratio)}x | '
                 f'**{"PASS" if statistics.median(ratio) >= THROUGHPUT_TARGET else "MISS"}** |')
    lines.append(f'| driver CPU <= {DRIVER_TARGET_MS} ms per small unit | '
                 f'{spread(small, "{:.3f}")} ms | '
                 f'**{"PASS" if max(small) <= DRIVER_TARGET_MS else "MISS"}** |')
    lines.append(f'| >= {WORKERS_TARGET:,} workers fed, units of {costs["rows"][-1]["frames"]:,} '
                 'frames | '
                 f'{min(large):,.0f} to {max(large):,.0f} | '
                 f'**{"PASS" if min(large) >= WORKERS_TARGET else "MISS"}** |')
    lines.append(f'| 0 lost, 0 wrong, 0 charged over {kills} node losses | {losses["lost"]} / '
                 f'{losses["wrong"]} / {losses["charged"]} | '
                 f'**{"PASS" if loss_ok and losses["during"] == kills else "MISS"}** |')
    return '\n'.join(lines) + '\n'
