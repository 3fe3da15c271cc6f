"""Scenario 13: every robot of example-robot-data, and two of its meshes in heavy contact.

Part A: every URDF of the package (:func:`collision_sensor.model.example_robots.
example_robot_files`, each with the SRDF that belongs to it) that has a collision mesh, timed
against pinocchio+coal on the same pairs as scenario 7 times its six
(:mod:`benchmarks.robot_timing`): seeded random configurations, one Python
``check`` against one ``computeCollisions`` each. Bigger robots get fewer configurations
(``PAIR_BUDGET`` pair checks per pass, within ``CONFIGURATIONS``). A URDF that we or pinocchio
cannot load is a row saying so; one without a collision mesh is named below the table. Then
the distribution of the ratios over the robots, and its two targets: every robot
at most 0.5x pinocchio+coal, the median robot at most 0.2x.

Part B: a real link mesh of about 2,000 triangles fixed (TIAGo Pro's second arm link), a
real 200-triangle one (the Panda's hand) on scenario 6's six joints (three sliders over the
fixed mesh's bounding box grown by ``MARGIN``, three revolute joints), at seeded random poses
of which about 60 % are in contact; one Python ``check`` per pose against python-fcl's
``collide`` of the two BVH models on the same triangles
(:func:`benchmarks.scenario_contact.time_contact`).
"""
import os
import warnings
from typing import List, Optional, Sequence

import numpy as np

from collision_sensor.errors import LoadWarning
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.model.example_robots import example_robot_data_dir, example_robot_files
from collision_sensor.model.mesh_loading import load_mesh_file
from benchmarks.robot_timing import RobotTiming, time_robot
from benchmarks.scenario_cells import Cell
from benchmarks.scenario_contact import (
    free_mesh_checker, report_contact, time_contact)
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 13: every example-robot-data robot, and two of its meshes in heavy contact'
EVERY_ROBOT_RATIO = 0.5
MEDIAN_ROBOT_RATIO = 0.2
#: Pair checks per timed pass and robot: configurations = PAIR_BUDGET // pairs, clamped to
#: CONFIGURATIONS (full run, --quick).
PAIR_BUDGET = {False: 20_000, True: 600}
CONFIGURATIONS = {False: (20, 300), True: (3, 10)}
#: Part B's meshes, under example-robot-data's robots/: the fixed one, the moving one.
FIXED_MESH = 'tiago_pro_description/meshes/arm_tiago_pro/arm_2_link_collision.stl'
TOOL_MESH = 'panda_description/meshes/collision/hand.stl'
POSES = {False: 3000, True: 500}
#: How far the sliders reach beyond the fixed mesh's bounding box (m): about 60 % of the poses
#: then touch (0: 98 %, all deep; 0.1 m: 28 %), so near misses, which a check must prove
#: apart, are timed as well as contacts.
MARGIN = 0.05


def every_robot_cells(names: Optional[Sequence[str]] = None) -> List[Cell]:
    """Return a cell per URDF of example-robot-data (``names``: only those, as
    ``<package>/<stem>``), each with its SRDF, name-sorted."""
    robots = example_robot_files()
    if names is not None:
        unknown = sorted(set(names) - {robot.name for robot in robots})
        if unknown:
            raise ValueError(f'not in example-robot-data: {", ".join(unknown)}')
        robots = [robot for robot in robots if robot.name in names]
    return [Cell(robot.name, robot.urdf, robot.srdf, dict(robot.package_paths))
            for robot in robots]


def configuration_count(checker, quick: bool) -> int:
    """Return how many configurations to time on ``checker``: fewer for more pairs."""
    low, high = CONFIGURATIONS[quick]
    return int(np.clip(PAIR_BUDGET[quick] // max(1, len(checker.checked_pairs)), low, high))


def distribution(values: Sequence[float]) -> dict:
    """Return ``{min, q1, median, q3, max}`` of ``values`` (linear interpolation)."""
    q = np.percentile(np.asarray(values, dtype=float), [0, 25, 50, 75, 100])
    return dict(zip(('min', 'q1', 'median', 'q3', 'max'), (float(v) for v in q)))


def _short(error: Exception, share: str) -> str:
    """One line of ``error``, the package's directory left out of its paths."""
    line = (str(error).strip().splitlines() or [''])[0].replace(share + os.sep, '')
    return f'{type(error).__name__}: {line}'[:140].replace('|', '/')


def _pinocchio_loads(cell) -> str:
    """Say whether pinocchio+coal loads ``cell`` (for a robot our loader refused)."""
    from benchmarks.peers import PinocchioPeer
    from benchmarks.scenario_peers import optional_peer
    peer, why = optional_peer(PinocchioPeer, cell.urdf, cell.srdf, cell.package_paths)
    if peer is not None:
        return 'pinocchio+coal loads it'
    return f'pinocchio+coal: {why}'.replace(example_robot_data_dir() + os.sep, '')[:140]


def measure_robots(settings, names: Optional[Sequence[str]] = None):
    """Time every robot with a collision mesh.

    :return: ``(timings, rows, meshless)``: the timings of the robots timed against
        pinocchio+coal, a table row per robot with a mesh or that did not load, and the
        robots without a collision mesh (``"name (why)"``).
    """
    share = example_robot_data_dir()
    timings, rows, meshless = [], [], []
    for cell in every_robot_cells(names):
        srdf = os.path.basename(cell.srdf) if cell.srdf else 'none'
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', LoadWarning)  # oddities tolerated on load
                checker = cell.checker()
        except Exception as error:  # a robot we cannot load is a row, never left out
            rows.append([cell.name, srdf, '-', '-', '-', '-', '-', '-', '-', '-',
                         f'not loaded by collision_sensor ({_short(error, share)}); '
                         f'{_pinocchio_loads(cell)}'])
            continue
        meshes = [e for e in checker.model.elements if e.solid is None]
        if not meshes:
            why = 'primitives only' if checker.model.elements else 'no collision element'
            meshless.append(f'{cell.name} ({why})')
            continue
        t = time_robot(cell, checker, lambda c: configuration_count(c, settings.quick),
                       settings.seed, settings.rounds)
        work = f'{t.work["boxes"]:.0f} / {t.work["triangles"]:.0f}' if t.work else '-'
        colliding = f'{t.colliding:.1f}' if t.colliding is not None else '-'
        rows.append([cell.name, srdf, f'{t.triangles:,}', t.pairs, t.configurations or '-',
                     us(t.ours_us), us(t.pinocchio_us), ratio(t.ours_us, t.pinocchio_us), work,
                     colliding, t.equal])
        if t.ratio is not None:
            timings.append(t)
        del checker
    return timings, rows, meshless


def judge_robots(section: Section, timings: Sequence[RobotTiming]) -> None:
    """Add the distribution of ours / pinocchio+coal over the robots and the two verdicts."""
    if not timings:
        section.judge('S13 every robot: `check` <= 0.5x pinocchio+coal',
                      'no robot timed against pinocchio+coal', None)
        section.judge('S13 the median robot: `check` <= 0.2x pinocchio+coal',
                      'no robot timed against pinocchio+coal', None)
        return
    ratios = [t.ratio for t in timings]
    d = distribution(ratios)
    over = sorted((t for t in timings if t.ratio > EVERY_ROBOT_RATIO), key=lambda t: -t.ratio)
    worst = max(timings, key=lambda t: t.ratio)
    section.table(['robots', 'min', 'first quartile', 'median', 'third quartile', 'max',
                   f'over {EVERY_ROBOT_RATIO}x', f'over {MEDIAN_ROBOT_RATIO}x'],
                  [[len(ratios)] + [f'{d[k]:.2f}x' for k in ('min', 'q1', 'median', 'q3', 'max')]
                   + [len(over), sum(r > MEDIAN_ROBOT_RATIO for r in ratios)]])
    if over:
        section.text('Over 0.5x: ' + ', '.join(
            f'{t.name} {t.ratio:.2f}x ({t.pairs} pair{"s" * (t.pairs != 1)}, '
            f'{t.triangles:,} triangles, {t.ours_us:.1f} vs {t.pinocchio_us:.1f} us)'
            for t in over) + '.', '')
    section.judge('S13 every robot: `check` <= 0.5x pinocchio+coal',
                  f'{len(ratios) - len(over)} of {len(ratios)} robots; worst {worst.name} '
                  f'{worst.ratio:.2f}x', not over)
    section.judge('S13 the median robot: `check` <= 0.2x pinocchio+coal',
                  f'median {d["median"]:.2f}x over {len(ratios)} robots',
                  d['median'] <= MEDIAN_ROBOT_RATIO)


def mesh_pair_checker(workdir: str):
    """Return Part B's checker: :data:`TOOL_MESH` on six joints over :data:`FIXED_MESH`
    (the sliders span the fixed mesh's bounding box grown by :data:`MARGIN`)."""
    robots = os.path.join(example_robot_data_dir(), 'robots')
    fixed, tool = os.path.join(robots, FIXED_MESH), os.path.join(robots, TOOL_MESH)
    vertices, _ = load_mesh_file(fixed)
    region = tuple(zip(vertices.min(axis=0) - MARGIN, vertices.max(axis=0) + MARGIN))
    return free_mesh_checker(tool, fixed, region)


def run(settings, workdir: str, robots: Optional[Sequence[str]] = None) -> Section:
    """Measure Part A (every robot, or those named) and Part B; return the section."""
    section = Section(13, TITLE)
    timings, rows, meshless = measure_robots(settings, robots)
    low, high = CONFIGURATIONS[settings.quick]
    section.text(
        '**A. Every robot with a collision mesh**, with the SRDF that belongs to it, against '
        'pinocchio+coal checking the geometry pairs of exactly our checked link pairs (both '
        'load the same files). Seeded random configurations within the limits, '
        f'{PAIR_BUDGET[settings.quick]:,} / pairs of them ({low} to {high}); time per '
        f'configuration (one Python `check` call), best of {settings.rounds} interleaved '
        'passes.')
    section.table(['robot', 'SRDF', 'triangles', 'pairs', 'configs', 'ours us',
                   'pinocchio+coal us', 'ours / pinocchio', 'ours box / triangle tests',
                   'colliding pairs', 'pair sets equal'], rows)
    if meshless:
        section.text('Without a collision mesh (not timed): ' + ', '.join(meshless) + '.', '')
    judge_robots(section, timings)
    checker = mesh_pair_checker(workdir)
    n = POSES[settings.quick]
    poses = random_configurations(checker, n, seed=settings.seed)
    timing = time_contact(checker, poses, settings.rounds)
    section.text(
        '', f'**B. Two real meshes in heavy contact.** Fixed: `{FIXED_MESH}` '
        f'({timing.fixed_triangles:,} triangles); moving: `{TOOL_MESH}` '
        f'({timing.tool_triangles} triangles) on three sliders spanning the fixed mesh\'s '
        f'bounding box grown by {MARGIN * 1000:.0f} mm and three revolute joints. {n} seeded '
        f'random poses, {timing.colliding:.0%} in contact. Best of {settings.rounds} '
        f'interleaved passes. Our work per check: {timing.work["boxes"]:.0f} box tests, '
        f'{timing.work["triangles"]:.0f} triangle tests.')
    report_contact(section, timing, 'S13 real meshes')
    section.text('Where the time goes: the same poses split by our answer, timed apart.')
    touching = np.array([checker.check(q).in_collision for q in poses], dtype=bool)
    rows = []
    for label, part in (('in contact', poses[touching]), ('apart', poses[~touching])):
        if len(part):
            t = time_contact(checker, part, settings.rounds)
            rows.append([f'{len(part)} poses {label}', us(t.ours_us), us(t.fcl_us),
                         ratio(t.ours_us, t.fcl_us), f'{t.work["boxes"]:.0f}',
                         f'{t.work["triangles"]:.0f}', t.equal])
    section.table(['poses', 'ours us', 'python-fcl us', 'ours / python-fcl', 'our box tests',
                   'our triangle tests', 'answers equal'], rows)
    return section
