"""``--jobs N``: units checked in N worker processes on this machine.

The tool's process builds the checker once and forks the workers from it
(:mod:`~collision_sensor.tools.audit.workers`): the model is held once, whatever N, and a worker
starts in milliseconds. Each takes calls over a pipe of its own, at most
:data:`~collision_sensor.tools.audit.scheduling.DEPTH` at a time; a call is one unit or several
small ones (:mod:`~collision_sensor.tools.audit.scheduling`). Before each unit the worker writes
the unit's index in a shared slot, so when it dies the driver knows which unit it was checking:
only that unit is charged; it is tried once more, alone on a fresh worker (so a second death
takes nothing else with it), and reported with the reason if it kills that one too. The other
units of its calls go back to the queue uncharged (those it had finished too: their lines died
with it). The standard library's pools do not allow this: ``multiprocessing.Pool`` hangs when a
worker dies, and ``concurrent.futures`` fails every pending unit of the pool.
"""
import collections
import multiprocessing.connection
import time
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Optional

from collision_sensor.errors import CollisionSensorError
from collision_sensor.tools.audit.scheduling import DEPTH, PoolStats, call_units, \
    charge_death, take_call, unit_weight
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker
from collision_sensor.tools.audit.units import Unit
from collision_sensor.tools.audit.workers import WorkerProcess, death_reason, fork_context, \
    preload, stop_workers

#: Workers that die before they are ready, in a row, before the run gives up.
MAX_START_FAILURES = 3


@dataclass
class _Worker:
    process: WorkerProcess
    calls: Deque[List[int]] = field(default_factory=collections.deque)
    ready: bool = False
    alone: bool = False     # holds a retried unit: nothing is queued behind it

    @property
    def name(self) -> str:
        return self.process.name


class LocalPool:
    """``jobs`` worker processes checking units (see the module docstring).

    :param checker: the checker the workers share (built here when None); its process is the
        one that forks them.
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions, jobs: int,
                 checker: Optional[UnitChecker] = None):
        self.spec, self.options, self.jobs = spec, options, jobs
        self._context = fork_context()
        self._shared = checker

    def _spawn(self) -> _Worker:
        return _Worker(WorkerProcess(self._context, self._shared, self.spec, self.options))

    def run(self, units: List[Unit], on_record: Callable[[int, dict], None],
            on_start: Optional[Callable[[int, int, int], None]] = None) -> PoolStats:
        """Check ``units``; call ``on_record(index, record)`` as each finishes (in the order
        they finish) and ``on_start(index, attempt, pid)`` as a worker starts one.

        :raises CollisionSensorError: workers keep dying before they are ready.
        """
        start = time.perf_counter()
        if self._shared is None and self._context.get_start_method() == 'fork':
            self._shared = UnitChecker(self.spec, self.options)
        preload(units)
        stats = PoolStats(workers=min(self.jobs, len(units)))
        weights = [unit_weight(unit) for unit in units]
        pending: Deque[int] = collections.deque(range(len(units)))
        deaths: Dict[int, int] = collections.Counter()
        alone = set()
        remaining = len(units)
        start_failures = 0
        workers = [self._spawn() for _ in range(stats.workers)]
        try:
            while remaining:
                for worker in workers:
                    self._fill(worker, units, weights, pending, alone, len(workers))
                waiting = {w.process.conn: w for w in workers}
                waiting.update({w.process.process.sentinel: w for w in workers})
                for ready in multiprocessing.connection.wait(list(waiting)):
                    worker = waiting[ready]
                    if worker not in workers:
                        continue                   # replaced earlier in this round
                    alive = self._drain(worker, on_record, on_start, deaths, stats, start)
                    remaining -= alive[1]
                    if alive[0] and worker.process.process.is_alive():
                        continue
                    if not worker.ready:
                        start_failures += 1
                        if start_failures >= MAX_START_FAILURES:
                            raise CollisionSensorError(
                                f'{MAX_START_FAILURES} workers died before they were ready '
                                f'(last: {death_reason(worker.process.process.exitcode)}); '
                                'run with --jobs 1 to see the error')
                    else:
                        start_failures = 0
                    remaining -= self._bury(worker, units, pending, deaths, alone, stats,
                                            on_record)
                    workers[workers.index(worker)] = self._spawn()
        finally:
            stop_workers(worker.process for worker in workers)
        return stats

    def _fill(self, worker: _Worker, units, weights, pending: Deque[int], alone: set,
              workers: int) -> None:
        """Give a ready ``worker`` calls up to DEPTH; a retried unit only to an idle worker,
        alone."""
        while worker.ready and pending and len(worker.calls) < DEPTH and not worker.alone:
            call = take_call(pending, weights, call_units(len(pending), workers), alone,
                             bool(worker.calls))
            if not call:
                return
            try:
                worker.process.conn.send([(index, units[index], None) for index in call])
            except OSError:               # it died; its sentinel says so next
                pending.extendleft(reversed(call))
                return
            worker.calls.append(call)
            worker.alone = call[0] in alone

    def _drain(self, worker: _Worker, on_record, on_start, deaths, stats: PoolStats,
               start: float) -> tuple:
        """Read every message waiting from ``worker``; return (still connected, units done)."""
        done = 0
        conn = worker.process.conn
        try:
            while conn.poll():
                message = conn.recv()
                if message[0] == 'ready':
                    worker.ready = True
                    if not stats.start_seconds:
                        stats.start_seconds = time.perf_counter() - start
                    stats.note_rss(worker.name, message[2])
                    stats.note_private(worker.name, message[3])
                elif message[0] == 'start':
                    if on_start is not None:
                        on_start(message[1], deaths[message[1]] + 1, worker.process.pid)
                else:
                    worker.calls.popleft()
                    worker.alone = False
                    for index, record, rss in message[1]:
                        stats.note_rss(worker.name, rss)
                        on_record(index, record)
                    stats.note_private(worker.name, message[2])
                    done += len(message[1])
        except (EOFError, OSError):
            return False, done
        return True, done

    def _bury(self, worker: _Worker, units, pending, deaths, alone, stats, on_record) -> int:
        """Handle a dead worker: charge the unit it was checking; requeue the rest. Return 1
        if that unit is now reported failed."""
        process = worker.process
        process.process.join(timeout=5)
        process.conn.close()
        stats.deaths += 1
        queue = [index for call in worker.calls for index in call]
        checking = process.slot.value
        charged = checking in queue
        if charged:             # first, as charge_death takes it
            queue.remove(checking)
            queue.insert(0, checking)
        return charge_death(
            queue, charged, deaths, alone, pending, stats,
            lambda index, error: on_record(index, UnitChecker.failed_record(
                units[index], self.options, error)),
            death_reason(process.process.exitcode))
