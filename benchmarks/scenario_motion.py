"""Scenario 10: motion between states, certified against its targets.

A. Certified, never sampled. Random straight motions (``U(0.2, 2)`` rad long, Euclidean in
   joint space, from clear starts, within the limits) of example-robot-data robots with meshes,
   each in a cluttered scene sized to its reach (:mod:`motion_cells`). Oracle
   (:mod:`motion_oracle`): the motion sampled every 1e-3 rad with ``check_batch``; python-fcl
   (links placed by pinocchio) confirms the first sampled contact state, and measures the
   distance at every reported ``first_contact``. A contact is *missed* when a sampled state at
   ``t_s`` is in contact and ``check_motion`` says free or ``first_contact > t_s``; *false*
   when python-fcl's distance at ``first_contact`` exceeds the touching tolerance (1e-6 m);
   *between samples* when reported, not sampled, and confirmed by python-fcl.
B. Speed. Panda and UR5 in their cluttered cells, random ``U(0.5, 2)`` rad segments:
   ``check_motion`` against the same motion discretized every 0.01 rad (max over joints)
   checked by pinocchio+coal (``computeCollisions`` with its own FK at each state, stopping at
   the first state in contact) and by our ``check_batch`` (one call per segment). A 1,000
   waypoint Panda trajectory (a smooth random path through the clutter, waypoints 0.01 to
   0.03 rad apart, every motion free): ``check_path`` against the same two, discretized alike.
C. python-fcl's ``continuousCollide`` (:mod:`motion_ccd`).
D. ``update_motion`` against ``update`` per Python call on the benchmark's coherent walks
   (scenario 8's 1 kHz walk, the target, and scenario 2's streams of ten times its steps),
   from a clear state; before timing, every ``update_motion`` answer is compared with
   ``check_motion`` from the previous state.

Times are the best of ``rounds`` interleaved passes (:mod:`scenario_measure`), with the
spread over passes printed; on a shared machine they are development figures (the load
average is printed with each part).
"""
import math
import time
from collections import Counter
from dataclasses import dataclass, fields
from typing import List

import numpy as np

from collision_sensor.engine.motion import TOUCH_TOLERANCE, interpolate
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.engine.traversal import COUNT_BOX_TESTS, COUNT_MEASURES, COUNT_TRIANGLE_TESTS
from benchmarks import motion_ccd
from benchmarks.robot_peers import stream
from benchmarks.motion_cells import (
    BASE_SQUARE, MotionCell, discretized, discretized_path, motion_cells, random_segments,
    smooth_path)
from benchmarks.motion_oracle import (
    FCL_SLACK, SAMPLE_STEP, FclConfirmation, first_sampled_contact)
from benchmarks.scenario_cells import Cell, robot_cell
from benchmarks.scenario_measure import Candidate, interleaved_rounds_us
from benchmarks.scenario_peers import optional_peer, pinocchio_peer
from benchmarks.scenario_proximity import WALK_STEP
from benchmarks.scenario_report import Section, load_note, ratio, spread, us

TITLE = 'Scenario 10: motion between states, certified'
#: Part B: check_motion <= this x pinocchio+coal on the discretized motion ...
PINOCCHIO_RATIO = 0.5
#: ... and below this x our check_batch on it.
BATCH_RATIO = 1.0
#: rad or m: the discretization the peers check a motion at (part B).
DISCRETIZATION = 0.01
#: Part D: two first contacts of one step are the same one when this near (fraction of the
#: step); each is certified to within the touching tolerance of contact, but update_motion
#: marches from its incremental query's fronts, check_motion from the roots.
FIRST_CONTACT_SAME = 1e-5
#: Part D: update_motion <= this x update.
STREAM_RATIO = 1.3
#: m: the path's clearance is measured up to this.
PATH_NEAR = 0.05
#: A sampled contact at t_s is missed if first_contact > t_s + this (rounding of t).
T_SLACK = 1e-12
#: Failures printed as literals, per robot.
SHOWN = 3


def run(settings, workdir: str) -> Section:
    """Run the four parts; return the section."""
    section = Section(10, TITLE)
    section.text(
        'Figures are development figures measured on a shared machine; the load average '
        '(1 min) is printed with each part. Ratios are ours / peer, measured in the same run.')
    start = time.perf_counter()
    # The cells are seeded per robot: the arms alone are those of the whole set.
    cells = motion_cells(settings.seed, settings.motion_robots
                         if 'A' in settings.motion_parts else ('panda', 'ur5'))
    arms = [cell for cell in cells if cell.name in ('panda', 'ur5')]
    panda = next(cell for cell in cells if cell.name == 'panda')
    took = [('robots and scenes', time.perf_counter() - start)]
    for name, part in (('A', lambda: certified(section, settings, cells)),
                       ('B', lambda: speed(section, settings, arms)),
                       ('C', lambda: motion_ccd.run(section, settings, workdir, panda)),
                       ('D', lambda: streams(section, settings, arms))):
        if name not in settings.motion_parts:
            continue
        start = time.perf_counter()
        part()
        took.append((f'part {name}', time.perf_counter() - start))
    section.text('', 'Wall time: ' + ', '.join(f'{name} {seconds:.0f} s'
                                               for name, seconds in took) + '.')
    return section


def _work(checker, run) -> np.ndarray:
    """Box and triangle tests done by ``run()`` (the engine's counters)."""
    checker.counters[:] = 0
    run()
    return checker.counters[[COUNT_BOX_TESTS, COUNT_TRIANGLE_TESTS]].astype(float)


# ---------------------------------------------------------------------------- A. certified
def certified(section: Section, settings, cells: List[MotionCell]) -> None:
    """Part A: every robot's random segments against the oracle; judge 0 missed, 0 false."""
    per_robot = math.ceil(settings.motion_segments / max(1, len(cells)))
    section.text(
        '', '#### A. Certified, never sampled', '',
        f'{per_robot} random segments per robot ({per_robot * len(cells):,} in all), '
        f'U(0.2, 2) rad long (Euclidean in joint space), from clear starts, within the limits '
        f'(continuous joints in [-pi, pi]; a planar base\'s x and y within +-{BASE_SQUARE:g} '
        'm, any heading). '
        f'Each robot in a scene of 14 boxes, rods and balls sized to its reach R (none on its '
        f'base). Oracle: the motion sampled every {SAMPLE_STEP:g} rad (max over joints) with '
        '`check_batch`; python-fcl, with the links placed by pinocchio, confirms the first '
        'sampled contact state (same colliding pairs; pairs in the sliver between a '
        'primitive\'s true shape and its inscribed tessellation may go either way) and '
        f'measures the distance at each reported first contact (within {TOUCH_TOLERANCE:g} m '
        f'+ {FCL_SLACK:g}: confirmed). Missed: a sampled contact at t_s with the motion '
        'reported free or first_contact > t_s. False: a reported contact python-fcl puts '
        f'beyond the tolerance. {load_note()}.')
    rows, total, shown = [], Tally(), []
    for k, cell in enumerate(cells):
        tally, failures, fcl_missing = _certify(
            cell, per_robot, np.random.default_rng([settings.seed, 10, k]))
        total.add(tally)
        shown += failures[:SHOWN]
        checker = cell.checker
        slivers = f', {tally.slivers} sliver pairs' if tally.slivers else ''
        rows.append([
            cell.name, len(checker.joint_names), f'{len(checker.forest.tris):,}',
            len(checker.checked_pairs), f'{cell.reach:.2f}', tally.segments, tally.contacts,
            f'{tally.sampled} ({fcl_missing or f"{tally.agreed} agreed"}{slivers})',
            tally.missed,
            f'{tally.between} ({fcl_missing or f"{tally.between_confirmed} confirmed"})',
            fcl_missing or tally.false, fcl_missing or f'{tally.max_distance:.1e}',
            tally.early, f'{tally.states / tally.segments:.0f}',
            f'{tally.motion_seconds / tally.segments * 1e3:.2f}'])
    section.table(['robot', 'joints', 'triangles', 'pairs', 'R (m)', 'segments',
                   'contacts reported', 'sampled contacts (python-fcl)', 'missed',
                   'between samples (python-fcl)', 'false contacts',
                   'largest python-fcl distance at a first contact (m)',
                   'reported > 1 sample step before the sampled contact',
                   'sampled states / segment', '`check_motion` ms / segment'], rows)
    section.text(
        f'In all: {total.segments:,} segments, {total.contacts:,} contacts reported '
        f'({total.between} between samples), {total.missed} missed, {total.false} false '
        f'(false-contact rate {total.false / max(1, total.measured):.2%} of the '
        f'{total.measured:,} python-fcl measured).')
    if shown:
        section.text('', 'Failures (paste into a test):', '', '```text', *shown, '```')
    section.judge(
        f'S10 certified: 0 missed contacts ({total.segments:,} segments, {len(cells)} '
        f'robots, sampled every {SAMPLE_STEP:g} rad)',
        f'{total.missed} missed of {total.sampled:,} sampled contacts (python-fcl agreed on '
        f'{total.agreed:,})', total.missed == 0)
    section.judge(
        'S10 certified: 0 false contacts (python-fcl distance at first_contact <= 1e-6 m)',
        f'{total.false} of {total.measured:,} reported contacts; largest distance '
        f'{total.max_distance:.1e} m' if total.measured else 'python-fcl or pinocchio not '
        'installed', total.false == 0 if total.measured else None)
    _paths_agree(section, settings, cells)


def _paths_agree(section: Section, settings, cells: List[MotionCell]) -> None:
    """``check_path`` marches a polyline as one path (pairs leap over waypoints): on random
    paths of very unequal segments it must name the first segment that ``check_motion``,
    certified above, finds not free one by one."""
    paths = contacts = differ = 0
    shown = []
    for k, cell in enumerate(cells):
        checker = cell.checker
        rng = np.random.default_rng([settings.seed, 14, k])
        for _ in range(settings.motion_paths):
            Q = _uneven_path(checker, cell.lower, cell.upper, rng)
            if Q is None:
                continue
            got = checker.check_path(Q).first_invalid_segment
            expected = next((i for i in range(len(Q) - 1)
                             if checker.check_motion(Q[i], Q[i + 1]).in_collision), None)
            paths += 1
            contacts += expected is not None
            if got != expected:
                differ += 1
                if len(shown) < SHOWN:
                    shown.append(f'{cell.name}: check_path {got}, segments {expected}, '
                                 f'Q={Q.tolist()}')
    section.text(
        '', f'Paths: {paths:,} random paths ({settings.motion_paths} per robot, from clear '
        'starts) of 3 to 60 segments, each 1e-4 rad up to 0.01, 0.1 or 0.5 rad long '
        '(log-uniform; the longest drawn per path), checked with `check_path` and segment by '
        'segment with '
        f'`check_motion`: {contacts:,} meet contact; the first segment not free differs on '
        f'{differ}.')
    if shown:
        section.text('', 'Paths that differ (paste into a test):', '', '```text', *shown, '```')
    section.judge('S10 paths: `check_path` names the segment `check_motion` does one by one',
                  f'{differ} of {paths:,} paths differ ({contacts:,} meet contact)',
                  differ == 0)


def _uneven_path(checker, lower, upper, rng):
    """A smooth random walk of 3 to 60 segments of very unequal lengths (log-uniform from
    1e-4 rad up to 0.01, 0.1 or 0.5 rad) within the limits, from a random clear state (None
    when 100 draws found none)."""
    q = next((q for q in rng.uniform(lower, upper, (100, len(lower)))
              if not checker.check(q).in_collision), None)
    if q is None:
        return None
    longest = rng.choice([0.01, 0.1, 0.5])
    direction = rng.normal(size=len(q))
    rows = [q]
    for _ in range(int(rng.integers(3, 61))):
        direction = 0.7 * direction + 0.7 * rng.normal(size=len(q))
        step = math.exp(rng.uniform(math.log(1e-4), math.log(longest)))
        q = np.clip(q + step * direction / np.linalg.norm(direction), lower, upper)
        rows.append(q)
    return np.array(rows)


@dataclass
class Tally:
    """Part A's counts over segments (see the table's columns)."""

    segments: int = 0
    states: int = 0             # states the oracle sampled
    contacts: int = 0           # reported by check_motion
    sampled: int = 0            # motions with a sampled state in contact
    agreed: int = 0             # ... whose first one python-fcl confirms
    slivers: int = 0            # pairs in a primitive's sliver there
    missed: int = 0
    early: int = 0              # first_contact more than one sample step before t_s
    between: int = 0            # reported, none sampled
    between_confirmed: int = 0
    measured: int = 0           # reported contacts python-fcl measured
    false: int = 0
    max_distance: float = 0.0
    motion_seconds: float = 0.0

    def add(self, other: 'Tally') -> None:
        """Add ``other``'s counts (the largest distance: the larger)."""
        for f in fields(self):
            mine, theirs = getattr(self, f.name), getattr(other, f.name)
            setattr(self, f.name, max(mine, theirs) if f.name == 'max_distance'
                    else mine + theirs)


def _certify(cell: MotionCell, n: int, rng):
    """Check ``n`` random segments of ``cell`` against the oracle; return the
    :class:`Tally`, the failures as literals and why python-fcl did not run (or None)."""
    checker = cell.checker
    oracle, fcl_missing = optional_peer(FclConfirmation, checker, cell.urdf)
    segments = random_segments(checker, cell.lower, cell.upper, n, rng, 0.2, 2.0)
    tally, failures = Tally(segments=len(segments)), []
    for q0, q1 in segments:
        start = time.perf_counter()
        result = checker.check_motion(q0, q1)
        tally.motion_seconds += time.perf_counter() - start
        t_s, pairs, q_s, states, samples = first_sampled_contact(checker, q0, q1)
        tally.states += states
        tally.contacts += result.in_collision
        literal = f'{cell.name}: q_from={q0.tolist()}, q_to={q1.tolist()}, result={result}'
        if t_s is not None:
            tally.sampled += 1
            if not result.in_collision or result.first_contact > t_s + T_SLACK:
                tally.missed += 1
                failures.append(f'MISSED {literal}, sampled contact t={t_s} {pairs}')
            elif t_s - result.first_contact > 1.0 / (samples - 1) + T_SLACK:
                tally.early += 1
            if oracle is not None:
                agrees, slivers = oracle.confirm_state(q_s, pairs)
                tally.agreed += agrees
                tally.slivers += slivers
                if not agrees:
                    failures.append(f'FCL DIFFERS at the sampled contact {literal}, t={t_s}')
        if not result.in_collision:
            continue
        tally.between += t_s is None
        if oracle is None:
            continue
        q = interpolate(checker.motion_kinds, q0, q1, [result.first_contact])[0]
        distance = oracle.nearest(q, result.colliding_pairs)
        tally.measured += 1
        tally.max_distance = max(tally.max_distance, distance)
        if distance <= TOUCH_TOLERANCE + FCL_SLACK:
            tally.between_confirmed += t_s is None
        else:
            tally.false += 1
            failures.append(f'FALSE {literal}, python-fcl distance {distance:.3e} m')
    return tally, failures, fcl_missing


# ---------------------------------------------------------------------------- B. speed
def _pinocchio_motion(peer):
    """``run(states)``: computeCollisions (its FK, every pair, stopping at the first pair in
    contact) at each state until one is in contact; True if one is."""
    compute = peer.pin.computeCollisions
    args = (peer.model, peer.data, peer.geom, peer.geom_data)

    def run(states):
        for q in states:
            if compute(*args, q, True):
                return True
        return False
    return run


def speed(section: Section, settings, cells: List[MotionCell]) -> None:
    """Part B: check_motion and check_path against the discretized motion, pinocchio+coal and
    our check_batch."""
    section.text(
        '', '#### B. Speed against the motion discretized every 0.01 rad', '',
        f'{settings.motion_speed_segments} random segments per robot, U(0.5, 2) rad, from clear '
        f'starts, in the cells of part A. The motion discretized every {DISCRETIZATION:g} rad '
        '(max over joints) is checked by pinocchio+coal (`computeCollisions`, its own FK and '
        'mesh loading, stopping at the first pair and the first state in contact; one Python '
        'call per state) and by our `check_batch` (all states in one call, no early stop). '
        'Time per segment (per path): the best of '
        f'{settings.rounds} interleaved passes, then min / median / max over the passes. '
        f'{load_note()}.')
    rows, notes = [], []
    for k, cell in enumerate(cells):
        checker = cell.checker
        rng = np.random.default_rng([settings.seed, 11, k])
        segments = random_segments(checker, cell.lower, cell.upper,
                                   settings.motion_speed_segments, rng, 0.5, 2.0)
        states = [discretized(checker, q0, q1, DISCRETIZATION) for q0, q1 in segments]
        rows.append(_speed_row(section, settings, cell, f'{len(segments)} segments', segments,
                               states, per='segment'))
        if cell.name == 'panda':
            path = smooth_path(checker, cell.lower, cell.upper, settings.motion_waypoints,
                               np.random.default_rng([settings.seed, 12]))
            rows.append(_speed_row(section, settings, cell, f'{len(path)}-waypoint path',
                                   [path], [discretized_path(checker, path, DISCRETIZATION)],
                                   per='path'))
            notes.append(_path_note(checker, path))
    section.table(['robot', 'motions', 'states at 0.01 rad', '`check_motion` / `check_path` '
                   'us', 'pinocchio+coal us', '`check_batch` us', 'ours / pinocchio',
                   'ours / check_batch', 'min / median / max over passes: ours; pinocchio; '
                   'check_batch', 'in contact: certified / check_batch / pinocchio',
                   'box / triangle tests: ours; check_batch'], rows)
    section.text(*notes)


def _path_note(checker, path) -> str:
    """How the path goes: its length, steps and clearance (smallest distance at a waypoint)."""
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    near = [min((r.distance for r in checker.proximity(q, PATH_NEAR)), default=PATH_NEAR)
            for q in path]
    return (f'The Panda trajectory: {len(path)} waypoints, {steps.sum():.1f} rad in all, '
            f'steps {steps.min():.3f} to {steps.max():.3f} rad (Euclidean); it bends around the '
            'objects it would hit (every motion between waypoints free: sampled every 2e-3 rad '
            'as it is drawn, and certified); clearance at the waypoints (`proximity`): '
            f'smallest {min(near) * 1e3:.3g} mm, {sum(d < 0.01 for d in near)} waypoints '
            'within 1 cm of something.')


def _speed_row(section, settings, cell, label, motions, states, per):
    checker = cell.checker
    peer, missing = optional_peer(
        pinocchio_peer, Cell(cell.name, cell.urdf, cell.srdf, cell.package_paths,
                             checker.scene_objects), checker)
    if per == 'path':
        def ours(path):
            return checker.check_path(path)
    else:
        def ours(motion):
            return checker.check_motion(motion[0], motion[1])
    answers = [ours(m).in_collision for m in motions]
    candidates = [Candidate('ours', ours, motions),
                  Candidate('check_batch', checker.check_batch, states)]
    batch_answers = [bool(checker.check_batch(S).any()) for S in states]
    pin_answers = None
    if peer is not None:
        run = _pinocchio_motion(peer)
        pin_states = [[peer.configuration(checker, q) for q in S] for S in states]
        pin_answers = [run(S) for S in pin_states]
        candidates.append(Candidate('pinocchio', run, pin_states))
    passes = interleaved_rounds_us(candidates, settings.rounds,
                                   warm_items=1 if per == 'path' else 0)
    best = {label_: min(values) for label_, values in passes.items()}
    theirs = best.get('pinocchio')
    work_ours = _work(checker, lambda: [ours(m) for m in motions]) / len(motions)
    work_batch = _work(checker, lambda: [checker.check_batch(S) for S in states]) / len(motions)
    what = '`check_path`' if per == 'path' else '`check_motion`'
    name = f'{cell.name} {"trajectory" if per == "path" else "segments"}'
    section.judge_ratio(f'S10 {name}: {what} <= {PINOCCHIO_RATIO}x pinocchio+coal at '
                        f'{DISCRETIZATION:g} rad', best['ours'], theirs, PINOCCHIO_RATIO,
                        'pinocchio+coal', missing)
    section.judge(f'S10 {name}: {what} < {BATCH_RATIO:g}x our `check_batch` at '
                  f'{DISCRETIZATION:g} rad', f'{ratio(best["ours"], best["check_batch"])} '
                  f'({us(best["ours"])} vs {us(best["check_batch"])} us)',
                  best['ours'] < BATCH_RATIO * best['check_batch'])
    contacts = (f'{sum(answers)} / {sum(batch_answers)} / '
                f'{sum(pin_answers) if pin_answers is not None else missing}')
    spreads = '; '.join(spread(passes[k]) if k in passes else '-'
                        for k in ('ours', 'pinocchio', 'check_batch'))
    return [cell.name, label, f'{sum(len(S) for S in states) / len(states):.0f} / {per}',
            us(best['ours']), us(theirs) if theirs is not None else missing,
            us(best['check_batch']), ratio(best['ours'], theirs),
            ratio(best['ours'], best['check_batch']), spreads, contacts,
            f'{work_ours[0]:.0f} / {work_ours[1]:.0f}; {work_batch[0]:.0f} / '
            f'{work_batch[1]:.0f}']


# ---------------------------------------------------------------------------- D. streams
def _clear_start(checker, seed: int) -> np.ndarray:
    """The first clear configuration of a seeded random draw within the limits."""
    for q in random_configurations(checker, 1000, seed):
        if not checker.check(q).in_collision:
            return q
    raise RuntimeError('no clear configuration in 1000 random draws')


def _walks(checker, settings):
    """The benchmark's coherent walks from a clear state: ``[(label, frames)]``."""
    start = _clear_start(checker, settings.seed)
    n = len(checker.joint_names)
    walks = [(f'S8 walk: all joints N(0, {WALK_STEP:g}), within limits',
              stream(checker, settings.motion_walk_steps, n, settings.seed, step=WALK_STEP,
                     bounds=sampling_bounds(checker), start=start))]
    for moving in sorted({1, 3, n}):
        walks.append((f'S2 stream: {moving} joint{"s" if moving > 1 else ""} N(0, 0.02)',
                      stream(checker, settings.stream_steps, moving, settings.seed,
                             start=start)))
    return walks


def motion_difference(a, b) -> str:
    """How motion answer ``a`` differs from ``b``: ``''`` (the same: first_contact to 1e-5 of
    the motion), ``'in contact'``, ``'first_contact'`` or ``'pairs'``."""
    if a.in_collision != b.in_collision:
        return 'in contact'
    if a.in_collision and abs(a.first_contact - b.first_contact) > FIRST_CONTACT_SAME:
        return 'first_contact'
    return 'pairs' if a.colliding_pairs != b.colliding_pairs else ''


def streams(section: Section, settings, cells: List[MotionCell]) -> None:
    """Part D: update_motion against update per Python call on the coherent walks."""
    section.text(
        '', '#### D. `update_motion` against `update` on the coherent walks', '',
        f'Scenario 8\'s 1 kHz walk ({settings.motion_walk_steps} steps, every joint N(0, '
        f'{WALK_STEP:g}) rad per step, within the limits) and scenario 2\'s streams '
        f'({settings.stream_steps} steps, 1, 3 or all joints N(0, 0.02) per step), each from '
        'a clear state; Panda and UR5 alone (as scenarios 2 and 8 have them) and in their '
        'cluttered cells of part A. One Python call per step; each pass starts from a full '
        'check of the first state (untimed). Before timing, every `update_motion` answer is '
        'compared with `check_motion` from the previous state (in contact, pairs, '
        f'first_contact to {FIRST_CONTACT_SAME:g} of the step: each a certified answer, its '
        'state within 1e-6 m of contact, marched from what each call knows, so not always '
        f'the same float). {load_note()}.')
    rows, differences, streams_2 = [], [], []
    for cell in cells:
        bare = robot_cell(cell.name).checker()
        for where, checker in (('alone', bare), ('cluttered', cell.checker)):
            worst = None
            for k, (label, frames) in enumerate(_walks(checker, settings)):
                row, r, first = _stream_row(checker, settings, frames)
                rows.append([cell.name, where, label] + row)
                if first:
                    differences.append(f'{cell.name} {where}, {label}: {first}')
                if k == 0:  # the 1 kHz walk: the target
                    section.judge(f'S10 {cell.name} {where}: `update_motion` <= '
                                  f'{STREAM_RATIO}x `update` on the 1 kHz walk',
                                  f'{r:.2f}x ({row[1]} vs {row[0]} us)', r <= STREAM_RATIO)
                elif worst is None or r > worst[0]:
                    worst = (r, label)
            streams_2.append(f'{cell.name} {where} {worst[0]:.2f}x ({worst[1]})')
    section.table(['robot', 'scene', 'walk', '`update` us', '`update_motion` us',
                   'update_motion / update', 'min / median / max over passes: update; '
                   'update_motion', 'steps with a contact on the way', 'answers equal',
                   'box / triangle tests per step: update; update_motion (pairs measured '
                   'at the step\'s end instead of marched)'], rows)
    section.text('', 'Not a target: scenario 2\'s streams step 0.02 rad per joint, ten times the '
                 '1 kHz walk\'s (20 rad/s at 1 kHz, beyond these arms\' joint speeds: a slow '
                 'stream\'s steps), so more pairs march; the worst of them per cell: ' +
                 ', '.join(streams_2) + '.')
    if differences:
        section.text('', 'Where `update_motion` and `check_motion` differ (the first step of '
                     'each walk; paste into a test):', '', '```text', *differences, '```')


def _stream_row(checker, settings, frames):
    checker.check(frames[0])
    previous, contacts, kinds, first = frames[0], 0, Counter(), None
    for step, q in enumerate(frames):
        expected = checker.check_motion(previous, q)
        got = checker.update_motion(q)
        kind = motion_difference(got, expected)
        if kind:
            kinds[kind] += 1
            first = first or (f'step {step}, q_from={previous.tolist()}, q_to={q.tolist()}: '
                              f'update_motion {got}, check_motion {expected}')
        contacts += got.in_collision
        previous = q
    candidates = [Candidate('update', checker.update, frames,
                            before=lambda: checker.check(frames[0])),
                  Candidate('update_motion', checker.update_motion, frames,
                            before=lambda: checker.check(frames[0]))]
    passes = interleaved_rounds_us(candidates, settings.rounds)
    update, motion = min(passes['update']), min(passes['update_motion'])

    def walk(call):
        checker.check(frames[0])
        for q in frames:
            call(q)
    work_update = _work(checker, lambda: walk(checker.update)) / len(frames)
    work_motion = _work(checker, lambda: walk(checker.update_motion)) / len(frames)
    measures = checker.counters[COUNT_MEASURES] / len(frames)
    return [us(update), us(motion), ratio(motion, update),
            f'{spread(passes["update"])}; {spread(passes["update_motion"])}',
            f'{contacts} of {len(frames)}',
            'yes' if not kinds else 'NO: ' + ', '.join(
                f'{n} step{"s" if n > 1 else ""} differ in {kind}' for kind, n in kinds.items()),
            f'{work_update[0]:.1f} / {work_update[1]:.1f}; {work_motion[0]:.1f} / '
            f'{work_motion[1]:.1f} ({measures:.2f} pairs measured)'], motion / update, first
