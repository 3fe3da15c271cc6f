"""Scenario 2: coherent streams where one, three or all joints move per step.

The streams come from :func:`benchmarks.robot_peers.stream` (random joints step by
N(0, 0.02) each step). ``update`` (incremental, paper sec. 4.2) is timed against ``check`` on
the same steps, and against the peers, which have no incremental mode and check every step in
full. Before timing, ``update``'s answers are compared with ``check``'s on every step.

Two ways of feeding a stream are timed. Per call: one Python call per step (what the node
does with each joint-state message); every call pays the same fixed cost of entering the
compiled code (the "0 joints moving" row), which is most of a Panda step. In a path: the
whole stream in one compiled call (``update_batch`` against ``check_batch``, for a whole
recorded path), which measures the engine's own work per step. The target is
judged on the latter, and both ratios are printed.
"""
import numpy as np

from benchmarks.robot_peers import stream
from benchmarks.scenario_measure import Candidate, interleaved_us
from benchmarks.scenario_peers import FclCell, optional_peer, pinocchio_peer
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 2: coherent streams, update against check and the peers'
TARGET_RATIO = 0.2          # one joint moving: update <= 0.2x check
#: Each pass of every candidate is preceded by an untimed run over this many items (a whole
#: path for the one-call candidates): a Panda path of 2000 steps in one call takes ~0.3 ms,
#: and after a peer's pass its first steps were refilling the caches (0.02 us per step
#: became 0.1 us; see :func:`interleaved_us`).
WARM_ITEMS = 200


def run(settings, cells) -> Section:
    """Measure every cell; return the section (target: one joint, update <= 0.2x check)."""
    section = Section(2, TITLE)
    section.text(
        f'{settings.stream_steps} steps per stream; each step moves 1, 3 or all joints '
        '(chosen at random) by N(0, 0.02) rad or m (not clipped to the limits), or none (the '
        'same q again: what a call costs when nothing is re-checked). Time per step, best of '
        f'{settings.rounds} interleaved passes; `update` starts each pass from a full check of '
        'the first step (untimed). Peers check every step in full (pinocchio+coal with its own '
        'FK; python-fcl placed with our poses, FK not counted). Every pass of every '
        f'implementation starts after an untimed run over its first {WARM_ITEMS} steps (the '
        'whole path for the one-call runs), with its data in the caches. Per call: one Python '
        'call per step, as the node makes for each joint-state message; each pays a fixed cost of '
        'entering compiled code (row 0). In a path: the whole stream in one compiled call '
        '(`update_batch` against `check_batch`, for a whole recorded path), the engine\'s '
        'own work per step; the target is judged on it.')
    plot = {}
    for cell in cells:
        checker = cell.checker()
        pin, pin_missing = optional_peer(pinocchio_peer, cell, checker)
        fcl_cell, fcl_missing = optional_peer(FclCell, checker, cell.scene)
        rows = []
        n_joints = len(checker.joint_names)
        for moving in sorted({0, 1, 3, n_joints}):
            rows.append(_measure(checker, pin, fcl_cell, moving, settings, section, cell.name,
                                 pin_missing, fcl_missing, plot))
        section.text('', f'#### {cell.name} ({n_joints} joints)')
        section.table(['joints moving', 'per call: `update` us', '`check` us', 'update / check',
                       'in a path: `update_batch` us / step', '`check_batch` us / step',
                       'update / check', 'pinocchio+coal us', 'python-fcl us',
                       'update / pinocchio', 'update / fcl', 'pairs re-checked / step',
                       'update == check'], rows)
    section.plot['streams'] = plot
    return section


def _measure(checker, pin, fcl_cell, moving, settings, section, name, pin_missing,
             fcl_missing, plot):
    frames = stream(checker, settings.stream_steps, moving, settings.seed)
    expected, poses = [], []
    for q in frames:
        expected.append(checker.check(q).colliding_pairs)
        poses.append(checker.link_poses())
    checker.check(frames[0])
    mismatches, rechecked = 0, 0
    for q, want in zip(frames, expected):
        result = checker.update(q)
        mismatches += result.colliding_pairs != want
        rechecked += result.rechecked_pairs

    path = np.array(frames)
    candidates = [Candidate('update', checker.update, frames,
                            before=lambda: checker.check(frames[0])),
                  Candidate('check', checker.check, frames),
                  Candidate('update_batch', checker.update_batch, [path],
                            before=lambda: checker.check(frames[0])),
                  Candidate('check_batch', checker.check_batch, [path])]
    if pin is not None:
        candidates.append(Candidate('pinocchio', pin.check,
                                    [pin.configuration(checker, q) for q in frames]))
    if fcl_cell is not None:
        candidates.append(Candidate('fcl', lambda P: (fcl_cell.place(P), fcl_cell.check()),
                                    poses))
    times = interleaved_us(candidates, settings.rounds, warm_items=WARM_ITEMS)
    for label in ('update_batch', 'check_batch'):
        times[label] /= len(frames)  # per step
    batch_mismatches = _batch_mismatches(checker, path, expected)
    update, check = times['update'], times['check']
    path_update, path_check = times['update_batch'], times['check_batch']
    if moving == 1:
        verdict = section.judge(
            f'S2 {name}: one joint moving, update <= {TARGET_RATIO}x check (engine per step, '
            'a path in one call)',
            f'{ratio(path_update, path_check)} ({us(path_update)} vs {us(path_check)} us); '
            f'per Python call {ratio(update, check)} ({us(update)} vs {us(check)} us)',
            path_update <= TARGET_RATIO * path_check)
        label = f'1 (target <= {TARGET_RATIO}x: **{verdict.word}**)'
    elif moving == 0:
        label = '0 (same q every step: the cost of a call)'
    else:
        label = str(moving)
    plot.setdefault(name, {})[moving] = times
    mismatches += batch_mismatches
    return [label, us(update), us(check), ratio(update, check), us(path_update),
            us(path_check), ratio(path_update, path_check),
            us(times['pinocchio']) if pin is not None else pin_missing,
            us(times['fcl']) if fcl_cell is not None else fcl_missing,
            ratio(update, times.get('pinocchio')), ratio(update, times.get('fcl')),
            f'{rechecked / len(frames):.1f} of {len(checker.checked_pairs)}',
            'yes' if mismatches == 0 else f'NO: {mismatches} steps differ']


def _batch_mismatches(checker, path, expected) -> int:
    """Steps where ``update_batch`` or ``check_batch`` differ from single ``check`` calls."""
    names = checker.checked_pairs
    checker.check(path[0])
    mismatches = 0
    for statuses in (checker.update_batch(path), checker.check_batch(path)):
        for row, want in zip(statuses, expected):
            mismatches += tuple(names[p] for p in np.flatnonzero(row)) != want
    return mismatches
