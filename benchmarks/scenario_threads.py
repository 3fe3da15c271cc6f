"""Scenario 11: the batches on every core (the ``threads`` setting, ``cpp/workers.hpp``).

The same Panda, built with ``threads`` 1 and 2, runs the same batches, passes interleaved
(1, 2, 1, 2, ...): ``check_batch`` of random configurations (the target: at least
:data:`SPEEDUP_TARGET` times faster on two threads), ``update_batch`` along a random walk,
``check_path`` along a free path of small steps, and short ``check_batch`` calls (what a
thread costs to start). Every pass's ratio (one thread's time / two threads') is printed
with its spread, and with how much of a second core the process got during the two-thread
passes (process CPU time / wall time): on a machine shared with other work the second core
is often busy, which no setting can help. The answers of both are compared (they must be
equal: the run stops if not).

Elsewhere the benchmark runs our checker on one thread against its peers (each runs on one
core): this scenario is the only one that measures the threads.
"""
import os
import time

import numpy as np

from collision_sensor.engine.sampling import random_configurations
from benchmarks.scenario_cells import robot_cell
from benchmarks.scenario_report import Section, load_note, us

TITLE = 'Scenario 11: batches on every core (the threads setting)'
#: ``check_batch`` of the Panda's random rows: one thread's time / two threads' at least this.
SPEEDUP_TARGET = 1.8


def run(settings) -> Section:
    """Measure the batches on one thread and on two; return the section."""
    section = Section(11, TITLE)
    cell = robot_cell('panda')
    checkers = {t: cell.checker({'threads': t}) for t in (1, 2)}
    rows = settings.thread_rows
    rounds = max(3, settings.rounds)
    Q = random_configurations(checkers[1], rows, settings.seed)
    walk = _walk(checkers[1], rows, settings.seed)
    path = _free_path(checkers[1], max(rows // 10, 20), settings.seed)
    short = Q[:16]
    cases = [
        (f'`check_batch`, {rows} random rows', lambda c: c.check_batch(Q), rows),
        (f'`update_batch`, a {rows}-step random walk', lambda c: _update_batch(c, walk), rows),
        (f'`check_path`, {len(path)} waypoints, free', lambda c: c.check_path(path),
         len(path) - 1),
        ('`check_batch`, 16 rows (x 200 calls)',
         lambda c: [c.check_batch(short) for _ in range(200)], 200 * len(short)),
    ]
    load_before = load_note()
    table = []
    verdict_ratios = None
    for label, call, items in cases:
        answers = {t: call(checker) for t, checker in checkers.items()}
        _same(answers[1], answers[2], label)
        times, cores = _passes(checkers, call, rounds)
        ratios = sorted(a / b for a, b in zip(times[1], times[2]))
        if verdict_ratios is None:
            verdict_ratios = ratios
        table.append([label, _spread_us(times[1], items), _spread_us(times[2], items),
                      _spread(ratios, '{:.2f}x'), _spread(sorted(cores), '{:.2f}')])
    section.text(
        f'The Panda (example-robot-data, its SRDF, {len(checkers[1].checked_pairs)} pairs), '
        f'built twice: `threads` 1 and 2 (this machine: {os.cpu_count()} hardware threads; '
        f'the default, 0, takes them all). {rounds} passes of each, interleaved; per item '
        'times (us) and the ratio of each pass pair, min / median / max. "cores" is the '
        'process\'s CPU time over the wall time of the two-thread passes: 2.00 when the second '
        'core was wholly ours. Both checkers gave the same answers on every case.',
        f'Load before: {load_before}; after: {load_note()}.')
    section.table(['batch', '1 thread us / item', '2 threads us / item', '1 / 2 threads',
                   'cores (2 threads)'], table)
    median = verdict_ratios[len(verdict_ratios) // 2]
    section.judge(f'S11 `check_batch` of {rows} Panda rows: >= {SPEEDUP_TARGET}x faster on '
                  '2 threads than on 1 (median of the passes)',
                  f'{_spread(verdict_ratios, "{:.2f}x")} (min / median / max)',
                  median >= SPEEDUP_TARGET)
    section.plot['threads'] = {'ratios': verdict_ratios}
    return section


def _passes(checkers, call, rounds):
    """``({threads: [seconds of each pass]}, [cores of each two-thread pass])``."""
    times = {t: [] for t in checkers}
    cores = []
    for _ in range(rounds):
        for t, checker in checkers.items():
            cpu = time.process_time()
            start = time.perf_counter()
            call(checker)
            wall = time.perf_counter() - start
            times[t].append(wall)
            if t == 2:
                cores.append((time.process_time() - cpu) / wall)
    return times, cores


def _update_batch(checker, walk):
    checker.check(walk[0])
    return checker.update_batch(walk)


def _same(a, b, label):
    if isinstance(a, list):
        same = all(np.array_equal(x, y) for x, y in zip(a, b))
    elif isinstance(a, np.ndarray):
        same = np.array_equal(a, b)
    else:
        same = a == b
    if not same:
        raise AssertionError(f'scenario 11, {label}: two threads answered otherwise than one')


def _walk(checker, n, seed):
    """A random walk of ``n`` rows, steps N(0, 0.02) rad per joint, within the limits."""
    rng = np.random.default_rng([seed, 11])
    lower = np.array([checker.joint_limits[name][0] for name in checker.joint_names])
    upper = np.array([checker.joint_limits[name][1] for name in checker.joint_names])
    q = random_configurations(checker, 1, seed + 11)[0]
    rows = np.empty((n, len(q)))
    for i in range(n):
        q = np.clip(q + rng.normal(scale=0.02, size=q.shape), lower, upper)
        rows[i] = q
    return rows


def _free_path(checker, n, seed):
    """``n`` waypoints of small steps (N(0, 0.01) rad) about a configuration apart from
    everything, every segment free (so every segment is checked)."""
    rng = np.random.default_rng([seed, 12])
    for q in random_configurations(checker, 200, seed + 12):
        if not checker.check(q).in_collision:
            break
    while True:
        path = q + np.cumsum(rng.normal(scale=0.01, size=(n, len(q))), axis=0) * 0.05
        if checker.check_path(path).first_invalid_segment is None:
            return path
        n = max(2, n // 2)


def _spread(values, form):
    ordered = sorted(values)
    return ' / '.join(form.format(v) for v in (ordered[0], ordered[len(ordered) // 2],
                                                ordered[-1]))


def _spread_us(seconds, items):
    ordered = sorted(s / items * 1e6 for s in seconds)
    return ' / '.join(us(v) for v in (ordered[0], ordered[len(ordered) // 2], ordered[-1]))
