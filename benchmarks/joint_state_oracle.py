"""The rules of the sensor's joint-state merge and motion stream, stated in plain Python: the
oracle the fuzzer and the sensor's tests compare the compiled core (``cpp/joint_merge.hpp``,
``cpp/sensor_core.hpp``) with.

:class:`JointStateMerger` takes the ``name`` and ``position`` fields of each
``sensor_msgs/JointState`` and gives back an :class:`Outcome` that says what happened and why.

The rules, in the order they are applied to one message:

1. no positions at all (velocity- or effort-only message, or an empty one): nothing changes;
2. ``name`` and ``position`` of different lengths: rejected whole;
3. a name given twice: rejected whole;
4. a position that is NaN or infinite (for any joint, known or not): rejected whole;
5. a known joint with limits whose value lies beyond them by more than ``limit_tolerance``
   (rad or m): by the ``limit_policy``, ``'reject'`` (the default) rejects the message whole,
   ``'clamp'`` stores the nearest limit instead, ``'accept'`` stores the value as given. Values
   beyond a limit by at most the tolerance (sensor noise, calibration) are stored as given.
   Joints without limits (continuous) take any finite value;
6. derived joints (mimic joints: they follow their source joint, so their own value is not
   used) are skipped silently; any other name the robot does not move (unknown or fixed joints)
   is ignored and reported once, the first time it is seen (``Outcome.new_unknown``). Memory
   stays bounded: at most ``max_unknown_names`` names are remembered, later ones are only
   counted (``unknown_overflow``);
7. the positions of the known joints are stored; joints a message does not name keep the value
   they had, so publishers that each name a subset (arm, gripper) merge into one state.

A rejected message changes nothing: neither the stored positions nor the set of unknown names.
Reasons quote names through :func:`~collision_sensor.untrusted_text.printable` (escaped,
bounded), so they are safe to log.
"""
import enum
import math
from dataclasses import dataclass, field
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.sensor.parameters import (  # noqa: F401 - the fuzzer's names for them
    DEFAULT_LIMIT_TOLERANCE, LIMIT_POLICIES, MAX_UNKNOWN_NAMES)
from collision_sensor.untrusted_text import listing, quoted

#: Most names listed in one rejection reason.
_MAX_LISTED = 5


class Verdict(enum.Enum):
    """What :meth:`JointStateMerger.merge` did with one message."""

    ACCEPTED = 'accepted'   # at least one known joint was named; the state was updated
    IGNORED = 'ignored'     # well formed, but nothing to store (no positions, no known name)
    REJECTED = 'rejected'   # malformed; nothing changed


class Problem(enum.Enum):
    """Why a message was rejected; one throttle per kind keeps warnings readable."""

    LENGTH_MISMATCH = 'length mismatch'
    DUPLICATE_NAMES = 'duplicate names'
    NOT_FINITE = 'non-finite position'
    OUT_OF_LIMITS = 'beyond the joint limits'


@dataclass(frozen=True)
class Outcome:
    """The result of merging one message.

    :ivar verdict: accepted, ignored or rejected.
    :ivar problem: why it was rejected (``None`` unless rejected).
    :ivar reason: one sentence naming the problem and the joints at fault (empty unless rejected).
    :ivar updated: the known joints this message set, in message order.
    :ivar unknown: the names in this message that the robot does not move.
    :ivar new_unknown: the subset of ``unknown`` never seen before and now remembered (warn
        once about these).
    :ivar unremembered: how many names of ``unknown`` were not remembered (the memory of
        unknown names is full); they may or may not have been seen before.
    :ivar clamped: the known joints whose value was replaced by a limit (policy ``'clamp'``).
    :ivar previous: for :meth:`JointStateMerger.undo`: each stored joint's value before this
        message (``None``: not heard before).
    """

    verdict: Verdict
    problem: Optional[Problem] = None
    reason: str = ''
    updated: Tuple[str, ...] = ()
    unknown: Tuple[str, ...] = ()
    new_unknown: Tuple[str, ...] = ()
    unremembered: int = 0
    clamped: Tuple[str, ...] = ()
    previous: Tuple[Tuple[str, Optional[float]], ...] = ()

    @property
    def accepted(self) -> bool:
        """Return True when the stored state was updated by this message."""
        return self.verdict is Verdict.ACCEPTED


def _rejected(problem: Problem, reason: str) -> Outcome:
    return Outcome(Verdict.REJECTED, problem=problem, reason=reason)


@dataclass
class JointStateMerger:
    """Hold the latest position of every movable joint, merged from partial messages.

    :param joint_names: the joints the robot model moves (movable, non-mimic), in model order.
    :param derived_names: joints a robot publishes but whose value follows another joint
        (mimic joints); skipped without a warning.
    :param positions: initial known positions, joint name -> value.
    :param limits: joint name -> (lower, upper); joints absent, or with a ``None`` or infinite
        bound, have no limit on that side.
    :param limit_policy: one of :data:`LIMIT_POLICIES` (rule 5).
    :param limit_tolerance: rad or m beyond a limit still taken as given, >= 0.
    :param max_unknown_names: the most unknown names remembered.
    :ivar unknown_names: the unknown names remembered, at most ``max_unknown_names``.
    :ivar unknown_overflow: how many times a name was not remembered because the memory of
        unknown names was full.
    :ivar array: (len(joint_names),) float64, C-contiguous: ``positions`` in ``joint_names``
        order, NaN for joints not heard yet; kept in step with ``positions`` so that the node
        hands the checker this array (its fast path) instead of a dict per message.
    """

    joint_names: Sequence[str]
    derived_names: frozenset = frozenset()
    positions: Dict[str, float] = field(default_factory=dict)
    limits: Mapping[str, Tuple[Optional[float], Optional[float]]] = field(default_factory=dict)
    limit_policy: str = 'reject'
    limit_tolerance: float = DEFAULT_LIMIT_TOLERANCE
    max_unknown_names: int = MAX_UNKNOWN_NAMES
    unknown_names: set = field(default_factory=set)
    unknown_overflow: int = 0

    def __post_init__(self):
        if self.limit_policy not in LIMIT_POLICIES:
            raise ValueError(f'limit_policy "{self.limit_policy}" is not one of '
                             f'{", ".join(LIMIT_POLICIES)}')
        if not (math.isfinite(self.limit_tolerance) and self.limit_tolerance >= 0.0):
            raise ValueError(f'limit_tolerance {self.limit_tolerance} is not a finite number >= 0')
        self.joint_names = tuple(self.joint_names)
        # Finite bounds only: None and +-inf mean "no limit on this side".
        self._bounds = {}
        for name, (lower, upper) in dict(self.limits).items():
            lower = lower if lower is not None and math.isfinite(lower) else None
            upper = upper if upper is not None and math.isfinite(upper) else None
            if lower is not None or upper is not None:
                self._bounds[name] = (lower, upper)
        self._known = frozenset(self.joint_names)
        self.derived_names = frozenset(self.derived_names) - self._known
        unexpected = set(self.positions) - self._known
        if unexpected:
            raise ValueError(f'initial positions name unknown joints {sorted(unexpected)}')
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self.array = np.full(len(self.joint_names), np.nan)
        for name, value in self.positions.items():
            self.array[self._index[name]] = value

    def set_default(self, name: str, value: float) -> None:
        """Give the known joint ``name`` the position ``value`` unless it has one already."""
        if name not in self.positions:
            self.positions[name] = float(value)
            self.array[self._index[name]] = value

    @property
    def complete(self) -> bool:
        """Return True once every movable joint has been heard at least once."""
        return len(self.positions) == len(self._known)

    def missing(self) -> List[str]:
        """Return the movable joints not heard yet, in model order."""
        return [name for name in self.joint_names if name not in self.positions]

    def merge(self, names: Sequence[str], positions: Sequence[float]) -> Outcome:
        """Validate one message and store its known positions; see the module rules.

        :param names: ``JointState.name``, (n,) str.
        :param positions: ``JointState.position``, (n,) float, or empty for a message that
            carries no positions.
        :return: what happened; ``updated`` lists the joints whose value was stored, a message
            naming only derived or unknown joints is ``IGNORED``.
        """
        if len(positions) == 0:
            return Outcome(Verdict.IGNORED)
        names = list(names)
        if len(names) != len(positions):
            return _rejected(
                Problem.LENGTH_MISMATCH,
                f'{len(names)} names but {len(positions)} positions; '
                'every named joint needs exactly one position')
        if len(set(names)) != len(names):
            seen, duplicates = set(), []
            for name in names:
                if name in seen and name not in duplicates:
                    duplicates.append(name)
                seen.add(name)
            return _rejected(
                Problem.DUPLICATE_NAMES,
                'joint names given more than once: '
                + listing(map(quoted, duplicates), max_items=_MAX_LISTED, escape=False))
        bad = [(name, value) for name, value in zip(names, positions)
               if not math.isfinite(value)]
        if bad:
            return _rejected(Problem.NOT_FINITE, 'positions that are not finite: ' + listing(
                (f'{quoted(name)}={value}' for name, value in bad), total=len(bad),
                max_items=_MAX_LISTED, escape=False))

        values = {}
        clamped, beyond = [], []
        for name, value in zip(names, positions):
            if name not in self._known:
                continue
            value = float(value)
            bounds = self._bounds.get(name)
            if bounds is not None:
                lower, upper = bounds
                tolerance = self.limit_tolerance
                if ((lower is not None and value < lower - tolerance)
                        or (upper is not None and value > upper + tolerance)):
                    beyond.append((name, value, lower, upper))
                    if self.limit_policy == 'clamp':
                        value = min(max(value, -math.inf if lower is None else lower),
                                    math.inf if upper is None else upper)
                        clamped.append(name)
            values[name] = value
        if beyond and self.limit_policy == 'reject':
            return _rejected(Problem.OUT_OF_LIMITS, _limits_reason(beyond, self.limit_tolerance))

        updated, unknown = [], []
        for name in names:
            if name in self._known:
                updated.append(name)
            elif name not in self.derived_names:
                unknown.append(name)
        new_unknown, unremembered = [], 0
        for name in unknown:
            if name in self.unknown_names:
                continue
            if len(self.unknown_names) < self.max_unknown_names:
                self.unknown_names.add(name)
                new_unknown.append(name)
            else:
                unremembered += 1
        self.unknown_overflow += unremembered
        previous = tuple((name, self.positions.get(name)) for name in values)
        self.positions.update(values)
        array, index = self.array, self._index
        for name, value in values.items():
            array[index[name]] = value
        verdict = Verdict.ACCEPTED if updated else Verdict.IGNORED
        return Outcome(verdict, updated=tuple(updated), unknown=tuple(unknown),
                       new_unknown=tuple(new_unknown), unremembered=unremembered,
                       clamped=tuple(clamped), previous=previous)

    def undo(self, outcome: Outcome) -> None:
        """Restore the positions a merged message replaced: the checker refused its state
        (a value its engine cannot honour), so the message is rejected after all and the
        state must stay what the last verdict described."""
        for name, value in outcome.previous:
            if value is None:
                self.positions.pop(name, None)
                self.array[self._index[name]] = np.nan
            else:
                self.positions[name] = value
                self.array[self._index[name]] = value

    def carry_over(self, joint_names: Sequence[str], derived_names: Iterable[str] = (),
                   limits: Optional[Mapping[str, Tuple[float, float]]] = None
                   ) -> 'JointStateMerger':
        """Return a merger for a new robot model that keeps the positions of shared joints.

        Unknown names start afresh: they are reported once more against the new model.

        :param joint_names: the new model's movable joints.
        :param derived_names: the new model's mimic joints.
        :param limits: the new model's joint limits (default: keep these).
        """
        kept = {name: value for name, value in self.positions.items() if name in joint_names}
        return JointStateMerger(joint_names, frozenset(derived_names), positions=kept,
                                limits=self.limits if limits is None else limits,
                                limit_policy=self.limit_policy,
                                limit_tolerance=self.limit_tolerance,
                                max_unknown_names=self.max_unknown_names)


def _limits_reason(beyond, tolerance: float) -> str:
    def bound(value):
        return 'none' if value is None else f'{value:.6g}'
    joints = listing((f'joint {quoted(name)} at {value:.6g} outside its limits '
                      f'[{bound(lower)}, {bound(upper)}]' for name, value, lower, upper in beyond),
                     total=len(beyond), max_items=_MAX_LISTED, limit=600, escape=False)
    # The node's parameter, as the user sets it (this merger is the node's).
    return (f'{joints} by more than joint_limit_tolerance {tolerance:g}; fix the publisher '
            '(units, joint order, calibration), or set the parameter joint_limit_policy to '
            '"clamp" or "accept"')


def joints_out_of_limits(positions: Mapping[str, float],
                         limits: Mapping[str, Tuple[float, float]],
                         names: Optional[Iterable[str]] = None
                         ) -> List[Tuple[str, float, float, float]]:
    """Return the joints whose position lies outside their limits.

    Joints without limits (absent from ``limits``, or ``None`` / infinite bounds, as for
    continuous joints) are never out of limits. Bounds are inclusive: a value equal to a bound
    is within limits.

    :param positions: joint name -> position.
    :param limits: joint name -> (lower, upper).
    :param names: only look at these joints (default: every joint in ``positions``).
    :return: ``(name, value, lower, upper)`` for each offending joint, in ``names`` order.
    """
    offending = []
    for name in (positions if names is None else names):
        bounds = limits.get(name)
        if bounds is None or name not in positions:
            continue
        lower, upper = bounds
        value = positions[name]
        below = lower is not None and value < lower
        above = upper is not None and value > upper
        if below or above:
            offending.append((name, value, lower, upper))
    return offending


def joint_spans(checker, tolerance: float) -> np.ndarray:
    """Return how far each variable of ``checker`` can move between two states the sensor
    sweeps: its joint's range widened by ``tolerance`` at both ends (``inf`` without limits);
    a longer move is a jump, checked as a new motion.

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
