"""The sensor, without ROS: joint states, scene changes and failures in, verdicts out.

:class:`Sensor` wraps the compiled core (``cpp/sensor_core.hpp``, whose comment states every
rule: the merge of partial joint states, the motion stream, the fail-safe policies, staleness,
the warning zone) around a :class:`~collision_sensor.engine.checker.CollisionChecker`. The node
(:mod:`collision_sensor.ros`) is this object plus the ROS graph: its sources parse and validate
their topics and hand the data here; it publishes what comes back. A test, an offline tool or
another middleware uses it the same way::

    sensor = Sensor(checker, {'check_motion': True})
    verdict = sensor.step(['shoulder', 'elbow'], [0.1, 0.2], stamp=12.5)
    verdict.contact, verdict.colliding_pairs, verdict.met_on_the_way, verdict.failure

Every answer is also ready to publish: ``verdict.messages`` holds the serialized messages
(``std_msgs/Bool``, ``diagnostic_msgs/DiagnosticArray``, ...) by topic, in publishing order.
A joint state the sensor refuses, or cannot check yet, is answered too: ``verdict.failure``
names why, and ``verdict.contact`` follows the fail-safe policy.

Changing the checker (scene edits, clouds, a new robot) goes through :meth:`Sensor.changing` or
:meth:`Sensor.use_checker`, which hold the core while the checker changes: a compiled caller of
the core (the node's joint-state hop) never sees a checker half changed.
"""
import contextlib
import math
import threading
import time
from dataclasses import dataclass
from typing import Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.engine.compiled import engine as compiled
from collision_sensor.engine.trajectory import check_trajectory
from collision_sensor.sensor.model import engine_arguments, model_arguments
from collision_sensor.sensor.parameters import NodeSettings, settings_from_values

Pair = Tuple[str, str]
Stamp = Union[None, float, Tuple[int, int]]

#: The topics of an answer, by the core's numbers, in publishing order.
TOPICS = {compiled.TOPIC_CONTACT: 'contact', compiled.TOPIC_COLLIDING_PAIRS: 'colliding_pairs',
          compiled.TOPIC_NEAR: 'near', compiled.TOPIC_MIN_DISTANCE: 'min_distance',
          compiled.TOPIC_NEAR_PAIRS: 'near_pairs'}
#: The parameters the core reads (the rest are the node's and the checker's).
CORE_PARAMETERS = ('check_motion', 'require_all_joints', 'joint_limit_policy',
                   'joint_limit_tolerance', 'max_unknown_joints', 'max_joint_state_bytes',
                   'stale_timeout', 'stale_policy', 'on_rejected_input', 'on_engine_error',
                   'warning_distance', 'warning_ignore', 'point_cloud_state_window')
#: Segments of a planned trajectory checked per engine call: between two calls the engine is
#: free for joint states (a long trajectory holds none back by more than a few such segments).
TRAJECTORY_SEGMENTS_PER_CALL = 16
#: Why a state was checked as an instant, not as a motion (counted on ``/diagnostics``).
NEW_MOTION_REASONS = tuple(compiled.NEW_MOTION_REASONS)


@dataclass(frozen=True)
class Failure:
    """Why an input was answered without a verdict of its own.

    :ivar kind: ``joint_state_rejected``, ``waiting_for_joints``, ``engine_error``,
        ``joint_states_stale``, or a source's (``point_cloud_timeout``).
    :ivar reason: one sentence, text from the input escaped.
    :ivar policy: ``contact`` (contact true) or ``hold`` (the held verdict repeated).
    """

    kind: str
    reason: str
    policy: str


@dataclass(frozen=True)
class NearPair:
    """A pair nearer than ``warning_distance``: padded distance (m, <= 0 in contact) and the
    nearest points (world frame, ``point_a`` on ``link_a``)."""

    link_a: str
    link_b: str
    distance: float
    point_a: Tuple[float, float, float]
    point_b: Tuple[float, float, float]


@dataclass(frozen=True)
class Zone:
    """The warning zone's answer: ``near``, ``min_distance`` (``inf``: no pair near; ``-inf``
    after a failure answered by contact) and the pairs, nearest first."""

    near: bool
    min_distance: float
    pairs: Tuple[NearPair, ...]


@dataclass(frozen=True)
class Verdict:
    """The sensor's answer to one input.

    :ivar contact: what ``contact`` says: some pair in contact at the state or on the way to
        it, or the sensor cannot say it is clear (a failure by policy ``contact``).
    :ivar colliding_pairs: the pairs in contact at the state (names sorted within a pair).
    :ivar met_on_the_way: the pairs in contact somewhere on the motion to the state and not
        at the state (with ``check_motion``).
    :ivar first_contact: the fraction of the motion where they met (None without).
    :ivar failure: why the input got no verdict of its own, or None.
    :ivar zone: the warning zone's answer (``warning_distance`` > 0), or None.
    :ivar stamp: ``(sec, nanosec)`` of the header answered; ``frame_id`` its frame (bytes as
        received).
    :ivar messages: ``(topic, serialized message)`` in publishing order (empty when the core
        publishes itself, through the node's hop).
    """

    contact: bool
    colliding_pairs: Tuple[Pair, ...]
    met_on_the_way: Tuple[Pair, ...]
    first_contact: Optional[float]
    failure: Optional[Failure]
    zone: Optional[Zone]
    stamp: Tuple[int, int]
    frame_id: bytes
    messages: Tuple[Tuple[str, bytes], ...] = ()


def stamp_parts(stamp: Stamp) -> Tuple[int, int]:
    """Return ``(sec, nanosec)`` of a stamp given as seconds, as a pair, or None (zero)."""
    if stamp is None:
        return 0, 0
    if isinstance(stamp, tuple):
        return int(stamp[0]), int(stamp[1])
    sec = math.floor(stamp)
    return int(sec), int(round((stamp - sec) * 1e9)) % 1_000_000_000


def core_settings(settings: NodeSettings) -> Dict[str, object]:
    """The core's settings (``engine.SensorCore``) from validated parameters."""
    values = settings.values
    out = {name: values[name] for name in CORE_PARAMETERS}
    out['warning_ignore'] = [list(pair) for pair in sorted(settings.warning_ignore)]
    return out


class Sensor:
    """The collision sensor on one checker (see the module docstring).

    :param checker: the :class:`CollisionChecker` to answer with, or None (a robot later:
        :meth:`use_checker`).
    :param parameters: the node's parameters by name (``config/collision_sensor.yaml``), or
        validated :class:`NodeSettings`; missing ones take their defaults.
    :param clock: monotonic seconds (``time.monotonic``): stale timeouts and motion gaps.
    :param publish: ``publish(topic, message)`` (``topic`` a name of :data:`TOPICS`, the
        message serialized), called for every answer as it is made, in order, from whichever
        thread made it; None: the answers' messages come back in ``Verdict.messages``.
    :raises ConfigError: a parameter value the node would refuse.
    """

    def __init__(self, checker=None, parameters: Union[None, Mapping, NodeSettings] = None,
                 clock: Callable[[], float] = time.monotonic,
                 publish: Optional[Callable[[str, bytes], None]] = None):
        self.settings = (parameters if isinstance(parameters, NodeSettings)
                         else settings_from_values(dict(parameters or {})))
        self.clock = clock
        self.core = compiled.SensorCore(core_settings(self.settings))
        self.checker = None
        self._engine = None     # the engine the core answers with (kept alive here)
        # Held by whatever changes the checker's scene or model, from preparing the change to
        # committing it, and by a reader that needs one scene throughout (a trajectory check):
        # taken before the core, never while holding it.
        self._edits = threading.RLock()
        self.set_publish(publish)
        if checker is not None:
            self.use_checker(checker)

    def set_publish(self, publish: Optional[Callable[[str, bytes], None]]) -> None:
        """Publish answers with ``publish(topic, message)`` from now on (None: return them in
        ``Verdict.messages``)."""
        if publish is None:
            self.core.set_publish(None)
        else:
            self.core.set_publish(lambda topic, data: publish(TOPICS[topic], data))

    # -- the model ------------------------------------------------------------------------------

    def use_checker(self, checker) -> None:
        """Answer with ``checker`` from now on (a new robot, or a checker rebuilt with other
        parameters): the merged state keeps the joints of the same name, the motion goes on
        from the last state checked when the joints are the same."""
        arguments = model_arguments(checker)
        self.core.use_model(**arguments)
        self.checker, self._engine = checker, checker._engine

    @contextlib.contextmanager
    def editing(self) -> Iterator[object]:
        """Hold the checker's scene and model still (others that change them wait): for
        preparing a change (:meth:`apply_scene_changes`, :meth:`commit_points`) and for reads
        that need one scene throughout (:meth:`check_trajectory`). Joint states are answered
        meanwhile. Yields the checker."""
        with self._edits:
            yield self.checker

    @contextlib.contextmanager
    def changing(self) -> Iterator[object]:
        """Hold the core while the checker changes (a scene edit, a cloud committed); yield the
        checker. A scene change the checker laid out in a new engine is taken up on leaving."""
        self.core.lock()
        try:
            yield self.checker
        finally:
            try:
                self._take_up_engine()
            finally:
                self.core.unlock()

    def _take_up_engine(self) -> None:
        """Answer with the engine the checker laid its scene out in, if it is a new one (the
        core held)."""
        if self.checker is not None and self.checker._engine is not self._engine:
            self.core.set_engine(**engine_arguments(self.checker))
            self._engine = self.checker._engine

    def configure(self, parameters: Union[Mapping, NodeSettings]) -> None:
        """Take parameters changed at run time (the core's: ``check_motion``,
        ``joint_limit_policy``, ``warning_distance``, ``warning_ignore``, ...)."""
        self.settings = (parameters if isinstance(parameters, NodeSettings)
                         else settings_from_values(dict(parameters)))
        self.core.configure(core_settings(self.settings))

    # -- inputs ---------------------------------------------------------------------------------

    def step(self, names: Sequence[str], positions: Sequence[float], stamp: Stamp = None,
             frame_id: str = '') -> Verdict:
        """Answer one joint state (``sensor_msgs/JointState``'s ``name`` and ``position``).

        :param stamp: the header's stamp: seconds, ``(sec, nanosec)`` or None (zero: now).
        """
        sec, nanosec = stamp_parts(stamp)
        self.core.take_message(sec, nanosec, frame_id, [str(n) for n in names],
                               [float(v) for v in positions], self.clock())
        return self._answered()

    def take(self, data: bytes) -> Verdict:
        """Answer one serialized ``sensor_msgs/JointState`` (as the middleware hands it)."""
        self.core.take(data, True, self.clock())
        return self._answered()

    def take_batch(self, batch: List[bytes], newest_only: bool = False) -> List[Tuple[str, bytes]]:
        """Answer serialized joint states in order, or under overload (``newest_only``) merge
        them all and answer the newest accepted; return the messages, in order."""
        self.core.take_batch(batch, newest_only, self.clock())
        return self._messages()

    def answer_current(self, stamp: Stamp = None) -> Optional[Verdict]:
        """Check the current state again (the scene or a parameter changed) and answer it, its
        header ``stamp`` and the root frame; None while there is no state to check."""
        sec, nanosec = stamp_parts(stamp)
        if not self.core.answer_current(sec, nanosec):
            return None
        return self._answered()

    def answer_failure(self, failure: Failure, stamp: Stamp = None) -> Verdict:
        """Answer with ``failure`` by its policy (a source's data went missing)."""
        sec, nanosec = stamp_parts(stamp)
        self.core.answer_failure(sec, nanosec, failure.kind, failure.reason, failure.policy)
        return self._answered()

    def fail_source(self, source: str, failure: Failure) -> None:
        """Answer every verdict with ``failure`` until :meth:`recover_source` (a source whose
        silence does not stop the joint states, such as a camera's)."""
        self.core.set_failing(source, failure.kind, failure.reason, failure.policy)

    def recover_source(self, source: str) -> None:
        """``source`` has data again: verdicts are its own again."""
        self.core.clear_failing(source)

    def poll(self, stamp: Stamp = None) -> Optional[Verdict]:
        """Look at the joint states' age: the first call after ``stale_timeout`` without an
        accepted state starts a stale episode (``snapshot()['stale']``) and, with
        ``stale_policy`` contact, answers ``joint_states_stale``. Returns that answer, or
        None."""
        now = self.clock()
        if not self.core.stale_due(now):
            return None
        sec, nanosec = stamp_parts(stamp)
        if not self.core.poll_stale(now, sec, nanosec):
            return None
        if self.settings.stale_policy != 'contact':
            return None
        return self._answered()

    def apply_scene_changes(self, prepared, stamp: Stamp = None) -> Optional[Verdict]:
        """Commit scene changes prepared on the checker (``checker.prepare_scene_changes``,
        inside :meth:`editing`) and answer the current state (None while there is none)."""
        with self.editing(), self.changing() as checker:
            checker.commit_scene_changes(prepared)
            self._take_up_engine()
            return self.answer_current(stamp)

    def commit_points(self, prepared, stamp: Stamp = None) -> Optional[Verdict]:
        """Make a prepared cloud (``checker.prepare_points``) its source's obstacle and answer
        the current state (None while there is none)."""
        with self.editing(), self.changing() as checker:
            checker.commit_points(prepared)
            self._take_up_engine()
            return self.answer_current(stamp)

    def clear_points(self, source: str, stamp: Stamp = None) -> Optional[Verdict]:
        """Remove ``source``'s cloud and answer the current state (None while there is none)."""
        with self.editing(), self.changing() as checker:
            checker.clear_points(source)
            self._take_up_engine()
            return self.answer_current(stamp)

    def check_trajectory(self, joint_names, points):
        """Check a planned trajectory from the state accepted last, with
        ``joint_limit_tolerance``, against one scene throughout (joint states are answered
        meanwhile): ``(TrajectoryResult, '')``, or ``(None, reason)`` when where the robot
        starts is not known."""
        with self.editing() as checker:
            if checker is None:
                return None, 'no robot model yet'
            start, reason = self.start_state()
            if start is None:
                return None, reason
            return check_trajectory(
                checker, joint_names, points, start=start,
                limit_tolerance=self.settings.joint_limit_tolerance,
                segments_per_call=TRAJECTORY_SEGMENTS_PER_CALL), ''

    # -- the state ------------------------------------------------------------------------------

    def positions_at(self, stamp: float):
        """Return the state at ``stamp`` (s): ``(J,)`` interpolated in the window of recent
        complete states (the newest for a later stamp), ``'old'`` when older than the window,
        None while there is no state."""
        return self.core.positions_at(stamp)

    def window_bounds(self) -> Tuple[float, float]:
        """The oldest and newest stamps in the window (NaN when empty)."""
        return self.core.window_bounds()

    def start_state(self) -> Tuple[Optional[Dict[str, float]], str]:
        """Where a planned trajectory starts: ``({joint: value}, '')``, or ``(None, reason)``
        when the state is not known (none yet, joints missing, stale)."""
        q, reason = self.core.start_state(self.clock())
        if q is None:
            return None, reason
        return dict(zip(self.checker.joint_names, (float(v) for v in q))), ''

    def merged_positions(self) -> np.ndarray:
        """``(J,)`` the joint state merged from the messages so far (NaN: not heard yet)."""
        return self.core.merged_positions()

    def current_positions(self) -> Optional[np.ndarray]:
        """The state a scene change is checked at (``(J,)``), or None while there is none."""
        return self.core.current_positions()

    def held(self) -> Optional[dict]:
        """The verdict held (the last published): ``contact``, ``now``, ``met``,
        ``first_contact``, ``zone``, ``serial`` (grows with each verdict); None before one."""
        return self.core.held()

    def snapshot(self, reset_period: bool = False) -> dict:
        """Counters and state for ``/diagnostics`` (``reset_period``: start a new period)."""
        return self.core.snapshot(self.clock(), reset_period)

    def notes(self) -> List[Tuple[str, Optional[str], str]]:
        """Log lines made since the last call: ``(level, throttle kind or None, text)``."""
        return self.core.take_notes()

    # -- answers --------------------------------------------------------------------------------

    def _messages(self) -> List[Tuple[str, bytes]]:
        return [(TOPICS[topic], data) for topic, data in self.core.take_outbox()]

    def _answered(self) -> Verdict:
        """The last answer, with the messages made for it."""
        messages = tuple(self._messages())
        answer = self.core.last_answer()
        verdict = answer['verdict']
        failure = answer['failure']
        zone = answer['zone']
        return Verdict(
            contact=answer['contact'],
            colliding_pairs=tuple(map(tuple, verdict['now'])),
            met_on_the_way=tuple(map(tuple, verdict['met'])),
            first_contact=verdict['first_contact'],
            failure=Failure(*failure) if failure is not None else None,
            zone=None if zone is None else Zone(
                zone['near'], zone['min_distance'],
                tuple(NearPair(a, b, d, tuple(pa), tuple(pb))
                      for a, b, d, pa, pb in zone['records'])),
            stamp=(answer['sec'], answer['nanosec']), frame_id=answer['frame_id'],
            messages=messages)
