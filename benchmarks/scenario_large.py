"""Scenario 7: robots with large meshes (50k triangles and more), against pinocchio+coal.

Every example-robot-data robot whose collision meshes hold at least 50,000 triangles that we
could measure here: arms (Kinova, Unitree Z1, SO-101) and whole robots with hundreds of pairs
(TIAGo Pro, Romeo, Unitree G1). Each with its SRDF where it ships one, timed against
pinocchio+coal on the same pairs as :mod:`benchmarks.robot_timing` says;
scenario 13 measures every robot of the package the same way.
"""
import os

from collision_sensor.model.example_robots import example_robot_data_dir
from benchmarks.robot_timing import time_robot
from benchmarks.scenario_cells import Cell
from benchmarks.scenario_report import Section, ratio, us

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
    for cell in large_cells():
        try:
            checker = cell.checker()
        except Exception as error:  # a robot this version cannot load is reported, not hidden
            rows.append([cell.name, '-', '-', '-', f'not loaded: {error}'[:80], '-', '-', '-'])
            continue
        t = time_robot(cell, checker, lambda checker: n, settings.seed, settings.rounds)
        rows.append([cell.name, f'{t.triangles:,}', t.pairs, us(t.ours_us), us(t.pinocchio_us),
                     ratio(t.ours_us, t.pinocchio_us),
                     f'{t.work["boxes"]:.0f} / {t.work["triangles"]:.0f}', t.equal])
        if t.pinocchio_us is not None:
            section.judge_ratio(f'S7 {cell.name}: `check` <= 0.5x pinocchio+coal',
                                t.ours_us, t.pinocchio_us, TARGET_RATIO, 'pinocchio+coal', None)
    section.table(['robot', 'triangles', 'pairs', 'ours us', 'pinocchio+coal us',
                   'ours / pinocchio', 'ours box / triangle tests', 'pair sets equal'], rows)
    return section
