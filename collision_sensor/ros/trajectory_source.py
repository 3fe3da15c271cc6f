"""The ``trajectory`` input: planned trajectories checked before they run; valid ones relayed.

The node subscribes ``trajectory`` (``trajectory_msgs/JointTrajectory``, reliable) and checks
each trajectory along the path joint_trajectory_controller will follow
(``CollisionChecker.check_trajectory``, :mod:`collision_sensor.engine.trajectory`: linear,
cubic or quintic between points, segment 0 from the current state at rest, wrap-around for
continuous joints), from the joint state accepted last, with the node's
``joint_limit_tolerance`` for the joint limits along the way. Each trajectory is answered by
one ``diagnostic_msgs/DiagnosticArray`` on ``trajectory_result`` (:data:`RESULT_QOS`: reliable,
transient local, keep last 100), its header the trajectory's, with one status:

- name ``<node>: trajectory``, level OK (valid) or ERROR, message ``valid`` or the reason,
  ``hardware_id`` the root link;
- values ``valid`` (``true``/``false``), ``kind`` (``valid``, ``contact``, ``joint_limits``,
  ``malformed``, ``no_start``, ``oversized``, ``dropped``, ``engine_error``),
  ``first_invalid_segment`` (0: from the start to point 0, i: point i - 1 to point i; empty
  when none), ``time_from_start`` (s, of the first contact or limit violation; empty when
  none), ``link_a``, ``link_b`` (the first pair in contact there; empty when none),
  ``colliding_pairs`` (every pair in contact there, ``a:b`` comma-separated), ``reason``
  (empty when valid), ``points``, ``joints``, ``trajectory_digest`` (:func:`trajectory_digest`
  of the trajectory; empty for one answered undecoded: ``oversized``, ``dropped``, and
  ``malformed`` bytes that do not decode), ``answer_index`` (1 for the node's first answer, then
  one more for each: the trajectory status's ``trajectories_total`` once it is out).

A client matches its answer by the digest, which it computes from what it sent (the header
alone identifies nothing: planners send stamp 0, and a non-zero stamp changes when
joint_trajectory_controller starts the trajectory), and by ``answer_index``, above the node's
``trajectories_total`` before it published (:func:`~collision_sensor.ros.answers.answers_it`).
Answers are kept (transient local), so an answer published before the node's publisher matched
the client's subscription (discovery is not symmetric: the client seeing the node's publisher
does not mean the node sees the client) still reaches it; a client that joins later receives
older answers too, and the index keeps it from taking one of them for its own.

A valid trajectory is then relayed unchanged (the bytes received) on ``trajectory_out``
(reliable), so the node can sit between a planner and a controller's ``joint_trajectory``
topic; an invalid one is never relayed. The start is the state accepted last: with none yet,
joints still missing (``require_all_joints``) or the state stale (``stale_timeout``), the
trajectory is invalid (``no_start``): fail safe. A trajectory above ``max_trajectory_bytes``
serialized is answered ``oversized`` before it is decoded; more than
:data:`MAX_TRAJECTORY_BACKLOG` waiting, the newcomers are answered ``dropped`` at once (nothing
is queued without bound). With ``publish_markers``, ``~/markers`` shows the boxes of the links
in contact at a trajectory's first contact (namespace ``trajectory_contact``, magenta, with a
text naming the time and the pairs) until the next trajectory is answered.

Threads: the executor only takes the bytes; trajectories are decoded and checked in arrival order
on a thread of their own, at a lower priority than the joint states' answers. A check reads the
start state from the sensor and holds the sensor's scene still throughout
(:meth:`~collision_sensor.sensor.Sensor.check_trajectory`): a scene array or a new checker waits
until the trajectory is answered, so a trajectory is checked against one scene and one model;
``check_trajectory`` leaves the carried state alone, so joint states keep being answered.
"""
import array
import collections
import hashlib
import struct
import sys
import time
from typing import Optional

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

from collision_sensor.engine.trajectory import (
    TrajectoryPoint, TrajectoryResult, build_segments)
from collision_sensor.ros.input_source import InputSource
from collision_sensor.ros.work_queue import BACKGROUND_NICE, NewestFirstWorker
from collision_sensor.sensor.model import root_link
from collision_sensor.untrusted_text import listing, printable

#: ``trajectory``: reliable, volatile (a trajectory is not for late joiners), keep last 100: a
#: burst of that many is taken (the executor only hands the bytes over; the excess is answered
#: ``dropped``), and what the middleware reports lost beyond it is counted (``lost_total``).
TRAJECTORY_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                            reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.VOLATILE)
#: ``trajectory_out``: reliable, volatile, as a controller's ``joint_trajectory`` subscription.
RELAY_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: ``trajectory_result``: reliable, transient local (an answer given before the node's
#: publisher matched the client's subscription still reaches it; a client tells its own from older
#: ones by the digest and the answer's index), keep last 100 (the ``trajectory`` subscription's
#: depth: a burst is answered whole).
RESULT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Trajectories that may wait to be checked; more are answered ``dropped`` at once.
MAX_TRAJECTORY_BACKLOG = 10
#: Longest reason in a result (characters).
MAX_REASON_CHARS = 1000
#: What ``kind`` says (see the module docstring).
KINDS = ('valid', 'contact', 'joint_limits', 'malformed', 'no_start', 'oversized', 'dropped',
         'engine_error')


def header_of(data: bytes) -> Header:
    """Read ``header`` from a serialized message (CDR: 4 bytes of encapsulation, then stamp
    sec int32, nanosec uint32, frame_id as uint32 length + bytes + NUL)."""
    header = Header()
    try:
        order = '<' if data[1] == 1 else '>'
        sec, nanosec, length = struct.unpack_from(order + 'iII', data, 4)
        header.stamp.sec, header.stamp.nanosec = sec, nanosec
        if 0 < length <= 257:
            header.frame_id = printable(data[16:16 + length - 1].decode('utf-8', 'replace'), 256)
    except (IndexError, struct.error, ValueError, AssertionError):
        pass
    return header


class Oversized:
    """A trajectory above ``max_trajectory_bytes``, left undecoded: answered by its header.

    :ivar size: its serialized size in bytes.
    """

    __slots__ = ('size', 'header')

    def __init__(self, data: bytes):
        self.size = len(data)
        self.header = header_of(data)


class Dropped:
    """A trajectory that arrived while :data:`MAX_TRAJECTORY_BACKLOG` waited: answered, never
    decoded."""

    __slots__ = ('header',)

    def __init__(self, data: bytes):
        self.header = header_of(data)


_COUNT = struct.Struct('<I')
_TIME = struct.Struct('<iI')


def _float64s(values) -> bytes:
    """``values`` as float64 little-endian (rclpy's arrays of float64 as they are)."""
    if isinstance(values, array.array) and values.typecode == 'd' and sys.byteorder == 'little':
        return values.tobytes()
    return struct.pack(f'<{len(values)}d', *values)


def trajectory_digest(msg: JointTrajectory) -> str:
    """Return the identifier of a trajectory's answer (``trajectory_digest``): the SHA-256, in
    hex, of every field of ``msg`` in the message's order, with integers as 4 bytes
    little-endian, a string as its UTF-8 length (uint32) then its bytes, and an array as its
    length (uint32) then its items (float64 little-endian)::

        header.stamp.sec (int32), header.stamp.nanosec (uint32), header.frame_id,
        len(joint_names), each name, len(points), for each point: positions, velocities,
        accelerations, effort, time_from_start.sec (int32), time_from_start.nanosec (uint32)

    A client computes it from the message it sends (not from serialized bytes: rclpy's
    ``serialize_message`` leaves the CDR padding undefined).
    """
    def text(value: str) -> bytes:
        data = value.encode('utf-8')
        return _COUNT.pack(len(data)) + data

    stamp = msg.header.stamp
    parts = [_TIME.pack(stamp.sec, stamp.nanosec), text(msg.header.frame_id),
             _COUNT.pack(len(msg.joint_names))]
    parts += [text(name) for name in msg.joint_names]
    parts.append(_COUNT.pack(len(msg.points)))
    for point in msg.points:
        for values in (point.positions, point.velocities, point.accelerations, point.effort):
            parts.append(_COUNT.pack(len(values)))
            parts.append(_float64s(values))
        parts.append(_TIME.pack(point.time_from_start.sec, point.time_from_start.nanosec))
    return hashlib.sha256(b''.join(parts)).hexdigest()


def points_of(msg: JointTrajectory) -> list:
    """Return the trajectory's points as ``TrajectoryPoint``\\ s (the engine validates them)."""
    return [TrajectoryPoint(point.time_from_start.sec + 1e-9 * point.time_from_start.nanosec,
                            point.positions, point.velocities, point.accelerations)
            for point in msg.points]


def kind_of(result: TrajectoryResult) -> str:
    """Return the ``kind`` of an engine answer."""
    if result.valid:
        return 'valid'
    if result.colliding_pairs:
        return 'contact'
    return 'joint_limits' if result.first_invalid_segment is not None else 'malformed'


def boxes_at(checker, q, names) -> list:
    """Return ``checker.collision_boxes(names)`` as they are at the state ``q``, without moving
    the carried state: each box of a link (or of an object attached to it) moved by the link's
    motion from the carried state to ``q`` (forward kinematics at both); world objects' boxes
    as they are (lock held: the carried poses are read).

    :param q: ``(J,)`` in the order of ``checker.joint_names``.
    """
    kinematics = checker.kinematics
    index = {name: i for i, name in enumerate(kinematics.link_names)}
    now = np.fromiter(checker.positions.values(), dtype=np.float64,
                      count=len(checker.joint_names))
    T_now, T_then = kinematics.forward_kinematics(now), kinematics.forward_kinematics(q)
    attached = checker.attachments
    boxes = []
    for name, T_world_box, half in checker.collision_boxes(names):
        link = name if name in index else attached.get(name, (None,))[0]
        if link is not None:
            k = index[link]
            T_world_box = T_then[k] @ np.linalg.inv(T_now[k]) @ T_world_box
        boxes.append((name, T_world_box, half))
    return boxes


class TrajectorySource(InputSource):
    """Planned trajectories: subscription, size bound, the check, the answer and the relay.

    :param node: the node the subscription and publishers belong to.
    :param sensor: the :class:`~collision_sensor.sensor.Sensor` that checks.
    :param settings: the node's settings (``max_trajectory_bytes``).
    :param log: the node's :class:`~collision_sensor.ros.node_log.NodeLog`.
    :param markers: the node's :class:`~collision_sensor.ros.markers.MarkerPublisher`.
    """

    name = 'trajectory'

    def __init__(self, node, sensor, settings, log, markers):
        self._node, self._sensor, self._log, self._markers = node, sensor, log, markers
        self._worker: Optional[NewestFirstWorker] = None
        self._result_pub = self._relay_pub = None
        self._max_bytes = settings.max_trajectory_bytes
        self.counts = collections.Counter()
        self.last = ('', '')     # the last answer's (kind, reason)
        self.problems = 0        # oversized, dropped or failed since the last status
        self.check_time_max = 0.0

    def start(self) -> None:
        node = self._node
        self._result_pub = node.create_publisher(
            DiagnosticArray, 'trajectory_result', RESULT_QOS,
            event_callbacks=PublisherEventCallbacks(
                incompatible_qos=self._on_incompatible_result_qos, use_default_callbacks=False))
        self._relay_pub = node.create_publisher(JointTrajectory, 'trajectory_out', RELAY_QOS)
        self._worker = NewestFirstWorker(self._check_batch, 'trajectory checker', None,
                                         nice=BACKGROUND_NICE)
        node.create_subscription(
            JointTrajectory, 'trajectory', self._take, TRAJECTORY_QOS, raw=True,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=self._on_message_lost, incompatible_qos=self._on_incompatible_qos,
                use_default_callbacks=False))

    def close(self) -> None:
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    # -- the executor's thread ----------------------------------------------------------------

    def _take(self, data: bytes) -> None:
        """Hand a trajectory's bytes to the checking thread, which decodes them (decoding a few
        thousand points takes milliseconds: not on the executor's thread); above the size
        bound or the backlog, a placeholder answered in its turn."""
        if len(data) > self._max_bytes:
            item = Oversized(data)
        elif self._worker.backlog() >= MAX_TRAJECTORY_BACKLOG:
            item = Dropped(data)
        else:
            item = data
        self._worker.put(item)

    def _on_message_lost(self, info) -> None:
        self.counts['lost'] += info.total_count_change
        self.problems += 1
        self._log.warn('trajectory_lost', f'{info.total_count_change} trajectories lost before '
                      f'the node took them ({info.total_count} in all): never answered; send '
                      'fewer at once (counted as lost_total on the trajectory status)')

    def _on_incompatible_qos(self, event) -> None:
        self._log.warn(
            'trajectory_qos', 'a publisher of trajectory offers a QoS this subscription cannot '
            f'match (policy {event.last_policy_kind}); its trajectories are never received. '
            'Publish reliable')

    def _on_incompatible_result_qos(self, event) -> None:
        self._log.warn(
            'trajectory_result_qos', 'a subscriber of trajectory_result asks for a QoS it does '
            f'not offer (policy {event.last_policy_kind}); it receives no answer. Answers are '
            'reliable, transient local, keep last 100: subscribe with that or less')

    # -- the checking thread ------------------------------------------------------------------

    def _check_batch(self, batch: list, _newest_only: bool) -> None:
        for item in batch:
            notes = []
            try:
                self._answer(item, notes)
            except Exception as error:  # noqa: B902 - one trajectory must never stop the node
                if not self._node.context.ok():
                    return
                notes.append(('error', None, 'trajectory skipped after an internal error: '
                              f'{printable(repr(error), 300)}'))
            self._log.write(notes)

    def _answer(self, item, notes: list) -> None:
        """Check one trajectory (or answer a placeholder), publish its result, relay it when
        valid."""
        if isinstance(item, Oversized):
            self._publish(item.header, 'oversized', None, (
                f'{item.size} bytes, above max_trajectory_bytes ({self._max_bytes}); raise the '
                'parameter if the planner\'s trajectories are really that large, or send fewer '
                'points'), notes)
            return
        if isinstance(item, Dropped):
            self._publish(item.header, 'dropped', None, (
                f'{MAX_TRAJECTORY_BACKLOG} trajectories waited to be checked already; send '
                'them one at a time'), notes)
            return
        data = item
        try:
            msg = deserialize_message(data, JointTrajectory)
        except Exception as error:  # noqa: B902 - whatever the bytes, answered
            self._publish(header_of(data), 'malformed', None, 'the message could not be '
                          f'decoded: {printable(repr(error), 300)}', notes)
            return
        points = points_of(msg)
        names = list(msg.joint_names)
        size = (len(points), len(names))
        digest = trajectory_digest(msg)
        started = time.perf_counter()
        sensor = self._sensor
        with sensor.editing() as checker:
            try:
                result, why = sensor.check_trajectory(names, points)
            except Exception as error:  # noqa: B902 - answered, never relayed
                self._publish(msg.header, 'engine_error', None, 'the check failed: '
                              f'{printable(repr(error), 300)}', notes, size, digest)
                return
            if result is None:
                self._publish(msg.header, 'no_start', None, why, notes, size, digest)
                return
            elapsed = time.perf_counter() - started
            self.check_time_max = max(self.check_time_max, elapsed)
            if self._markers.enabled:
                try:
                    start, _ = sensor.start_state()
                    self._show_contact(checker, msg, names, points, start, result)
                except Exception as error:  # noqa: B902 - the answer goes out regardless
                    notes.append(('warning', 'trajectory_markers', 'trajectory markers '
                                  f'skipped after an error: {printable(repr(error), 300)}'))
        if result.valid:
            self._relay_pub.publish(data)   # the bytes received: unchanged
        self._publish(msg.header, kind_of(result), result, printable(result.reason,
                                                                    MAX_REASON_CHARS), notes,
                      size, digest)

    def _show_contact(self, checker, msg, names, points, start, result) -> None:
        """Show on ``~/markers`` the boxes of the pairs in contact at the first contact, or
        clear the last trajectory's (a trajectory without contact)."""
        boxes, text = [], ''
        if result.colliding_pairs:
            q_start = np.array([start[name] for name in checker.joint_names])
            coef, _ = build_segments(checker, names, points, q_start)
            i = result.first_invalid_segment
            u = checker.check_spline(coef[i:i + 1]).motion.first_contact
            q = np.polynomial.polynomial.polyval(u, coef[i].T)
            linked = sorted({name for pair in result.colliding_pairs for name in pair})
            text = printable(f'trajectory: first contact at {result.time_from_start:.3f} s '
                             f'(segment {i}): ' + ', '.join(f'{a}:{b}' for a, b
                                                            in result.colliding_pairs), 300)
        with self._sensor.changing():
            if not self._markers.enabled or self._sensor.checker is not checker:
                return
            if text:
                boxes = boxes_at(checker, q, linked)
            self._markers.trajectory_contact(boxes, msg.header.stamp, text)

    def _publish(self, header, kind: str, result: Optional[TrajectoryResult], reason: str,
                 notes: list, size=(0, 0), digest: str = '') -> None:
        """Publish the one status answering a trajectory (``digest``: its
        :func:`trajectory_digest`, '' when undecoded); log an invalid one (throttled)."""
        checker = self._sensor.checker
        root = root_link(checker) if checker is not None else ''
        valid = kind == 'valid'
        segment = result.first_invalid_segment if result is not None else None
        at = result.time_from_start if result is not None else None
        pairs = result.colliding_pairs if result is not None else ()
        if len(reason) > MAX_REASON_CHARS:
            reason = reason[:MAX_REASON_CHARS - 3] + '...'
        values = {
            'valid': str(valid).lower(),
            'kind': kind,
            'first_invalid_segment': '' if segment is None else str(segment),
            'time_from_start': '' if at is None else f'{at:.9g}',
            'link_a': pairs[0][0] if pairs else '',
            'link_b': pairs[0][1] if pairs else '',
            'colliding_pairs': listing((f'{a}:{b}' for a, b in pairs), total=len(pairs)),
            'reason': reason,
            'points': str(size[0]),
            'joints': str(size[1]),
            'trajectory_digest': digest,
            'answer_index': str(self.counts['trajectories'] + 1),
        }
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK if valid else DiagnosticStatus.ERROR,
            name=f'{self._node.get_fully_qualified_name().lstrip("/")}: trajectory',
            message='valid' if valid else reason, hardware_id=root,
            values=[KeyValue(key=key, value=value) for key, value in values.items()])
        self._result_pub.publish(DiagnosticArray(header=header, status=[status]))
        counts = self.counts
        counts['trajectories'] += 1
        counts[kind] += 1
        counts['relayed'] += valid
        if kind in ('oversized', 'dropped', 'engine_error'):
            self.problems += 1
        self.last = (kind, reason)
        if not valid:
            notes.append(('warning', f'trajectory_{kind}',
                          f'trajectory refused ({kind}), not relayed: {reason}'))

    # -- diagnostics --------------------------------------------------------------------------

    def status(self, now: float) -> Optional[DiagnosticStatus]:
        """The ``trajectory`` status on /diagnostics, once the source started."""
        if self._result_pub is None:
            return None
        counts = self.counts
        checker = self._sensor.checker
        kind, reason = self.last
        level, message = DiagnosticStatus.OK, 'no trajectory yet'
        if kind:
            message = 'last trajectory valid, relayed' if kind == 'valid' else \
                f'last trajectory refused ({kind}): {reason}'
        if self.problems:
            level = DiagnosticStatus.WARN
            message = (f'{self.problems} trajectories oversized, dropped, lost or failed; '
                       f'{message}')
        self.problems = 0
        values = {
            'trajectories_total': str(counts['trajectories']),
            'relayed_total': str(counts['relayed']),
            'lost_total': str(counts['lost']),
            **{f'{k}_total': str(counts[k]) for k in KINDS},
            'last_kind': kind,
            'last_reason': reason,
            'check_time_max_ms': f'{1e3 * self.check_time_max:.3f}',
            'max_trajectory_bytes': str(self._max_bytes),
            'waiting': str(self._worker.backlog() if self._worker is not None else 0),
        }
        return DiagnosticStatus(
            level=level, name=f'{self._node.get_fully_qualified_name().lstrip("/")}: trajectory',
            message=printable(message, 1000),
            hardware_id=printable(root_link(checker) if checker is not None else ''),
            values=[KeyValue(key=key, value=value) for key, value in values.items()])
