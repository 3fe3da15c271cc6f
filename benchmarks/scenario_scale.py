"""Scenario 4: the Panda against scene meshes of growing size (build, memory, query).

The scene is one wavy terrain (:func:`benchmarks.scenario_cells.wavy_terrain`)
written to an STL file and loaded as a user's scene would be. Each size is built once per
implementation. The checker checks only the robot-versus-terrain pairs, and so does fcl.

Memory is the process's RSS growth around each build (``/proc/self/statm``, glibc's mmap
threshold pinned, free heap trimmed before and after; see
:mod:`benchmarks.scenario_measure`), minus, for ours, the growth of building the
robot alone; ``forest.nbytes()`` (the arrays of the OBB forest) is shown beside it.
"""
import tempfile

import numpy as np

from collision_sensor.engine.sampling import random_configurations
from benchmarks.scenario_cells import (
    robot_cell, robot_pair_exceptions, terrain_object)
from benchmarks.scenario_measure import (
    Candidate, interleaved_us, pin_mmap_threshold, resident_growth, work_per_check)
from benchmarks.scenario_peers import FclCell, agreement, fcl_answers, fcl_bvh
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 4: scale, the Panda against scene meshes of growing size'
LOG_RESIDUAL = 0.10         # a log fit within 10 % of every point counts as log growth


def run(settings) -> Section:
    """Measure every terrain size; return the section with its verdicts and plot data."""
    section = Section(4, TITLE)
    pinned = pin_mmap_threshold()
    cell = robot_cell('panda')
    robot = cell.checker()                      # loads meshes and kernels before measuring
    allowed = {'allowed_collisions': list(robot_pair_exceptions(robot))}
    _, robot_rss, robot_build = resident_growth(lambda: cell.checker(config=allowed))
    robot_nbytes = robot.forest.nbytes()
    configurations = list(random_configurations(robot, settings.scale_configurations,
                                                settings.seed))
    poses = []
    for q in configurations:
        robot.check(q)
        poses.append(robot.link_poses())

    rows, points = [], []
    try:
        import fcl  # noqa: F401
        fcl_missing = None
    except ImportError as exc:
        fcl_missing = f'not installed ({exc.name})'
    with tempfile.TemporaryDirectory(prefix='collision_sensor_benchmarks_') as workdir:
        for size in settings.terrain_triangles:
            point = _measure_size(cell, allowed, size, workdir, configurations, poses,
                                  robot_rss, robot_nbytes, fcl_missing, settings)
            points.append(point)
            rows.append(_row(point, fcl_missing))

    section.text(
        f'{settings.scale_configurations} seeded random Panda configurations per size (the '
        f'same for every size); robot-vs-terrain pairs only ({points[0]["pairs"]}). Query: '
        f'ours `check` (FK + pairs) against python-fcl placed with our poses (FK not '
        f'counted); best of {settings.rounds} interleaved passes. Build: wall time of one '
        f'build; ours is the whole checker constructor (the robot alone takes '
        f'{robot_build * 1e3:.0f} ms of it), fcl the terrain BVH (OBBRSS). Memory: RSS growth '
        'around the build per terrain triangle (`/proc/self/statm`'
        + (', free heap trimmed before and after, glibc mmap threshold pinned' if pinned
           else ', not glibc: expect noise') + '); ours minus the robot-only build; '
        '`forest.nbytes()` counts the OBB forest\'s arrays (views into the buffers the '
        'engine reads, so the checker holds them once). The smallest '
        'size\'s RSS figures are the least precise (page and allocator granularity).')
    section.table(['terrain triangles', 'in contact', 'ours build s', 'fcl build s',
                   'ours query us', 'fcl query us', 'ours / fcl query',
                   'ours box / triangle tests per query',
                   'ours forest.nbytes B/tri', 'ours RSS B/tri', 'fcl RSS B/tri',
                   'colliding pairs equal'], rows)
    _judge(section, points, fcl_missing)
    section.plot['scale'] = points
    return section


def _measure_size(cell, allowed, size, workdir, configurations, poses, robot_rss,
                  robot_nbytes, fcl_missing, settings):
    terrain = terrain_object(size, workdir)
    triangles = len(terrain.faces)
    checker, ours_rss, ours_build = resident_growth(
        lambda: cell.checker(config=allowed, scene=[terrain]))
    ours_sets = [frozenset(checker.check(q).colliding_pairs) for q in configurations]
    point = dict(triangles=triangles, pairs=len(checker.checked_pairs),
                 contact=sum(bool(s) for s in ours_sets) / len(ours_sets),
                 ours_build=ours_build, ours_rss=(ours_rss - robot_rss) / triangles,
                 ours_nbytes=(checker.forest.nbytes() - robot_nbytes) / triangles)
    work = work_per_check(checker, configurations)
    point.update(boxes=work['boxes'], triangle_tests=work['triangles'])
    candidates = [Candidate('ours', checker.check, configurations)]
    fcl_cell = model = None
    if fcl_missing is None:
        model, fcl_rss, fcl_build = resident_growth(
            lambda: fcl_bvh(terrain.vertices, terrain.faces))
        fcl_cell = FclCell(checker, [terrain], {terrain.name: model})
        point.update(fcl_build=fcl_build, fcl_rss=fcl_rss / triangles)
        sets = fcl_answers(fcl_cell, poses)
        point['agree'] = agreement(ours_sets, sets)
        candidates.append(Candidate('fcl', lambda P: (fcl_cell.place(P), fcl_cell.check()),
                                    poses))
    times = interleaved_us(candidates, settings.rounds)
    point['ours_query'] = times['ours']
    point['fcl_query'] = times.get('fcl')
    del checker, fcl_cell, model        # the next size should not share memory with this one
    return point


def _row(p, fcl_missing):
    fcl = fcl_missing is None
    return [f'{p["triangles"]:,}', f'{p["contact"]:.0%}', f'{p["ours_build"]:.2f}',
            f'{p["fcl_build"]:.2f}' if fcl else fcl_missing, us(p['ours_query']),
            us(p['fcl_query']), ratio(p['ours_query'], p['fcl_query']),
            f'{p["boxes"]:.0f} / {p["triangle_tests"]:.0f}',
            f'{p["ours_nbytes"]:.0f}', f'{p["ours_rss"]:.0f}',
            f'{p["fcl_rss"]:.0f}' if fcl else '-', p.get('agree', '-')]


def growth_fits(triangles, times):
    """Fit ``t = a + b log10 N`` and ``t = c N^k`` to query times.

    :return: dict with a, b (us per decade), the log fit's largest relative residual, k, and
        the growth per decade over the first and the last interval.
    """
    x = np.log10(np.asarray(triangles, dtype=float))
    t = np.asarray(times, dtype=float)
    b, a = np.polyfit(x, t, 1)
    residual = float(np.max(np.abs(a + b * x - t) / t))
    k = float(np.polyfit(x, np.log10(t), 1)[0])
    first = (t[1] - t[0]) / (x[1] - x[0])
    last = (t[-1] - t[-2]) / (x[-1] - x[-2])
    return dict(a=float(a), b=float(b), residual=residual, k=k, first=float(first),
                last=float(last))


def _judge(section, points, fcl_missing):
    triangles = [p['triangles'] for p in points]
    ours = [p['ours_query'] for p in points]
    fit = growth_fits(triangles, ours)
    passed = fit['last'] <= fit['first'] or fit['residual'] <= LOG_RESIDUAL
    lines = [f'Fit of ours: t = {fit["a"]:.1f} + {fit["b"]:.1f} log10(N) us (largest residual '
             f'{fit["residual"]:.0%}); power law t ~ N^{fit["k"]:.3f}; growth per decade '
             f'{fit["first"]:.1f} us over the first interval, {fit["last"]:.1f} us over the '
             f'last. Criterion for "no faster than log N": the growth per decade does not rise '
             f'from the first interval to the last, or the log fit is within '
             f'{LOG_RESIDUAL:.0%} of every point.']
    if fcl_missing is None:
        fcl_fit = growth_fits(triangles, [p['fcl_query'] for p in points])
        lines.append(f'Fit of python-fcl: t = {fcl_fit["a"]:.1f} + {fcl_fit["b"]:.1f} '
                     f'log10(N) us (largest residual {fcl_fit["residual"]:.0%}); '
                     f't ~ N^{fcl_fit["k"]:.3f}.')
    section.text(*lines)
    growth = section.judge(
        'S4 query time grows no faster than log N',
        f'log fit residual {fit["residual"]:.0%}, per decade {fit["first"]:.1f} -> '
        f'{fit["last"]:.1f} us, N^{fit["k"]:.3f}', passed)
    largest = points[-1]
    n = f'{largest["triangles"]:,}'
    if fcl_missing is None:
        query = section.judge_ratio(
            f'S4 query at {n} triangles <= python-fcl', largest['ours_query'],
            largest['fcl_query'], 1.0, 'python-fcl', fcl_missing)
        arrays = section.judge(
            f'S4 memory/tri at {n}: forest.nbytes <= python-fcl RSS growth',
            f'{largest["ours_nbytes"]:.0f} vs {largest["fcl_rss"]:.0f} B/tri',
            largest['ours_nbytes'] <= largest['fcl_rss'])
        process = section.judge(
            f'S4 memory/tri at {n}: checker RSS growth <= python-fcl RSS growth',
            f'{largest["ours_rss"]:.0f} vs {largest["fcl_rss"]:.0f} B/tri',
            largest['ours_rss'] <= largest['fcl_rss'])
        verdicts = [query, arrays, process]
    else:
        verdicts = [section.judge(f'S4 at {n} triangles against python-fcl',
                                  f'python-fcl {fcl_missing}', None)]
    section.text('', f'Targets: log growth **{growth.word}**; '
                 + '; '.join(f'{v.target[3:]}: **{v.word}** ({v.measured})' for v in verdicts)
                 + '.')

