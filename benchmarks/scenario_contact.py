"""Scenario 6: heavy contact, one robot-sized mesh among clutter, most poses colliding.

A tool mesh of a few hundred triangles (a torus: non-convex, so boxes alone cannot decide)
rides on six joints (three sliders, three revolute) to random poses inside a cluttered
environment mesh of a few thousand triangles (random boxes, spheres and cylinders merged into
one object). More than half of the poses collide, so every query has to descend to meeting
triangles: the case where a hierarchy's pruning helps least.

Ours: one Python ``check`` call per pose, forward kinematics included. python-fcl: one
``fcl.collide`` of the two BVH models (OBBRSS) on the same triangles, the tool placed at the
pose our kinematics computed (placement not timed, each pose its own ``CollisionObject``).
Scenario 13 puts two real meshes of example-robot-data on the same joints
(:func:`free_mesh_checker`, :func:`time_contact`).
"""
import os
from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.sampling import random_configurations
from benchmarks.scenario_measure import Candidate, interleaved_us, work_per_check
from benchmarks.scenario_peers import fcl_bvh
from benchmarks.scenario_report import Section, ratio, us

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


def free_mesh_checker(tool_path: str, fixed_path: str, region) -> CollisionChecker:
    """Return a checker of the tool mesh on URDF's six joints against one fixed scene mesh.

    :param tool_path: the tool's mesh file (the link "tool").
    :param fixed_path: the fixed mesh file (the scene object "fixed", at the world origin).
    :param region: ``((x0, x1), (y0, y1), (z0, z1))``: the sliders' limits (m).
    """
    (x0, x1), (y0, y1), (z0, z1) = region
    urdf = URDF.format(geometry=f'<mesh filename="file://{tool_path}"/>', x0=x0, x1=x1, y0=y0,
                       y1=y1, z0=z0, z1=z1)
    scene = {'objects': [{'name': 'fixed', 'mesh': {'filename': fixed_path}}]}
    return CollisionChecker.from_urdf(urdf, scene=scene)


def contact_checker(workdir: str, seed: int) -> CollisionChecker:
    """Return the checker of scenario 6: the torus tool among the clutter."""
    import trimesh
    paths = []
    for name, (vertices, faces) in (('tool', tool_mesh()), ('clutter', clutter_mesh(seed))):
        paths.append(os.path.join(workdir, f'contact_{name}.stl'))
        trimesh.Trimesh(vertices, faces, process=False).export(paths[-1])
    return free_mesh_checker(paths[0], paths[1], REGION)


@dataclass
class ContactTiming:
    """Ours (``check``) against python-fcl's ``collide`` on the same poses of the tool.

    :ivar colliding: the share of poses in contact (our answers).
    :ivar fcl_us: None when python-fcl is not installed (``fcl_missing`` says so).
    :ivar equal: ``"k/n"`` poses where python-fcl's answer equals ours (``-`` without it).
    """

    tool_triangles: int
    fixed_triangles: int
    poses: int
    colliding: float
    ours_us: float
    fcl_us: Optional[float]
    fcl_missing: Optional[str]
    equal: str
    work: Dict[str, float]


def time_contact(checker: CollisionChecker, poses, rounds: int) -> ContactTiming:
    """Time one Python ``check`` per pose against one ``fcl.collide`` of the two BVH models
    (OBBRSS) on the triangles our loader read, the tool placed where our kinematics put it
    (placement not timed: each pose its own ``CollisionObject``).

    :param checker: from :func:`free_mesh_checker`.
    :param poses: ``(n, 6)`` joint positions.
    """
    ours = [bool(checker.check(q).in_collision) for q in poses]
    (tool,), (fixed,) = checker.model.elements, checker.scene_objects
    candidates = [Candidate('check', checker.check, poses)]
    equal, missing = '-', None
    try:
        import fcl
    except ImportError as error:
        fcl, missing = None, f'not installed ({error.name or error})'
    if fcl is not None:
        T = tool.T_link_element
        tool_model = fcl_bvh(tool.vertices @ T[:3, :3].T + T[:3, 3], tool.faces)
        T = fixed.T_world_object
        fixed_object = fcl.CollisionObject(fcl_bvh(fixed.vertices, fixed.faces),
                                           fcl.Transform(T[:3, :3].copy(), T[:3, 3].copy()))
        placed = []
        for q in poses:
            checker.check(q)
            T = checker.link_poses()['tool']
            placed.append(fcl.CollisionObject(tool_model, fcl.Transform(T[:3, :3], T[:3, 3])))
        request = fcl.CollisionRequest()

        def fcl_collide(obj):
            return fcl.collide(obj, fixed_object, request, fcl.CollisionResult())
        answers = [bool(fcl_collide(obj)) for obj in placed]
        equal = f'{sum(a == b for a, b in zip(ours, answers))}/{len(poses)}'
        candidates.append(Candidate('fcl', fcl_collide, placed))
    times = interleaved_us(candidates, rounds=rounds)
    return ContactTiming(len(tool.faces), len(fixed.faces), len(poses), sum(ours) / len(poses),
                         times['check'], times.get('fcl'), missing, equal,
                         work_per_check(checker, poses))


def report_contact(section: Section, timing: ContactTiming, tag: str) -> None:
    """Add the table of ``timing`` and its two verdicts (most poses in contact; ours <= 0.5x
    python-fcl), named ``tag`` (``S6``)."""
    rows = [['collision_sensor `check` (FK + the pair, one Python call)', us(timing.ours_us),
             '1.00x', '-']]
    if timing.fcl_us is not None:
        rows.append(['python-fcl `collide` (placement not counted)', us(timing.fcl_us),
                     ratio(timing.ours_us, timing.fcl_us), timing.equal])
    section.table(['implementation', 'us / pose', 'ours / this', 'answers equal to ours'],
                  rows)
    section.judge(f'{tag} more than half the poses collide', f'{timing.colliding:.0%}',
                  timing.colliding > 0.5)
    section.judge_ratio(f'{tag} heavy contact: `check` <= 0.5x python-fcl `collide`',
                        timing.ours_us, timing.fcl_us, TARGET_RATIO, 'python-fcl',
                        timing.fcl_missing)


def run(settings, workdir: str) -> Section:
    """Time ours against python-fcl on random poses of the tool in the clutter."""
    section = Section(6, TITLE)
    checker = contact_checker(workdir, settings.seed)
    n = 500 if settings.quick else 3000
    timing = time_contact(checker, random_configurations(checker, n, seed=settings.seed),
                          settings.rounds)
    section.text(
        f'Tool {timing.tool_triangles} triangles, clutter {timing.fixed_triangles} triangles '
        f'(70 random boxes, spheres and cylinders, seed {settings.seed}); {n} random poses, '
        f'{timing.colliding:.0%} colliding. Best of {settings.rounds} interleaved passes. Our '
        f'work per check: {timing.work["boxes"]:.0f} box tests, '
        f'{timing.work["triangles"]:.0f} triangle tests.')
    report_contact(section, timing, 'S6')
    return section
