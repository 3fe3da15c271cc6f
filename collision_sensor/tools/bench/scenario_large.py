"""Scenario 7: robots with large meshes (50k triangles and more), against pinocchio+coal.

Every example-robot-data robot whose collision meshes hold at least 50,000 triangles that we
could measure here: arms (Kinova, Unitree Z1, SO-101) and whole robots with hundreds of pairs
(TIAGo Pro, Romeo, Unitree G1). Each with its SRDF where it ships one. Per robot, the same
seeded random configurations go to ours (``check``: FK and every checked pair) and to
pinocchio+coal (``computeCollisions``: its FK, placements and the geometry pairs of exactly
our checked link pairs, each stopping at its first contact). Both load the same mesh files,
each with its own loader, so a few pairs can differ where the loaders read a file
differently; the agreement column counts configurations with equal colliding pair sets.
"""
import os

from collision_sensor.engine.sampling import random_configurations
from collision_sensor.model.example_robots import example_robot_data_dir
from collision_sensor.tools.bench.scenario_cells import Cell
from collision_sensor.tools.bench.scenario_measure import Candidate, interleaved_us, work_per_check
from collision_sensor.tools.bench.scenario_peers import (
    agreement, optional_peer, pinocchio_answers, pinocchio_peer)
from collision_sensor.tools.bench.scenario_report import Section, ratio, us

TITLE = 'Scenario 7: large meshes (>= 50k triangles), many pairs, against pinocchio+coal'
TARGET_RATIO = 0.5
ROBOTS = (  # (label, URDF, SRDF or None) under example-robot-data's robots/
    ('kinova', 'kinova_description/robots/kinova.urdf', 'kinova_description/srdf/kinova.srdf'),
    ('z1', 'z1_description/urdf/z1.urdf', 'z1_description/srdf/z1.srdf'),
    ('so101', 'so_arm_description/urdf/so101.urdf', None),
    ('tiago_pro', 'tiago_pro_description/robots/tiago_pro.urdf',
     'tiago_pro_description/srdf/tiago_pro.srdf'),
    ('romeo', 'romeo_description/urdf/romeo.urdf', 'romeo_description/srdf/romeo.srdf'),
    ('g1', 'g1_description/urdf/g1_29dof_rev_1_0.urdf', None),
)


def large_cells():
    """Return a cell per robot of ROBOTS whose files are installed."""
    share = example_robot_data_dir()
    cells = []
    for label, urdf, srdf in ROBOTS:
        urdf = os.path.join(share, 'robots', urdf)
        srdf = os.path.join(share, 'robots', srdf) if srdf else None
        if os.path.exists(urdf):
            cells.append(Cell(label, urdf, srdf if srdf and os.path.exists(srdf) else None,
                              {'example-robot-data': share}))
    return cells


def run(settings) -> Section:
    """Measure every large robot; return the section (target: ours <= 0.5x pinocchio+coal)."""
    section = Section(7, TITLE)
    n = 30 if settings.quick else 300
    section.text(f'{n} seeded random configurations per robot; time per configuration, best '
                 f'of {settings.rounds} interleaved passes.')
    rows = []
    worst = None
    for cell in large_cells():
        try:
            checker = cell.checker()
        except Exception as error:  # a robot this version cannot load is reported, not hidden
            rows.append([cell.name, '-', '-', '-', f'not loaded: {error}'[:80], '-', '-', '-'])
            continue
        configurations = list(random_configurations(checker, n, settings.seed))
        ours_sets = [frozenset(checker.check(q).colliding_pairs) for q in configurations]
        pin, missing = optional_peer(pinocchio_peer, cell, checker)
        candidates = [Candidate('ours', checker.check, configurations)]
        if pin is not None:
            pin_qs = [pin.configuration(checker, q) for q in configurations]
            candidates.append(Candidate('pinocchio', pin.check, pin_qs))
        times = interleaved_us(candidates, settings.rounds)
        work = work_per_check(checker, configurations)
        theirs = times.get('pinocchio')
        equal = agreement(ours_sets, pinocchio_answers(pin, pin_qs)) if pin else missing
        rows.append([cell.name, f'{len(checker.forest.tris):,}', len(checker.checked_pairs),
                     us(times['ours']), us(theirs), ratio(times['ours'], theirs),
                     f'{work["boxes"]:.0f} / {work["triangles"]:.0f}', equal])
        if theirs is not None:
            r = times['ours'] / theirs
            worst = max(worst or 0.0, r)
            section.judge_ratio(f'S7 {cell.name}: `check` <= 0.5x pinocchio+coal',
                                times['ours'], theirs, TARGET_RATIO, 'pinocchio+coal', None)
    section.table(['robot', 'triangles', 'pairs', 'ours us', 'pinocchio+coal us',
                   'ours / pinocchio', 'ours box / triangle tests', 'pair sets equal'], rows)
    return section
