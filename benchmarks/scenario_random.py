"""Scenario 1: random configurations (no coherence, the paper's case), full check with FK.

Per robot, the same seeded configurations (uniform within the joint limits) go to:

- ours: ``checker.check(q)`` (FK, every checked pair, result tuple built);
- pinocchio+coal: ``computeCollisions`` (its FK + placements + every pair), same link pairs
  and, for the demo arm, the scene's triangles fixed to the universe joint;
- python-fcl placed by pinocchio's FK (FK counted);
- python-fcl placed with our FK's poses (FK not counted: fcl alone).

Every peer's colliding pair sets are compared with ours on every configuration (untimed).
"""
from collision_sensor.engine.sampling import random_configurations
from benchmarks.scenario_measure import Candidate, interleaved_us, work_per_check
from benchmarks.scenario_peers import (
    FclCell, PinocchioFkFcl, agreement, fcl_answers, optional_peer, pinocchio_answers,
    pinocchio_peer)
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 1: random configurations, full check including kinematics'
TARGET_RATIO = 0.5


def run(settings, cells) -> Section:
    """Measure every cell; return the section (target: ours <= 0.5x pinocchio+coal)."""
    section = Section(1, TITLE)
    section.text(
        f'{settings.configurations} seeded random configurations per robot, uniform within '
        'the joint limits; the same configurations for every implementation. Time per '
        f'configuration, best of {settings.rounds} interleaved passes. All implementations '
        'check the same link pairs (our exception list: adjacent links and the SRDF).')
    plot = {}
    for cell in cells:
        rows, notes, times = _measure(cell, settings, section)
        section.text('', f'#### {cell.name}')
        section.table(['implementation', 'kinematics', 'pairs', 'us / config',
                       'ours / this', 'colliding pairs equal to ours'], rows)
        section.text(*notes)
        plot[cell.name] = times
    section.plot['random'] = plot
    return section


def _measure(cell, settings, section):
    checker = cell.checker()
    configurations = list(random_configurations(checker, settings.configurations,
                                                settings.seed))
    ours_sets, poses = [], []
    for q in configurations:   # also warms the kernel up
        ours_sets.append(frozenset(checker.check(q).colliding_pairs))
        poses.append(checker.link_poses())
    pin, pin_missing = optional_peer(pinocchio_peer, cell, checker)
    fcl_cell, fcl_missing = optional_peer(FclCell, checker, cell.scene)

    candidates = [Candidate('ours', checker.check, configurations)]
    pin_qs = None
    if pin is not None:
        pin_qs = [pin.configuration(checker, q) for q in configurations]
        candidates.append(Candidate('pinocchio', pin.check, pin_qs))
    if fcl_cell is not None:
        candidates.append(Candidate('fcl_ours', lambda P: (fcl_cell.place(P), fcl_cell.check()),
                                    poses))
    fk_fcl = None
    if pin is not None and fcl_cell is not None:
        fk_fcl = PinocchioFkFcl(pin, fcl_cell)
        candidates.append(Candidate('fcl_pin', fk_fcl.check, pin_qs))
    times = interleaved_us(candidates, settings.rounds)

    n_pairs = len(checker.checked_pairs)
    ours = times['ours']
    rows = [['collision_sensor `check`', 'ours (in the engine)', f'{n_pairs}', us(ours), '1.00x',
             '-']]
    if pin is not None:
        sets = pinocchio_answers(pin, pin_qs)
        rows.append(['pinocchio+coal `computeCollisions`', 'pinocchio',
                     f'{n_pairs} ({pin.pair_count} geometry pairs)', us(times['pinocchio']),
                     ratio(ours, times['pinocchio']), agreement(ours_sets, sets)])
    else:
        rows.append(['pinocchio+coal', '', '', pin_missing, '', ''])
    if fcl_cell is not None:
        sets = fcl_answers(fcl_cell, poses)
        fcl_agree = agreement(ours_sets, sets)
        if fk_fcl is not None:
            rows.append(['python-fcl, one `collide` per pair', 'pinocchio (counted)',
                         f'{len(fcl_cell.pairs)}', us(times['fcl_pin']),
                         ratio(ours, times['fcl_pin']), fcl_agree])
        rows.append(['python-fcl, one `collide` per pair', 'ours (not counted)',
                     f'{len(fcl_cell.pairs)}', us(times['fcl_ours']),
                     ratio(ours, times['fcl_ours']), fcl_agree])
    else:
        rows.append(['python-fcl', '', '', fcl_missing, '', ''])

    colliding = sum(bool(s) for s in ours_sets) / len(ours_sets)
    work = work_per_check(checker, configurations)
    triangles = sum(len(e.faces) for e in checker.model.elements)
    notes = [f'Robot: {triangles} triangles in {len(checker.model.elements)} collision elements'
             + (f'; scene: {", ".join(checker.scene_object_names)} '
                f'({sum(len(o.faces) for o in cell.scene)} triangles, in every peer)'
                if cell.scene else '') + f'. Configurations in collision: {colliding:.1%}. '
             f'Our work per configuration: {work["boxes"]:.0f} box tests, '
             f'{work["triangles"]:.0f} triangle tests, {work["spheres"]:.0f} box pairs skipped '
             'by the sphere pre-test.']
    if pin is not None and any(type(g.geometry).__name__ != 'BVHModelOBBRSS'
                               for g in pin.geom.geometryObjects):
        notes.append('pinocchio loads the URDF primitives (here boxes) as analytic coal shapes; '
                     'we and fcl check their triangulation (12 triangles per box).')
    verdict = section.judge_ratio(
        f'S1 {cell.name}: ours <= {TARGET_RATIO}x pinocchio+coal per config', ours,
        times.get('pinocchio'), TARGET_RATIO, 'pinocchio+coal', pin_missing)
    notes.append(f'Target ours <= {TARGET_RATIO}x pinocchio+coal: **{verdict.word}** '
                 f'({verdict.measured}).')
    plot_times = {'collision_sensor (ours)': ours}
    if pin is not None:
        plot_times['pinocchio+coal'] = times['pinocchio']
    if fk_fcl is not None:
        plot_times['python-fcl (pinocchio FK)'] = times['fcl_pin']
    if fcl_cell is not None:
        plot_times['python-fcl (our poses)'] = times['fcl_ours']
    return rows, notes, plot_times
