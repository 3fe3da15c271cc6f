"""Scenario 3: the paper's experiment, the demo arm driven into the washing machine.

The bundled approach path ``config/sequences/paper_experiment.csv`` is replayed step by step.
The checker's pairs are only robot-versus-machine (every robot-robot pair is given as
``allowed_collisions``); the scene is the washer's three parts (cabinet, drum, door), without
the floor. python-fcl and pinocchio+coal check the same pairs on the same triangles.

For the record, the paper's figure: one robot-machine check averaged 6 ms on an SGI Indigo2
Extreme (a 6-DOF robot of more than 2000 triangles, a machine of more than 3000).
"""
from collision_sensor.model.sequences import read_sequence
from collision_sensor.model.share import config_path
from benchmarks.scenario_cells import robot_pair_exceptions
from benchmarks.scenario_measure import Candidate, interleaved_us, work_per_check
from benchmarks.scenario_peers import (
    FclCell, PinocchioFkFcl, agreement, fcl_answers, optional_peer, pinocchio_answers,
    pinocchio_peer)
from benchmarks.scenario_report import Section, ratio, us

TITLE = "Scenario 3: the paper's experiment, demo arm against the washing machine"
TARGET_RATIO = 0.5
PAPER_US = 6000.0           # sec. 6: 6 ms per robot-machine check, SGI Indigo2 Extreme
PATH = ('sequences', 'paper_experiment.csv')


def run(settings, cell) -> Section:
    """Replay the approach path on ``cell`` (the demo arm and the washer's parts)."""
    section = Section(3, TITLE)
    allowed = robot_pair_exceptions(cell.checker())
    checker = cell.checker(config={'allowed_collisions': list(allowed)})
    path = [q for q in read_sequence(config_path(*PATH)).select(checker.joint_names).positions]
    ours_sets, poses = [], []
    for q in path:
        ours_sets.append(frozenset(checker.check(q).colliding_pairs))
        poses.append(checker.link_poses())
    pin, pin_missing = optional_peer(pinocchio_peer, cell, checker)
    fcl_cell, fcl_missing = optional_peer(FclCell, checker, cell.scene)

    candidates = [Candidate('check', checker.check, path),
                  Candidate('update', checker.update, path,
                            before=lambda: checker.check(path[0]))]
    pin_qs = fk_fcl = None
    if pin is not None:
        pin_qs = [pin.configuration(checker, q) for q in path]
        candidates.append(Candidate('pinocchio', pin.check, pin_qs))
    if fcl_cell is not None:
        candidates.append(Candidate('fcl', lambda P: (fcl_cell.place(P), fcl_cell.check()),
                                    poses))
        if pin is not None:
            fk_fcl = PinocchioFkFcl(pin, fcl_cell)
            candidates.append(Candidate('fcl_pin', fk_fcl.check, pin_qs))
    times = interleaved_us(candidates, settings.rounds)

    check = times['check']
    robot_tris = sum(len(e.faces) for e in checker.model.elements)
    machine_tris = sum(len(o.faces) for o in cell.scene)
    first_hit = next((k for k, s in enumerate(ours_sets) if s), None)
    work = work_per_check(checker, path)
    work_contact = work_per_check(checker, [q for q, s in zip(path, ours_sets) if s] or path)
    section.text(
        f'Path: `config/{"/".join(PATH)}`, {len(path)} steps '
        f'({sum(bool(s) for s in ours_sets)} in contact, the first at step {first_hit}). '
        f'Robot {robot_tris} triangles, machine {machine_tris} triangles '
        f'({", ".join(checker.scene_object_names)}); {len(checker.checked_pairs)} '
        f'robot-machine pairs, robot-robot pairs excluded. Time per step, best of '
        f'{settings.rounds} interleaved passes. Our work per `check`: {work["boxes"]:.0f} box '
        f'tests, {work["triangles"]:.0f} triangle tests ({work_contact["boxes"]:.0f} and '
        f'{work_contact["triangles"]:.0f} on the steps in contact).')
    rows = [['collision_sensor `check` (FK + all pairs)', us(check), '1.00x', '-'],
            ['collision_sensor `update` along the path (incremental)', us(times['update']),
             ratio(times['update'], check), '-']]
    if fcl_cell is not None:
        sets = fcl_answers(fcl_cell, poses)
        fcl_agree = agreement(ours_sets, sets)
        rows.append(['python-fcl, our poses (FK not counted)', us(times['fcl']),
                     ratio(check, times['fcl']), fcl_agree])
        if fk_fcl is not None:
            rows.append(['python-fcl, pinocchio FK (counted)', us(times['fcl_pin']),
                         ratio(check, times['fcl_pin']), fcl_agree])
    else:
        rows.append(['python-fcl', fcl_missing, '', ''])
    if pin is not None:
        sets = pinocchio_answers(pin, pin_qs)
        rows.append([f'pinocchio+coal `computeCollisions` ({pin.pair_count} geometry pairs)',
                     us(times['pinocchio']), ratio(check, times['pinocchio']),
                     agreement(ours_sets, sets)])
    else:
        rows.append(['pinocchio+coal', pin_missing, '', ''])
    rows.append(['paper (1998): SGI Indigo2 Extreme, >2000 + >3000 triangles', us(PAPER_US),
                 ratio(check, PAPER_US), 'for the record only'])
    section.table(['implementation', 'us / robot-machine check', 'ours (`check`) / this',
                   'colliding pairs equal to ours'], rows)
    verdict = section.judge_ratio(
        f'S3 paper experiment: ours <= {TARGET_RATIO}x python-fcl per check', check,
        times.get('fcl'), TARGET_RATIO, 'python-fcl', fcl_missing)
    section.text(f'Target `check` <= {TARGET_RATIO}x python-fcl (our poses): '
                 f'**{verdict.word}** ({verdict.measured}).')
    return section
