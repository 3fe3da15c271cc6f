"""The verdict topics, ``contact`` and ``colliding_pairs``, and the fail-safe answers.

A verdict is one ``contact`` (``std_msgs/Bool``) and then one ``colliding_pairs``
(``diagnostic_msgs/DiagnosticArray``, the answered input's header; one status per colliding
pair, level ERROR, name ``link_a:link_b``, values ``link_a``, ``link_b``).

With ``check_motion`` (:mod:`.motion_stream`) the verdict covers the motion from the previous
state: ``contact`` is true if any state on the way is in contact. The pairs in contact at the
state itself come first, as above (in contact now); then one status per pair met on the way
and not in contact now (the pairs in contact at the motion's first contact), level ERROR, name
``link_a:link_b``, message ``link_a met link_b on the way, at 0.42 of the motion``, values
``link_a``, ``link_b`` and ``first_contact`` (the fraction of the motion from the previous
state, in [0, 1]). A subscriber tells the two apart by the ``first_contact`` key: only pairs met
on the way have it.

When the node cannot say where the robot is, or cannot check it, it answers with a failure entry
instead: a ``colliding_pairs`` status whose name has no ``:`` (one of :data:`FAILURE_KINDS`),
level ERROR, the reason as its message, values ``kind``, ``reason`` and ``policy``. What
``contact`` says then is the policy's choice (parameters ``on_rejected_input``,
``on_engine_error``, ``stale_policy``), one of :data:`FAIL_SAFE_POLICIES`:

- ``contact``: ``contact`` true, ``colliding_pairs`` the failure entry alone: the node does not
  know that the robot is clear, so it does not say so;
- ``hold``: ``contact`` repeats the verdict of the last state checked (the state the node holds:
  an input it could not take changed nothing), ``colliding_pairs`` the failure entry, then that
  verdict's pairs. With no state checked yet there is nothing to hold: as ``contact``.
"""
from typing import Optional, Tuple

from collision_sensor.model.point_cloud_message import write_stamp
from collision_sensor.ros.motion_stream import NO_MOTION, MotionVerdict

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool

# The values of on_rejected_input, on_engine_error and stale_policy.
from collision_sensor.ros.node_parameters import CONTACT, FAIL_SAFE_POLICIES, HOLD  # noqa: F401
from collision_sensor.ros.work_queue import MAX_INPUT_RATE

#: Verdicts and the robot description: late joiners get the latest message.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: The verdict history that covers 0.1 s of input at ``MAX_INPUT_RATE``: a reliable subscriber
#: 0.1 s behind still gets every verdict.
VERDICT_DEPTH = int(0.1 * MAX_INPUT_RATE)
VERDICT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=VERDICT_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


#: Failure entries in ``colliding_pairs`` (their status names).
REJECTED = 'joint_state_rejected'     # a joint state the node refused (on_rejected_input)
WAITING = 'waiting_for_joints'        # no state to check yet (on_rejected_input)
ENGINE_ERROR = 'engine_error'         # the engine failed on this state (on_engine_error)
STALE = 'joint_states_stale'          # no joint state for stale_timeout (stale_policy)
FAILURE_KINDS = (REJECTED, WAITING, ENGINE_ERROR, STALE)


#: Longest reason in a failure entry (characters).
MAX_REASON_CHARS = 1000


def failure_status(kind: str, reason: str, policy: str, root_frame: str) -> DiagnosticStatus:
    """Return a failure entry of ``colliding_pairs`` (see the module docstring).

    :param reason: text safe to show already (built from
        :mod:`~collision_sensor.untrusted_text` parts: a flood of refused messages must not
        cost an escape each); only cut here.
    """
    if len(reason) > MAX_REASON_CHARS:
        reason = reason[:MAX_REASON_CHARS - 3] + '...'
    return DiagnosticStatus(level=DiagnosticStatus.ERROR, name=kind, message=reason,
                            hardware_id=root_frame,
                            values=[KeyValue(key='kind', value=kind),
                                    KeyValue(key='reason', value=reason),
                                    KeyValue(key='policy', value=policy)])


class VerdictPublisher:
    """Publish ``contact`` and ``colliding_pairs`` (call with the node's lock held).

    :param node: the node that owns the publishers.
    :ivar held: the verdict of the last state checked, ``(in_collision, colliding pairs,
        MotionVerdict)``, or None before one (or since a new model).
    """

    def __init__(self, node):
        self._contact_pub = node.create_publisher(Bool, 'contact', VERDICT_QOS)
        self._pairs_pub = node.create_publisher(DiagnosticArray, 'colliding_pairs', VERDICT_QOS)
        # Published serialized (rclpy converts a message from Python on every publish: 15 us
        # for an empty DiagnosticArray, 38 us with three pairs; the bytes take 5 us): the
        # contacts once and for all, the pairs' message when the colliding set or the
        # header's frame changes, the stamp written in place for each verdict.
        self._contact_raw = tuple(serialize_message(Bool(data=v)) for v in (False, True))
        self._pairs_msg = DiagnosticArray()
        self._pairs_raw = None      # bytearray of _pairs_msg, serialized with _raw_frame
        self._raw_frame = None
        self._last_pairs = None
        self.root_frame = ''
        self.held: Optional[Tuple[bool, tuple, MotionVerdict]] = None

    def forget(self, root_frame: str) -> None:
        """A new model: no state of it checked yet."""
        self.root_frame = root_frame
        self._last_pairs = None
        self.held = None

    def publish(self, header, result, motion: MotionVerdict = NO_MOTION) -> None:
        """Publish the verdict ``result`` (a ``CheckResult``) answering ``header``; ``motion``:
        what the motion to it met on the way (see the module docstring)."""
        pairs = result.colliding_pairs
        in_collision = bool(result.in_collision) or motion.in_collision
        self._contact_pub.publish(self._contact_raw[in_collision])
        key = (pairs, motion.met and motion)
        if key != self._last_pairs:
            self._last_pairs = key
            self._pairs_msg.status = self._pair_statuses(pairs, motion)
            self._pairs_raw = None
            self.held = (in_collision, pairs, motion)
        self._publish_pairs(header)

    def publish_held(self, header) -> bool:
        """Publish the held verdict again, answering ``header``; return False (nothing
        published) when there is none."""
        if self.held is None:
            return False
        in_collision = self.held[0]
        self._contact_pub.publish(self._contact_raw[in_collision])
        self._publish_pairs(header)
        return True

    def _publish_pairs(self, header) -> None:
        """Publish ``_pairs_msg`` answering ``header``."""
        if self._pairs_raw is None or header.frame_id != self._raw_frame:
            self._pairs_msg.header = header
            self._pairs_raw = bytearray(serialize_message(self._pairs_msg))
            self._raw_frame = header.frame_id
        write_stamp(self._pairs_raw, header.stamp.sec, header.stamp.nanosec)
        self._pairs_pub.publish(bytes(self._pairs_raw))

    def publish_failure(self, header, entry: DiagnosticStatus, policy: str) -> bool:
        """Answer ``header`` with the failure ``entry`` by ``policy``; return the ``contact``
        published."""
        if policy == HOLD and self.held is not None:
            in_collision, pairs, motion = self.held
            statuses = [entry] + self._pair_statuses(pairs, motion)
        else:
            in_collision, statuses = True, [entry]
        self._contact_pub.publish(self._contact_raw[in_collision])
        self._pairs_pub.publish(DiagnosticArray(header=header, status=statuses))
        return in_collision

    def _pair_statuses(self, pairs, motion: MotionVerdict = NO_MOTION) -> list:
        root = self.root_frame
        statuses = [DiagnosticStatus(level=DiagnosticStatus.ERROR, name=f'{a}:{b}',
                                     message=f'{a} collides with {b}', hardware_id=root,
                                     values=[KeyValue(key='link_a', value=a),
                                             KeyValue(key='link_b', value=b)])
                    for a, b in pairs]
        if motion.met:
            at = f'{motion.first_contact:.6g}'
            statuses.extend(
                DiagnosticStatus(level=DiagnosticStatus.ERROR, name=f'{a}:{b}',
                                 message=f'{a} met {b} on the way, at {at} of the motion',
                                 hardware_id=root,
                                 values=[KeyValue(key='link_a', value=a),
                                         KeyValue(key='link_b', value=b),
                                         KeyValue(key='first_contact', value=at)])
                for a, b in motion.met)
        return statuses
