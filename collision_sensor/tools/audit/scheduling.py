"""How a driver hands units to workers: calls of several small units, how deep a worker's
queue is, and how the units of a worker (or a node) that died are settled.

Shared by the local pool (:mod:`~collision_sensor.tools.audit.local_pool`) and Ray
(:mod:`~collision_sensor.tools.audit.ray_pool`). A call is one unit, or several small ones
(:func:`take_call`): a worker answers once per call, so the driver wakes once per call, not once
per unit. A worker holds at most :data:`DEPTH` calls: the one it checks and the next, which
waits beside it so that it never idles on the driver.

When a worker process dies, the unit it was checking is charged (:func:`charge_death`): tried
once more alone on a fresh worker, then reported with the reason; the other units it held go
back to the queue uncharged. When a whole node is lost, none of its units is charged: they go
back to the queue (:meth:`PoolStats.note_lost`), and only a unit whose nodes are lost
:data:`LOST_LIMIT` times while it is checked is reported (a unit that brings its node down).
"""
import os
import stat
from dataclasses import dataclass, field
from typing import Callable, Container, Deque, Dict, List, Optional

from collision_sensor.tools.audit.units import Unit

#: Calls a worker holds at once: the one it checks and the next.
DEPTH = 2
#: Units in one call of local workers at most, and bytes of recordings (a larger recording
#: goes on its own); calls to Ray nodes cost the driver more, and are larger
#: (:mod:`~collision_sensor.tools.audit.ray_pool`).
CALL_UNITS = 16
CALL_BYTES = 2 * 2 ** 20
#: Times a unit is tried again after its worker died.
RETRIES = 1
#: Times a unit's node may be lost while it is checked before the unit is reported.
LOST_LIMIT = 3


def unit_weight(unit: Unit) -> int:
    """Bytes of a unit's recording (an episode: its frames times 64), 0 if unknown."""
    if unit.kind == 'lerobot':
        return unit.episode.length * 64
    try:
        status = os.stat(unit.path)
        if not stat.S_ISDIR(status.st_mode):
            return status.st_size
        return sum(entry.stat().st_size for entry in os.scandir(unit.path) if entry.is_file())
    except OSError:
        return 0


def call_units(pending: int, workers: int, most: int = CALL_UNITS) -> int:
    """How many small units the next call takes: ``most``, fewer as the queue runs out (the
    last calls take one each, so that no worker idles while another finishes a long call)."""
    return max(1, min(most, pending // (2 * workers)))


def take_call(pending: Deque[int], weights: List[int], most: int, alone: set,
              busy: bool, most_bytes: int = CALL_BYTES) -> List[int]:
    """Take the next call's units from the front of ``pending``: small ones together (up to
    ``most`` units and ``most_bytes`` of recordings); a larger one or a retried one (in
    ``alone``) on its own, a retried one only for an idle worker (not ``busy``).

    :param weights: each unit's :func:`unit_weight`, by index.
    """
    call, size = [], 0
    while pending and len(call) < most:
        index = pending[0]
        weight = weights[index]
        on_its_own = index in alone or weight >= most_bytes
        if call and (on_its_own or size + weight > most_bytes):
            break
        if index in alone and busy:
            break
        call.append(pending.popleft())
        size += weight
        if on_its_own:
            break
    return call


def died_error(attempts: int, reason: str) -> str:
    """The ``error`` of a unit whose worker died on every attempt."""
    return (f'the worker checking it died on each of {attempts} attempts (last: {reason}); '
            'the recording may exhaust memory or crash the engine: check it alone '
            '(collision_sensor_check FILE) and report it')


def lost_error(times: int) -> str:
    """The ``error`` of a unit whose node was lost each time it was being checked."""
    return (f'the node checking it was lost each of the {times} times it was checked; the '
            'recording may exhaust the node\'s memory: check it alone (collision_sensor_check '
            'FILE) and report it')


@dataclass
class PoolStats:
    """What a run of workers did, for the summary.

    :ivar workers: how many checked at once (at the start).
    :ivar rss: ``{worker: [RSS when ready, RSS after its last unit]}`` in bytes.
    :ivar private: ``{worker: [bytes of its own when ready, after its last call]}``: its
        resident pages not shared with another process (the model is shared by forked
        workers; 0 where the system does not say).
    :ivar retried: units tried again after their worker died.
    :ivar deaths: workers that died.
    :ivar lost_nodes: nodes lost during the run (Ray).
    :ivar rerun: units checked again because their node was lost.
    :ivar nodes: nodes that checked units (Ray; 1 on this machine).
    :ivar start_seconds: from the start of the run until the first worker was ready.
    :ivar driver_cpu: CPU seconds of the driver's process during the run.
    :ivar steady_cpu: those after the first line (what each further unit costs the driver,
        without the start-up).
    :ivar calls: calls sent to workers (Ray).
    """

    workers: int = 0
    rss: Dict[str, List[int]] = field(default_factory=dict)
    private: Dict[str, List[int]] = field(default_factory=dict)
    retried: int = 0
    deaths: int = 0
    lost_nodes: int = 0
    rerun: int = 0
    nodes: int = 1
    start_seconds: float = 0.0
    driver_cpu: float = 0.0
    steady_cpu: float = 0.0
    calls: int = 0
    #: ``{worker: [RSS after each unit]}``, the first TRACE units of each.
    trace: Dict[str, List[int]] = field(default_factory=dict)

    TRACE = 10_000

    def note_rss(self, worker: str, value: int) -> None:
        entry = self.rss.setdefault(worker, [value, value])
        entry[1] = value
        trace = self.trace.setdefault(worker, [])
        if len(trace) < self.TRACE:
            trace.append(value)

    def note_private(self, worker: str, value: int) -> None:
        self.private.setdefault(worker, [value, value])[1] = value


def charge_death(queue: List[int], charged: bool, deaths, alone: set, pending: Deque[int],
                 stats: PoolStats, report_failed: Callable[[int, str], None],
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


def settle_lost(queue: List[int], losses, pending: Deque[int], stats: PoolStats,
                report_failed: Callable[[int, str], None],
                checking: Optional[Container[int]] = None) -> int:
    """Settle the units a lost node held (``queue``, in order): none is charged, all go back
    to the front of ``pending``; a unit in ``checking`` (being checked then, default all)
    whose node is lost for the LOST_LIMIT-th time is reported instead. Return how many were
    reported."""
    back, reported = [], 0
    for index in queue:
        if checking is None or index in checking:
            losses[index] += 1
            if losses[index] >= LOST_LIMIT:
                report_failed(index, lost_error(losses[index]))
                reported += 1
                continue
        back.append(index)
    stats.rerun += len(back)
    pending.extendleft(reversed(back))
    return reported
