"""``collision_sensor_acm``: find the pairs of links that need no collision check.

The self-collision matrix of a robot, as the MoveIt Setup Assistant computes it, from the URDF
alone::

    collision_sensor_acm panda.urdf --package-path example-robot-data=DIR --output panda.srdf
    collision_sensor_acm arm.urdf --srdf arm.srdf --in-place --never --yaml acm.yaml
    collision_sensor_acm ur5.urdf --srdf ur5.srdf --warning-distance 0.05 --yaml ur5_acm.yaml

Each pair of links with geometry gets at most one reason, the first that applies:

``Adjacent``
    a link and its nearest ancestor with geometry (parent and child, also across links
    without geometry): they touch by design. Found from the tree, no sampling.
``Default``
    in collision in the default pose: all joints at zero, or a ``group_state`` of the SRDF
    (``--default-state``; joints it does not name stay at zero).
``Always``
    in collision in at least ``--always-fraction`` of random configurations. Sampled in
    rounds of ``--samples-per-round``; the counts add up over rounds, and sampling stops
    after a round that neither adds a pair to the list nor drops one (at least two rounds:
    the first sets the list, the next must confirm it; at most ``--max-rounds``).
``Never`` (only with ``--never``)
    no collision in ``--never-samples`` random configurations (the samples of the Always
    rounds count, more are drawn up to the number). Sampling is not proof: a pair that never
    collided in N samples can still collide in a configuration that was not drawn.

Configurations are uniform within the joint limits (continuous joints in [-pi, pi]); the
random generator is seeded (``--seed``), so a run can be repeated exactly. The sampling checks
the raw matrix: no SRDF pairs and no adjacency exceptions, only the pairs not yet explained by
an earlier reason are sampled, with :meth:`CollisionChecker.check_batch`.

With ``--clearance``, each Never pair's smallest distance is measured by the engine
(:meth:`CollisionChecker.proximity`, the triangles' distance), over a subset of the samples
(``--clearance-samples``); the output says over how many.

The warning zone (``--warning-distance D``): the pairs that stay checked (neither found above
nor disabled by ``--srdf``) whose distance is below ``D`` in every one of
``--warning-samples`` random configurations (the default pose first), measured by the engine
as the node measures its ``warning_distance``. Such a pair, e.g. the UR5's ``ee_link`` and
``wrist_2_link`` (0.0198 m apart wherever the arm goes), would keep the node's warning zone on
for good; the list goes to the node's ``warning_ignore`` parameter (``link_a:link_b`` strings:
printed, and in ``--yaml``). Distances are the links' surfaces', unpadded: the node subtracts
both links' paddings, so with padding give ``D`` plus the two paddings. Sampling is not proof:
a pair listed may still move farther apart in a configuration that was not drawn.

Exit status 0 on success, 2 on error (one line on stderr: ``collision_sensor_acm: error:
...``).
"""
import argparse
import math
import os
import sys
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from collision_sensor.engine.sampling import sampling_bounds, uniform_configurations
from collision_sensor.errors import ConfigError
from collision_sensor.model.exception_list import adjacent_pairs, sorted_pair
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.model.xacro_expansion import parse_xacro_args
from collision_sensor.tools.command_line import run_command
from collision_sensor.tools.progress import MODES, ProgressBar

PROG = 'collision_sensor_acm'
EXIT_OK, EXIT_ERROR = 0, 2

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

NOT_PROOF = ('sampling is not proof: a Never pair did not collide in the configurations '
             'drawn, it can still collide in one that was not drawn')
NO_DISTANCE = 'clearance not measured (add --clearance to measure it)'

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


# ------------------------------------------------------------------ the matrix, no I/O

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


# ------------------------------------------------------------------ output

def allowed_collisions(matrix: CollisionMatrix) -> List[str]:
    """Return the ``"link_a:link_b"`` strings of every pair found (all reasons)."""
    return [f'{a}:{b}' for a, b in matrix.pairs()]


def params_yaml(matrix: CollisionMatrix, command: str = '') -> str:
    """Return a ros2 params file setting ``allowed_collisions`` to every pair found (and
    ``warning_ignore`` to the warning zone's pairs, when measured)."""
    listed = 'allowed_collisions' + (' and warning_ignore' if matrix.warning_zone else '')
    lines = [f'# {listed} of robot "{matrix.robot_name}", generated by {PROG}'
             + (f': {command}' if command else ''),
             f'# {_provenance(matrix)}',
             '# Use as one more --params-file of collision_sensor_node, or copy the lists.',
             '/**:', '  ros__parameters:']
    lines += _yaml_list('allowed_collisions', allowed_collisions(matrix))
    zone = matrix.warning_zone
    if zone is not None:
        lines.append(f'    # pairs nearer than {zone.distance:g} m in all {zone.samples} samples '
                     '(surfaces, unpadded; not proof)')
        lines += _yaml_list('warning_ignore', zone.warning_ignore())
    return '\n'.join(lines) + '\n'


def _yaml_list(name: str, entries: Sequence[str]) -> List[str]:
    if not entries:
        return [f'    {name}: []']
    return [f'    {name}: ['] + [f'      "{entry}",' for entry in entries] + ['    ]']


def srdf_entries(matrix: CollisionMatrix) -> List[Tuple[str, str, str]]:
    """Return ``(link1, link2, reason)`` of every pair found, sorted by pair."""
    return sorted((f.link1, f.link2, f.reason) for f in matrix.findings)


def _provenance(matrix: CollisionMatrix) -> str:
    text = (f'default pose {matrix.default_state}; Always: >= {matrix.always_fraction:g} of '
            f'samples, {matrix.rounds} round(s) of {matrix.samples_per_round}; seed {matrix.seed}')
    if matrix.never_samples:
        text += f'; Never: 0 collisions in {matrix.samples} samples (not proof)'
    return text


def report(matrix: CollisionMatrix) -> str:
    """Return the human report: the pairs by reason with their evidence."""
    counts = ', '.join(f'{len(matrix.pairs(reason))} {reason}' for reason in REASONS
                       if reason != NEVER or matrix.never_samples)
    lines = [f'robot "{matrix.robot_name}": {matrix.pair_count} pairs of links with geometry; '
             f'{len(matrix.findings)} need no check ({counts}), '
             f'{matrix.pair_count - len(matrix.findings)} stay checked']
    lines.append(f'default pose: {matrix.default_state}')
    rounds = f'{matrix.rounds} round(s) of {matrix.samples_per_round} samples'
    lines.append(f'Always: colliding in >= {matrix.always_fraction:g} of the samples; {rounds}, '
                 + ('the list stopped changing' if matrix.stable else
                    'WARNING: the list was still changing at --max-rounds; pairs near the '
                    'fraction may be missing or extra, raise --max-rounds or '
                    '--samples-per-round'))
    if matrix.never_samples:
        lines.append(f'Never: no collision in {matrix.samples} random samples; {NOT_PROOF}')
        if not any(f.clearance is not None for f in matrix.findings):
            lines.append(f'Never: {NO_DISTANCE}')
    lines.append(f'seed: {matrix.seed}')
    width = max((len(f'{f.link1} -- {f.link2}') for f in matrix.findings), default=0)
    for f in matrix.findings:
        name = f'{f.link1} -- {f.link2}'
        if f.reason == ADJACENT:
            detail = 'parent and child (nearest ancestor with geometry)'
        elif f.reason == DEFAULT:
            detail = f'in collision in the default pose ({matrix.default_state})'
        elif f.reason == ALWAYS:
            detail = (f'collided in {f.hits} of {f.samples} samples '
                      f'({100.0 * f.hits / f.samples:.1f} %)')
        else:
            detail = f'0 collisions in {f.samples} samples'
            if f.clearance is not None:
                detail += (f'; smallest clearance {f.clearance:.4f} m over {f.clearance_samples}'
                           ' of them')
        lines.append(f'  {f.reason:<8}  {name:<{width}}  {detail}')
    zone = matrix.warning_zone
    if zone is not None:
        lines.append(f'warning zone: {len(zone.farthest)} of the {zone.candidates} pairs that '
                     f'stay checked are nearer than {zone.distance:g} m in all {zone.samples} '
                     'samples (the default pose and random ones; surfaces, unpadded; not proof)'
                     + (': with warning_distance ' f'{zone.distance:g} the node warns about them '
                        'wherever the robot is; leave them out with warning_ignore'
                        if zone.farthest else ''))
        width = max((len(f'{a} -- {b}') for a, b in zone.farthest), default=0)
        for (a, b), farthest in zone.farthest.items():
            lines.append(f'  {"Warning":<8}  {a + " -- " + b:<{width}}  at most '
                         f'{farthest:.4f} m apart in every sample')
    return '\n'.join(lines)


# ------------------------------------------------------------------ command line

class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, as every other error of the tool
        self.exit(EXIT_ERROR, f'{PROG}: error: {message} (see --help)\n')


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f'"{text}" is not a fraction in (0, 1], e.g. 0.95')
    return value


def _distance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f'"{text}" is not a distance in metres > 0, e.g. 0.05')
    return value


def _at_least(least: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'"{text}" is not a whole number') from None
        if value < least:
            raise argparse.ArgumentTypeError(f'{value} is less than {least}')
        return value
    return parse


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = _Parser(
        prog=PROG,
        description='Compute the self-collision matrix of a robot: the pairs of links that '
                    'need no collision check (Adjacent, Default, Always and, with --never, '
                    'Never), as SRDF <disable_collisions> entries and as the '
                    'allowed_collisions list of collision_sensor_node.',
        epilog='Sampling is not proof: "Always" and "Never" come from random configurations '
               '(uniform within the joint limits, continuous joints in [-pi, pi]), and a '
               'configuration that was not drawn can behave otherwise; check a Never list '
               'before you trust it. The default pose is all joints at zero (even where zero '
               'lies outside a joint\'s limits), or --default-state. Exit status: 0 success, '
               '2 error.')
    parser.add_argument('urdf', metavar='URDF', help='robot description file')
    parser.add_argument('--package-path', metavar='NAME=DIR', action='append', default=[],
                        help='directory of a package named in package:// URIs (repeatable)')
    parser.add_argument('--xacro-arg', metavar='NAME:=VALUE', action='append', default=[],
                        help='argument of a .xacro robot description (repeatable)')
    parser.add_argument('--srdf', metavar='EXISTING',
                        help='existing SRDF: its group_states for --default-state, and the '
                             'document --in-place merges into (or --output copies merged); its '
                             'disable_collisions entries are kept, never used for sampling')
    parser.add_argument('--default-state', metavar='NAME',
                        help='group_state of --srdf used as the default pose (default: zero)')
    parser.add_argument('--always-fraction', type=_fraction, default=DEFAULT_ALWAYS_FRACTION,
                        metavar='F', help='a pair colliding in at least this fraction of the '
                                          'samples is "Always" (default %(default)s)')
    parser.add_argument('--samples-per-round', type=_at_least(1), metavar='N',
                        default=DEFAULT_SAMPLES_PER_ROUND,
                        help='random configurations per Always round (default %(default)s)')
    parser.add_argument('--max-rounds', type=_at_least(2), default=DEFAULT_MAX_ROUNDS,
                        metavar='N', help='stop the Always rounds here even if the list still '
                                          'changes, with a warning (default %(default)s)')
    parser.add_argument('--never', action='store_true',
                        help='also list "Never" pairs: no collision in --never-samples random '
                             'configurations (not proof that they cannot collide)')
    parser.add_argument('--never-samples', type=_at_least(1), default=DEFAULT_NEVER_SAMPLES,
                        metavar='N', help='samples a Never pair must stay clear in, the Always '
                                          'rounds\' included (default %(default)s)')
    parser.add_argument('--clearance', action='store_true',
                        help='with --never: measure each Never pair\'s smallest distance (the '
                             'engine\'s proximity query) over --clearance-samples of the '
                             'samples')
    parser.add_argument('--clearance-samples', type=_at_least(1),
                        default=DEFAULT_CLEARANCE_SAMPLES, metavar='N',
                        help='samples the clearance is measured over (default %(default)s)')
    parser.add_argument('--warning-distance', type=_distance, metavar='D',
                        help='also list the pairs that stay checked yet are nearer than D '
                             'metres in every sample (the node\'s warning zone would be on for '
                             'good): printed and written to --yaml as the node\'s '
                             'warning_ignore; surfaces unpadded, with padding add the two '
                             'links\' paddings to D')
    parser.add_argument('--warning-samples', type=_at_least(1), default=DEFAULT_WARNING_SAMPLES,
                        metavar='N', help='configurations a pair must stay nearer than D in, '
                                          'the default pose first (default %(default)s)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the random configurations (default %(default)s)')
    written = parser.add_mutually_exclusive_group()
    written.add_argument('--output', metavar='FILE.srdf',
                         help='write an SRDF: a new one, or with --srdf a copy of it with the new '
                              'entries merged in')
    written.add_argument('--in-place', action='store_true',
                         help='merge the new entries into the --srdf file itself; entries '
                              'already there are kept as they are, every other byte stays')
    parser.add_argument('--yaml', metavar='FILE',
                        help='write a ros2 params file setting allowed_collisions to every '
                             'pair found (and warning_ignore, with --warning-distance)')
    parser.add_argument('--progress', choices=MODES, default='auto',
                        help='progress bar on stderr: auto (on a terminal), always, never')
    return parser


def _write(path: str, data: bytes) -> None:
    try:
        with open(path, 'wb') as stream:
            stream.write(data)
    except OSError as err:
        raise ConfigError(f'cannot write "{path}": {err.strerror}; check the directory and '
                          'permissions') from None


def _run(args, argv: Sequence[str], start: float) -> int:
    from collision_sensor.engine.checker import CollisionChecker
    from collision_sensor.model.srdf import load_srdf_for_model
    from collision_sensor.model.srdf_merge import merge_disable_collisions, new_srdf

    if args.in_place and not args.srdf:
        raise ConfigError('--in-place merges into the --srdf file; add --srdf FILE, or write a '
                          'new file with --output')
    if args.clearance and not args.never:
        raise ConfigError('--clearance measures Never pairs; add --never')
    if not os.path.isfile(args.urdf):
        raise ConfigError(f'URDF "{args.urdf}" not found; give the path of the robot\'s URDF '
                          '(or .xacro) file')
    base = CollisionChecker.from_urdf(args.urdf,
                                      package_paths=parse_package_paths(args.package_path) or None,
                                      config={'ignore_adjacent': False},
                                      xacro_args=parse_xacro_args(args.xacro_arg) or None)
    srdf = original = None
    if args.srdf:
        srdf = load_srdf_for_model(args.srdf, base.model)
        with open(args.srdf, 'rb') as stream:
            original = stream.read()
    elif args.default_state:
        raise ConfigError(f'--default-state "{args.default_state}" needs the SRDF that defines '
                          'it; add --srdf FILE')

    matrix = compute_matrix(
        base, srdf=srdf, default_state=args.default_state, always_fraction=args.always_fraction,
        samples_per_round=args.samples_per_round, max_rounds=args.max_rounds, never=args.never,
        never_samples=args.never_samples, clearance=args.clearance,
        clearance_samples=args.clearance_samples, seed=args.seed,
        warning_distance=args.warning_distance, warning_samples=args.warning_samples,
        progress=args.progress)

    command = ' '.join([PROG] + list(argv))
    outcome = []
    entries = srdf_entries(matrix)
    if original is not None and (args.output or args.in_place):
        merged, added = merge_disable_collisions(original, entries, source=args.srdf)
        target = args.srdf if args.in_place else args.output
        _write(target, merged)
        outcome.append(f'SRDF: {target}: kept the {len(srdf.disabled_pairs)} entries of '
                       f'{args.srdf}, added {len(added)} new')
    elif args.output:
        _write(args.output, new_srdf(matrix.robot_name, entries,
                                     f'generated by {command}; {_provenance(matrix)}')
               .encode('utf-8'))
        outcome.append(f'SRDF: {args.output}: {len(entries)} entries')
    if args.yaml:
        _write(args.yaml, params_yaml(matrix, command).encode('utf-8'))
        outcome.append(f'params file: {args.yaml}')

    print(report(matrix))
    print('allowed_collisions: [' + ', '.join(f'"{e}"' for e in allowed_collisions(matrix))
          + ']')
    if matrix.warning_zone is not None:
        print('warning_ignore: [' + ', '.join(f'"{e}"' for e in
                                              matrix.warning_zone.warning_ignore()) + ']')
    for line in outcome:
        print(line)
    print(f'took {time.monotonic() - start:.1f} s')
    return EXIT_OK


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the tool; return the exit status (0 success, 2 error)."""
    start = time.monotonic()
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_command(PROG, build_parser(), lambda args: _run(args, argv, start), argv)


if __name__ == '__main__':
    sys.exit(main())
