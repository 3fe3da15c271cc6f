"""``--jobs N``: units checked in N worker processes on this machine.

Each worker builds its checker once (:class:`~collision_sensor.tools.audit.unit_check.UnitChecker`)
and then takes units over a pipe of its own, at most :data:`DEPTH` at a time (the next one
waits in the pipe while it checks one, so it never idles on the driver). It says when it starts
a unit, so when a worker dies the driver knows which unit it was checking: only that unit is
charged; it is tried once more, alone on a fresh worker (so a second death takes nothing else
with it), and reported with the reason if it kills that one too. Units queued behind it go
back to the queue uncharged. The standard library's pools do not allow this:
``multiprocessing.Pool`` hangs when a worker dies, and ``concurrent.futures`` fails every
pending unit of the pool.

Workers are forked on Linux (they start in milliseconds; the spec is inherited, not pickled)
and spawned elsewhere. They ignore SIGINT: Ctrl-C stops the driver, which stops them.
"""
import collections
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Optional

from collision_sensor.errors import CollisionSensorError
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker, \
    rss_bytes
from collision_sensor.tools.audit.units import Unit

#: Units a worker holds at once: the one it checks and the next.
DEPTH = 2
#: Times a unit is tried again after its worker died.
RETRIES = 1
#: Workers that die before they are ready, in a row, before the run gives up.
MAX_START_FAILURES = 3


def death_reason(exitcode: Optional[int]) -> str:
    """Say how a worker process ended (``exitcode`` as multiprocessing gives it)."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f'signal {-exitcode}'
        return f'killed by {name}'
    return f'exited with status {exitcode}'


def died_error(attempts: int, reason: str) -> str:
    """The ``error`` of a unit whose worker died on every attempt."""
    return (f'the worker checking it died on each of {attempts} attempts (last: {reason}); '
            'the recording may exhaust memory or crash the engine: check it alone '
            '(collision_sensor_check FILE) and report it')


def charge_death(queue: List[int], charged: bool, deaths, alone: set, pending: Deque[int],
                 stats: 'PoolStats', report_failed: Callable[[int, str], None],
                 reason: str) -> int:
    """Settle the units a dead worker held (``queue``, in order): with ``charged`` the first
    one was being checked: it is tried again alone, or reported failed after RETRIES; the
    others go back to the front of ``pending`` uncharged. Return 1 if a unit was reported."""
    reported = 0
    if queue and charged:
        index = queue.pop(0)
        deaths[index] += 1
        if deaths[index] > RETRIES:
            alone.discard(index)
            report_failed(index, died_error(deaths[index], reason))
            reported = 1
        else:
            stats.retried += 1
            alone.add(index)
            queue.insert(0, index)
    pending.extendleft(reversed(queue))
    return reported


@dataclass
class PoolStats:
    """What a run of workers did, for the summary.

    :ivar workers: how many checked at once.
    :ivar rss: ``{worker: [RSS when ready, RSS after its last unit]}`` in bytes.
    :ivar retried: units tried again after their worker died.
    :ivar deaths: workers that died.
    """

    workers: int = 0
    rss: Dict[str, List[int]] = field(default_factory=dict)
    retried: int = 0
    deaths: int = 0
    #: ``{worker: [RSS after each unit]}``, the first TRACE units of each.
    trace: Dict[str, List[int]] = field(default_factory=dict)

    TRACE = 10_000

    def note_rss(self, worker: str, value: int) -> None:
        entry = self.rss.setdefault(worker, [value, value])
        entry[1] = value
        trace = self.trace.setdefault(worker, [])
        if len(trace) < self.TRACE:
            trace.append(value)


def _serve(conn, spec: RobotSpec, options: CheckOptions) -> None:
    """A worker: build the checker, then check what the pipe brings until it brings None."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    checker = UnitChecker(spec, options)
    checker.checker  # build the trees now, before the first unit
    conn.send(('ready', os.getpid(), rss_bytes()))
    while True:
        message = conn.recv()
        if message is None:
            return
        index, unit = message
        conn.send(('start', index))
        conn.send(('done', index, checker.check(unit), rss_bytes()))


@dataclass
class _Worker:
    process: object
    conn: object
    queue: Deque[int] = field(default_factory=collections.deque)
    started: Optional[int] = None
    ready: bool = False
    alone: bool = False     # holds a retried unit: nothing is queued behind it

    @property
    def name(self) -> str:
        return f'pid {self.process.pid}'


class LocalPool:
    """``jobs`` worker processes checking units (see the module docstring)."""

    def __init__(self, spec: RobotSpec, options: CheckOptions, jobs: int):
        self.spec, self.options, self.jobs = spec, options, jobs
        method = 'fork' if sys.platform.startswith('linux') else 'spawn'
        self._context = multiprocessing.get_context(method)

    def _spawn(self) -> _Worker:
        parent, child = self._context.Pipe()
        process = self._context.Process(target=_serve, args=(child, self.spec, self.options),
                                        daemon=True, name='collision_sensor_check worker')
        process.start()
        child.close()
        return _Worker(process, parent)

    def run(self, units: List[Unit], on_record: Callable[[int, dict], None],
            on_start: Optional[Callable[[int, int, int], None]] = None) -> PoolStats:
        """Check ``units``; call ``on_record(index, record)`` as each finishes (in the order
        they finish) and ``on_start(index, attempt, pid)`` as a worker starts one.

        :raises CollisionSensorError: workers keep dying before they are ready.
        """
        stats = PoolStats(workers=min(self.jobs, len(units)))
        pending: Deque[int] = collections.deque(range(len(units)))
        deaths: Dict[int, int] = collections.Counter()
        alone = set()
        remaining = len(units)
        start_failures = 0
        workers = [self._spawn() for _ in range(stats.workers)]
        try:
            while remaining:
                for worker in workers:
                    self._fill(worker, units, pending, alone)
                waiting = {w.conn: w for w in workers}
                waiting.update({w.process.sentinel: w for w in workers})
                for ready in multiprocessing.connection.wait(list(waiting)):
                    worker = waiting[ready]
                    if worker not in workers:
                        continue                   # replaced earlier in this round
                    alive = self._drain(worker, on_record, on_start, deaths, stats)
                    remaining -= alive[1]
                    if alive[0] and worker.process.is_alive():
                        continue
                    if not worker.ready:
                        start_failures += 1
                        if start_failures >= MAX_START_FAILURES:
                            raise CollisionSensorError(
                                f'{MAX_START_FAILURES} workers died before they were ready '
                                f'(last: {death_reason(worker.process.exitcode)}); run with '
                                '--jobs 1 to see the error')
                    else:
                        start_failures = 0
                    remaining -= self._bury(worker, units, pending, deaths, alone, stats,
                                            on_record)
                    workers[workers.index(worker)] = self._spawn()
        finally:
            self._stop(workers)
        return stats

    def _fill(self, worker: _Worker, units, pending: Deque[int], alone: set) -> None:
        """Give ``worker`` units up to DEPTH; a retried unit only to an idle worker, alone."""
        while pending and len(worker.queue) < DEPTH and not worker.alone:
            index = pending[0]
            if index in alone and worker.queue:
                return
            pending.popleft()
            try:
                worker.conn.send((index, units[index]))
            except OSError:               # it died; its sentinel says so next
                pending.appendleft(index)
                return
            worker.queue.append(index)
            worker.alone = index in alone

    def _drain(self, worker: _Worker, on_record, on_start, deaths, stats) -> tuple:
        """Read every message waiting from ``worker``; return (still connected, units done)."""
        done = 0
        try:
            while worker.conn.poll():
                message = worker.conn.recv()
                if message[0] == 'ready':
                    worker.ready = True
                    stats.note_rss(worker.name, message[2])
                elif message[0] == 'start':
                    worker.started = message[1]
                    if on_start is not None:
                        on_start(message[1], deaths[message[1]] + 1, worker.process.pid)
                else:
                    _, index, record, rss = message
                    worker.queue.popleft()
                    worker.started, worker.alone = None, False
                    stats.note_rss(worker.name, rss)
                    on_record(index, record)
                    done += 1
        except (EOFError, OSError):
            return False, done
        return True, done

    def _bury(self, worker: _Worker, units, pending, deaths, alone, stats, on_record) -> int:
        """Handle a dead worker: charge the unit it was checking; requeue the rest. Return 1
        if that unit is now reported failed."""
        worker.process.join(timeout=5)
        worker.conn.close()
        stats.deaths += 1
        queue = list(worker.queue)
        return charge_death(
            queue, bool(queue) and worker.started == queue[0], deaths, alone, pending, stats,
            lambda index, error: on_record(index, UnitChecker.failed_record(
                units[index], self.options, error)),
            death_reason(worker.process.exitcode))

    @staticmethod
    def _stop(workers: List[_Worker]) -> None:
        for worker in workers:
            try:
                worker.conn.send(None)
            except OSError:
                pass
        for worker in workers:
            worker.process.join(timeout=2)
            if worker.process.is_alive():
                worker.process.terminate()
                worker.process.join(timeout=2)
            worker.conn.close()
