"""Scenario 5: the parts, each alternative measured on the same input.

- box tests: the paper's (sec. 5) against the 15-axis test, ns per test on random and
  near-touching pairs (:mod:`benchmarks.box_tests`, compiled loops);
- expansion rules (sec. 4.1) with each box test: time and work per query on the Panda;
- bounding-volume fits (vertex PCA, hull PCA, minimum volume): total volume of all the trees'
  boxes, of the root boxes, build time and query time on the Panda;
- the cost of a call: one Python ``check(q)`` against the engine's own time for the same
  check (``check_batch``, one call for all configurations), on the Panda.

These tables choose the checker's defaults; the one target is the binding's overhead.
"""
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.engine.traversal import EXPANSION_RULES
from benchmarks import box_tests
from benchmarks.scenario_cells import robot_cell
from benchmarks.scenario_measure import (
    Candidate, interleaved_us, seconds, work_per_check)
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 5: the parts (box tests, expansion rules, bounding-volume fits)'


def run(settings) -> Section:
    """Measure the three comparisons; return the section."""
    section = Section(5, TITLE)
    _box_tests(section, settings)
    cell = robot_cell('panda')
    base = cell.checker()
    configurations = list(random_configurations(base, settings.configurations, settings.seed))
    _rules(section, cell, configurations, settings)
    _fits(section, cell, configurations, settings)
    _call_cost(section, base, configurations, settings)
    return section


def _call_cost(section, checker, configurations, settings):
    """One Python call per check against the engine's own time per check (a batch)."""
    import numpy as np
    Q = np.asarray(configurations)
    same = Q[0].copy()
    checker.check(same)
    times = interleaved_us([
        Candidate('check', checker.check, configurations),
        Candidate('batch', lambda _: checker.check_batch(Q), [None]),
        Candidate('update_same', checker.update, [same] * len(configurations)),
    ], settings.rounds)
    engine_us = times['batch'] / len(Q)
    overhead = times['check'] - engine_us
    section.text('', '#### The cost of a call (Panda)', '',
                 f'{len(Q)} random configurations. The engine\'s own time per check is '
                 '`check_batch` over all of them in one call, divided by their number; a Python '
                 '`check(q)` adds the binding (argument checks, the GIL released and taken '
                 'back) and the result tuple. `update` with nothing moved is a call that does '
                 'no work at all.')
    section.table(['call', 'us'], [
        ['`check(q)`, one Python call per configuration', us(times['check'])],
        ['`check_batch(Q)`, per configuration (the engine alone)', us(engine_us)],
        ['overhead of a call: the difference', us(overhead)],
        ['`update(q)` with q unchanged (a call that does nothing)', us(times['update_same'])],
    ])
    section.judge('S5 binding overhead of `check(array)` over the engine\'s own time <= 1 us',
                  f'{us(overhead)} us ({us(times["check"])} vs {us(engine_us)} us)',
                  overhead <= 1.0)


def _box_tests(section, settings):
    rows = box_tests.measure(settings.box_pairs, settings.box_repeat, settings.seed,
                             rounds=settings.rounds)
    section.text('', '#### Box tests (ns per test)', '',
                 f'{settings.box_pairs} pairs per set, {settings.box_repeat} loops, best of '
                 f'{settings.rounds}; both tests run on the same pairs and must agree on every '
                 'one (the run stops if they do not).')
    section.table(['pair set', 'paper ns', '15-axis ns', 'paper / 15-axis', 'separated'],
                  [[name, f'{paper:.1f}', f'{sat:.1f}', f'{paper / sat:.2f}', f'{frac:.1%}']
                   for name, paper, sat, frac in rows])


def _rules(section, cell, configurations, settings):
    default = CheckerConfig()
    checkers = {}
    for box_test in ('sat', 'paper'):
        for expansion in EXPANSION_RULES:
            checkers[(box_test, expansion)] = cell.checker(
                config={'box_test': box_test, 'expansion': expansion})
    work = {key: work_per_check(c, configurations) for key, c in checkers.items()}
    times = interleaved_us([Candidate(key, c.check, configurations)
                            for key, c in checkers.items()], settings.rounds)
    best = min(times, key=times.get)
    rows = []
    for key, c in checkers.items():
        box_test, expansion = key
        mark = ' (default)' if (box_test, expansion) == (default.box_test,
                                                         default.expansion) else ''
        w = work[key]
        rows.append([f'{box_test}{mark}', expansion, us(times[key]),
                     ratio(times[key], times[best]), f'{w["boxes"]:.0f}',
                     f'{w["spheres"]:.0f}', f'{w["triangles"]:.0f}'])
    section.text('', '#### Expansion rules on the Panda (per random configuration)', '',
                 f'{len(configurations)} random configurations, full `check`; best of '
                 f'{settings.rounds} interleaved passes. Fastest: {best[0]} + {best[1]}.')
    section.table(['box test', 'expansion', 'us / query', 'vs fastest', 'box tests / query',
                   'sphere skips / query', 'triangle tests / query'], rows)


def _fits(section, cell, configurations, settings):
    checkers, builds = {}, {}
    for fit in settings.fits:
        checkers[fit], builds[fit] = seconds(lambda: cell.checker(config={'obb_fit': fit}))
    times = interleaved_us([Candidate(fit, c.check, configurations)
                            for fit, c in checkers.items()], settings.rounds)
    reference = checkers[settings.fits[0]].forest
    rows = []
    for fit, checker in checkers.items():
        forest = checker.forest
        work = work_per_check(checker, configurations)
        mark = ' (default)' if fit == CheckerConfig().obb_fit else ''
        rows.append([f'{fit}{mark}', f'{forest.volume.sum() * 1e3:.2f}',
                     f'{forest.volume.sum() / reference.volume.sum():.2f}',
                     f'{forest.volume[forest.roots].sum() * 1e3:.2f}',
                     f'{builds[fit]:.2f}', us(times[fit]), f'{work["boxes"]:.0f}'])
    skipped = [f for f in ('pca', 'refined', 'hull_pca', 'min_volume') if f not in settings.fits]
    section.text('', '#### Bounding-volume fits on the Panda', '',
                 '`hull_pca` and `min_volume` refit the boxes of the `pca` trees; `refined` '
                 'fits the top of each tree as it is built and cuts nodes along those boxes; '
                 f'{forest.node_count} boxes over {len(forest.tris)} triangles. Volumes in litres (1e-3 m^3); build is '
                 'the whole checker constructor.'
                 + (f' Not measured in --quick: {", ".join(skipped)}.' if skipped else ''))
    section.table(['fit', 'all boxes L', 'vs pca', 'root boxes L', 'build s', 'us / query',
                   'box tests / query'], rows)

