"""``--ray ADDRESS``: units checked by Ray actors, on this machine or a cluster.

``ADDRESS`` is ``auto`` (join the cluster running here, as ``ray start --head`` leaves it),
``local`` (start a cluster in this process with ``--jobs`` CPUs, stopped at the end), or any
address ``ray.init`` takes (``ray://head:10001``, ``head:6379``). Ray is an optional extra:
``pip install 'collision_sensor[cluster]'``; every node needs collision_sensor installed.

One actor per CPU of the cluster (or ``--jobs``), each building its checker once from the
:class:`~collision_sensor.tools.audit.unit_check.RobotSpec` put in the object store once. The
cluster's nodes need not share a file system with the driver: the robot travels as that spec
(the loaded model, no path), and a recording checked on another machine than the driver's
travels as its bytes, read by the driver when its task is sent
(:mod:`~collision_sensor.tools.audit.shipping`; at most :data:`DEPTH` per actor in flight, so
the driver holds a bounded number of files; an episode's parquet file is put in the object
store once while its episodes are being sent). An actor on the driver's machine reads the
files itself (shipping a 175 kB file through the object store costs ~3 ms a unit here, a
third of checking it).

Small recordings go several to a call, large ones one per call, as with local workers
(:func:`~collision_sensor.tools.audit.local_pool.take_call`; a call costs the driver and the
raylet about a millisecond of CPU here, a seventh of a 1000-frame CSV file's check). Faults are
settled as with local workers (:mod:`~collision_sensor.tools.audit.local_pool`), but an actor
has no slot saying which unit it checks: it runs its calls in order, so when it dies its first
call was running. A call of one unit charges that unit: it is tried once more alone on a new
actor, then reported; a call of several charges none, and its units are sent again one per
call, so that a unit that kills an actor again is the one charged. Calls queued behind go again
uncharged.
"""
import collections
import os
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Optional

from collision_sensor.errors import ConfigError
from collision_sensor.tools.audit import shipping
from collision_sensor.tools.audit.local_pool import DEPTH, PoolStats, call_units, \
    charge_death, take_call
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker, \
    rss_bytes
from collision_sensor.tools.audit.units import Unit

INSTALL_HINT = ('--ray needs Ray, an optional extra: pip install "collision_sensor[cluster]" '
                '(or pip install "ray>=2.9")')
#: Parquet files kept in the object store while their episodes are sent.
SHARED_FILES = 4


def require_ray():
    """Return the ``ray`` module, or raise ConfigError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise ConfigError(INSTALL_HINT) from None
    return ray


class RayWorker:
    """The actor: a :class:`UnitChecker` built once (wrapped by ``ray.remote`` in
    :meth:`RayPool.run`, so importing this module needs no Ray)."""

    def __init__(self, spec: RobotSpec, options: CheckOptions):
        self.checker = UnitChecker(spec, options)
        self.checker.checker   # build the trees now

    def hello(self):
        """Return (pid, RSS in bytes, Ray node id) once ready."""
        import ray
        return os.getpid(), rss_bytes(), ray.get_runtime_context().get_node_id()

    def check_many(self, items):
        """Check ``[(unit, payload)]`` in order; return ``[(report line, RSS in bytes)]``. A
        payload may be an ObjectRef (a parquet file shared by episodes): Ray resolves only
        the call's own arguments, so it is fetched here."""
        import ray
        out = []
        for unit, payload in items:
            if isinstance(payload, ray.ObjectRef):
                payload = ray.get(payload)
            out.append((self.checker.check(unit, payload), rss_bytes()))
        return out


@dataclass
class _Actor:
    handle: object
    pid: int = 0
    local: bool = False     # on the driver's machine: reads the files itself
    queue: Deque = field(default_factory=collections.deque)   # (index, ref)
    alone: bool = False


class RayPool:
    """Ray actors checking units (see the module docstring).

    :param address: ``auto``, ``local`` or a cluster address.
    :param jobs: actors (None: one per CPU of the cluster); with ``local``, the CPUs of the
        cluster started.
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions, address: str,
                 jobs: Optional[int] = None, ship: Optional[bool] = None):
        self.ray = require_ray()
        self.spec, self.options, self.address, self.jobs = spec, options, address, jobs
        self.ship = ship

    def _connect(self) -> bool:
        """Join or start the cluster; return whether this call started Ray here."""
        ray = self.ray
        if ray.is_initialized():
            return False
        kwargs = dict(include_dashboard=False, log_to_driver=False,
                      configure_logging=False)
        if self.address == 'local':
            kwargs['num_cpus'] = self.jobs or len(os.sched_getaffinity(0))
        try:
            ray.init(address=self.address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as err:
            fix = ('start one with "ray start --head", or use --ray local'
                   if self.address == 'auto' else 'check the address')
            raise ConfigError(f'--ray {self.address}: cannot join the cluster: {err}; {fix}') \
                from None
        return True

    def run(self, units: List[Unit], on_record: Callable[[int, dict], None],
            on_start: Optional[Callable[[int, int, int], None]] = None) -> PoolStats:
        """Check ``units`` as :meth:`LocalPool.run` does (``on_start`` for the first unit of
        each call)."""
        ray = self.ray
        started_here = self._connect()
        remote = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(RayWorker)
        cpus = int(ray.cluster_resources().get('CPU', 1))
        stats = PoolStats(workers=max(1, min(self.jobs or cpus, cpus, len(units))))
        spec_ref = ray.put(self.spec)
        shared: Dict[str, object] = collections.OrderedDict()
        pending: Deque[int] = collections.deque(range(len(units)))
        deaths: Dict[int, int] = collections.Counter()
        alone, single, remaining = set(), set(), len(units)
        actors: List[_Actor] = []
        here = ray.get_runtime_context().get_node_id()

        def new_actors(count: int) -> List[_Actor]:
            # All started before any is waited for: each builds its checker (its trees) as
            # it starts, so they start side by side, not one after the other.
            started = [_Actor(remote.remote(spec_ref, self.options)) for _ in range(count)]
            for actor, (pid, rss, node) in zip(started, ray.get(
                    [actor.handle.hello.remote() for actor in started])):
                actor.pid = pid
                actor.local = node == here if self.ship is None else not self.ship
                stats.note_rss(f'pid {actor.pid}', rss)
            return started

        def payload(unit: Unit, actor: _Actor):
            if actor.local:
                return None
            if unit.kind != 'lerobot':
                return shipping.pack(unit)
            key = os.path.join(unit.episode.root, unit.episode.data_file)
            if key not in shared:
                shared[key] = ray.put(shipping.pack(unit))
                while len(shared) > SHARED_FILES:
                    shared.popitem(last=False)
            return shared[key]

        def announce(actor: _Actor) -> None:
            if on_start is not None and actor.queue:
                index = actor.queue[0][0][0]
                on_start(index, deaths[index] + 1, actor.pid)

        try:
            actors = new_actors(stats.workers)
            while remaining:
                for actor in actors:
                    while pending and len(actor.queue) < DEPTH and not actor.alone:
                        call = take_call(pending, units,
                                         call_units(len(pending), stats.workers), alone,
                                         bool(actor.queue), single)
                        if not call:
                            break
                        items = []
                        for index in call:
                            try:
                                items.append((units[index], payload(units[index], actor)))
                            except OSError as err:
                                on_record(index, UnitChecker.failed_record(
                                    units[index], self.options, f'{err.filename or "file"}: '
                                    f'cannot read: {err.strerror or err}'))
                                remaining -= 1
                                call = [i for i in call if i != index]
                        if not call:
                            continue
                        actor.queue.append((call, actor.handle.check_many.remote(items)))
                        actor.alone = call[0] in alone
                        single.difference_update(call)
                        if len(actor.queue) == 1:
                            announce(actor)
                heads = {actor.queue[0][1]: actor for actor in actors if actor.queue}
                if not heads:
                    continue
                ready, _ = ray.wait(list(heads), num_returns=1)
                actor = heads[ready[0]]
                call, ref = actor.queue[0]
                try:
                    results = ray.get(ref)
                except ray.exceptions.RayError as err:
                    remaining -= self._bury(actor, units, pending, deaths, alone, single,
                                            stats, on_record, err)
                    actors[actors.index(actor)] = new_actors(1)[0]
                    continue
                actor.queue.popleft()
                actor.alone = False
                for index, (record, rss) in zip(call, results):
                    stats.note_rss(f'pid {actor.pid}', rss)
                    on_record(index, record)
                remaining -= len(call)
                announce(actor)
        finally:
            for actor in actors:
                ray.kill(actor.handle)
            if started_here:
                ray.shutdown()
        return stats

    def _bury(self, actor: _Actor, units, pending, deaths, alone, single, stats, on_record,
              err) -> int:
        """Handle a dead actor; return 1 if a unit is now reported failed. A call of one unit
        charges it (:func:`charge_death`); a call of several charges none, and its units go
        back to be sent one per call, so that a unit that kills again is named."""
        self.ray.kill(actor.handle)
        stats.deaths += 1
        calls = [call for call, _ in actor.queue]
        if len(calls[0]) > 1:
            single.update(calls[0])
            pending.extendleft(reversed([index for call in calls for index in call]))
            return 0
        return charge_death(
            [index for call in calls for index in call], True, deaths, alone, pending, stats,
            lambda index, error: on_record(index, UnitChecker.failed_record(
                units[index], self.options, error)),
            f'the Ray actor died: {type(err).__name__}')
