"""Check many units: in this process, in local workers (``--jobs``) or on Ray (``--ray``).

:func:`run_batch` skips the units a resumed report holds, runs the rest, writes each line as it
comes (:mod:`~collision_sensor.tools.audit.report`), draws a tqdm bar of units (frames as its
note), then prints the summary across the whole report and draws the plot. The exit status:
0 every unit checked and none in collision, 1 some in collision, 3 some unit failed (its
``error`` says why; the others were checked).
"""
import os
import sys
import time
from dataclasses import dataclass
from typing import Callable, List, Optional

from collision_sensor.engine.checker_config import usable_cores
from collision_sensor.tools.audit import report
from collision_sensor.tools.audit.local_pool import LocalPool
from collision_sensor.tools.audit.scheduling import PoolStats
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker, \
    checks_for, rss_bytes
from collision_sensor.tools.audit.workers import memory
from collision_sensor.tools.audit.units import Unit
from collision_sensor.tools.progress import ProgressBar
from collision_sensor.tools.recorded_clouds import cloud_summary_lines

EXIT_CLEAR, EXIT_COLLISION, EXIT_FAILED = 0, 1, 3


def default_jobs() -> int:
    """All the cores this process may use."""
    return usable_cores()


@dataclass
class BatchResult:
    """What :func:`run_batch` did: every line of the report (resumed ones first), this run's
    new ones, the workers' figures and the wall time of the checking."""

    records: List[dict]
    new: List[dict]
    stats: PoolStats
    seconds: float
    #: seconds from the start to the first new line (the workers' start-up and one unit).
    first_seconds: float = 0.0

    @property
    def status(self) -> int:
        if any(r['error'] is not None for r in self.records):
            return EXIT_FAILED
        return EXIT_COLLISION if any(in_collision(r) for r in self.records) else EXIT_CLEAR


def in_collision(record: dict) -> bool:
    """True iff a unit's line has a frame in collision, or (``--motion``) a motion between
    frames that meets contact."""
    return bool(record['frames_in_collision']) or bool(
        record.get('motion') and record['motion']['segments_in_contact'])


class SerialRunner:
    """``--jobs 1``: every unit in this process, with one checker.

    :param checker: the checker to use (None: built here).
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions,
                 checker: Optional[UnitChecker] = None):
        self.checker = checker if checker is not None else UnitChecker(spec, options)

    def run(self, units, on_record, on_start=None) -> PoolStats:
        stats = PoolStats(workers=1)
        stats.note_rss('driver', rss_bytes())
        for index, unit in enumerate(units):
            if on_start is not None:
                on_start(index, 1, os.getpid())
            on_record(index, self.checker.check(unit))
            stats.note_rss('driver', rss_bytes())
        stats.note_private('driver', memory()[1])
        return stats


def make_runner(spec: RobotSpec, options: CheckOptions, jobs: Optional[int],
                ray_address: Optional[str], checker=None):
    """Return the runner for ``--jobs`` / ``--ray``.

    :param checker: a checker of ``spec`` built with UNIT_THREADS threads, which this process
        and the workers it forks then use (None: one is built).
    """
    if ray_address:
        from collision_sensor.tools.audit.ray_pool import RayPool
        return RayPool(spec, options, ray_address, jobs)
    jobs = jobs or default_jobs()
    shared = UnitChecker(spec, options, checker) if checker is not None else None
    return SerialRunner(spec, options, shared) if jobs == 1 else \
        LocalPool(spec, options, jobs, shared)


def run_batch(units: List[Unit], spec: RobotSpec, options: CheckOptions, runner,
              report_path: Optional[str] = None, resume: bool = False,
              progress: str = 'auto',
              on_start: Optional[Callable[[int, int, int], None]] = None) -> BatchResult:
    """Check ``units`` with ``runner`` (:func:`make_runner`), writing the report.

    :raises CollisionSensorError: a report that cannot be resumed or written.
    """
    digest = spec.digest(options)
    done = report.read_report(report_path, digest) if (report_path and resume) else []
    known = {record['source'] for record in done}
    todo = [unit for unit in units if unit.source not in known]
    writer = report.ReportWriter(report_path, resume)
    new: List[dict] = []
    frames = [0]
    first = [0.0]
    start = time.perf_counter()
    # The bar (and tqdm's monitor thread) starts with the first line, after the local pool
    # has forked its workers: a forked child gets no copy of a thread's locks then.
    bar: List[ProgressBar] = []

    def on_record(index: int, record: dict) -> None:
        record['settings'] = digest
        if not new:
            first[0] = time.perf_counter() - start
            first_cpu[0] = time.process_time()
            bar.append(ProgressBar(len(todo), label='units', mode=progress))
        writer.write(record)
        new.append(record)
        frames[0] += record['frames'] or 0
        elapsed = time.perf_counter() - start
        bar[0].update(len(new), note=f'{frames[0]:,} frames, {frames[0] / elapsed:,.0f} '
                      'frames/s')

    cpu = time.process_time()
    first_cpu = [cpu]
    try:
        stats = runner.run(todo, on_record, on_start) if todo else PoolStats()
    finally:
        writer.close()
        if bar:
            bar[0].close()
    seconds = time.perf_counter() - start
    if not isinstance(runner, SerialRunner):   # feeding the workers, writing the report
        stats.driver_cpu = time.process_time() - cpu
        stats.steady_cpu = time.process_time() - first_cpu[0]
    order = {unit.source: k for k, unit in enumerate(units)}
    new.sort(key=lambda record: order.get(record['source'], len(order)))
    return BatchResult(done + new, new, stats, seconds, first[0])


def run_lines(stats: PoolStats, units: int) -> List[str]:
    """Return the summary's lines on how the run went: the cluster, faults, memory, the
    driver's CPU."""
    lines = []
    if stats.nodes > 1 or stats.lost_nodes:
        lines.append(f'cluster:   {stats.nodes} nodes, {stats.workers} workers; the first ready '
                     f'{stats.start_seconds:.1f} s after the start')
    if stats.retried or stats.deaths:
        lines.append(f'workers:   {stats.deaths} died; {stats.retried} units tried again (the '
                     'one each was checking)')
    if stats.lost_nodes:
        lines.append(f'nodes:     {stats.lost_nodes} lost; {stats.rerun} units they held '
                     'checked again on the others (none charged)')
    if stats.rss:
        last = max(v[1] for v in stats.rss.values()) / 2 ** 20
        own = max((v[1] for v in stats.private.values()), default=0) / 2 ** 20
        if stats.workers > 1 and own:
            lines.append(f'memory:    {last:.0f} MiB resident per worker, {own:.1f} MiB of it '
                         'its own (largest worker; the model is shared)')
        else:
            lines.append(f'memory:    {last:.0f} MiB resident (largest worker)')
    if stats.driver_cpu and units:
        lines.append(f'driver:    {1e3 * stats.driver_cpu / units:.2f} ms of CPU per unit')
    return lines


def print_summary(result: BatchResult, spec: RobotSpec, checker, options: CheckOptions,
                  runner_label: str, stream=None) -> None:
    """Print the summary table (the whole report) and this run's figures."""
    stream = stream or sys.stdout
    lines = [f'robot:     {spec.label} ({len(checker.joint_names)} joints, '
             f'{len(checker.checked_pairs)} pairs checked; '
             f'{"incremental update" if options.incremental else "full check"})']
    lines += report.summary_lines(result.records)
    checked = [r for r in result.records if r['error'] is None]
    for check in checks_for(options)[1:]:       # the contacts are the table above
        lines += check.summary_lines(checked)
    lines += cloud_summary_lines(checked)
    new_frames = sum(r['frames'] or 0 for r in result.new)
    resumed = len(result.records) - len(result.new)
    run = (f'this run:  {len(result.new)} units, {new_frames:,} frames in '
           f'{result.seconds:.1f} s')
    if result.seconds > 0 and new_frames:
        run += f' ({new_frames / result.seconds:,.0f} frames/s)'
    run += f' on {runner_label}'
    if resumed:
        run += f'; {resumed} units resumed from the report'
    lines += ['', run] + run_lines(result.stats, len(result.new))
    status = result.status
    met = any(in_collision(r) for r in result.records if r['error'] is None)
    verdict = {0: 'clear', 1: 'COLLISION',
               3: 'COLLISION and FAILED UNITS' if met else 'FAILED UNITS'}[status]
    lines.append(f'result: {verdict}')
    print('\n'.join(lines), file=stream)
