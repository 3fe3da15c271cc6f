"""``check_motion``: each joint-state verdict covers the motion from the previous state checked.

With ``check_motion`` on, the verdict on a joint state is about the straight motion from the
state the node checked last to this one (``CollisionChecker.update_motion``: certified, not
sampled; :mod:`collision_sensor.engine.motion` has the interpolation rules), not about the
instant alone: ``contact`` is true if any state on the way is in contact, its two ends
included. Off, every verdict is the instant (``CollisionChecker.update``).

A motion needs a start the robot really passed through, checked with the checker in use. So a
state is checked as an instant, a *new motion*, counted on ``/diagnostics`` by reason
(:data:`NEW_MOTION_REASONS`), when:

- ``first_state``: no state was checked before (start-up, or a new robot with other joints);
- ``stale_gap``: more than ``stale_timeout`` passed since the state accepted before it (the
  robot may have gone anywhere meanwhile: no sweep across the gap; ``stale_timeout`` 0 turns
  the check off and every motion is swept);
- ``engine_error``: the engine failed on the state before; the carried state is not trusted,
  and the state is checked from scratch;
- ``new_checker``: a new checker replaced the one in use (a parameter that changes the
  checker, a new ``robot_description``) and the previous state is not known in its joints;
- ``jump``: a variable moved farther than its joint's range allows (limits widened by
  ``joint_limit_tolerance`` at both ends; :func:`joint_spans`): not a motion of the robot.
  Only ``joint_limit_policy: accept`` lets such values in (1e9 rad, say), and sweeping them
  would take without bound.

A new checker whose joints are those of the one it replaces (a parameter change, the same robot
published again) does not break the motion: the first state it checks is swept from the last
state the old one checked (``CollisionChecker.check_motion``: the new checker carries a state of
its own, from its build, which the stream never passed through; against the new checker's model
and scene). A scene change keeps the motion's start: the next state is swept from the last one,
against the scene as it is when that state is checked. A rejected joint state, one waiting for
joints or one refused by the engine changes nothing: the next accepted state is swept from the
last state checked. Under overload (``overload_policy: newest``) the states skipped are not
swept through: the motion runs straight from the last state checked to the newest.

No rclpy here: the node (:mod:`.sensor_node`) calls :meth:`MotionStream.check` under its lock.
"""
import collections
from typing import NamedTuple, Optional, Tuple

import numpy as np

from collision_sensor.errors import JointStateError

FIRST_STATE = 'first_state'
STALE_GAP = 'stale_gap'
ENGINE_ERROR = 'engine_error'
NEW_CHECKER = 'new_checker'
JUMP = 'jump'
#: Why a state was checked as an instant instead of a motion (``/diagnostics`` counts each).
NEW_MOTION_REASONS = (FIRST_STATE, STALE_GAP, ENGINE_ERROR, NEW_CHECKER, JUMP)

Pair = Tuple[str, str]


class MotionVerdict(NamedTuple):
    """What a verdict says besides the state's own pairs.

    :ivar in_collision: True iff the motion (its ends included) or the state is in contact.
    :ivar first_contact: the fraction of the motion at its first contact, None when the motion
        is free or was not checked (an instant).
    :ivar met: the pairs in contact at ``first_contact`` that are not in contact at the state
        itself, sorted (met on the way, left since).
    """

    in_collision: bool
    first_contact: Optional[float]
    met: Tuple[Pair, ...]


#: An instant, or a motion proven free.
NO_MOTION = MotionVerdict(False, None, ())


def joint_spans(checker, tolerance: float) -> np.ndarray:
    """Return how far each variable of ``checker`` can move between two states it takes:
    its joint's range widened by ``tolerance`` at both ends (``inf`` without limits).

    :return: ``(J,) float64`` in the order of ``checker.joint_names``.
    """
    limits = np.array([checker.joint_limits[name] for name in checker.joint_names],
                      dtype=np.float64).reshape(-1, 2)
    span = limits[:, 1] - limits[:, 0] + 2.0 * tolerance
    span[~np.isfinite(span)] = np.inf
    return span


def jumped(spans: np.ndarray, q_from: np.ndarray, q_to: np.ndarray) -> bool:
    """Return True when some variable moved farther than its span (:func:`joint_spans`)."""
    return bool(np.any(np.abs(q_to - q_from) > spans))


class MotionStream:
    """The motion's start and its counters (every method with the node's lock held).

    :ivar reason: why the next state will be an instant (one of :data:`NEW_MOTION_REASONS`),
        '' while the next state's motion can be swept.
    :ivar counts: ``collections.Counter``: ``swept`` (verdicts that covered a motion),
        ``met_on_the_way`` (verdicts whose contact was only on the way), and each reason of
        :data:`NEW_MOTION_REASONS` (new motions started for it).
    """

    def __init__(self):
        self.reason = FIRST_STATE
        self.counts = collections.Counter()
        # The last state checked (in the order of _names), when the accepted_at time; and
        # whether the checker in use carries it (else a new checker: check_motion from it).
        self._last: Optional[np.ndarray] = None
        self._accepted_at: Optional[float] = None
        self._carried = False
        self._names: Tuple[str, ...] = ()
        self._index = {}
        self._spans: Optional[np.ndarray] = None
        self._spans_key = None

    def restart(self, reason: str) -> None:
        """Check the next state as an instant, for ``reason``."""
        self.reason, self._last, self._carried = reason, None, False

    def replace_checker(self, old, new) -> None:
        """``new`` replaces ``old``: its first state is swept from the last state checked when
        the two have the same joints (a parameter change, the same robot again), else it is an
        instant."""
        keep = self._last is not None and tuple(new.joint_names) == self._names
        last = self._last
        self.restart(FIRST_STATE if old is None else NEW_CHECKER)
        if keep:
            self._last = last

    def _array(self, checker, positions) -> np.ndarray:
        """``positions`` as ``(J,)`` in the order of ``checker.joint_names`` (a mapping applied
        to the last state, or to the checker's own)."""
        names = tuple(checker.joint_names)
        if names != self._names:
            self._names, self._index = names, {name: j for j, name in enumerate(names)}
            self._last, self._spans_key = None, None
        if isinstance(positions, np.ndarray) and positions.shape == (len(names),):
            return positions
        q = (self._last.copy() if self._last is not None
             else np.fromiter(checker.positions.values(), dtype=np.float64, count=len(names)))
        for name, value in positions.items():
            j = self._index.get(name)
            if j is not None:
                q[j] = value
        return q

    def check(self, checker, positions, accepted_at: Optional[float], settings,
              from_scratch: bool):
        """Check ``positions`` with ``checker``; return ``(CheckResult, MotionVerdict)``.

        :param accepted_at: ``time.monotonic()`` when the state was accepted (a scene change
            checks the state accepted last again: its time).
        :param settings: the node's settings: ``check_motion`` (sweep the motion from the last
            state, else the instant), ``stale_timeout`` (a longer gap since the last state
            checked starts a new motion), ``joint_limit_tolerance``.
        :param from_scratch: check every pair from scratch (after an engine error).
        :raises: what the engine raises; nothing changes here then.
        """
        motion = settings.check_motion
        q = self._array(checker, positions)
        last, found, reason = self._last, None, ''
        if motion and from_scratch:
            reason = self.reason or ENGINE_ERROR
        elif motion:
            timeout = settings.stale_timeout
            if last is None:
                reason = self.reason or FIRST_STATE
            elif (timeout > 0 and accepted_at is not None and self._accepted_at is not None
                  and accepted_at - self._accepted_at > timeout):
                reason = STALE_GAP
            elif jumped(self._joint_spans(checker, settings.joint_limit_tolerance), last, q):
                reason = JUMP
        if not motion or from_scratch or reason:
            result = checker.check(positions) if from_scratch else checker.update(positions)
        elif self._carried:
            found = checker.update_motion(positions)
            result = checker.update(positions)  # the same state: the answer update_motion left
        else:   # a new checker with the same joints: from the state the one before checked
            found = checker.check_motion(last, positions)
            result = checker.update(positions)
        if motion:
            self.counts[reason or 'swept'] += 1
        self.reason, self._carried, self._accepted_at = '', True, accepted_at
        self._last = q.copy() if q is positions else q
        if found is None or not found.in_collision:
            return result, NO_MOTION
        now = result.colliding_pairs
        met = tuple(pair for pair in found.colliding_pairs if pair not in now)
        if met and not now:
            self.counts['met_on_the_way'] += 1
        return result, MotionVerdict(True, found.first_contact, met)

    def _joint_spans(self, checker, tolerance: float) -> np.ndarray:
        key = (id(checker), tolerance)
        if key != self._spans_key:
            self._spans, self._spans_key = joint_spans(checker, tolerance), key
        return self._spans

    def state(self, motion: bool) -> str:
        """The motion's state for ``/diagnostics``: ``off``; ``sweeping`` (the next state's
        verdict covers the motion from the last state checked, by this checker or the one it
        replaced); ``new_motion: <reason>`` (the next state is an instant)."""
        if not motion:
            return 'off'
        if self._last is not None:
            return 'sweeping'
        return f'new_motion: {self.reason or FIRST_STATE}'
