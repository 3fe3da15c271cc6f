"""The warning zone (``warning_distance`` > 0): ``near``, ``min_distance`` and ``near_pairs``
after every verdict, as nav2's collision monitor slows down before it stops.

With every verdict, for the same input: ``near`` (``std_msgs/Bool``: some checked pair is nearer
than ``warning_distance``), ``min_distance`` (``std_msgs/Float64``: the smallest padded distance
of those pairs, <= 0 in contact; ``inf`` when no pair is that near) and ``near_pairs``
(``diagnostic_msgs/DiagnosticArray``, the input's header; one status per such pair, nearest
first: level ERROR in contact, else WARN; name ``link_a:link_b``; values ``link_a``, ``link_b``,
``distance`` (m) and ``point_a``, ``point_b``, the nearest points as "x y z" in metres in the
robot's root link frame, also its ``hardware_id``): :meth:`CollisionChecker.proximity` at
``max_distance = warning_distance``. Pairs named in ``warning_ignore`` are left out.

A fail-safe answer (see :mod:`collision_sensor.ros.verdicts`) is followed here too: with policy
``contact``, ``near`` true, ``min_distance`` ``-inf`` (not a distance: no comparison says
"far") and ``near_pairs`` the failure entry; with ``hold``, the last state's values, the failure
entry first.

At start-up (and for each new model) the pairs nearer than ``warning_distance`` wherever the
robot goes are named, with the fix: sampled as the exception-list tool samples
(:func:`~collision_sensor.engine.sampling.pairs_near_everywhere`).
"""
import math
from typing import FrozenSet, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Bool, Float64

from collision_sensor.ros.verdicts import HOLD, VERDICT_QOS

Pair = Tuple[str, str]


def _xyz(point) -> str:
    """A point as "x y z" (metres, 9 significant digits)."""
    return ' '.join(f'{float(v):.9g}' for v in point)


class WarningZone:
    """Publish the warning zone's topics (call everything with the node's lock held).

    :param node: the node that owns the publishers.
    :param distance: ``warning_distance`` (m); 0: off, nothing advertised.
    :param ignore: pairs left out (``warning_ignore``), each sorted.
    """

    def __init__(self, node, distance: float, ignore: FrozenSet[Pair] = frozenset()):
        self._node = node
        self.distance = 0.0
        self.ignore = ignore
        self.root_frame = ''
        self._publishers = None
        self._near_msgs = (Bool(data=False), Bool(data=True))
        self._held: Optional[tuple] = None   # (near, min_distance, statuses) of the last state
        self.configure(distance, ignore)

    @property
    def enabled(self) -> bool:
        return self._publishers is not None

    def configure(self, distance: float, ignore: FrozenSet[Pair]) -> None:
        """Set ``warning_distance`` and ``warning_ignore``: advertise the topics when the zone
        turns on, withdraw them when it turns off (0)."""
        node = self._node
        if distance > 0 and self._publishers is None:
            self._publishers = (
                node.create_publisher(Bool, 'near', VERDICT_QOS),
                node.create_publisher(Float64, 'min_distance', VERDICT_QOS),
                node.create_publisher(DiagnosticArray, 'near_pairs', VERDICT_QOS))
        elif distance <= 0 and self._publishers is not None:
            for publisher in self._publishers:
                node.destroy_publisher(publisher)
            self._publishers = None
        if distance != self.distance or ignore != self.ignore:
            self._held = None
        self.distance, self.ignore = distance, ignore

    def forget(self, root_frame: str) -> None:
        """A new model: no state of it measured yet."""
        self.root_frame = root_frame
        self._held = None

    def measure(self, checker, positions) -> list:
        """Return the ``ProximityRecord``\\ s of the pairs nearer than ``warning_distance`` at
        ``positions`` (the state just checked: proximity re-checks nothing, it measures),
        without the ignored pairs."""
        records = checker.proximity(positions, self.distance)
        if self.ignore:
            ignore = self.ignore
            records = [r for r in records if (r.link_a, r.link_b) not in ignore]
        return records

    def publish(self, header, records) -> None:
        """Publish ``near``, ``min_distance`` and ``near_pairs`` for ``records``."""
        near, minimum, pairs = self._publishers
        statuses = [self._status(r) for r in records]
        held = (bool(records), float(records[0].distance) if records else math.inf, statuses)
        self._held = held
        near.publish(self._near_msgs[held[0]])
        minimum.publish(Float64(data=held[1]))
        pairs.publish(DiagnosticArray(header=header, status=statuses))

    def publish_held(self, header) -> None:
        """Publish the last state's values again, answering ``header``."""
        if self._held is not None:
            self._publish(header, *self._held)

    def publish_failure(self, header, entry: DiagnosticStatus, policy: str) -> None:
        """Follow a fail-safe verdict (see the module docstring)."""
        if policy == HOLD and self._held is not None:
            near, minimum, statuses = self._held
            self._publish(header, near, minimum, [entry] + statuses)
        else:
            self._publish(header, True, -math.inf, [entry])

    def _publish(self, header, near: bool, minimum: float, statuses: list) -> None:
        near_pub, minimum_pub, pairs_pub = self._publishers
        near_pub.publish(self._near_msgs[near])
        minimum_pub.publish(Float64(data=minimum))
        pairs_pub.publish(DiagnosticArray(header=header, status=statuses))

    def _status(self, record) -> DiagnosticStatus:
        """One ``near_pairs`` entry (see the module docstring)."""
        a, b, distance = record.link_a, record.link_b, float(record.distance)
        message = (f'{a} is in contact with {b} ({distance:.4f} m)' if distance <= 0
                   else f'{a} is {distance:.4f} m from {b}')
        return DiagnosticStatus(
            level=DiagnosticStatus.ERROR if distance <= 0 else DiagnosticStatus.WARN,
            name=f'{a}:{b}', message=message, hardware_id=self.root_frame,
            values=[KeyValue(key='link_a', value=a), KeyValue(key='link_b', value=b),
                    KeyValue(key='distance', value=repr(distance)),
                    KeyValue(key='point_a', value=_xyz(record.point_a)),
                    KeyValue(key='point_b', value=_xyz(record.point_b))])


def near_everywhere_notes(checker, distance: float, ignore: FrozenSet[Pair]) -> List[tuple]:
    """Name the pairs nearer than ``distance`` wherever the robot goes, with the fix (log notes,
    see :mod:`collision_sensor.ros.node_log`); nothing when there are none.

    Runs :func:`pairs_near_everywhere` on ``checker``: call it on a checker not in use yet.
    """
    if distance <= 0:
        return []
    # Imported here: sampling brings numpy.random (2 MiB) that a node without a zone never uses.
    from collision_sensor.engine.sampling import (
        NEAR_FRACTION, NEAR_SAMPLES, pairs_near_everywhere)
    found = [pair for pair in pairs_near_everywhere(checker, distance)
             if (pair.link_a, pair.link_b) not in ignore]
    if not found:
        return []
    samples = found[0].samples
    listed = ', '.join(f'{p.link_a}:{p.link_b} ({p.largest:.4f} m at most'
                       + ('' if p.near == p.samples else f', near in {p.near} of {p.samples}')
                       + ')' for p in found)
    entries = ', '.join(f'"{p.link_a}:{p.link_b}"' for p in found)
    return [('warning', None, (
        f'warning zone: {len(found)} pair(s) nearer than warning_distance {distance:g} m '
        f'wherever the robot goes (in at least {NEAR_FRACTION:.0%} of {samples} configurations '
        f'sampled: the neutral one and {NEAR_SAMPLES} uniform within the joint limits), so near '
        f'would be true all the time: {listed}. Leave them out of the zone with the parameter '
        f'warning_ignore: [{entries}], or lower warning_distance below their distance'))]
