"""The motion scenario's oracle: dense sampling with ``check_batch``, confirmed by python-fcl.

Sampling: the straight motion at steps of at most ``SAMPLE_STEP`` of every variable, states
interpolated as ``check_motion`` moves (:func:`motion_cells.discretized`), checked with
``check_batch`` in chunks until the first state in contact.

python-fcl (:class:`FclConfirmation`) shares only the triangles with the engine: link poses
come from pinocchio's kinematics (its own URDF parsing), and every element and scene object is
an ``fcl.BVHModel`` (OBBRSS) over the triangles our loader produced. Primitives are solid
(docs/engine.md, "Contact rule"): a body also meets a box, sphere or cylinder (scene object or URDF
element) when fcl's true shape meets any of its triangles, so a body wholly inside one is in
contact. A pair is in contact if its BVHs collide or a solid meets the other; its distance is
fcl's BVH distance, 0 when in contact.
"""
import math
import os
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.motion import TOUCH_TOLERANCE
from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_CYLINDER, SOLID_SPHERE
from benchmarks.motion_cells import discretized
from benchmarks.scenario_peers import fcl_bvh

Pair = Tuple[str, str]

#: rad or m: the oracle's sampling resolution (at most 1e-3: finer than any gap it must see).
SAMPLE_STEP = 1e-3
#: fcl's distances and our contact rule agree to this, m (the triangle test's tolerance is
#: 1e-12 relative, fcl's triangle distance is exact up to rounding).
FCL_SLACK = 1e-9
#: States per ``check_batch`` call while sampling (the first chunk with a contact ends it).
CHUNK = 256


def first_sampled_contact(checker: CollisionChecker, q_from: np.ndarray, q_to: np.ndarray,
                          step: float = SAMPLE_STEP):
    """Sample the straight motion every ``step`` (rad or m, max over variables) until a state
    is in contact.

    :return: ``(t, pairs, q, checked, samples)``: the fraction, checked pairs in contact and
        state of the first sampled state in contact (``None, (), None`` when none is), how
        many states were checked and how many samples the whole motion has.
    """
    Q = discretized(checker, q_from, q_to, step)
    T = np.linspace(0.0, 1.0, len(Q))
    names = checker.checked_pairs
    for start in range(0, len(Q), CHUNK):
        statuses = checker.check_batch(Q[start:start + CHUNK])
        hits = np.flatnonzero(statuses.any(axis=1))
        if len(hits):
            i = hits[0]
            pairs = tuple(names[p] for p in np.flatnonzero(statuses[i]))
            return float(T[start + i]), pairs, Q[start + i], start + i + 1, len(Q)
    return None, (), None, len(Q), len(Q)


class Element(NamedTuple):
    """One element of a body, as the oracle holds it (body frame)."""

    bvh: object                      # fcl.CollisionObject over its triangles
    vertices: np.ndarray             # (n, 3) float
    solid: Optional[tuple]           # (kind, half sizes (3,), T_body_solid (4, 4)) or None


class FclConfirmation:
    """python-fcl on the checker's triangles, links placed by pinocchio (see the module).

    Whether two bodies share a point is asked in three ways, each independent of the engine:
    their triangles meet (``fcl.collide`` on the BVHs); an element of one lies wholly inside
    a solid primitive of the other (every vertex inside the true shape, numpy); some vertex
    of one lies inside such a solid (the sliver between an inscribed tessellation and the true
    shape: the engine lets one vertex decide there, docs/engine.md "Contact rule", so either answer
    is right). Pairs whose bounding spheres are apart are not asked.

    :raises ImportError: python-fcl or pinocchio is not installed.
    """

    def __init__(self, checker: CollisionChecker, urdf: str):
        import fcl
        import pinocchio as pin
        self.fcl, self.pin = fcl, pin
        self.checker = checker
        virtual = checker.model.joints[0] if checker.model.joints else None
        roots = {'floating': pin.JointModelFreeFlyer, 'planar': pin.JointModelPlanar}
        build = pin.buildModelFromUrdf if os.path.exists(urdf) else pin.buildModelFromXML
        if (virtual is not None and virtual.parent == checker.model.root_link
                and virtual.type in roots):
            # An SRDF virtual joint above the URDF's root: pinocchio's own root joint.
            self.model = build(urdf, roots[virtual.type](), virtual.name)
        else:
            self.model = build(urdf)
        self.data = self.model.createData()
        self.frames = {link: self.model.getFrameId(link, pin.FrameType.BODY)
                       for link in checker.link_names
                       if self.model.existFrame(link, pin.FrameType.BODY)}
        self.elements: Dict[str, List[Element]] = {}
        for element in checker.model.elements:
            T = element.T_link_element
            vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
            solid = None if element.solid is None else (
                element.solid.kind, np.asarray(element.solid.size, dtype=float), T)
            self.elements.setdefault(element.link, []).append(
                Element(fcl.CollisionObject(fcl_bvh(vertices, element.faces)), vertices, solid))
        self.fixed: Dict[str, np.ndarray] = {}
        for obj in checker.scene_objects:
            solid = None if obj.solid is None else (
                obj.solid.kind, np.asarray(obj.solid.size, dtype=float), np.eye(4))
            bvh = fcl.CollisionObject(fcl_bvh(obj.vertices, obj.faces))
            T = obj.T_world_object
            bvh.setTransform(fcl.Transform(T[:3, :3].copy(), T[:3, 3].copy()))
            self.elements[obj.name] = [Element(bvh, obj.vertices, solid)]
            self.fixed[obj.name] = T
        self.spheres = {}   # body: (centre (3,), radius) in the body frame
        for body, elements in self.elements.items():
            points = np.concatenate([e.vertices for e in elements])
            centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
            self.spheres[body] = (centre, float(np.linalg.norm(points - centre, axis=1).max()))
        bodies = {b for pair in checker.checked_pairs for b in pair}
        missing = sorted(bodies - set(self.fixed) - set(self.frames))
        if missing:
            raise ValueError(f'pinocchio has no frame for {missing}')
        self.poses_now: Dict[str, np.ndarray] = dict(self.fixed)

    def configuration(self, positions: np.ndarray) -> np.ndarray:
        """pinocchio's q for our joint vector: mimic joints derived, a continuous joint as
        (cos, sin), a planar joint as (x, y, cos, sin), a floating one (xyz, quaternion)."""
        from collision_sensor.model.robot_model import resolve_mimics
        q = self.pin.neutral(self.model)
        values = dict(zip(self.checker.joint_names, positions))
        for name, (source, multiplier, offset) in resolve_mimics(
                self.checker.model.joints).items():
            values[name] = multiplier * values[source] + offset
        for j in range(1, self.model.njoints):
            name, joint = self.model.names[j], self.model.joints[j]
            i = joint.idx_q
            if joint.nq == 7:
                quaternion = np.array([values[f'{name}/rot_{a}'] for a in 'xyzw'])
                q[i:i + 3] = [values[f'{name}/trans_{a}'] for a in 'xyz']
                q[i + 3:i + 7] = quaternion / np.linalg.norm(quaternion)
            elif joint.nq == 4:
                theta = values[f'{name}/theta']
                q[i:i + 4] = (values[f'{name}/x'], values[f'{name}/y'], math.cos(theta),
                              math.sin(theta))
            elif joint.nq == 2:
                q[i:i + 2] = math.cos(values[name]), math.sin(values[name])
            elif name in values:
                q[i] = values[name]
        return q

    def place(self, positions: np.ndarray) -> Dict[str, np.ndarray]:
        """Place every link where pinocchio's kinematics puts it at ``positions``; return every
        body's world pose ``{name: (4, 4)}``."""
        self.pin.framesForwardKinematics(self.model, self.data, self.configuration(positions))
        Transform = self.fcl.Transform
        poses = self.poses_now
        for link, frame in self.frames.items():
            M = self.data.oMf[frame]
            poses[link] = M.homogeneous
            if link in self.elements:
                transform = Transform(M.rotation, M.translation)
                for element in self.elements[link]:
                    element.bvh.setTransform(transform)
        return poses

    def _near(self, a: str, b: str, margin: float) -> bool:
        """False when the bodies' bounding spheres are more than ``margin`` apart."""
        (ca, ra), (cb, rb) = self.spheres[a], self.spheres[b]
        Ta, Tb = self.poses_now[a], self.poses_now[b]
        gap = np.linalg.norm(Ta[:3, :3] @ ca + Ta[:3, 3] - Tb[:3, :3] @ cb - Tb[:3, 3])
        return gap - ra - rb <= margin

    def _solid_gap(self, a: str, b: str) -> Tuple[float, bool]:
        """``(d, whole)``: the smallest distance of a vertex of b to a solid of a (0 inside),
        and whether some element of b lies wholly inside one (numpy, true shapes)."""
        best, whole = math.inf, False
        Ta, Tb = self.poses_now[a], self.poses_now[b]
        for ea in self.elements[a]:
            if ea.solid is None:
                continue
            kind, h, T_local = ea.solid
            T = Ta @ T_local
            for eb in self.elements[b]:
                x = (eb.vertices @ Tb[:3, :3].T + Tb[:3, 3] - T[:3, 3]) @ T[:3, :3]
                d = solid_distance(kind, h, x)
                best = min(best, float(d.min()))
                whole = whole or bool(np.all(d == 0.0))
        return best, whole

    def contact(self, a: str, b: str) -> str:
        """At the placed poses: ``'surfaces'`` (triangles meet), ``'inside'`` (an element wholly
        inside the other's solid), ``'sliver'`` (only some vertex inside a solid) or ``''``."""
        if not self._near(a, b, 0.0):
            return ''
        fcl = self.fcl
        request = fcl.CollisionRequest()
        for ea in self.elements[a]:
            for eb in self.elements[b]:
                if fcl.collide(ea.bvh, eb.bvh, request, fcl.CollisionResult()):
                    return 'surfaces'
        (gap_ab, whole_ab), (gap_ba, whole_ba) = self._solid_gap(a, b), self._solid_gap(b, a)
        if whole_ab or whole_ba:
            return 'inside'
        return 'sliver' if min(gap_ab, gap_ba) == 0.0 else ''

    def distance(self, a: str, b: str) -> float:
        """At the placed poses: the distance between bodies a and b, m (0 when a vertex of one
        is inside a solid of the other or their triangles meet): fcl's BVH distance, or a
        vertex's distance to a solid's true shape if smaller."""
        if self.contact(a, b):
            return 0.0
        fcl = self.fcl
        request = fcl.DistanceRequest()
        d = min(fcl.distance(ea.bvh, eb.bvh, request, fcl.DistanceResult())
                for ea in self.elements[a] for eb in self.elements[b])
        return min(d, self._solid_gap(a, b)[0], self._solid_gap(b, a)[0])

    def confirm_state(self, positions: np.ndarray, ours: Sequence[Pair]) -> Tuple[bool, int]:
        """Check our colliding pairs at a state against fcl's: ``(agrees, slivers)``.

        Agrees: every pair whose triangles meet or that lies wholly inside a solid is ours,
        and each of ours is one of those or a sliver case. ``slivers``: pairs in the sliver
        (either answer is right).
        """
        self.place(positions)
        ours = set(ours)
        agrees, slivers = True, 0
        for pair in self.checker.checked_pairs:
            kind = self.contact(*pair)
            slivers += kind == 'sliver'
            if kind in ('surfaces', 'inside') and pair not in ours:
                agrees = False
            if not kind and pair in ours:
                agrees = False
        return agrees, slivers

    def nearest(self, positions: np.ndarray, pairs: Sequence[Pair]) -> float:
        """The smallest distance over ``pairs`` at ``positions``, m (0 if one is in contact)."""
        self.place(positions)
        return min(self.distance(a, b) for a, b in pairs)


def solid_distance(kind: int, h: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Distances of points ``x`` (n, 3), in a solid's frame, to the solid (0 inside): a box of
    half extents ``h``, a sphere of radius ``h[0]``, a cylinder along z of radius ``h[0]`` and
    half length ``h[1]`` (the true shapes, not their tessellations)."""
    if kind == SOLID_BOX:
        return np.linalg.norm(np.maximum(np.abs(x) - h[:3], 0.0), axis=1)
    if kind == SOLID_SPHERE:
        return np.maximum(np.linalg.norm(x, axis=1) - h[0], 0.0)
    if kind == SOLID_CYLINDER:
        radial = np.maximum(np.hypot(x[:, 0], x[:, 1]) - h[0], 0.0)
        return np.hypot(radial, np.maximum(np.abs(x[:, 2]) - h[1], 0.0))
    return np.full(len(x), math.inf)


def confirms_touch(distance: float) -> bool:
    """True iff a reported first contact at ``distance`` (fcl's) is within the tolerance."""
    return distance <= TOUCH_TOLERANCE + FCL_SLACK
