"""Merge partial joint states into one robot state, rejecting malformed messages whole.

Pure Python, no ROS: the node hands over the ``name`` and ``position`` fields of each
``sensor_msgs/JointState`` and gets back an :class:`Outcome` that says what happened and why.

The rules, in the order they are applied to one message:

1. no positions at all (velocity- or effort-only message, or an empty one): nothing changes;
2. ``name`` and ``position`` of different lengths: rejected whole;
3. a name given twice: rejected whole;
4. a position that is NaN or infinite (for any joint, known or not): rejected whole;
5. derived joints (mimic joints: they follow their source joint, so their own value is not
   used) are skipped silently; any other name the robot does not move (unknown or fixed joints)
   is ignored and reported once, the first time it is seen (``Outcome.new_unknown``);
6. the positions of the known joints are stored; joints a message does not name keep the value
   they had, so publishers that each name a subset (arm, gripper) merge into one state.

A rejected message changes nothing: neither the stored positions nor the set of unknown names.
"""
import enum
import math
from dataclasses import dataclass, field
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple


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


@dataclass(frozen=True)
class Outcome:
    """The result of merging one message.

    :ivar verdict: accepted, ignored or rejected.
    :ivar problem: why it was rejected (``None`` unless rejected).
    :ivar reason: one sentence naming the problem and the joints at fault (empty unless rejected).
    :ivar updated: the known joints this message set, in message order.
    :ivar unknown: the names in this message that the robot does not move.
    :ivar new_unknown: the subset of ``unknown`` never seen before (warn once about these).
    """

    verdict: Verdict
    problem: Optional[Problem] = None
    reason: str = ''
    updated: Tuple[str, ...] = ()
    unknown: Tuple[str, ...] = ()
    new_unknown: Tuple[str, ...] = ()

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
    """

    joint_names: Sequence[str]
    derived_names: frozenset = frozenset()
    positions: Dict[str, float] = field(default_factory=dict)
    unknown_names: set = field(default_factory=set)

    def __post_init__(self):
        self.joint_names = tuple(self.joint_names)
        self._known = frozenset(self.joint_names)
        self.derived_names = frozenset(self.derived_names) - self._known
        unexpected = set(self.positions) - self._known
        if unexpected:
            raise ValueError(f'initial positions name unknown joints {sorted(unexpected)}')

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
                f'joint names given more than once: {", ".join(map(repr, duplicates))}')
        bad = [(name, value) for name, value in zip(names, positions)
               if not math.isfinite(value)]
        if bad:
            listing = ', '.join(f'{name!r}={value}' for name, value in bad)
            return _rejected(Problem.NOT_FINITE, f'positions that are not finite: {listing}')

        updated, unknown = [], []
        for name in names:
            if name in self._known:
                updated.append(name)
            elif name not in self.derived_names:
                unknown.append(name)
        new_unknown = tuple(name for name in unknown if name not in self.unknown_names)
        self.unknown_names.update(new_unknown)
        for name, value in zip(names, positions):
            if name in self._known:
                self.positions[name] = float(value)
        verdict = Verdict.ACCEPTED if updated else Verdict.IGNORED
        return Outcome(verdict, updated=tuple(updated), unknown=tuple(unknown),
                       new_unknown=new_unknown)

    def carry_over(self, joint_names: Sequence[str],
                   derived_names: Iterable[str] = ()) -> 'JointStateMerger':
        """Return a merger for a new robot model that keeps the positions of shared joints.

        Unknown names start afresh: they are reported once more against the new model.

        :param joint_names: the new model's movable joints.
        :param derived_names: the new model's mimic joints.
        """
        kept = {name: value for name, value in self.positions.items() if name in joint_names}
        return JointStateMerger(joint_names, frozenset(derived_names), positions=kept)


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
