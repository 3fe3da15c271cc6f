"""Scenario 9: the dynamic scene, objects moving and added while the robot is checked.

Moving: the Panda among 50 world objects of mixed shapes (boxes, spheres, cylinders, and
tori as plain meshes), spread around it so that some touch it. The joints hold one
configuration; at each step one object, chosen at random, moves a little (a seeded random
walk of its pose). Each step is ``move_object`` (untimed) then the query, timed per call:
``update`` re-checks the moved object's pairs only, ``check`` every pair; two checkers, one
for each, take the same steps, interleaved round by round, each figure the best round's mean
(the garbage collector off, as in ``timeit``). ``move_object`` is timed on its own too, and
the whole step (move and query) is reported both ways. The answers must agree at every step
(checked before timing; the run stops if they differ).

Adding: one mesh of 100,000 triangles (a noisy torus) added as a world object:
``add_object`` (its tree built, the scene's pairs and buffers rebuilt) plus the ``update``
that checks its pairs, against python-fcl building its BVH (OBBRSS) of the same triangles.
Each figure is the best of several additions (the object removed in between, untimed). That
the node answers every joint state while such a mesh is added (it builds the tree off the
checking thread) is a test: ``test/ros/test_node_scene.py``.
"""
import gc
import time

import numpy as np

from collision_sensor.engine.sampling import random_configurations
from collision_sensor.model import mesh_loading
from collision_sensor.model.scene import SceneObject
from benchmarks.scenario_cells import robot_cell
from benchmarks.scenario_report import Section, ratio, us

TITLE = 'Scenario 9: the dynamic scene, objects moving and added'
MOVE_TARGET = 0.1
ADD_TARGET = 1.0
OBJECTS = 50
BIG_TRIANGLES = 100_000
STEP = 0.01         # m and rad per axis of one move, at most


def objects(seed: int, count: int = OBJECTS):
    """Return ``count`` world objects of mixed shapes around the Panda, seeded."""
    import trimesh
    rng = np.random.default_rng(seed)
    out = []
    for index in range(count):
        kind = index % 4
        size = rng.uniform(0.04, 0.12)
        if kind == 0:
            extents = rng.uniform(0.5, 1.5, 3) * size
            (vertices, faces), solid = mesh_loading.box_mesh(extents), \
                mesh_loading.box_solid(extents)
        elif kind == 1:
            (vertices, faces), solid = mesh_loading.sphere_mesh(size, 16), \
                mesh_loading.sphere_solid(size)
        elif kind == 2:
            (vertices, faces), solid = mesh_loading.cylinder_mesh(size / 2, size * 3, 16), \
                mesh_loading.cylinder_solid(size / 2, size * 3)
        else:
            torus = trimesh.creation.torus(major_radius=size, minor_radius=size / 4,
                                           major_sections=16, minor_sections=8)
            vertices, faces, solid = torus.vertices, torus.faces, None
        T = trimesh.transformations.random_rotation_matrix(rng.random(3))
        T[:3, 3] = (rng.uniform(-0.7, 0.7), rng.uniform(-0.7, 0.7), rng.uniform(0.0, 1.1))
        out.append(SceneObject(f'object_{index:02d}', 'bench', T,
                               np.ascontiguousarray(vertices, dtype=np.float64),
                               np.ascontiguousarray(faces, dtype=np.int64), solid))
    return out


def moves(objs, steps: int, seed: int):
    """Return ``[(name, pose)]``: each step one object's pose moved a little from its last."""
    import trimesh
    rng = np.random.default_rng(seed + 1)
    poses = {obj.name: obj.T_world_object.copy() for obj in objs}
    names = sorted(poses)
    out = []
    for _ in range(steps):
        name = names[rng.integers(len(names))]
        turn = trimesh.transformations.euler_matrix(*rng.uniform(-STEP, STEP, 3))
        turn[:3, 3] = rng.uniform(-STEP, STEP, 3)
        poses[name] = poses[name] @ turn
        out.append((name, poses[name]))
    return out


def big_mesh(triangles: int, seed: int):
    """Return a noisy torus of ``triangles`` triangles (a multiple of 200), 0.6 m across."""
    import trimesh
    minor = 100
    torus = trimesh.creation.torus(major_radius=0.25, minor_radius=0.05,
                                   major_sections=triangles // (2 * minor), minor_sections=minor)
    rng = np.random.default_rng(seed)
    vertices = torus.vertices * (1.0 + 0.002 * rng.standard_normal((len(torus.vertices), 1)))
    return (np.ascontiguousarray(vertices, dtype=np.float64),
            np.ascontiguousarray(torus.faces, dtype=np.int64))


def run(settings) -> Section:
    """Time the moving and the adding; return the section."""
    section = Section(9, TITLE)
    cell = robot_cell('panda')
    _moving(section, cell, settings)
    _adding(section, cell, settings)
    return section


def _step_times(checkers, steps, q, rounds: int, initial):
    """Return ``{label: us}``: each checker's query (``{label: (checker, method name)}``)
    timed per call after each step's ``move_object``, and ``move``, the moves themselves;
    the best round's mean per step, rounds interleaved, every checker back at the
    ``initial`` poses (``[(name, pose)]``, untimed) before each round."""
    best = {label: float('inf') for label in (*checkers, 'move')}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(rounds):
            for label, (checker, method) in checkers.items():
                for name, pose in initial:
                    checker.move_object(name, pose)
                query = getattr(checker, method)
                checker.check(q)
                moving = querying = 0.0
                for name, pose in steps:
                    start = time.perf_counter()
                    checker.move_object(name, pose)
                    middle = time.perf_counter()
                    query(q)
                    querying += time.perf_counter() - middle
                    moving += middle - start
                best[label] = min(best[label], querying / len(steps))
                best['move'] = min(best['move'], moving / len(steps))
    finally:
        if enabled:
            gc.enable()
    return {label: value * 1e6 for label, value in best.items()}


def _moving(section, cell, settings):
    objs = objects(settings.seed)
    incremental, scratch = cell.checker(), cell.checker()
    for checker in (incremental, scratch):
        for obj in objs:
            checker.add_object(obj)
        q = random_configurations(checker, 1, seed=settings.seed)[0]
        checker.check(q)
    steps = moves(objs, 100 if settings.quick else 2000, settings.seed)
    for name, pose in steps:       # the answers, untimed: update against check at every step
        incremental.move_object(name, pose)
        scratch.move_object(name, pose)
        if incremental.update(q).colliding_pairs != scratch.check(q).colliding_pairs:
            raise AssertionError(f'scenario 9: update differs from check after moving {name}')
    in_contact = len(scratch.check(q).colliding_pairs)
    pairs = len(incremental.checked_pairs)
    object_pairs = sum(1 for a, b in incremental.checked_pairs
                       if a.startswith('object_') or b.startswith('object_'))
    initial = [(obj.name, obj.T_world_object) for obj in objs]
    times = _step_times({'update': (incremental, 'update'), 'check': (scratch, 'check')},
                        steps, q, settings.rounds, initial)
    section.text('', f'The Panda (one configuration held, {in_contact} pairs in contact at the '
                 f'end) among {len(objs)} world objects (boxes, spheres, cylinders, tori as '
                 f'meshes); {pairs} pairs checked, {object_pairs} of them robot-object. '
                 f'{len(steps)} steps, each moving one object by up to {STEP:g} m and rad per '
                 'axis; `update` and `check` agreed at every step.')
    move = times['move']
    section.table(['per step', 'us'], [
        ['`move_object` (one object\'s pose checked and written)', us(move)],
        ['`update` after it (that object\'s pairs only)', us(times['update'])],
        ['`check` after it (every pair)', us(times['check'])],
        ['`update` / `check`', ratio(times['update'], times['check'])],
        ['whole step: (`move_object` + `update`) / (`move_object` + `check`)',
         ratio(move + times['update'], move + times['check'])],
    ])
    section.judge(f'S9 {len(objs)} objects, one moving per step: `update` <= {MOVE_TARGET}x a '
                  'full check', f'{ratio(times["update"], times["check"])} '
                  f'({us(times["update"])} vs {us(times["check"])} us)',
                  times['update'] <= MOVE_TARGET * times['check'])


def _adding(section, cell, settings):
    triangles = 10_000 if settings.quick else BIG_TRIANGLES
    vertices, faces = big_mesh(triangles, settings.seed)
    checker = cell.checker()
    q = random_configurations(checker, 1, seed=settings.seed)[0]
    checker.check(q)
    T = np.eye(4)
    T[:3, 3] = (0.45, 0.0, 0.5)
    repeats = 2 if settings.quick else 5
    ours = []
    for _ in range(repeats):
        obj = SceneObject('big', 'bench', T, vertices, faces)
        start = time.perf_counter()
        checker.add_object(obj)
        checker.update(q)
        ours.append(time.perf_counter() - start)
        checker.remove_object('big')
    rows = [['ours: `add_object` + `update`', f'{min(ours) * 1e3:.1f}']]
    try:
        import fcl
    except ImportError as error:
        section.table([f'adding a mesh of {len(faces):,} triangles', 'ms'], rows)
        section.judge('S9 adding a 100k-triangle mesh <= python-fcl\'s BVH build',
                      f'python-fcl not installed ({error})', None)
        return
    theirs = []
    faces32 = faces.astype(np.int32)
    for _ in range(repeats):
        start = time.perf_counter()
        model = fcl.BVHModel()
        model.beginModel(len(vertices), len(faces32))
        model.addSubModel(vertices, faces32)
        model.endModel()
        theirs.append(time.perf_counter() - start)
    rows.append(['python-fcl: `BVHModel` build (OBBRSS)', f'{min(theirs) * 1e3:.1f}'])
    rows.append(['ratio', ratio(min(ours), min(theirs))])
    section.text('', f'Adding one mesh of {len(faces):,} triangles as a world object, best of '
                 f'{repeats}.')
    section.table([f'adding a mesh of {len(faces):,} triangles', 'ms'], rows)
    section.judge(f'S9 adding a {len(faces):,}-triangle mesh <= python-fcl\'s BVH build',
                  f'{ratio(min(ours), min(theirs))} ({min(ours) * 1e3:.0f} vs '
                  f'{min(theirs) * 1e3:.0f} ms)', min(ours) <= ADD_TARGET * min(theirs))
