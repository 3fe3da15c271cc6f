"""Scenario 10, part C: python-fcl's ``continuousCollide`` next to ``check_motion``.

Primitives (the cases fcl can answer): a box, ball or cylinder, turned at random, translating
in a straight line past or through another, fixed one. Ours: scenario 6's tool URDF carrying
the moving primitive on three prismatic joints (x, y, z) and three revolute ones (yaw, pitch,
roll, the same at both ends, so the motion is a pure translation), the other primitive a
scene object. fcl: the same shapes and poses, ``continuousCollide`` with its defaults
(``CCDM_TRANS``, the motion that matches; conservative advancement; libccd), one fresh
result per call. Both answer "is there a contact on the way, and when first".

Which answer is right is decided apart from both: fcl's own discrete ``collide`` on the true
shapes along the motion every ``SAMPLE_MM`` mm. Our primitives are tessellated (inscribed,
32 sections), so a motion that only grazes the true shape may miss the tessellation: a case
is *decisive* when the sampled answer is the same for the true shapes and for the shapes
shrunk to our tessellation's inscribed radius; only those are judged.

Meshes (the cases fcl cannot answer): a BVH box or a Panda link mesh translating (or swung
about an axis) through a plate, every fcl solver with the matching motion type, next to ours.
"""
import contextlib
import math
import os
from typing import List, NamedTuple

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from benchmarks.motion_cells import MotionCell, write_stl
from benchmarks.scenario_contact import URDF as CONTACT_TOOL_URDF
from benchmarks.scenario_measure import Candidate, interleaved_rounds_us
from benchmarks.scenario_peers import fcl_bvh
from benchmarks.scenario_report import Section, load_note, ratio, spread, us

TARGET_RATIO = 0.5
#: The moving and the fixed primitive's kinds.
KINDS = ('box', 'sphere', 'cylinder')
#: mm: the resolution of the sampled fcl.collide that decides which answer is right.
SAMPLE_MM = 1.0
#: The mover's joints' ranges: sliders +-5 m, revolute joints as scenario 6's tool has them
#: (turns are drawn within +-TURN).
SLIDE, TURN = 5.0, 3.1
#: The link that moves, in both URDFs.
MOVING = 'tool'
#: A link swung about the z axis of a revolute joint ``radius`` m from its origin.
SWING = '''<robot name="swing">
  <link name="world"/>
  <link name="tool"><collision><origin xyz="{radius} 0 0"/><geometry>
    <mesh filename="file://{mesh}"/></geometry></collision></link>
  <joint name="swing" type="revolute"><parent link="world"/><child link="tool"/>
    <axis xyz="0 0 1"/><limit lower="-4" upper="4" effort="1" velocity="1"/></joint>
</robot>
'''


@contextlib.contextmanager
def quiet_stderr():
    """Silence fcl's C++ warnings ("Invalid continuous collision checking") at the fd."""
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def rotation_zyx(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``: the mover's joints yaw, pitch, roll in turn."""
    cz, sz, cy, sy = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    cx, sx = math.cos(roll), math.sin(roll)
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
            @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


def mover_urdf(geometry: str) -> str:
    """Scenario 6's tool URDF (link ``tool`` on x, y, z sliders, then yaw, pitch, roll)
    carrying ``geometry`` (a URDF ``<geometry>``'s content)."""
    return CONTACT_TOOL_URDF.format(geometry=geometry, x0=-SLIDE, x1=SLIDE, y0=-SLIDE,
                                    y1=SLIDE, z0=-SLIDE, z1=SLIDE)


def _dimensions(kind: str, rng) -> np.ndarray:
    """Box edges, or (radius, length) of a cylinder, or (radius,) of a ball: 2 to 30 cm."""
    if kind == 'box':
        return rng.uniform(0.02, 0.3, 3)
    if kind == 'cylinder':
        return np.array([rng.uniform(0.01, 0.15), rng.uniform(0.02, 0.3)])
    return np.array([rng.uniform(0.01, 0.15)])


def _urdf_geometry(kind: str, d: np.ndarray) -> str:
    d = [repr(float(x)) for x in d]   # every digit: fcl gets the same numbers
    if kind == 'box':
        return f'<box size="{d[0]} {d[1]} {d[2]}"/>'
    if kind == 'cylinder':
        return f'<cylinder radius="{d[0]}" length="{d[1]}"/>'
    return f'<sphere radius="{d[0]}"/>'


def _scene_shape(kind: str, d: np.ndarray) -> dict:
    if kind == 'box':
        return {'box': {'size': [float(x) for x in d]}}
    if kind == 'cylinder':
        return {'cylinder': {'radius': float(d[0]), 'length': float(d[1])}}
    return {'sphere': {'radius': float(d[0])}}


def _fcl_shape(fcl, kind: str, d: np.ndarray, inradius: float = None):
    """fcl's true shape, or (``inradius``) shrunk to lie inside our tessellation."""
    if kind == 'box':
        return fcl.Box(*d)
    if kind == 'cylinder':
        return fcl.Cylinder(d[0] if inradius is None else inradius, d[1])
    return fcl.Sphere(d[0] if inradius is None else inradius)


def _inradius(vertices: np.ndarray, faces: np.ndarray, kind: str) -> float:
    """The radius of the ball (the cylinder, for its side faces) inscribed in our
    tessellation, centred at the element's origin: its faces' smallest plane distance."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    distance = np.abs(np.einsum('ij,ij->i', n, a))
    if kind == 'cylinder':
        distance = distance[np.abs(n[:, 2]) < 0.5]
    return float(distance.min())


class Case(NamedTuple):
    """One translation: ours (checker, q_from, q_to) and fcl's (objects and end poses)."""

    kinds: str
    check_motion: object
    q_from: np.ndarray
    q_to: np.ndarray
    fcl_args: tuple                 # (o1, tf1_end, o2, tf2_end) for continuousCollide
    truth: bool                     # fcl.collide sampled on the true shapes
    decisive: bool                  # ... and on the shrunk ones alike
    truth_t: float                  # the first sampled contact (fraction), or 1
    checker: object                 # whose check_motion it is (its counters)


def _primitive_cases(settings, fcl) -> List[Case]:
    """``settings.ccd_cases`` translations per (moving, fixed) pair of primitive kinds."""
    rng = np.random.default_rng([settings.seed, 13])
    cases = []
    for moving in KINDS:
        for fixed in KINDS:
            dm, df = _dimensions(moving, rng), _dimensions(fixed, rng)
            rpy = rng.uniform(-math.pi, math.pi, 3)
            scene = {'objects': [{'name': 'fixed', 'pose': {'rpy': [float(x) for x in rpy]},
                                  **_scene_shape(fixed, df)}]}
            checker = CollisionChecker.from_urdf(mover_urdf(_urdf_geometry(moving, dm)),
                                                 scene=scene)
            element, obj = checker.model.elements[0], checker.scene_objects[0]
            shrunk = (_fcl_shape(fcl, moving, dm, _inradius(element.vertices, element.faces,
                                                            moving)),
                      _fcl_shape(fcl, fixed, df, _inradius(obj.vertices, obj.faces, fixed)))
            true = _fcl_shape(fcl, moving, dm), _fcl_shape(fcl, fixed, df)
            T_fixed = obj.T_world_object
            tf_fixed = fcl.Transform(T_fixed[:3, :3].copy(), T_fixed[:3, 3].copy())
            for _ in range(settings.ccd_cases):
                turn = rng.uniform(-TURN, TURN, 3)
                R = rotation_zyx(*turn)
                u = rng.normal(size=3)
                u /= np.linalg.norm(u)
                w = rng.normal(size=3)
                w -= (w @ u) * u
                w *= rng.uniform(0.0, 0.3) / np.linalg.norm(w)   # closest pass of the centre
                p0, p1 = w - u, w + rng.uniform(0.2, 1.2) * u
                q0, q1 = np.concatenate([p0, turn]), np.concatenate([p1, turn])
                checker.check(q0)
                if not np.allclose(checker.link_poses()[MOVING][:3, :3], R, atol=1e-12):
                    raise AssertionError('the mover\'s rotation is not Rz Ry Rx')
                truth, truth_t = _sampled(fcl, true, R, p0, p1, T_fixed)
                shrunk_truth, _ = _sampled(fcl, shrunk, R, p0, p1, T_fixed)
                o1 = fcl.CollisionObject(true[0], fcl.Transform(R.copy(), p0.copy()))
                o2 = fcl.CollisionObject(true[1], tf_fixed)
                cases.append(Case(f'{moving}-{fixed}', checker.check_motion, q0, q1,
                                  (o1, fcl.Transform(R.copy(), p1.copy()), o2, tf_fixed),
                                  truth, truth == shrunk_truth, truth_t, checker))
    return cases


def _sampled(fcl, shapes, R, p0, p1, T_fixed):
    """fcl.collide along the translation every SAMPLE_MM: ``(contact, first fraction)``."""
    n = max(2, int(math.ceil(np.linalg.norm(p1 - p0) * 1e3 / SAMPLE_MM)) + 1)
    moving = fcl.CollisionObject(shapes[0], fcl.Transform())
    fixed = fcl.CollisionObject(shapes[1], fcl.Transform(T_fixed[:3, :3].copy(),
                                                         T_fixed[:3, 3].copy()))
    request = fcl.CollisionRequest()
    for t in np.linspace(0.0, 1.0, n):
        moving.setTransform(fcl.Transform(R, p0 + t * (p1 - p0)))
        if fcl.collide(moving, fixed, request, fcl.CollisionResult()):
            return True, float(t)
    return False, 1.0


def run(section: Section, settings, workdir: str, panda: MotionCell) -> None:
    """Part C: primitives against continuousCollide (judged), then the mesh cases."""
    section.text('', '#### C. python-fcl `continuousCollide`', '')
    try:
        import fcl
    except ImportError as error:
        section.text(f'python-fcl not installed ({error.name}): part C not run.')
        section.judge('S10 primitives: the same answer as continuousCollide', 'python-fcl '
                      'not installed', None)
        section.judge(f'S10 primitives: `check_motion` <= {TARGET_RATIO}x continuousCollide',
                      'python-fcl not installed', None)
        return
    cases = _primitive_cases(settings, fcl)
    request = fcl.ContinuousCollisionRequest()
    Result = fcl.ContinuousCollisionResult
    collide = fcl.continuousCollide

    def theirs(case):
        result = Result()
        collide(*case.fcl_args, request, result)
        return result

    with quiet_stderr():
        fcl_answers = [theirs(case) for case in cases]
    ours = [case.check_motion(case.q_from, case.q_to) for case in cases]
    rows, fcl_wrong, ours_wrong, same, worst_t = [], 0, 0, 0, 0.0
    for case, mine, their in zip(cases, ours, fcl_answers):
        same += mine.in_collision == bool(their.is_collide)
        if not case.decisive:
            continue
        fcl_wrong += bool(their.is_collide) != case.truth
        ours_wrong += mine.in_collision != case.truth
        if mine.in_collision and their.is_collide and case.truth:
            worst_t = max(worst_t, abs(mine.first_contact - their.time_of_contact))
    decisive = [c for c in cases if c.decisive]
    fcl_right = [k for k, c in enumerate(cases)
                 if c.decisive and bool(fcl_answers[k].is_collide) == c.truth]
    same_where_fcl_right = sum(ours[k].in_collision == bool(fcl_answers[k].is_collide)
                               for k in fcl_right)
    timing = {}
    groups = (('all', cases), ('in contact', [c for c in cases if c.truth]),
              ('free', [c for c in cases if not c.truth]))
    with quiet_stderr():
        for label, group in groups:
            if not group:
                continue
            # Every pass starts after an untimed one over the same cases (caches, and fcl's
            # first calls).
            passes = interleaved_rounds_us(
                [Candidate('ours', lambda c: c.check_motion(c.q_from, c.q_to), group),
                 Candidate('fcl', theirs, group)], settings.rounds, warm_items=len(group))
            timing[label] = passes
            rows.append([label, len(group), us(min(passes['ours'])), us(min(passes['fcl'])),
                         ratio(min(passes['ours']), min(passes['fcl'])),
                         f'{spread(passes["ours"])}; {spread(passes["fcl"])}'])
    section.text(
        f'{len(cases)} translations ({settings.ccd_cases} per pair of kinds: box, ball, '
        'cylinder moving past or through a fixed one; 2 to 30 cm, turned at random, 1.2 to '
        '2.2 m long, the centre passing within 0.3 m). fcl: `continuousCollide` with its '
        'defaults (CCDM_TRANS, conservative advancement, libccd). The right answer: fcl\'s '
        f'discrete `collide` on the true shapes every {SAMPLE_MM:g} mm of the motion; '
        f'{len(decisive)} cases are decisive (the same answer with the shapes shrunk to our '
        f'32-section tessellation\'s inscribed radius). {load_note()}.')
    section.table(['cases', 'count', '`check_motion` us', '`continuousCollide` us',
                   'ours / fcl', 'min / median / max over passes: ours; fcl'], rows)
    section.text(
        f'Answers: ours and continuousCollide the same on {same} of {len(cases)}. On the '
        f'{len(decisive)} decisive cases, continuousCollide is wrong on {fcl_wrong} (it '
        f'misses contacts that its own sampled `collide` finds), ours on {ours_wrong}; where '
        f'fcl is right ({len(fcl_right)} cases) ours gives the same answer on '
        f'{same_where_fcl_right}. Largest difference of the first contact from fcl\'s time '
        f'of contact where both find one: {worst_t:.4f} of the motion (fcl\'s toc_err is '
        '1e-4; our tessellation is inscribed).')
    if timing.get('in contact') and timing.get('free'):
        counters = _ccd_work(cases)
        section.text(
            'Where the time goes (our counters, per motion; a translation of two convex '
            'bodies is swept by GJK ray casts, docs/motion.md): in contact '
            f'{counters["in contact"][0]:.1f} box and {counters["in contact"][1]:.1f} '
            f'triangle tests, {counters["in contact"][2]:.2f} pairs swept in '
            f'{counters["in contact"][3]:.1f} GJK iterations; free '
            f'{counters["free"][0]:.1f} box and {counters["free"][1]:.1f} triangle tests, '
            f'{counters["free"][2]:.2f} pairs swept in {counters["free"][3]:.1f} GJK '
            'iterations.')
    section.judge('S10 primitives: the same answer as continuousCollide (decisive cases '
                  'where it is right)',
                  f'{same_where_fcl_right} of {len(fcl_right)} (fcl wrong on {fcl_wrong} of '
                  f'{len(decisive)} decisive; ours on {ours_wrong})',
                  same_where_fcl_right == len(fcl_right) and ours_wrong == 0)
    best = {k: min(v) for k, v in timing['all'].items()}
    section.judge_ratio(f'S10 primitives: `check_motion` <= {TARGET_RATIO}x '
                        'continuousCollide (all cases)', best['ours'], best['fcl'],
                        TARGET_RATIO, 'python-fcl', None)
    mesh_cases(section, fcl, workdir, panda)


def _ccd_work(cases):
    """Box and triangle tests, pairs swept and their GJK iterations per motion, for motions
    in contact and free."""
    from collision_sensor.engine.traversal import (
        COUNT_BOX_TESTS, COUNT_SWEEP_STEPS, COUNT_SWEEPS, COUNT_TRIANGLE_TESTS)
    columns = [COUNT_BOX_TESTS, COUNT_TRIANGLE_TESTS, COUNT_SWEEPS, COUNT_SWEEP_STEPS]
    work = {}
    for label, truth in (('in contact', True), ('free', False)):
        group = [c for c in cases if c.truth == truth]
        total = np.zeros(len(columns))
        for case in group:
            checker = case.checker
            checker.counters[:] = 0
            case.check_motion(case.q_from, case.q_to)
            total += checker.counters[columns]
        work[label] = total / max(1, len(group))
    return work


# ---------------------------------------------------------------------------- meshes
def _box(extents):
    import trimesh
    mesh = trimesh.creation.box(extents=extents)
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


def mesh_cases(section: Section, fcl, workdir: str, panda: MotionCell) -> None:
    """The mesh cases fcl misses, next to ours (not judged: listed)."""
    hand = [e for e in panda.checker.model.elements if e.link == 'panda_hand']
    T = hand[0].T_link_element
    hand_v = hand[0].vertices @ T[:3, :3].T + T[:3, 3]
    hand_v = hand_v - 0.5 * (hand_v.min(axis=0) + hand_v.max(axis=0))   # centred
    hand_f = hand[0].faces
    box_v, box_f = _box([0.1, 0.1, 0.1])
    plate_5cm, plate_1mm = _box([0.05, 1.0, 1.0]), _box([0.001, 1.0, 1.0])
    cases = [
        ('BVH box (10 cm) translating 2 m through a 5 cm plate', box_v, box_f, plate_5cm,
         'translate'),
        ('BVH box (10 cm) translating 2 m through a 1 mm plate', box_v, box_f, plate_1mm,
         'translate'),
        (f'Panda hand mesh ({len(hand_f)} triangles) translating 2 m through a 5 cm plate',
         hand_v, hand_f, plate_5cm, 'translate'),
        ('Panda hand mesh swung 90 deg about an axis 0.5 m away through a 5 cm plate',
         hand_v, hand_f, plate_5cm, 'swing'),
    ]
    solvers = (('naive (samples 10 states)', 0), ('conservative advancement', 1),
               ('ray shooting', 2), ('polynomial', 3))
    rows = []
    for label, v, f, (plate_v, plate_f), motion in cases:
        mesh = write_stl(v, f, os.path.join(workdir, f'ccd_{len(rows)}.stl'))
        plate = write_stl(plate_v, plate_f, os.path.join(workdir, f'plate_{len(rows)}.stl'))
        scene = {'objects': [{'name': 'plate', 'mesh': {'filename': plate}}]}
        if motion == 'translate':
            checker = CollisionChecker.from_urdf(
                mover_urdf(f'<mesh filename="file://{mesh}"/>'), scene=scene)
            q0, q1 = np.array([-1.0, 0, 0, 0, 0, 0]), np.array([1.0, 0, 0, 0, 0, 0])
            start = fcl.Transform(np.eye(3), np.array([-1.0, 0.0, 0.0]))
            end = fcl.Transform(np.eye(3), np.array([1.0, 0.0, 0.0]))
            motion_type = 0   # CCDM_TRANS
        else:
            # The plate at x = 0.5 m... the hand 0.5 m from the axis, swung from -45 to 45 deg
            # about z: it crosses the x axis, where the plate stands across its way.
            scene['objects'][0]['pose'] = {'xyz': [0.5, 0.0, 0.0], 'rpy': [0.0, 0.0,
                                                                           math.pi / 2]}
            checker = CollisionChecker.from_urdf(SWING.format(radius=0.5, mesh=mesh),
                                                 scene=scene)
            q0, q1 = np.array([-math.pi / 4]), np.array([math.pi / 4])
            start, end = (_swung(fcl, -math.pi / 4, 0.5), _swung(fcl, math.pi / 4, 0.5))
            motion_type = 2   # CCDM_SCREW: a rotation about a fixed axis
        ours = checker.check_motion(q0, q1)
        plate_T = checker.scene_objects[0].T_world_object
        plate_tf = fcl.Transform(plate_T[:3, :3].copy(), plate_T[:3, 3].copy())
        truth = _sampled_mesh(fcl, (v, f), (plate_v, plate_f), plate_tf, checker, q0, q1)
        answers = []
        with quiet_stderr():
            for name, solver in solvers:
                o1 = fcl.CollisionObject(fcl_bvh(v, f), start)
                o2 = fcl.CollisionObject(fcl_bvh(plate_v, plate_f), plate_tf)
                result = fcl.ContinuousCollisionResult()
                fcl.continuousCollide(o1, end, o2, plate_tf, fcl.ContinuousCollisionRequest(
                    ccd_motion_type=motion_type, ccd_solver_type=solver), result)
                answers.append(f'{name}: ' + (f'contact at {result.time_of_contact:.3f}'
                                              if result.is_collide else '**no contact**'))
        rows.append([label, f'contact at {truth:.3f}' if truth is not None else 'no contact',
                     '; '.join(answers),
                     f'contact at {ours.first_contact:.3f}' if ours.in_collision
                     else '**no contact**'])
    section.text('', 'Meshes (not judged): fcl\'s BVH models, every solver with the matching '
                 'motion type (CCDM_TRANS for a translation, CCDM_SCREW for the swing), '
                 'defaults otherwise; ours on the same triangles.')
    section.table(['case', f'fcl.collide every {SAMPLE_MM:g} mm (1e-3 rad for the swing)',
                   'python-fcl continuousCollide', 'ours `check_motion`'], rows)


def _sampled_mesh(fcl, moving, fixed, fixed_tf, checker, q0, q1):
    """The first contact of fcl.collide on the BVHs along the motion (our kinematics place
    the moving body: a slider or one revolute joint), every SAMPLE_MM mm or 1e-3 rad; None
    when none is found."""
    n = max(2, int(math.ceil(np.abs(np.asarray(q1) - q0).max() * 1e3 / SAMPLE_MM)) + 1)
    body = fcl.CollisionObject(fcl_bvh(*moving))
    plate = fcl.CollisionObject(fcl_bvh(*fixed), fixed_tf)
    request = fcl.CollisionRequest()
    T_link_element = checker.model.elements[0].T_link_element
    for t in np.linspace(0.0, 1.0, n):
        checker.check(q0 + t * (np.asarray(q1) - q0))
        T = checker.link_poses()[MOVING] @ T_link_element
        body.setTransform(fcl.Transform(T[:3, :3].copy(), T[:3, 3].copy()))
        if fcl.collide(body, plate, request, fcl.CollisionResult()):
            return float(t)
    return None


def _swung(fcl, angle: float, radius: float):
    """The pose of a body ``radius`` m out along x, turned by ``angle`` about the world z."""
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return fcl.Transform(R, R @ np.array([radius, 0.0, 0.0]))
