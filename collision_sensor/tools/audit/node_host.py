"""One Ray actor per node: the node's checker, built once, and the worker processes it forks.

A :class:`NodeHost` takes the node's CPUs (one worker each), builds the checker from the spec
the object store brings (once per node) and forks its workers from it
(:mod:`~collision_sensor.tools.audit.workers`), so the node holds the model once. The driver
addresses a call to one of its workers (a slot) with the call's number in that slot's
sequence; the host runs each slot's calls in that order (Ray may hand a threaded actor's calls
to its threads in another), one at a time, each on the call's own thread of the actor. A worker
that dies is forked anew at once; the call's answer then says which unit it was checking, and
the driver settles it as for local workers. Losing the host itself (its node lost) is the
driver's to settle (:mod:`~collision_sensor.tools.audit.ray_pool`).

Recordings the node cannot read (it does not share the driver's disk) are fetched from a
:class:`FileServer`, an actor on the driver's machine, not through the driver: the driver only
says which units to fetch. A dataset's parquet file is fetched once per node and kept in a
scratch directory of the host's until the run ends (``close``), so that its episodes read their
rows from a file, as on the driver's machine; a scratch directory a killed host left behind is
removed by the next host on that node.
"""
import glob
import os
import shutil
import tempfile
import threading
from typing import Dict, List, Sequence

from collision_sensor.tools.audit import shipping
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker
from collision_sensor.tools.audit.units import Unit
from collision_sensor.tools.audit.workers import WorkerProcess, fork_context, memory, \
    stop_workers

#: The payload marker of a unit the host fetches from the file server.
FETCH = 'fetch'
SCRATCH_PREFIX = 'collision_sensor_node_'


class FileServer:
    """The actor on the driver's machine that reads recordings for nodes that cannot."""

    def pack(self, unit: Unit):
        """Return :func:`shipping.pack` of ``unit`` (raises OSError)."""
        return shipping.pack(unit)

    def read(self, path: str) -> bytes:
        """Return the bytes of ``path`` (a dataset's data file; raises OSError)."""
        with open(path, 'rb') as stream:
            return stream.read()


def _sweep_scratch() -> None:
    """Remove the scratch directories of hosts that are gone (killed with their node's run)."""
    for path in glob.glob(os.path.join(tempfile.gettempdir(), SCRATCH_PREFIX + '*')):
        try:
            pid = int(path.rsplit('_', 1)[1])
            os.kill(pid, 0)
        except ProcessLookupError:
            shutil.rmtree(path, ignore_errors=True)
        except (ValueError, IndexError, PermissionError):
            pass


class _Slot:
    def __init__(self, worker: WorkerProcess):
        self.worker = worker
        self.turn = threading.Condition()
        self.next = 0


class NodeHost:
    """The actor (wrapped by ``ray.remote`` in the pool, so importing this needs no Ray).

    :param slots: the workers to fork (the node's CPUs this actor holds).
    :param servers: :class:`FileServer` handles to fetch recordings from.
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions, slots: int,
                 servers: Sequence = ()):
        self.spec, self.options, self.servers = spec, options, list(servers)
        self.checker = UnitChecker(spec, options)
        self.checker.checker     # built once, here: the workers share it
        for reader in ('pyarrow.parquet', 'rosbags.rosbag2', 'rosbags.typesys'):
            try:
                __import__(reader)
            except ImportError:
                pass
        self.context = fork_context()
        self.slots = [_Slot(self._fork()) for _ in range(slots)]
        _sweep_scratch()
        self.scratch = os.path.join(tempfile.gettempdir(), f'{SCRATCH_PREFIX}{os.getpid()}')
        os.makedirs(self.scratch, exist_ok=True)
        self.files: Dict[str, str] = {}
        self.fetching: Dict[str, threading.Lock] = {}
        self.lock = threading.Lock()

    def _fork(self) -> WorkerProcess:
        return WorkerProcess(self.context, self.checker, self.spec, self.options)

    def hello(self) -> tuple:
        """Return (node id, host pid, [(worker pid, RSS, bytes of its own)]) once every
        worker is ready."""
        import ray
        workers = []
        for slot in self.slots:
            worker = slot.worker
            while worker.ready is None:
                worker.ready = worker.conn.recv()
            workers.append(worker.ready[1:])
        return ray.get_runtime_context().get_node_id(), os.getpid(), workers

    def check(self, slot: int, number: int, items: List[tuple]) -> tuple:
        """Check ``items`` (``[(index, unit, payload)]``) on worker ``slot`` as its call
        ``number``: ``('done', [(index, report line, RSS)], bytes of its own)`` or ``('died',
        index it was checking or None, reason, new worker's pid)``."""
        place = self.slots[slot]
        failed, call = [], []
        for index, unit, payload in items:   # fetched while the slot's last call runs
            try:
                call.append((index, unit, self._payload(unit, payload)))
            except OSError as err:
                failed.append((index, UnitChecker.failed_record(
                    unit, self.options, f'{err.filename or unit.path}: cannot read: '
                    f'{err.strerror or err}'), 0))
            except Exception as err:     # the file server's fault: the unit's line says so
                failed.append((index, UnitChecker.failed_record(
                    unit, self.options, f'{unit.path}: cannot fetch it from the driver\'s '
                    f'machine: {type(err).__name__}: {err}'), 0))
        with place.turn:
            place.turn.wait_for(lambda: place.next == number)
        try:
            if not call:
                return 'done', failed, 0
            outcome = place.worker.run_call(call)
            if outcome[0] == 'died':
                place.worker = self._fork()
                return outcome + (place.worker.pid,)
            return 'done', failed + outcome[1], outcome[2]
        finally:
            with place.turn:
                place.next += 1
                place.turn.notify_all()

    def _payload(self, unit: Unit, payload):
        """What the worker reads ``unit`` from: the payload as sent, or for ``(FETCH,
        stamp)`` its path when this node sees the files so stamped, else its files fetched
        from a file server (a dataset's data file: a path to this node's copy)."""
        import ray
        if isinstance(payload, ray.ObjectRef):    # a data file the driver put (Ray Client)
            return ray.get(payload)
        if not (isinstance(payload, tuple) and payload[:1] == (FETCH,)):
            return payload
        if shipping.sees(payload[1]):
            return None
        server = self.servers[hash(unit.source) % len(self.servers)]
        try:
            if unit.kind != 'lerobot':
                return ray.get(server.pack.remote(unit))
            return self._data_file(server, os.path.join(unit.episode.root,
                                                        unit.episode.data_file))
        except ray.exceptions.RayTaskError as err:
            if isinstance(err.cause, OSError):
                raise err.cause from None
            raise

    def _data_file(self, server, path: str) -> str:
        """Return this node's copy of the data file ``path``, fetched once."""
        with self.lock:
            if path in self.files:
                return self.files[path]
            lock = self.fetching.setdefault(path, threading.Lock())
        with lock:
            with self.lock:
                if path in self.files:
                    return self.files[path]
            import ray
            data = ray.get(server.read.remote(path))
            local = os.path.join(self.scratch, f'{len(self.files)}_{os.path.basename(path)}')
            with open(local, 'wb') as stream:
                stream.write(data)
            with self.lock:
                self.files[path] = local
            return local

    def memory(self) -> tuple:
        """Return the host's (RSS, bytes of its own): the model's holder."""
        return memory()

    def close(self) -> None:
        """Stop the workers and remove the scratch directory."""
        stop_workers(slot.worker for slot in self.slots)
        shutil.rmtree(self.scratch, ignore_errors=True)
