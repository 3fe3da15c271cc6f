"""``--ray ADDRESS``: units checked on a Ray cluster, this machine's or many machines'.

``ADDRESS`` is ``auto`` (join the cluster running here, as ``ray start --head`` leaves it),
``local`` (start a cluster in this process with ``--jobs`` CPUs, stopped at the end), or any
address ``ray.init`` takes (``ray://head:10001``, ``head:6379``). Ray is an optional extra:
``pip install 'collision_sensor[cluster]'``; every node needs collision_sensor installed.

Each node with CPUs gets one :class:`~collision_sensor.tools.audit.node_host.NodeHost`, which
builds the checker once from the spec put in the object store and forks one worker per CPU
(``--jobs`` caps the workers over the cluster). The driver keeps up to
:data:`~collision_sensor.tools.audit.scheduling.DEPTH` calls queued per worker, several small
units a call; it reads no recording for a node that does not share its disk: that node's host
fetches the files from a :class:`~collision_sensor.tools.audit.node_host.FileServer` on the
driver's machine (through Ray Client, ``ray://``, the driver packs them itself). The driver
waits on all its calls at once and takes every answer ready when it wakes.

Faults: a worker process that dies is settled as on one machine (the unit it was checking is
charged: tried once more alone, then reported; the rest go on). A host that is lost (its node
gone: Ray says so within seconds, ``ActorUnavailableError`` or ``ActorDiedError``) costs no unit
anything: every unit it held goes back to the queue and is checked on the nodes left; the
summary counts them. Hosts start without blocking the run: a node that joins is taken up at the
next look at the cluster (every :data:`LOOK_SECONDS`), and a run whose cluster has no CPU left
stops with an error saying so (the report holds every unit finished: ``--resume``).
"""
import collections
import dataclasses
import os
import time
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Optional

from collision_sensor.engine.checker_config import usable_cores
from collision_sensor.errors import ConfigError
from collision_sensor.tools.audit import shipping
from collision_sensor.tools.audit.node_host import FETCH, FileServer, NodeHost
from collision_sensor.tools.audit.scheduling import DEPTH, PoolStats, call_units, \
    charge_death, settle_lost, take_call
from collision_sensor.tools.audit.unit_check import CheckOptions, RobotSpec, UnitChecker
from collision_sensor.tools.audit.units import Unit

INSTALL_HINT = ('--ray needs Ray, an optional extra: pip install "collision_sensor[cluster]" '
                '(or pip install "ray>=2.9")')
#: Seconds between looks at the cluster for nodes that joined (or whose host was lost).
LOOK_SECONDS = 5.0
#: Seconds the run waits for a first worker of the cluster before it gives up.
START_SECONDS = 300.0
#: Hosts that fail to start on a node, in a row, before that node is left alone.
NODE_START_FAILURES = 3
#: File servers on the driver's machine.
FILE_SERVERS = 2
#: Units in one call at most, and bytes of recordings: a call costs the driver about 2 ms of
#: CPU whatever it holds (Ray's submission, wait and answer), a unit a few microseconds more.
CALL_UNITS = 128
CALL_BYTES = 128 * 2 ** 20


def require_ray():
    """Return the ``ray`` module, or raise ConfigError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise ConfigError(INSTALL_HINT) from None
    return ray


@dataclass
class _Host:
    handle: object
    node: str
    workers: int
    hello: object                      # the ObjectRef of its hello() until it is ready
    local: bool = False                # on the driver's machine: reads the files itself
    slots: List['_Slot'] = field(default_factory=list)


@dataclass
class _Slot:
    host: _Host
    index: int
    pid: int
    queue: Deque = field(default_factory=collections.deque)   # (call, ref)
    sent: int = 0                      # calls sent: the next call's number
    alone: bool = False                # holds a retried unit: nothing is queued behind it

    @property
    def name(self) -> str:
        return f'{self.host.node[:8]} pid {self.pid}'


_REMOTE: Dict[type, object] = {}


def remote_class(ray, cls):
    """``ray.remote(cls)``, made once per process (each costs the driver ~50 ms of CPU to
    export; Ray exports it again to a new job by itself)."""
    if cls not in _REMOTE:
        _REMOTE[cls] = ray.remote(cls)
    return _REMOTE[cls]


def absolute(unit: Unit) -> Unit:
    """``unit`` with an absolute path (itself when it has one)."""
    path = os.path.abspath(unit.path)
    if path == unit.path:
        return unit
    episode = unit.episode
    if episode is not None:
        episode = dataclasses.replace(episode, root=os.path.abspath(episode.root))
    return Unit(unit.source, unit.kind, path, episode)


class RayPool:
    """Ray node hosts checking units (see the module docstring).

    :param address: ``auto``, ``local`` or a cluster address.
    :param jobs: workers over the cluster at most (None: one per CPU); with ``local``, the
        CPUs of the cluster started.
    :param ship: True: every host fetches the files (as from another machine); False: none
        does; None: the hosts on other machines than the driver's, of the files they do not
        see as the driver stamped them.
    :param call_units: units in one call at most.
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions, address: str,
                 jobs: Optional[int] = None, ship: Optional[bool] = None,
                 call_units: int = CALL_UNITS):
        self.ray = require_ray()
        self.spec, self.options, self.address, self.jobs = spec, options, address, jobs
        self.ship, self.call_units = ship, call_units

    def _connect(self) -> bool:
        """Join or start the cluster; return whether this call started Ray here."""
        ray = self.ray
        if ray.is_initialized():
            return False
        kwargs = dict(include_dashboard=False, log_to_driver=False,
                      configure_logging=False)
        if self.address == 'local':
            kwargs['num_cpus'] = self.jobs or usable_cores()
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
        """Check ``units`` as :meth:`LocalPool.run` does (``on_start`` as a worker's next
        call becomes the one it checks).

        :raises ConfigError: the cluster has no CPU to check on (any more).
        """
        started_here = self._connect()
        run = _Run(self, units, on_record, on_start)
        try:
            return run.loop()
        finally:
            run.stop()
            if started_here:
                self.ray.shutdown()


class _Run:
    """One :meth:`RayPool.run`: the queue, the hosts and their slots."""

    def __init__(self, pool: RayPool, units: List[Unit], on_record, on_start):
        ray = self.ray = pool.ray
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy
        self.affinity = NodeAffinitySchedulingStrategy
        self.pool, self.units, self.on_record, self.on_start = pool, units, on_record, on_start
        self.options = pool.options
        # A host's working directory is its raylet's, not the driver's: units travel with
        # absolute paths (their lines keep their sources, and errors name them as given).
        self.sent = [absolute(unit) for unit in units]
        self.start = time.perf_counter()
        self.stats = PoolStats(nodes=0)
        stamps: Dict[str, tuple] = {}      # a dataset's data file: stamped once
        self.stamps = []
        for unit in self.sent:
            paths = shipping.files(unit)
            key = paths[0] if unit.kind == 'lerobot' else None
            if key not in stamps:
                stamps[key] = shipping.stamp(paths)
            self.stamps.append(stamps.pop(None) if key is None else stamps[key])
        self.weights = [unit.episode.length * 64 if unit.kind == 'lerobot'
                        else sum(max(size, 0) for _, size, _ in stamped)
                        for unit, stamped in zip(units, self.stamps)]
        self.pending: Deque[int] = collections.deque(range(len(units)))
        self.deaths: Dict[int, int] = collections.Counter()
        self.losses: Dict[int, int] = collections.Counter()
        self.alone = set()
        self.remaining = len(units)
        self.hosts: Dict[str, _Host] = {}
        self.failures: Dict[str, int] = collections.Counter()
        self.slots: List[_Slot] = []
        self.here = ray.get_runtime_context().get_node_id()
        self.client = ray.util.client.ray.is_connected()
        self.spec_ref = ray.put(pool.spec)
        self.shared: Dict[str, object] = collections.OrderedDict()  # client: data files put
        self.remote = remote_class(ray, NodeHost)
        self.servers = [] if self.client else [
            remote_class(ray, FileServer).options(
                num_cpus=0, scheduling_strategy=self.affinity(self.here, soft=False)).remote()
            for _ in range(FILE_SERVERS)]
        self.looked = 0.0

    # ------------------------------------------------------------------ hosts
    def look(self) -> None:
        """Start a host on every live node with CPUs that has none (within ``--jobs``)."""
        self.looked = time.perf_counter()
        budget = self.pool.jobs
        if budget is not None:
            budget -= sum(host.workers for host in self.hosts.values())
        for node in self.ray.nodes():
            node_id = node.get('NodeID')
            cpus = int(node.get('Resources', {}).get('CPU', 0))
            if not node.get('Alive') or node_id in self.hosts or cpus < 1 or \
                    self.failures[node_id] >= NODE_START_FAILURES:
                continue
            workers = cpus if budget is None else min(cpus, budget)
            if workers < 1:
                return
            handle = self.remote.options(
                num_cpus=workers, max_concurrency=workers * DEPTH + 2, max_restarts=0,
                max_task_retries=0, scheduling_strategy=self.affinity(node_id, soft=False)
            ).remote(self.spec_ref, self.options, workers, self.servers)
            local = node_id == self.here if self.pool.ship is None else not self.pool.ship
            # (a host elsewhere reads in place what it sees as the driver stamped it)
            self.hosts[node_id] = _Host(handle, node_id, workers, handle.hello.remote(),
                                        local and not self.client)
            if budget is not None:
                budget -= workers

    def ready(self, host: _Host, answer) -> None:
        """A host said hello: its workers take calls from now on."""
        node, _, workers = answer
        host.hello = None
        self.failures[node] = 0
        if not self.stats.start_seconds:
            self.stats.start_seconds = time.perf_counter() - self.start
        self.stats.nodes += 1
        self.stats.workers += len(workers)
        for index, (pid, rss, private) in enumerate(workers):
            slot = _Slot(host, index, pid)
            host.slots.append(slot)
            self.slots.append(slot)
            self.stats.note_rss(slot.name, rss)
            self.stats.note_private(slot.name, private)

    def lost(self, host: _Host) -> None:
        """A host is gone (its node lost, or it failed to start): its units go back to the
        queue uncharged."""
        self.ray.kill(host.handle)
        self.hosts.pop(host.node, None)
        if host.hello is not None:
            self.failures[host.node] += 1
            return
        self.stats.lost_nodes += 1
        for slot in host.slots:
            self.slots.remove(slot)
            if slot.queue:
                queue = [index for call, _ in slot.queue for index in call]
                self.remaining -= settle_lost(queue, self.losses, self.pending, self.stats,
                                              self.failed, checking=slot.queue[0][0])
        self.look()

    def failed(self, index: int, error: str) -> None:
        self.on_record(index, UnitChecker.failed_record(self.units[index], self.options,
                                                        error))

    # ------------------------------------------------------------------ calls
    def payload(self, index: int, host: _Host):
        """What a host reads unit ``index`` from: None, its path; ``(FETCH, stamp)``, its
        path if the node sees the files the driver stamped, else the file server's; or (Ray
        Client) its files packed here."""
        if host.local:
            return None
        if not self.client:
            return FETCH, (() if self.pool.ship else self.stamps[index])
        unit = self.sent[index]
        if unit.kind != 'lerobot':
            return shipping.pack(unit)
        key = os.path.join(unit.episode.root, unit.episode.data_file)
        if key not in self.shared:
            self.shared[key] = self.ray.put(shipping.pack(unit))
            while len(self.shared) > 4:
                self.shared.popitem(last=False)
        return self.shared[key]

    def fill(self, slot: _Slot) -> None:
        """Give ``slot`` calls up to DEPTH; a retried unit only to an idle worker, alone."""
        while self.pending and len(slot.queue) < DEPTH and not slot.alone:
            call = take_call(self.pending, self.weights,
                             call_units(len(self.pending), max(1, len(self.slots)),
                                        self.pool.call_units),
                             self.alone, bool(slot.queue), CALL_BYTES)
            if not call:
                return
            items = []
            for index in call:
                try:
                    items.append((index, self.sent[index], self.payload(index, slot.host)))
                except OSError as err:     # packed here (Ray Client): the unit fails
                    self.failed(index, f'{err.filename or "file"}: cannot read: '
                                f'{err.strerror or err}')
                    self.remaining -= 1
            call = [index for index, _, _ in items]
            if not call:
                continue
            ref = slot.host.handle.check.remote(slot.index, slot.sent, items)
            slot.sent += 1
            self.stats.calls += 1
            slot.queue.append((call, ref))
            slot.alone = call[0] in self.alone
            if len(slot.queue) == 1:
                self.announce(slot)

    def announce(self, slot: _Slot) -> None:
        if self.on_start is not None and slot.queue:
            index = slot.queue[0][0][0]
            self.on_start(index, self.deaths[index] + 1, slot.pid)

    def answer(self, slot: _Slot, outcome) -> None:
        """The answer to ``slot``'s first call."""
        call, _ = slot.queue.popleft()
        slot.alone = False
        if outcome[0] == 'done':
            for index, record, rss in outcome[1]:
                self.stats.note_rss(slot.name, rss)
                if record['error'] is not None and self.sent[index] is not self.units[index]:
                    record['error'] = shipping.relabel(record['error'], self.sent[index].path,
                                                       self.units[index].path)
                self.on_record(index, record)
            self.stats.note_private(slot.name, outcome[2])
            self.remaining -= len(outcome[1])
        else:
            _, checking, reason, pid = outcome
            self.stats.deaths += 1
            queue = list(call)
            if checking in queue:
                queue.remove(checking)
                queue.insert(0, checking)
            slot.pid = pid
            self.remaining -= charge_death(queue, checking in call, self.deaths, self.alone,
                                           self.pending, self.stats, self.failed, reason)
        self.announce(slot)

    def loop(self) -> PoolStats:
        ray = self.ray
        self.look()
        while self.remaining:
            for slot in self.slots:
                self.fill(slot)
            waits = {slot.queue[0][1]: slot for slot in self.slots if slot.queue}
            waits.update({host.hello: host for host in self.hosts.values()
                          if host.hello is not None})
            if not waits:
                if not self.hosts and time.perf_counter() - self.looked < LOOK_SECONDS:
                    time.sleep(0.5)   # nothing to wait on: a node may join
                self.check_start()
                self.look()
                continue
            ready, rest = ray.wait(list(waits), num_returns=1, timeout=LOOK_SECONDS)
            if rest and ready:    # take every answer there is now, not one per wake-up
                ready += ray.wait(rest, num_returns=len(rest), timeout=0)[0]
            for ref in ready:
                owner = waits[ref]
                host = owner if isinstance(owner, _Host) else owner.host
                if host.node not in self.hosts or self.hosts[host.node] is not host:
                    continue                # lost earlier in this round
                try:
                    outcome = ray.get(ref)
                except ray.exceptions.RayError:
                    self.lost(host)
                    continue
                if owner is host:
                    self.ready(host, outcome)
                else:
                    self.answer(owner, outcome)
            if time.perf_counter() - self.looked > LOOK_SECONDS:
                self.check_start()
                self.look()
        return self.stats

    def check_start(self) -> None:
        """Give up when no worker can check: none ready, none starting, or none ready after
        START_SECONDS."""
        if self.slots:
            return
        starting = [host for host in self.hosts.values() if host.hello is not None]
        waited = time.perf_counter() - self.start
        if (not starting and waited > LOOK_SECONDS) or waited > START_SECONDS:
            cpus = int(self.ray.cluster_resources().get('CPU', 0))
            raise ConfigError(
                f'--ray {self.pool.address}: no worker of the cluster can check ('
                f'{cpus} CPUs in the cluster, {len(starting)} node hosts still starting after '
                f'{waited:.0f} s, {self.stats.lost_nodes} lost); add nodes (ray start '
                '--address ...) and continue with --resume')

    def stop(self) -> None:
        """End the hosts (their workers and scratch files) and the file servers."""
        ray = self.ray
        closing = [host.handle.close.remote() for host in self.hosts.values()
                   if host.hello is None]
        if closing:
            ray.wait(closing, num_returns=len(closing), timeout=10)
        for host in self.hosts.values():
            ray.kill(host.handle)
        for server in self.servers:
            ray.kill(server)
