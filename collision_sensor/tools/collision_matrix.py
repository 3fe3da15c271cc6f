"""The self-collision matrix of a robot, computed: which pairs of links need no check, each with
its reason (Adjacent, Default, Always, Never) and the evidence; and the warning zone's pairs.
No I/O: :mod:`collision_sensor.tools.acm` is the command line, the rules are in its docstring;
:mod:`collision_sensor.tools.collision_matrix_report` writes the results.
"""
import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from collision_sensor.engine.sampling import sampling_bounds, uniform_configurations
from collision_sensor.errors import ConfigError
from collision_sensor.model.exception_list import adjacent_pairs, sorted_pair
from collision_sensor.tools.progress import ProgressBar

ADJACENT, DEFAULT, ALWAYS, NEVER = 'Adjacent', 'Default', 'Always', 'Never'
#: The reasons, in the order they are tried: a pair gets the first that applies.
REASONS = (ADJACENT, DEFAULT, ALWAYS, NEVER)

DEFAULT_ALWAYS_FRACTION = 0.95
DEFAULT_SAMPLES_PER_ROUND = 2000
DEFAULT_MAX_ROUNDS = 20
DEFAULT_NEVER_SAMPLES = 10000
DEFAULT_CLEARANCE_SAMPLES = 500
DEFAULT_WARNING_SAMPLES = 2000
#: Configurations per check_batch call: the progress bar moves between calls.
BATCH = 250

Pair = Tuple[str, str]


@dataclass(frozen=True)
class PairFinding:
    """One pair that needs no check, and the evidence.

    :ivar hits: sampled configurations in which the pair collided (Always, Never).
    :ivar samples: sampled configurations in which the pair was checked (Always, Never).
    :ivar clearance: smallest distance [m] the engine measured (Never, with ``--clearance``),
        over ``clearance_samples`` of the samples; None when not measured.
    """

    link1: str
    link2: str
    reason: str
    hits: int = 0
    samples: int = 0
    clearance: Optional[float] = None
    clearance_samples: int = 0

    @property
    def pair(self) -> Pair:
        return (self.link1, self.link2)


@dataclass(frozen=True)
class CollisionMatrix:
    """The result of :func:`compute_matrix`.

    :ivar findings: sorted by reason (in :data:`REASONS` order), then by pair.
    :ivar pair_count: pairs of links with geometry, all of them.
    :ivar default_state: ``'zero'`` or the name of the SRDF group_state used.
    :ivar rounds: Always rounds run; ``stable`` is False if ``max_rounds`` ended them.
    :ivar samples: configurations drawn in all (Always rounds plus the Never top-up).
    """

    robot_name: str
    pair_count: int
    findings: Tuple[PairFinding, ...]
    default_state: str
    seed: int
    always_fraction: float
    samples_per_round: int
    rounds: int
    stable: bool
    samples: int
    never_samples: int  # 0: Never not sought
    warning_zone: Optional['WarningZone'] = None

    def pairs(self, reason: Optional[str] = None) -> List[Pair]:
        """Return the pairs found, all or of one reason."""
        return [f.pair for f in self.findings if reason is None or f.reason == reason]


@dataclass(frozen=True)
class WarningZone:
    """The pairs nearer than ``distance`` in every sample (``--warning-distance``).

    :ivar farthest: ``{pair: largest distance [m] over the samples}``, sorted by pair; every
        value is below ``distance``.
    :ivar candidates: pairs measured (those that stay checked).
    :ivar samples: configurations measured (the default pose and random ones).
    """

    distance: float
    farthest: Dict[Pair, float]
    candidates: int
    samples: int

    def warning_ignore(self) -> List[str]:
        """Return the ``"link_a:link_b"`` strings of the node's ``warning_ignore``."""
        return [f'{a}:{b}' for a, b in self.farthest]


def find_adjacent(model, link_names: Sequence[str]) -> Set[Pair]:
    """Return each link with geometry paired with its nearest ancestor that has geometry.

    :param model: the :class:`RobotModel`.
    :param link_names: the links with collision geometry.
    """
    parents = {link: None for link in model.links}
    for joint in model.joints:
        parents[joint.child] = joint.parent
    return adjacent_pairs(parents, link_names)


def default_configuration(checker, srdf=None, state: Optional[str] = None) -> np.ndarray:
    """Return the default pose: zeros (identity quaternions), with the named SRDF
    ``group_state`` applied.

    :param srdf: a loaded :class:`Srdf` (needed when ``state`` is given).
    :raises ConfigError: ``state`` is given without an SRDF, or the SRDF lacks it.
    """
    q = checker.kinematics.neutral()   # a floating joint's quaternion: the identity
    if state is None:
        return q
    if srdf is None:
        raise ConfigError(f'--default-state "{state}" needs the SRDF that defines it; '
                          'add --srdf FILE')
    if state not in srdf.group_states:
        known = ', '.join(f'"{name}"' for name in srdf.group_states) or 'none'
        raise ConfigError(f'--default-state "{state}": SRDF "{srdf.source}" has no group_state '
                          f'of that name (it has: {known}); use one of those, or leave '
                          '--default-state out for the zero pose')
    index = {name: j for j, name in enumerate(checker.joint_names)}
    for joint, value in srdf.group_states[state]['joints'].items():
        if joint in index:  # mimic and virtual joints follow or do not move
            q[index[joint]] = value
    return q


def pair_checker(base, pairs: Sequence[Pair]):
    """Return a checker of ``base``'s robot that checks exactly ``pairs`` (raw: no exceptions).

    Built on ``base.model``, so the meshes are not read again.
    """
    from collision_sensor.engine.checker import CollisionChecker
    wanted = set(pairs)
    robot = base.link_names
    others = [f'{a}:{b}' for i, a in enumerate(robot) for b in robot[i + 1:]
              if sorted_pair(a, b) not in wanted]
    config = dict(vars(base.config))
    config.update(ignore_adjacent=False, allowed_collisions=others)
    return CollisionChecker(base.model, None, (), config)


def count_collisions(checker, Q: np.ndarray, progress: Optional[ProgressBar] = None,
                     done: int = 0) -> np.ndarray:
    """Return ``(P,) int``: in how many rows of ``Q`` each of ``checker.checked_pairs`` collides.

    :param Q: ``(n, J) float`` configurations.
    :param done: steps already shown on ``progress``.
    """
    hits = np.zeros(len(checker.checked_pairs), dtype=np.int64)
    if not len(checker.checked_pairs):
        if progress is not None:
            progress.update(done + len(Q))
        return hits
    for start in range(0, len(Q), BATCH):
        chunk = Q[start:start + BATCH]
        hits += checker.check_batch(chunk).sum(axis=0)
        if progress is not None:
            progress.update(done + start + len(chunk))
    return hits


def compute_matrix(base, *, srdf=None, default_state: Optional[str] = None,
                   always_fraction: float = DEFAULT_ALWAYS_FRACTION,
                   samples_per_round: int = DEFAULT_SAMPLES_PER_ROUND,
                   max_rounds: int = DEFAULT_MAX_ROUNDS, never: bool = False,
                   never_samples: int = DEFAULT_NEVER_SAMPLES, clearance: bool = False,
                   clearance_samples: int = DEFAULT_CLEARANCE_SAMPLES, seed: int = 0,
                   warning_distance: Optional[float] = None,
                   warning_samples: int = DEFAULT_WARNING_SAMPLES,
                   progress: str = 'never') -> CollisionMatrix:
    """Classify every pair of ``base``'s links with geometry (see the module docstring).

    :param base: a checker of the robot alone, built without SRDF (its exceptions are not
        used: the pairs sampled are chosen here).
    :param srdf: the loaded SRDF, for ``default_state``, and its disabled pairs, which the
        warning zone leaves out.
    :param warning_distance: measure the warning zone (:class:`WarningZone`) at this distance
        [m]; None: not measured.
    :param progress: progress bar mode on stderr (``auto``, ``always``, ``never``).
    :raises ConfigError: a bad setting or an unknown default state, naming it.
    """
    _check_settings(always_fraction, samples_per_round, max_rounds, never_samples,
                    clearance_samples, warning_distance, warning_samples)
    q_default = default_configuration(base, srdf, default_state)
    rng = np.random.default_rng(seed)
    lower, upper = sampling_bounds(base)
    robot = base.link_names
    all_pairs = [sorted_pair(a, b) for i, a in enumerate(robot) for b in robot[i + 1:]]
    findings: Dict[Pair, PairFinding] = {}

    for pair in find_adjacent(base.model, robot):
        findings[pair] = PairFinding(*pair, ADJACENT)
    at_default = pair_checker(base, [p for p in all_pairs if p not in findings]).check(q_default)
    for pair in at_default.colliding_pairs:
        findings[pair] = PairFinding(*pair, DEFAULT)

    # Always: rounds until the list stops changing.
    candidates = [p for p in all_pairs if p not in findings]
    sampler = pair_checker(base, candidates)
    columns = list(sampler.checked_pairs)
    hits = np.zeros(len(columns), dtype=np.int64)
    drawn, rounds, stable = [], 0, False
    always_before: Set[Pair] = set()
    while rounds < max_rounds:
        rounds += 1
        Q = uniform_configurations(lower, upper, samples_per_round, rng)
        drawn.append(Q)
        with ProgressBar(samples_per_round, f'Always, round {rounds}', progress) as bar:
            hits += count_collisions(sampler, Q, bar)
        n = rounds * samples_per_round
        always_now = {pair for pair, h in zip(columns, hits) if h >= always_fraction * n}
        if rounds >= 2 and always_now == always_before:
            stable = True
            break
        always_before = always_now
    n_always = rounds * samples_per_round
    for pair, h in zip(columns, hits):
        if pair in always_now:
            findings[pair] = PairFinding(*pair, ALWAYS, hits=int(h), samples=n_always)

    # Never: the Always samples count; draw more up to never_samples.
    n_total = n_always
    if never:
        quiet = [pair for pair, h in zip(columns, hits) if h == 0]
        extra = max(0, never_samples - n_always)
        if quiet and extra:
            Q = uniform_configurations(lower, upper, extra, rng)
            drawn.append(Q)
            never_sampler = pair_checker(base, quiet)
            with ProgressBar(extra, 'Never', progress) as bar:
                extra_hits = count_collisions(never_sampler, Q, bar)
            quiet = [pair for pair, h in zip(never_sampler.checked_pairs, extra_hits) if h == 0]
            n_total += extra
        distances, subset = {}, ()
        if clearance and quiet:
            Q_all = np.concatenate(drawn)
            subset = Q_all[rng.choice(len(Q_all), size=min(clearance_samples, len(Q_all)),
                                      replace=False)]
            distances = smallest_distances(base, quiet, subset, progress)
        for pair in quiet:
            d = distances.get(pair)
            findings[pair] = PairFinding(
                *pair, NEVER, hits=0, samples=n_total, clearance=d,
                clearance_samples=len(subset) if d is not None else 0)

    zone = None
    if warning_distance is not None:
        disabled = ({sorted_pair(p.link1, p.link2) for p in srdf.disabled_pairs}
                    if srdf is not None else set())
        checked = [p for p in all_pairs if p not in findings and p not in disabled]
        Q = np.concatenate([q_default[None, :],
                            uniform_configurations(lower, upper, warning_samples - 1, rng)])
        zone = find_warning_zone(base, checked, warning_distance, Q, progress)

    order = {reason: k for k, reason in enumerate(REASONS)}
    ordered = tuple(sorted(findings.values(), key=lambda f: (order[f.reason], f.pair)))
    return CollisionMatrix(
        robot_name=base.model.name, pair_count=len(all_pairs), findings=ordered,
        default_state=default_state or 'zero', seed=seed, always_fraction=always_fraction,
        samples_per_round=samples_per_round, rounds=rounds, stable=stable, samples=n_total,
        never_samples=never_samples if never else 0, warning_zone=zone)


def smallest_distances(base, pairs: Sequence[Pair], Q: np.ndarray,
                       progress: str = 'never') -> Dict[Pair, float]:
    """Return each pair's smallest distance [m] over the configurations ``Q``: the engine's
    :meth:`~CollisionChecker.proximity` on a checker of exactly ``pairs`` (0 in contact)."""
    checker = pair_checker(base, pairs)
    smallest = {pair: math.inf for pair in checker.checked_pairs}
    with ProgressBar(len(Q), 'clearance', progress) as bar:
        for k, q in enumerate(Q):
            for record in checker.proximity(q, math.inf):
                pair = (record.link_a, record.link_b)
                smallest[pair] = min(smallest[pair], max(record.distance, 0.0))
            bar.update(k + 1)
    return smallest


#: The warning zone's checker is rebuilt on the pairs still in the running once fewer than
#: this share of the pairs it measures are: most pairs drop out within the first samples.
REBUILD_SHARE = 0.5


def find_warning_zone(base, pairs: Sequence[Pair], distance: float, Q: np.ndarray,
                      progress: str = 'never') -> WarningZone:
    """Return the pairs of ``pairs`` nearer than ``distance`` in every configuration of ``Q``.

    A pair drops out at the first configuration where the engine's
    :meth:`~CollisionChecker.proximity` (as the node's warning zone measures it, unpadded here)
    finds it at ``distance`` or farther; the others keep their largest distance seen.

    :param Q: ``(n, J) float`` configurations.
    """
    near = {sorted_pair(*pair) for pair in pairs}
    farthest: Dict[Pair, float] = {pair: -math.inf for pair in near}
    checker = pair_checker(base, sorted(near)) if near else None
    with ProgressBar(len(Q), 'warning zone', progress) as bar:
        for k, q in enumerate(Q):
            if not near:
                bar.update(len(Q))
                break
            seen = {}
            for record in checker.proximity(q, distance):
                seen[(record.link_a, record.link_b)] = max(record.distance, 0.0)
            near = {pair for pair in near if pair in seen}
            for pair in near:
                farthest[pair] = max(farthest[pair], seen[pair])
            if near and len(near) < REBUILD_SHARE * len(checker.checked_pairs):
                checker = pair_checker(base, sorted(near))
            bar.update(k + 1)
    return WarningZone(distance=distance,
                       farthest={pair: farthest[pair] for pair in sorted(near)},
                       candidates=len(farthest), samples=len(Q))


def _check_settings(always_fraction, samples_per_round, max_rounds, never_samples,
                    clearance_samples, warning_distance=None, warning_samples=1):
    if not (isinstance(always_fraction, (int, float)) and 0.0 < always_fraction <= 1.0):
        raise ConfigError(f'--always-fraction {always_fraction}: expected a fraction in (0, 1], '
                          'e.g. 0.95')
    if warning_distance is not None and not (
            isinstance(warning_distance, (int, float)) and 0.0 < warning_distance < math.inf):
        raise ConfigError(f'--warning-distance {warning_distance}: expected a distance in '
                          'metres > 0, e.g. 0.05 (the node\'s warning_distance)')
    for option, value, least in (('--samples-per-round', samples_per_round, 1),
                                 ('--max-rounds', max_rounds, 2),
                                 ('--never-samples', never_samples, 1),
                                 ('--clearance-samples', clearance_samples, 1),
                                 ('--warning-samples', warning_samples, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ConfigError(f'{option} {value}: expected a whole number >= {least}')
