"""Robots in clutter for the motion scenario (10): scenes sized to each robot's reach, random
segments from clear starts, a smooth path through the clutter, and motions discretized.

A cluttered scene is made from where the robot actually goes: random configurations within
the limits put its moving links' geometry somewhere; each object is centred at one of those
places (jittered), so every object is within reach. Sizes scale with the reach ``R`` (the
farthest such place from the root, m): boxes of edges ``U(0.002, 0.15) R`` (plates and rods
among them), cylinders of radius ``U(0.002, 0.05) R`` and length ``U(0.05, 0.4) R``, balls of
radius ``U(0.01, 0.08) R``; the motion tests' scene scaled to each robot. None is on
the base: an object met in more than ``MAX_CONTACT_SHARE`` of random configurations is drawn
again (a base in contact would make every state a contact; so would a link that no joint
takes far, such as a shoulder turning in place).
"""
import math
import os
import warnings
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.motion import interpolate
from collision_sensor.engine.sampling import sampling_bounds, uniform_configurations
from collision_sensor.errors import LoadWarning
from collision_sensor.model.example_robots import example_robot_files
from collision_sensor.model.robot_model import load_urdf
from collision_sensor.model.scene import load_scene
from collision_sensor.model.srdf import load_srdf_for_model

#: The robots of the certification part: (label, example-robot-data name ``<pkg>/<stem>``).
#: Two arms the whole benchmark uses, three more arms (continuous joints on the Kinova), the
#: arm of a humanoid and a mobile manipulator (PR2: its SRDF's planar base joint moves too).
ROBOTS = (
    ('panda', 'panda_description/panda'),
    ('ur5', 'ur_description/ur5_robot'),
    ('kinova', 'kinova_description/kinova'),
    ('xarm7', 'xarm_description/xarm7'),
    ('z1', 'z1_description/z1'),
    ('talos_left_arm', 'talos_data/talos_left_arm'),
    ('pr2', 'pr2_description/pr2'),
)
#: Our checkers run on one thread, as the peers they are measured against (scenario 11
#: measures the threads).
ONE_THREAD = {'threads': 1}
#: Objects per scene (boxes, cylinders and balls in turn).
SCENE_OBJECTS = 14
#: An object met in more than this share of random configurations is drawn again.
MAX_CONTACT_SHARE = 0.1
#: Bounds of a mobile base's planar x and y when drawing configurations (m): its limits are
#: infinite, and the scene is built around the base's reach from this square.
BASE_SQUARE = 0.5


@dataclass
class MotionCell:
    """A robot in its cluttered scene.

    :ivar urdf: path of the URDF (for the oracle's pinocchio model).
    :ivar scene: the scene as a dict (``{'objects': [...]}``), the form ``from_urdf`` takes.
    :ivar reach: the reach ``R`` the scene was sized to, m.
    :ivar lower, upper: ``(J,) float`` bounds the configurations are drawn from (the joint
        limits; [-pi, pi] for continuous joints; ``BASE_SQUARE`` for a planar base's x, y).
    """

    name: str
    urdf: str
    srdf: Optional[str]
    package_paths: Dict[str, str]
    checker: CollisionChecker
    scene: dict
    reach: float
    lower: np.ndarray
    upper: np.ndarray


def draw_bounds(checker: CollisionChecker) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(lower, upper)`` to draw configurations from (see :class:`MotionCell`)."""
    lower, upper = sampling_bounds(checker)
    for j, name in enumerate(checker.joint_names):
        if name.endswith('/x') or name.endswith('/y'):   # a planar joint's translation
            lower[j], upper[j] = -BASE_SQUARE, BASE_SQUARE
    return lower, upper


def motion_cells(seed: int, names: Optional[Sequence[str]] = None) -> List[MotionCell]:
    """Return a cell per robot of :data:`ROBOTS` (or of ``names``) whose files are installed."""
    files = {robot.name: robot for robot in example_robot_files()}
    cells = []
    for k, (label, name) in enumerate(ROBOTS):
        if (names is not None and label not in names) or name not in files:
            continue
        robot = files[name]
        with warnings.catch_warnings():   # what the SRDFs hold for other variants
            warnings.simplefilter('ignore', LoadWarning)
            model = load_urdf(robot.urdf, robot.package_paths)
            srdf = load_srdf_for_model(robot.srdf, model) if robot.srdf else None
        bare = CollisionChecker(model, srdf, config=ONE_THREAD)
        lower, upper = draw_bounds(bare)
        scene, reach = cluttered_scene(bare, lower, upper, np.random.default_rng([seed, k]))
        checker = CollisionChecker(model, srdf, load_scene(scene), config=ONE_THREAD)
        cells.append(MotionCell(label, robot.urdf, robot.srdf, dict(robot.package_paths),
                                checker, scene, reach, lower, upper))
    return cells


def _element_centres(checker: CollisionChecker) -> Dict[str, np.ndarray]:
    """The centre of each link's geometry (its vertices' bounding box) in the link frame."""
    points: Dict[str, list] = {}
    for element in checker.model.elements:
        T = element.T_link_element
        points.setdefault(element.link, []).append(element.vertices @ T[:3, :3].T + T[:3, 3])
    return {link: 0.5 * (np.concatenate(p).min(axis=0) + np.concatenate(p).max(axis=0))
            for link, p in points.items()}


def _random_object(name: str, kind: int, xyz: np.ndarray, reach: float,
                   rng: np.random.Generator) -> dict:
    """A box (kind 0), cylinder (1) or ball (2) at ``xyz``, sized to ``reach``, turned at
    random: a scene entry."""
    if kind == 0:
        shape = {'box': {'size': [float(x) for x in rng.uniform(0.002, 0.15, 3) * reach]}}
    elif kind == 1:
        shape = {'cylinder': {'radius': float(rng.uniform(0.002, 0.05) * reach),
                              'length': float(rng.uniform(0.05, 0.4) * reach)}}
    else:
        shape = {'sphere': {'radius': float(rng.uniform(0.01, 0.08) * reach)}}
    return {'name': name, 'pose': {'xyz': [float(x) for x in xyz],
                                   'rpy': [float(x) for x in rng.uniform(-math.pi, math.pi, 3)]},
            **shape}


def cluttered_scene(checker: CollisionChecker, lower: np.ndarray, upper: np.ndarray,
                    rng: np.random.Generator, n_objects: int = SCENE_OBJECTS,
                    n_configurations: int = 300) -> Tuple[dict, float]:
    """Return a scene of ``n_objects`` boxes, rods and balls in reach of ``checker``'s robot,
    none on its base, and the reach ``R`` it was sized to (see the module's docstring).

    :param checker: the robot without a scene (each object is added to it to be tried, and
        removed again).
    """
    centres = _element_centres(checker)
    links = sorted(centres)
    Q = uniform_configurations(lower, upper, n_configurations, rng)
    places = []
    for q in Q:
        checker.check(q)
        poses = checker.link_poses()
        places += [poses[link][:3, :3] @ centres[link] + poses[link][:3, 3] for link in links]
    places = np.array(places)
    reach = float(np.linalg.norm(places, axis=1).max())
    objects, tried = [], 0
    while len(objects) < n_objects:
        tried += 1
        if tried > 100 * n_objects:
            raise RuntimeError(f'no room for {n_objects} objects around {checker.model.name}')
        centre = places[rng.integers(len(places))] + rng.normal(0.0, 0.05 * reach, 3)
        entry = _random_object(f'clutter_{len(objects)}', len(objects) % 3, centre, reach, rng)
        obj = load_scene({'objects': [entry]})[0]
        checker.add_object(obj)
        statuses = checker.check_batch(Q)
        mine = [p for p, pair in enumerate(checker.checked_pairs) if obj.name in pair]
        checker.remove_object(obj.name)
        if statuses[:, mine].any(axis=1).mean() <= MAX_CONTACT_SHARE:
            objects.append(entry)
    return {'objects': objects}, reach


def random_segments(checker: CollisionChecker, lower: np.ndarray, upper: np.ndarray, n: int,
                    rng: np.random.Generator, shortest: float, longest: float
                    ) -> List[Tuple[np.ndarray, np.ndarray]]:
    """Return ``n`` motions ``(q_from, q_to)`` from clear states, of Euclidean length
    ``U(shortest, longest)`` in joint space (rad or m), both ends within ``[lower, upper]``.

    A start in contact is drawn again; a direction that leaves the bounds is drawn again (up
    to 20 times; never clipped, so every segment has the length drawn).
    """
    segments = []
    attempts = 0
    while len(segments) < n:
        attempts += 1
        if attempts > 200 * n + 1000:
            raise RuntimeError(f'{n} clear starts with segments within limits not found in '
                               f'{attempts} draws; the scene is too full')
        q0 = uniform_configurations(lower, upper, 1, rng)[0]
        if checker.check(q0).in_collision:
            continue
        length = rng.uniform(shortest, longest)
        for _ in range(20):
            d = rng.normal(size=len(q0))
            q1 = q0 + d * (length / np.linalg.norm(d))
            if np.all(q1 >= lower) and np.all(q1 <= upper):
                segments.append((q0, q1))
                break
    return segments


def discretized(checker: CollisionChecker, q_from: np.ndarray, q_to: np.ndarray,
                step: float) -> np.ndarray:
    """Return the states of the straight motion at steps of at most ``step`` of every variable
    (rad or m; a floating joint's rotation by its angle), both ends included: ``(n, J)``.

    The motion is interpolated as ``check_motion`` moves (:func:`motion.interpolate`).
    """
    kinds = checker.motion_kinds
    ends = interpolate(kinds, q_from, q_to, np.array([0.0, 1.0]))
    delta = np.abs(ends[1] - ends[0])
    for j in np.flatnonzero(kinds == engine.MOTION_QUATERNION):   # the rotation angle
        a = ends[0, j:j + 4] / np.linalg.norm(ends[0, j:j + 4])
        b = ends[1, j:j + 4] / np.linalg.norm(ends[1, j:j + 4])
        delta[j:j + 4] = 2.0 * math.acos(min(abs(float(a @ b)), 1.0))
    n = max(2, int(math.ceil(delta.max() / step)) + 1)
    return interpolate(kinds, q_from, q_to, np.linspace(0.0, 1.0, n))


def discretized_path(checker: CollisionChecker, Q: np.ndarray, step: float) -> np.ndarray:
    """Return the states of the path through waypoints ``Q`` (n, J), each motion discretized
    as :func:`discretized` does, each waypoint once."""
    parts = [Q[:1]]
    for q0, q1 in zip(Q[:-1], Q[1:]):
        parts.append(discretized(checker, q0, q1, step)[1:])
    return np.concatenate(parts)


def smooth_path(checker: CollisionChecker, lower: np.ndarray, upper: np.ndarray,
                n: int, rng: np.random.Generator, shortest: float = 0.01,
                longest: float = 0.03, turn: float = 0.15, check_step: float = 2e-3
                ) -> np.ndarray:
    """Return ``(n, J)`` waypoints of a smooth random path through the clutter, every motion
    between them free: what a planner hands over.

    From a clear start, the direction drifts by ``N(0, turn)`` per waypoint (unit vector),
    reflects off the bounds, and each step is ``U(shortest, longest)`` long (Euclidean). A
    step whose motion, sampled every ``check_step``, meets something is drawn again with a
    wider turn, so the path bends around the objects it would hit.
    """
    def free(q0, q1):
        return not checker.check_batch(discretized(checker, q0, q1, check_step)).any()

    while True:
        q = uniform_configurations(lower, upper, 1, rng)[0]
        if not checker.check(q).in_collision:
            break
    v = rng.normal(size=len(q))
    v /= np.linalg.norm(v)
    path = [q]
    while len(path) < n:
        spread = turn
        for _ in range(200):
            w = v + rng.normal(0.0, spread, len(q))
            w /= np.linalg.norm(w)
            q1 = path[-1] + w * rng.uniform(shortest, longest)
            outside = (q1 < lower) | (q1 > upper)
            if outside.any():   # reflect off the bounds
                w[outside] = -w[outside]
                q1 = path[-1] + w * np.linalg.norm(q1 - path[-1])
            if np.all(q1 >= lower) and np.all(q1 <= upper) and free(path[-1], q1):
                break
            spread = min(4.0, spread * 1.5)
        else:
            raise RuntimeError('the smooth path is boxed in; draw another seed')
        path.append(q1)
        v = w
    return np.array(path)


def write_stl(vertices: np.ndarray, faces: np.ndarray, path: str) -> str:
    """Write triangles to an STL file (what a URDF or scene mesh names); return the path."""
    import trimesh
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return os.path.abspath(path)
