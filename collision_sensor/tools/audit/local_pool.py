"""``--jobs N``: units checked in N worker processes on this machine.

Each worker builds its checker once (:class:`~collision_sensor.tools.audit.unit_check.UnitChecker`)
and then takes calls over a pipe of its own, at most :data:`DEPTH` at a time (the next one
waits in the pipe while it checks one, so it never idles on the driver). A call is one unit, or
several small ones (:func:`take_call`): the worker answers once per call, so the driver wakes
once per call, not once per unit (on two cores its wake-ups took a tenth of a core from the two
workers). Before each unit the worker writes the unit's index in a shared slot, so when it
dies the driver knows which unit it was checking: only that unit is charged; it is tried once
more, alone on a fresh worker (so a second death takes nothing else with it), and reported with
the reason if it kills that one too. The other units of its calls go back to the queue
uncharged (those it had finished too: their lines died with it). The standard library's pools
do not allow this: ``multiprocessing.Pool`` hangs when a worker dies, and
``concurrent.futures`` fails every pending unit of the pool.

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
from typing import Callable, Container, Deque, Dict, List, Optional

from collision_sensor.errors import CollisionSensorError
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker, \
    rss_bytes
from collision_sensor.tools.audit.units import Unit

#: Calls a worker holds at once: the one it checks and the next.
DEPTH = 2
#: Units in one call at most, and bytes of recordings (a larger recording goes on its own).
CALL_UNITS = 16
CALL_BYTES = 2 * 2 ** 20
#: Times a unit is tried again after its worker died.
RETRIES = 1
#: Workers that die before they are ready, in a row, before the run gives up.
MAX_START_FAILURES = 3


def unit_weight(unit: Unit) -> int:
    """Bytes of a unit's recording (an episode: its frames times 64), 0 if unknown."""
    try:
        if unit.kind == 'lerobot':
            return unit.episode.length * 64
        if os.path.isdir(unit.path):
            return sum(entry.stat().st_size for entry in os.scandir(unit.path)
                       if entry.is_file())
        return os.path.getsize(unit.path)
    except OSError:
        return 0


def call_units(pending: int, workers: int) -> int:
    """How many small units the next call takes: CALL_UNITS, fewer as the queue runs out (the
    last calls take one each, so that no worker idles while another finishes a long call)."""
    return max(1, min(CALL_UNITS, pending // (2 * workers)))


def take_call(pending: Deque[int], units: List[Unit], most: int, alone: set,
              busy: bool, single: Container[int] = ()) -> List[int]:
    """Take the next call's units from the front of ``pending``: small ones together (up to
    ``most`` units and CALL_BYTES); a large one, one in ``single`` or a retried one (in
    ``alone``) on its own, a retried one only for an idle worker (not ``busy``)."""
    call, size = [], 0
    while pending and len(call) < most:
        index = pending[0]
        weight = unit_weight(units[index])
        on_its_own = index in alone or index in single or weight >= CALL_BYTES
        if call and (on_its_own or size + weight > CALL_BYTES):
            break
        if index in alone and busy:
            break
        call.append(pending.popleft())
        size += weight
        if on_its_own:
            break
    return call


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


def _serve(conn, slot, spec: RobotSpec, options: CheckOptions) -> None:
    """A worker: build the checker, then check the calls the pipe brings until it brings None,
    with the index of the unit it checks in ``slot``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    checker = UnitChecker(spec, options)
    checker.checker  # build the trees now, before the first unit
    conn.send(('ready', os.getpid(), rss_bytes()))
    while True:
        call = conn.recv()
        if call is None:
            return
        slot.value = call[0][0]      # before the driver hears of it: a kill then charges it
        conn.send(('start', call[0][0]))
        done = []
        for index, unit in call:
            slot.value = index
            done.append((index, checker.check(unit), rss_bytes()))
        slot.value = -1
        conn.send(('done', done))


@dataclass
class _Worker:
    process: object
    conn: object
    slot: object            # the unit it checks (-1: none), written by the worker
    calls: Deque[List[int]] = field(default_factory=collections.deque)
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
        slot = self._context.RawValue('q', -1)
        process = self._context.Process(target=_serve,
                                        args=(child, slot, self.spec, self.options),
                                        daemon=True, name='collision_sensor_check worker')
        process.start()
        child.close()
        return _Worker(process, parent, slot)

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
                    self._fill(worker, units, pending, alone, len(workers))
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

    def _fill(self, worker: _Worker, units, pending: Deque[int], alone: set,
              workers: int) -> None:
        """Give a ready ``worker`` calls up to DEPTH; a retried unit only to an idle worker,
        alone."""
        while worker.ready and pending and len(worker.calls) < DEPTH and not worker.alone:
            call = take_call(pending, units, call_units(len(pending), workers), alone,
                             bool(worker.calls))
            if not call:
                return
            try:
                worker.conn.send([(index, units[index]) for index in call])
            except OSError:               # it died; its sentinel says so next
                pending.extendleft(reversed(call))
                return
            worker.calls.append(call)
            worker.alone = call[0] in alone

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
                    if on_start is not None:
                        on_start(message[1], deaths[message[1]] + 1, worker.process.pid)
                else:
                    worker.calls.popleft()
                    worker.alone = False
                    for index, record, rss in message[1]:
                        stats.note_rss(worker.name, rss)
                        on_record(index, record)
                    done += len(message[1])
        except (EOFError, OSError):
            return False, done
        return True, done

    def _bury(self, worker: _Worker, units, pending, deaths, alone, stats, on_record) -> int:
        """Handle a dead worker: charge the unit it was checking; requeue the rest. Return 1
        if that unit is now reported failed."""
        worker.process.join(timeout=5)
        worker.conn.close()
        stats.deaths += 1
        queue = [index for call in worker.calls for index in call]
        checking = worker.slot.value
        charged = checking in queue
        if charged:             # first, as charge_death takes it
            queue.remove(checking)
            queue.insert(0, checking)
        return charge_death(
            queue, charged, deaths, alone, pending, stats,
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
