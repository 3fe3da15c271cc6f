"""The ``joint_states`` input: the robot's state, merged from partial messages; every message
answered.

The executor's raw callback (:func:`joint_state_taker`) decodes a message of at most
``max_joint_state_bytes`` and hands it to the checking thread
(:class:`~collision_sensor.ros.work_queue.NewestFirstWorker`), which merges it
(:class:`~collision_sensor.ros.joint_state_merger.JointStateMerger`), checks the merged state and
publishes the verdict, under the node's lock. Every message is answered, in input order:

- accepted and the state complete: the verdict of the merged state;
- rejected (malformed, beyond its limits, above ``max_joint_state_bytes``, refused by the
  engine): a ``joint_state_rejected`` entry naming the reason, ``contact`` by
  ``on_rejected_input`` (:mod:`collision_sensor.ros.verdicts`); the state is unchanged;
- accepted while joints are still missing (``require_all_joints``), or ignored before any state
  was checked: a ``waiting_for_joints`` entry, ``contact`` by ``on_rejected_input``;
- ignored (no positions, or no joint of the robot named) once a state was checked: that state's
  verdict again (nothing changed);
- the engine fails: an ``engine_error`` entry, ``contact`` by ``on_engine_error``; the merge is
  undone, whatever the error, and the next state is checked from scratch.

Under overload (more than ``MAX_BACKLOG`` waiting, ``overload_policy: newest``) every message is
still merged, but only the newest accepted state is answered (or, if none was accepted, the
newest message); the others are counted as ``skipped_superseded``.

Timeout: no accepted joint state for ``stale_timeout`` (after the first) is a stale episode:
/diagnostics ERROR, and with ``stale_policy: contact`` a ``joint_states_stale`` answer
(``contact`` true); logged once per episode, with the episode count, at most once per
:data:`STALE_REPORT_PERIOD` (a planner that pauses makes many).
"""
import struct
import time
from typing import Callable, Dict, Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, DurabilityPolicy
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from collision_sensor.errors import JointStateError
from collision_sensor.ros.input_source import InputSource, Timeout
from collision_sensor.ros.joint_state_merger import JointStateMerger, joints_out_of_limits
from collision_sensor.ros.joint_state_window import JointStateWindow
from collision_sensor.ros.verdicts import REJECTED, STALE, WAITING
from collision_sensor.ros.work_queue import MAX_BACKLOG, NewestFirstWorker
from collision_sensor.untrusted_text import listing, printable, quoted

#: ``joint_states_qos: reliable``: every message checked, none dropped. KEEP_ALL, because a
#: reliable reader acknowledges a message once it is in its history, not once it is taken: with
#: KEEP_LAST depth N a publisher that waits for acknowledgements (``collision_sensor_play
#: --as-fast-as-possible``) still overruns the node whenever the node falls N messages behind.
#: KEEP_ALL makes the writer wait instead (DDS flow control), so replay is lossless.
RELIABLE_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.VOLATILE)
JOINT_STATES_QOS = {'sensor_data': qos_profile_sensor_data, 'reliable': RELIABLE_INPUT_QOS}
#: s between two log lines about stale episodes (and between two about resumed ones).
STALE_REPORT_PERIOD = 30.0


class Oversized:
    """A message above its size limit (``max_joint_state_bytes``, ``max_trajectory_bytes``),
    left undecoded; any message type that starts with a ``std_msgs/Header``.

    :ivar size: its serialized size in bytes.
    :ivar header: its header, read from the first bytes (stamp, and frame up to 256 bytes), so
        that its answer names it; an empty header if they cannot be read.
    """

    __slots__ = ('size', 'header')

    def __init__(self, data: bytes):
        self.size = len(data)
        self.header = header_of(data)


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


def joint_state_taker(put: Callable[[object], None], max_bytes: int) -> Callable[[bytes], None]:
    """Return the raw joint_states callback: decode a message of at most ``max_bytes`` and
    ``put`` it, or ``put`` an :class:`Oversized` in its place (so it is answered, in order).

    Taking the serialized bytes keeps a flood of huge messages (10^4 names each) from being
    decoded into Python objects at all; the check is one ``len``.
    """
    def take(data: bytes) -> None:
        put(Oversized(data) if len(data) > max_bytes else deserialize_message(data, JointState))
    return take


def _bound(value) -> str:
    return 'none' if value is None else f'{value:.6g}'


class JointStateSource(InputSource):
    """Joint states: subscription, merging and validation, the answer to each, staleness.

    :ivar merger: the merged state (None before the first model).
    """

    name = 'joint_states'

    def __init__(self, host):
        super().__init__(host)
        self.merger: Optional[JointStateMerger] = None
        self.limits: Dict[str, tuple] = {}
        self.out_of_limits: Dict[str, tuple] = {}
        self.last_accepted: Optional[float] = None    # time.monotonic() of the last one
        self.stale = False
        self.stale_episodes = 0
        self._stale_since = 0.0
        self._announced_waiting = False
        self._unchecked = []    # (message, outcome) merged but superseded since the last check
        self._worker: Optional[NewestFirstWorker] = None
        self.subscription = None
        # The complete states accepted, by stamp: what a point cloud is self-filtered with.
        self.window = JointStateWindow(host.settings.point_cloud_state_window)

    # -- set-up -----------------------------------------------------------------------------

    def start(self) -> None:
        host = self.host
        settings = host.settings
        # Public rclpy only: the executor takes each message and the callback hands it to the
        # checking thread; the group of its own lets a multi-threaded executor take joint
        # states while the diagnostics timer or a model install runs. Middleware-reported
        # losses are counted, and a publisher that can never be heard is named.
        self._worker = NewestFirstWorker(
            self.take_batch, 'joint_states checker',
            None if settings.overload_policy == 'every' else MAX_BACKLOG)
        self.subscription = host.create_subscription(
            JointState, 'joint_states',
            joint_state_taker(self._worker.put, settings.max_joint_state_bytes),
            JOINT_STATES_QOS[settings.joint_states_qos], raw=True,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=self._on_message_lost, incompatible_qos=self._on_incompatible_qos,
                use_default_callbacks=False))

    def close(self) -> None:
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    def prepare_model(self, checker, stack):
        """Carry the merged state over to ``checker``'s joints (joints it shares keep their
        value); variables of planar and floating joints start at their neutral values."""
        derived = _mimic_joints(checker)
        limits = dict(checker.joint_limits)
        settings = self.host.settings

        def commit(notes: list) -> None:
            if self.merger is not None:
                merger = self.merger.carry_over(checker.joint_names, derived, limits=limits)
            else:
                merger = JointStateMerger(checker.joint_names, derived, limits=limits,
                                          limit_policy=settings.joint_limit_policy,
                                          limit_tolerance=settings.joint_limit_tolerance,
                                          max_unknown_names=settings.max_unknown_joints)
            for name, value in _base_variables(checker).items():
                merger.set_default(name, value)  # not waited for: see _base_variables
            self.out_of_limits = {name: rest for name, *rest
                                  in joints_out_of_limits(merger.positions, limits)}
            self.merger, self.limits = merger, limits
            self.window.clear()     # another robot's joints, maybe in another order
            self.window.kinds = checker.motion_kinds
            self._unchecked = []
            self._announced_waiting = False
        return commit

    def apply_settings(self, settings) -> None:
        if self.merger is not None:
            self.merger.limit_policy = settings.joint_limit_policy

    # -- the state, for scene verdicts --------------------------------------------------------

    def current_positions(self):
        """Return the state to check for a scene change (the array when every joint is known,
        else the mapping), or None while no state can be checked yet (lock held)."""
        merger = self.merger
        if merger is None or self.last_accepted is None:
            return None
        if merger.complete:
            return merger.array
        return None if self.host.settings.require_all_joints else merger.positions

    def start_state(self, checker, now: float):
        """Return where a planned trajectory starts: ``(positions, '')``, the state accepted
        last as ``{joint: value}`` for every joint of ``checker`` (joints not heard yet at the
        checker's values, when ``require_all_joints`` is off); or ``(None, reason)`` when the
        state is not known: no joint state accepted yet, joints still missing, or stale (lock
        held)."""
        merger, settings = self.merger, self.host.settings
        if merger is None or self.last_accepted is None:
            return None, 'no joint state accepted yet: where the robot starts is unknown'
        timeout = settings.stale_timeout
        if timeout > 0 and now - self.last_accepted > timeout:
            return None, (f'joint states stale: none accepted for {now - self.last_accepted:.1f}'
                          f' s (stale_timeout {timeout:g} s): where the robot starts is unknown')
        if settings.require_all_joints and not merger.complete:
            return None, (f'waiting for joints {listing(merger.missing(), max_items=20)} '
                          '(require_all_joints): where the robot starts is unknown')
        positions = checker.positions
        positions.update((name, value) for name, value in merger.positions.items()
                         if name in positions)
        return positions, ''

    def positions_at(self, stamp: float):
        """Return the state at ``stamp`` (s; interpolated in the window of recent states, the
        newest for a later stamp), ``'old'`` when ``stamp`` is older than the window, or None
        while no state can be checked yet (lock held)."""
        if not len(self.window):
            return self.current_positions()
        q = self.window.at(stamp)
        return 'old' if q is None else q

    # -- events -------------------------------------------------------------------------------

    def _on_message_lost(self, info) -> None:
        host = self.host
        with host.lock:
            host.totals['lost'] += info.total_count_change
        host.log.warn('lost', f'{info.total_count_change} joint states lost before the node '
                      f'took them ({info.total_count} in all): the input is faster than the node '
                      'or the subscription queue (joint_states_qos); counted as lost_total')

    def _on_incompatible_qos(self, event) -> None:
        self.host.log.warn(
            'qos', 'a publisher of joint_states offers a QoS this subscription cannot match '
            f'(policy {event.last_policy_kind}); its messages are never received. Publish '
            'reliable, or set joint_states_qos: sensor_data')

    # -- the checking thread ------------------------------------------------------------------

    def take_batch(self, batch: list, newest_only: bool) -> None:
        """Merge every message of ``batch`` in order; answer each, or with ``newest_only`` the
        newest accepted (see the module docstring)."""
        host = self.host
        notes = []
        with host.lock:
            last = len(batch) - 1
            for index, msg in enumerate(batch):
                try:
                    self._take(msg, notes, answer=not newest_only or index == last)
                    if index == last and self._unchecked:
                        # The newest message was not accepted: answer the newest that was.
                        host.totals['superseded'] -= 1
                        msg, outcome = self._unchecked.pop()
                        self._check(msg, outcome, notes)
                except Exception as error:  # noqa: B902 - one message must never stop the node
                    if not host.context.ok():
                        return      # shutting down: the publishers are gone, nothing to report
                    # The merge was undone where it happened: answer as an engine error.
                    host.fail(getattr(msg, 'header', None) or Header(), error, notes)
        host.log.write(notes)

    def _take(self, msg, notes: list, answer: bool = True) -> None:
        """Merge one message and answer it (``answer``: unless a newer one waits)."""
        host = self.host
        period, totals = host.period, host.totals
        period.received += 1
        totals['received'] += 1
        merger = self.merger
        if merger is None:     # not subscribed before a model: kept for safety
            totals['no_model'] += 1
            return
        if isinstance(msg, Oversized):
            self._reject('oversized', msg.header, (
                f'{msg.size} bytes, above max_joint_state_bytes '
                f'({host.settings.max_joint_state_bytes}); raise the parameter if the robot\'s '
                'joint states are really that large'), notes, answer, 'OVERSIZED',
                'joint state rejected before decoding, state unchanged: ')
            return
        outcome = merger.merge(msg.name, msg.position)
        if outcome.problem is not None:
            self._reject(outcome.problem.name.lower(), msg.header, outcome.reason, notes, answer,
                         outcome.problem.name)
            return
        if outcome.new_unknown or outcome.unremembered:
            remembered = len(merger.unknown_names)
            notes.append(('warning', 'unknown', (
                f'ignoring {len(outcome.unknown)} joint name(s) in joint_states that the robot '
                'model does not move: '
                + listing(outcome.unknown, max_items=5, limit=300)
                + f'; {remembered} distinct unknown names remembered (at most '
                f'{merger.max_unknown_names}), {merger.unknown_overflow} not remembered; '
                '/diagnostics lists them')))
        if outcome.clamped:
            totals['clamped'] += 1
            notes.append(('warning', 'clamped', 'joints beyond their limits clamped to them '
                          '(joint_limit_policy clamp): ' + listing(outcome.clamped, max_items=5)))
        if not outcome.accepted:
            totals['ignored'] += 1
            if answer and not self._unchecked and not host.answer_held(msg.header):
                self._answer_waiting(msg.header, notes)
            return
        totals['accepted'] += 1
        self.last_accepted = time.monotonic()
        if self.stale:
            self._resume(notes)
        try:
            self._update_limits(outcome.updated, merger.positions, notes)
            if host.settings.require_all_joints and not merger.complete:
                totals['waiting_for_joints'] += 1
                if not self._announced_waiting:
                    self._announced_waiting = True
                    notes.append(('info', None, 'waiting for joints '
                                  f'{listing(merger.missing(), max_items=20)} before the first '
                                  'verdict (require_all_joints)'))
                if answer and not self._unchecked:
                    self._answer_waiting(msg.header, notes)
                return
        except Exception:
            merger.undo(outcome)    # whatever failed, the state stays the one last answered
            raise
        if merger.complete:
            self.window.record(self.host.stamp_seconds(msg.header), merger.array)
        if not answer:
            # Overloaded: a newer state waits; this one is merged but not checked.
            self._unchecked.append((msg, outcome))
            totals['superseded'] += 1
            return
        self._check(msg, outcome, notes)

    def _check(self, msg, outcome, notes: list) -> None:
        """Check the merged state ``msg`` completed and publish the verdict; on a state the
        engine refuses or fails on, roll back ``outcome`` and the superseded ones merged before
        it, and answer by the policy."""
        host, merger = self.host, self.merger
        # Every joint known: the array in checker.joint_names order, the engine's fast path;
        # otherwise the mapping (joints not heard yet keep the checker's value).
        positions = merger.array if merger.complete else merger.positions
        try:
            host.check(msg.header, positions)
        except Exception as error:  # noqa: B902 - any failure: the state stays the last answered
            undone = [outcome] + [each for _, each in reversed(self._unchecked)]
            for each in undone:
                merger.undo(each)
            host.totals['superseded'] -= len(self._unchecked)
            self._unchecked = []
            if not isinstance(error, JointStateError):
                host.fail(msg.header, error, notes)
                return
            # The engine refuses a value it cannot honour (a slider beyond its range, a zero
            # quaternion): the message is rejected after all (superseded states merged since
            # are rolled back with it and counted as rejected instead).
            host.period.rejected += len(undone) - 1
            host.totals['rejected'] += len(undone) - 1
            host.totals['rejected_engine_range'] += len(undone) - 1
            self._reject('engine_range', msg.header, printable(error, 500), notes, True,
                         'ENGINE_RANGE')
            return
        self._unchecked = []
        host.totals['verdicts'] += 1

    def _reject(self, problem: str, header, reason: str, notes: list, answer: bool, kind: str,
                prefix: str = 'joint state rejected, state unchanged: ') -> None:
        """Count a rejected message, warn (throttled by ``kind``) and answer it."""
        host = self.host
        host.period.rejected += 1
        host.totals['rejected'] += 1
        host.totals['rejected_' + problem] += 1
        notes.append(('warning', kind, prefix + reason))
        if answer and not self._unchecked:
            host.refuse(header, REJECTED, f'joint state rejected: {reason}', notes)

    def _answer_waiting(self, header, notes: list) -> None:
        missing = self.merger.missing()
        reason = (f'waiting for joints {listing(missing, max_items=20)} before the first verdict '
                  '(require_all_joints)' if missing and self.host.settings.require_all_joints
                  else 'no joint state has named a joint of the robot yet')
        self.host.refuse(header, WAITING, reason, notes)

    def _update_limits(self, updated, positions, notes) -> None:
        for name in updated:
            self.out_of_limits.pop(name, None)
        for name, value, lower, upper in joints_out_of_limits(positions, self.limits, updated):
            self.out_of_limits[name] = (value, lower, upper)
            notes.append(('warning', 'limits',
                          f'joint {quoted(name)} at {value:.6g} is outside its limits '
                          f'[{_bound(lower)}, {_bound(upper)}]; checked as given '
                          f'(joint_limit_policy {self.host.settings.joint_limit_policy})'))

    # -- staleness ----------------------------------------------------------------------------

    def timeout_due(self, now: float) -> bool:
        timeout, last = self.host.settings.stale_timeout, self.last_accepted
        return not self.stale and timeout > 0 and last is not None and now - last > timeout

    def poll_timeout(self, now: float, notes: list) -> Optional[Timeout]:
        if not self.timeout_due(now):
            return None
        timeout = self.host.settings.stale_timeout
        self.stale, self._stale_since = True, self.last_accepted
        self.stale_episodes += 1
        held = self.host.log.throttle.admit('stale', now, STALE_REPORT_PERIOD)
        reason = (f'joint states stale: none accepted for {now - self.last_accepted:.1f} s '
                  f'(stale_timeout {timeout:g} s)')
        if held is not None:
            notes.append(('warning', None, f'{reason}; stale episode {self.stale_episodes}'
                          + (f' ({held} more since the last report)' if held else '')))
        return Timeout(STALE, reason, self.host.settings.stale_policy)

    def _resume(self, notes: list) -> None:
        self.stale = False
        now = time.monotonic()
        held = self.host.log.throttle.admit('resumed', now, STALE_REPORT_PERIOD)
        if held is not None:
            notes.append(('info', None, f'joint states resumed after {now - self._stale_since:.1f}'
                          f' s without (stale episode {self.stale_episodes}'
                          + (f'; {held} more resumed since the last report' if held else '')
                          + ')'))

    def timed_out(self) -> bool:
        return self.stale


def _mimic_joints(checker) -> frozenset:
    """Return the names of the checker's mimic joints (published by drivers, never needed)."""
    joints = getattr(getattr(checker, 'model', None), 'joints', ())
    return frozenset(joint.name for joint in joints if getattr(joint, 'mimic', None) is not None)


def _base_variables(checker) -> dict:
    """The variables of planar and floating joints (a mobile or floating base, an SRDF virtual
    joint) at their neutral values. Robots rarely publish them in joint_states (MoveIt takes
    them from TF): the node starts them at the world origin instead of waiting for them."""
    kinematics = getattr(checker, 'kinematics', None)
    if kinematics is None or not hasattr(kinematics, 'neutral'):
        return {}
    from collision_sensor.engine.kinematics import JOINT_FLOATING, JOINT_PLANAR
    sizes = {JOINT_PLANAR: 3, JOINT_FLOATING: 7}
    neutral = kinematics.neutral()
    out = {}
    for kind, first in zip(kinematics.joint_type, kinematics.q_index):
        for j in range(int(first), int(first) + sizes.get(int(kind), 0)):
            out[checker.joint_names[j]] = float(neutral[j])
    return out
