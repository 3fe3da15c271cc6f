"""Scenario 6: heavy contact, one robot-sized mesh among clutter, most poses colliding.

A tool mesh of a few hundred triangles (a torus: non-convex, so boxes alone cannot decide)
rides on six joints (three sliders, three revolute) to random poses inside a cluttered
environment mesh of a few thousand triangles (random boxes, spheres and cylinders merged into
one object). More than half of the poses collide, so every query has to descend to meeting
triangles: the case where a hierarchy's pruning helps least.

Ours: one Python ``check`` call per pose, forward kinematics included. python-fcl: one
``fcl.collide`` of the two BVH models (OBBRSS) on the same triangles, the tool placed at the
pose our kinematics computed (placement not timed, each pose its own ``CollisionObject``).
"""
import os

import numpy as np

from collision_sensor.tools.bench.scenario_measure import Candidate, interleaved_us, work_per_check
from collision_sensor.tools.bench.scenario_report import Section, ratio, us

TITLE = 'Scenario 6: heavy contact, a tool mesh among clutter'
TARGET_RATIO = 0.5
REGION = ((-0.6, 0.6), (-0.6, 0.6), (0.0, 0.8))


def tool_mesh():
    """Return the tool: a torus of 480 triangles, 0.5 m across."""
    import trimesh
    mesh = trimesh.creation.torus(major_radius=0.2, minor_radius=0.05, major_sections=24,
                                  minor_sections=10)
    return mesh.vertices, mesh.faces


def clutter_mesh(seed: int, objects: int = 70):
    """Return the environment: ``objects`` random boxes, spheres and cylinders, one mesh."""
    import trimesh
    rng = np.random.default_rng(seed)
    parts = []
    for _ in range(objects):
        kind = rng.integers(3)
        size = rng.uniform(0.05, 0.25)
        if kind == 0:
            part = trimesh.creation.box(extents=rng.uniform(0.3, 1.0, 3) * size * 2)
        elif kind == 1:
            part = trimesh.creation.icosphere(subdivisions=1, radius=size)
        else:
            part = trimesh.creation.cylinder(radius=size * 0.5, height=size * 3, sections=16)
        T = trimesh.transformations.random_rotation_matrix(rng.random(3))
        T[:3, 3] = [rng.uniform(*REGION[k]) for k in range(3)]
        part.apply_transform(T)
        parts.append(part)
    merged = trimesh.util.concatenate(parts)
    return merged.vertices, merged.faces


#: A tool on three sliders (x, y, z within the given limits) and three revolute joints (yaw,
#: pitch, roll): any pose in the region.
URDF = '''<robot name="contact_tool">
  <link name="base"/>
  <link name="slide_x"/><link name="slide_y"/><link name="slide_z"/>
  <link name="turn_z"/><link name="turn_y"/>
  <link name="tool"><collision><geometry>{geometry}</geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="slide_x"/>
    <axis xyz="1 0 0"/><limit lower="{x0}" upper="{x1}" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="slide_x"/><child link="slide_y"/>
    <axis xyz="0 1 0"/><limit lower="{y0}" upper="{y1}" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="slide_y"/><child link="slide_z"/>
    <axis xyz="0 0 1"/><limit lower="{z0}" upper="{z1}" effort="1" velocity="1"/></joint>
  <joint name="yaw" type="revolute"><parent link="slide_z"/><child link="turn_z"/>
    <axis xyz="0 0 1"/><limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
  <joint name="pitch" type="revolute"><parent link="turn_z"/><child link="turn_y"/>
    <axis xyz="0 1 0"/><limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
  <joint name="roll" type="revolute"><parent link="turn_y"/><child link="tool"/>
    <axis xyz="1 0 0"/><limit lower="-3.14159" upper="3.14159" effort="1" velocity="1"/></joint>
</robot>
'''


def contact_checker(workdir: str, seed: int):
    """Return ``(checker, tool vertices, tool faces, clutter vertices, clutter faces)``."""
    import trimesh
    from collision_sensor.engine.checker import CollisionChecker
    tool_v, tool_f = tool_mesh()
    path = os.path.join(workdir, 'contact_tool.stl')
    trimesh.Trimesh(tool_v, tool_f, process=False).export(path)
    clutter_v, clutter_f = clutter_mesh(seed)
    clutter_path = os.path.join(workdir, 'contact_clutter.stl')
    trimesh.Trimesh(clutter_v, clutter_f, process=False).export(clutter_path)
    (x0, x1), (y0, y1), (z0, z1) = REGION
    urdf = URDF.format(geometry=f'<mesh filename="file://{path}"/>', x0=x0, x1=x1, y0=y0,
                       y1=y1, z0=z0, z1=z1)
    scene = {'objects': [{'name': 'clutter', 'mesh': {'filename': clutter_path}}]}
    checker = CollisionChecker.from_urdf(urdf, scene=scene)
    return checker, tool_v, tool_f, clutter_v, clutter_f


def run(settings, workdir: str) -> Section:
    """Time ours against python-fcl on random poses of the tool in the clutter."""
    section = Section(6, TITLE)
    checker, tool_v, tool_f, clutter_v, clutter_f = contact_checker(workdir, settings.seed)
    from collision_sensor.engine.sampling import random_configurations
    n = 500 if settings.quick else 3000
    poses = random_configurations(checker, n, seed=settings.seed)
    ours = [bool(checker.check(q).in_collision) for q in poses]
    tool_tris = len(checker.forest.tris) - len(clutter_f)
    try:
        import fcl
    except ImportError as error:
        fcl = None
        missing = f'not installed ({error})'
    rows = []
    theirs_us = None
    agree = '-'
    candidates = [Candidate('check', checker.check, poses)]
    if fcl is not None:
        def bvh(vertices, faces):
            model = fcl.BVHModel()
            model.beginModel(len(vertices), len(faces))
            model.addSubModel(np.asarray(vertices, dtype=np.float64),
                              np.asarray(faces, dtype=np.int32))
            model.endModel()
            return model
        tool_model = bvh(tool_v, tool_f)
        clutter = fcl.CollisionObject(bvh(clutter_v, clutter_f))
        placed = []
        for q in poses:
            checker.check(q)
            T = checker.link_poses()['tool']
            placed.append(fcl.CollisionObject(tool_model, fcl.Transform(T[:3, :3], T[:3, 3])))
        request = fcl.CollisionRequest()
        answers = [bool(fcl.collide(obj, clutter, request, fcl.CollisionResult()))
                   for obj in placed]
        agree = f'{sum(a == b for a, b in zip(ours, answers))}/{n}'

        def fcl_collide(obj):
            return fcl.collide(obj, clutter, request, fcl.CollisionResult())
        candidates.append(Candidate('fcl', fcl_collide, placed))
    times = interleaved_us(candidates, rounds=settings.rounds)
    theirs_us = times.get('fcl')
    work = work_per_check(checker, poses)
    colliding = sum(ours) / n
    rows.append(['collision_sensor `check` (FK + the pair, one Python call)', us(times['check']),
                 '1.00x', '-'])
    if theirs_us is not None:
        rows.append(['python-fcl `collide` (placement not counted)', us(theirs_us),
                     ratio(times['check'], theirs_us), agree])
    section.text(
        f'Tool {tool_tris} triangles, clutter {len(clutter_f)} triangles (70 random boxes, '
        f'spheres and cylinders, seed {settings.seed}); {n} random poses, {colliding:.0%} '
        f'colliding. Best of {settings.rounds} interleaved passes. Our work per check: '
        f'{work["boxes"]:.0f} box tests, {work["triangles"]:.0f} triangle tests.')
    section.table(['implementation', 'us / pose', 'ours / this', 'answers equal to ours'],
                  rows)
    section.judge(f'S6 more than half the poses collide', f'{colliding:.0%}', colliding > 0.5)
    section.judge_ratio('S6 heavy contact: `check` <= 0.5x python-fcl `collide`',
                        times['check'], theirs_us, TARGET_RATIO, 'python-fcl',
                        None if fcl is not None else missing)
    return section
