"""Worker processes forked from the process that holds the checker (the tool's own process for
``--jobs``, one process per node on Ray), so that a machine holds the model once.

The parent builds one :class:`~collision_sensor.tools.audit.unit_check.UnitChecker` and forks
the workers from it: each checks with that checker, its trees in pages shared copy-on-write
with the parent and the other workers (queries write only the engine's carried state, never
the trees; the Python objects are frozen out of the collector's way before the fork, so that
collecting does not write to their pages either). What the units need to read (pyarrow for
datasets, rosbags for bags) is imported before the fork too (:func:`preload`). Where fork is
not available (macOS, Windows), workers are spawned and build a checker each.

A worker takes calls over a pipe of its own::

    worker -> ('ready', pid, rss, private)                       once, then for each call:
    parent -> [(index, unit, payload), ...]      (None: stop)
    worker -> ('start', index of the call's first unit)
    worker -> ('done', [(index, report line, rss), ...], private)

Before each unit it writes the unit's index in a shared slot, so when it dies its parent knows
which unit it was checking. Workers ignore SIGINT: Ctrl-C stops the parent, which stops them.
"""
import gc
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
from typing import Iterable, List, Optional, Tuple

from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker, \
    rss_bytes
from collision_sensor.tools.audit.units import Unit


def fork_context():
    """The multiprocessing context workers start in: fork on Linux, spawn elsewhere."""
    return multiprocessing.get_context('fork' if sys.platform.startswith('linux') else 'spawn')


def preload(units: Iterable[Unit]) -> None:
    """Import the readers ``units`` need, so that forked workers share them."""
    kinds = {unit.kind for unit in units}
    if 'lerobot' in kinds:
        import pyarrow.parquet  # noqa: F401
    if 'bag' in kinds:
        import rosbags.rosbag2  # noqa: F401
        import rosbags.typesys  # noqa: F401


def memory() -> Tuple[int, int]:
    """Return this process's resident bytes and those of them no other process shares
    (``/proc/self/smaps_rollup``; the second 0 where the system does not say)."""
    resident = private = 0
    try:
        with open('/proc/self/smaps_rollup') as stream:
            for line in stream:
                name, _, value = line.partition(':')
                if name == 'Rss':
                    resident = int(value.split()[0]) * 1024
                elif name in ('Private_Clean', 'Private_Dirty'):
                    private += int(value.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        return rss_bytes(), 0
    return resident, private


def death_reason(exitcode: Optional[int]) -> str:
    """Say how a worker process ended (``exitcode`` as multiprocessing gives it)."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f'signal {-exitcode}'
        return f'killed by {name}'
    return f'exited with status {exitcode}'


def _serve(conn, slot, shared: Optional[UnitChecker], spec: RobotSpec,
           options: CheckOptions) -> None:
    """A worker: check the calls the pipe brings until it brings None (see the module doc)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)   # not a handler inherited from a Ray worker
    checker = shared if shared is not None else UnitChecker(spec, options)
    checker.checker  # build the trees now (spawned), before the first unit
    conn.send(('ready', os.getpid(), *memory()))
    while True:
        call = conn.recv()
        if call is None:
            return
        slot.value = call[0][0]      # before the parent hears of it: a kill then charges it
        conn.send(('start', call[0][0]))
        done = []
        for index, unit, payload in call:
            slot.value = index
            done.append((index, checker.check(unit, payload), rss_bytes()))
        slot.value = -1
        conn.send(('done', done, memory()[1]))


class WorkerProcess:
    """One worker (see the module docstring), started at once.

    :param shared: the parent's checker, used by a forked worker (None: build one).
    """

    def __init__(self, context, shared: Optional[UnitChecker], spec: RobotSpec,
                 options: CheckOptions):
        forked = context.get_start_method() == 'fork'
        self.conn, child = context.Pipe()
        self.slot = context.RawValue('q', -1)
        self.process = context.Process(
            target=_serve, args=(child, self.slot, shared if forked else None, spec, options),
            daemon=True, name='collision_sensor_check worker')
        gc.freeze()          # the objects there now are the parent's: never collected here
        try:
            self.process.start()
        finally:
            gc.unfreeze()
        child.close()
        self.ready: Optional[tuple] = None   # ('ready', pid, rss, private) once received

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def name(self) -> str:
        return f'pid {self.process.pid}'

    def run_call(self, call: List[tuple]) -> tuple:
        """Check one call and wait for it (a node's host does this, one thread per worker):
        return ``('done', [(index, report line, rss)], private)``, or ``('died', index,
        reason)`` with the index of the unit it was checking (None if none) when it died."""
        try:
            while self.ready is None:
                self.ready = self.conn.recv()
            self.conn.send(call)
            while True:
                message = self.conn.recv()
                if message[0] == 'done':
                    return message
        except (EOFError, OSError):
            pass
        self.process.join(timeout=5)
        checking = self.slot.value
        return ('died', checking if checking >= 0 else None,
                death_reason(self.process.exitcode))


def stop_workers(workers: Iterable[WorkerProcess]) -> None:
    """Ask every worker to stop, then wait; kill one that has not stopped within 2 s."""
    workers = list(workers)
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
