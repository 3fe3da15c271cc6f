"""The collision checker: a robot and a static scene, checked on every joint-state update.

This is the API the node, the command-line tools and the benchmarks build on::

    checker = CollisionChecker.from_urdf(urdf, srdf=None, package_paths=None, scene=None,
                                         config=None)
    result = checker.check(positions)    # full check, trusts nothing carried over
    result = checker.update(positions)   # incremental: re-checks only what the motion changed
    result.in_collision, result.colliding_pairs

Everything between ``positions`` and the pair statuses runs in one call into the compiled
engine (``cpp/query.hpp``: ``Engine::query``, C++17); this module turns files into flat arrays
once, and names back into answers.
"""
import dataclasses
import math
from typing import Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.bounding_volumes import fit_obb
from collision_sensor.checker_config import CheckerConfig
from collision_sensor.errors import JointStateError, SceneError, SrdfError
from collision_sensor.exception_list import adjacent_pairs, parse_pair_strings, sorted_pair
from collision_sensor.kinematics import (JOINT_FLOATING, JOINT_PLANAR, JOINT_PRISMATIC,
                                         KinematicTree, build_kinematic_tree)
from collision_sensor.mesh_loading import SOLID_CLOSED_MESH, Solid, is_closed_surface
from collision_sensor.obb_tree import BOX_WIDTH, box_table, build_forest, forest_view, node_table
from collision_sensor.array_pack import ArrayPack
from collision_sensor.compiled import engine
from collision_sensor.robot_model import Joint, RobotModel, load_urdf
from collision_sensor.scene import SceneObject, load_scene
from collision_sensor.srdf import Srdf, load_srdf_for_model

Pair = Tuple[str, str]
_NOT_AN_ARRAY = engine.NOT_AN_ARRAY
#: Distinct colliding-pair sets whose answer tuples are kept for reuse (a robot in use meets
#: few of them; the bound keeps a random stream from growing the cache without end).
RESULT_CACHE_SIZE = 4096
Positions = Union[Mapping[str, float], Sequence[float], np.ndarray]
#: How far a point can move per unit of a floating joint's quaternion component, for the
#: incremental bounds (_pair_reaches): huge, so that any move beyond motion_tolerance forces
#: a re-check (the true bound grows as 1 / |quaternion|; the engine refuses quaternions with a
#: norm below QUATERNION_NORM_MIN = 1e-100, which keeps it below this, see cpp/kinematics.hpp).
#: Finite on purpose: inf * 0 would be NaN.
QUATERNION_REACH = 1e300
_VARIABLE_COUNT = {JOINT_PLANAR: 3, JOINT_FLOATING: 7}


class CheckResult(NamedTuple):
    """The answer of one check.

    :ivar in_collision: True iff at least one checked pair collides.
    :ivar colliding_pairs: sorted tuple of ``(a, b)`` with ``a < b``.
    :ivar rechecked_pairs: how many pairs this call actually re-checked (all for ``check``).
    """

    in_collision: bool
    colliding_pairs: Tuple[Pair, ...]
    rechecked_pairs: int


class ProximityRecord(NamedTuple):
    """One checked pair nearer than the ``max_distance`` of :meth:`CollisionChecker.proximity`.

    :ivar link_a: the pair's first name (``link_a < link_b``, as in ``checked_pairs``).
    :ivar link_b: the second name (a link or a scene object).
    :ivar distance: the distance between the two bodies' triangle surfaces (m); 0 when they
        collide (no penetration depth is computed).
    :ivar point_a: (3,) float, a nearest point on ``link_a``, in the world (root link) frame;
        when colliding, a point where the surfaces meet (or a vertex inside a solid primitive).
    :ivar point_b: (3,) float, the nearest point on ``link_b`` (``point_a`` when colliding).
    """

    link_a: str
    link_b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray


def _transformed(T: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(vertices @ T[:3, :3].T + T[:3, 3])


class CollisionChecker:
    """Self-collision and robot-versus-scene checking for one robot.

    Bodies are the robot's links and the scene objects. The world frame, in which scene poses
    are given, is the root link's frame; with an SRDF whose ``virtual_joint`` is planar or
    floating, it is the virtual joint's ``parent_frame`` (added as a link without geometry above
    the URDF root), and the robot stands where the joint's variables place it. Pairs
    are every two bodies with geometry, robot-robot and robot-scene, minus the exception list
    (adjacent links, SRDF ``disable_collisions``, ``allowed_collisions``). Contact means the
    two bodies' triangle surfaces share a point (touching counts); a body wholly inside another
    without touching its surface is not reported (see README, "Contact rule").
    """

    def __init__(self, model: RobotModel, srdf: Optional[Srdf] = None,
                 scene: Sequence[SceneObject] = (), config=None):
        """Build the hierarchies and the exception list; prefer :meth:`from_urdf`.

        :raises CollisionSensorError: on a bad scene, configuration or exception list.
        """
        self.config = CheckerConfig.from_mapping(config)
        model = self.model = _with_virtual_joint(model, srdf)
        self.kinematics: KinematicTree = build_kinematic_tree(model)
        kin = self.kinematics
        link_names = list(kin.link_names)
        scene = tuple(scene)
        clashes = sorted(set(link_names) & {obj.name for obj in scene})
        if clashes:
            raise SceneError(f'scene object name(s) {", ".join(clashes)} are also link names of '
                             f'robot "{model.name}"; rename the scene objects')
        self.scene_objects: Tuple[SceneObject, ...] = scene
        self.scene_object_names: Tuple[str, ...] = tuple(obj.name for obj in scene)
        body_names = link_names + list(self.scene_object_names)
        n_links, n_bodies = len(link_names), len(body_names)
        self._n_links = n_links

        # One tree per collision element (the paper's per-link sub-groups), in body frames.
        link_index = {name: i for i, name in enumerate(link_names)}
        meshes, owners, solids = [], [], []
        for element in model.elements:
            meshes.append((_transformed(element.T_link_element, element.vertices),
                           element.faces))
            owners.append(link_index[element.link])
            solids.append(self._solid_row(element.solid, element.faces,
                                          element.T_link_element))
        for s, obj in enumerate(scene):
            meshes.append((np.asarray(obj.vertices, dtype=np.float64), obj.faces))
            owners.append(n_links + s)
            solids.append(self._solid_row(obj.solid, obj.faces, np.eye(4)))
        order = np.argsort(np.asarray(owners, dtype=np.int64), kind='stable')
        meshes = [meshes[i] for i in order]
        elem_solid = (np.array([solids[i] for i in order]) if solids
                      else np.zeros((1, engine.SOLID_WIDTH)))
        owners = np.asarray(owners, dtype=np.int64)[order]
        forest = build_forest(meshes, leaf_size=self.config.leaf_size,
                              fit=self.config.obb_fit_code)
        counts = np.bincount(owners, minlength=n_bodies) if len(owners) else np.zeros(
            n_bodies, dtype=np.int64)
        self._body_elem_end = np.cumsum(counts).astype(np.int64)
        self._body_elem_start = (self._body_elem_end - counts).astype(np.int64)

        # Each body's box over all its sub-groups, in the body frame (sec. 2.1: computed once).
        self._body_center = np.zeros((n_bodies, 3))
        self._body_axes = np.tile(np.eye(3), (n_bodies, 1, 1))
        self._body_half = np.zeros((n_bodies, 3))
        for b in range(n_bodies):
            chunk = [meshes[e][0] for e in range(self._body_elem_start[b],
                                                 self._body_elem_end[b])]
            if chunk:
                points = np.concatenate(chunk)
                faces = np.concatenate([meshes[e][1] + sum(len(c) for c in chunk[:k])
                                        for k, e in enumerate(range(self._body_elem_start[b],
                                                                    self._body_elem_end[b]))])
                c, a, h = fit_obb(points, self.config.obb_fit_code, faces=faces)
                self._body_center[b], self._body_axes[b], self._body_half[b] = c, a, h

        with_geometry = [name for b, name in enumerate(body_names) if counts[b] > 0]
        self.link_names: Tuple[str, ...] = tuple(
            name for name in with_geometry if name in link_index)
        self.excluded_pairs: Dict[Pair, str] = self._exception_list(srdf, link_names)
        candidates = []
        robot = list(self.link_names)
        for i, a in enumerate(robot):
            for b in robot[i + 1:]:
                candidates.append(sorted_pair(a, b))
        for obj in self.scene_object_names:
            if counts[body_names.index(obj)] > 0:
                candidates.extend(sorted_pair(link, obj) for link in robot)
        self.checked_pairs: Tuple[Pair, ...] = tuple(
            sorted(pair for pair in set(candidates) if pair not in self.excluded_pairs))

        body_index = {name: b for b, name in enumerate(body_names)}
        self._body_index = body_index
        pair_a, pair_b = [], []
        for a, b in self.checked_pairs:
            ia, ib = body_index[a], body_index[b]
            if ia >= n_links:  # the engine expects the scene body second
                ia, ib = ib, ia
            pair_a.append(ia)
            pair_b.append(ib)
        self._pair_a = np.asarray(pair_a, dtype=np.int64)
        self._pair_b = np.asarray(pair_b, dtype=np.int64)
        pair_path = self._pair_paths(n_links)
        vertex_radius = np.zeros(n_bodies)
        for e, owner in enumerate(owners):
            if len(meshes[e][0]):
                vertex_radius[owner] = max(vertex_radius[owner],
                                           float(np.sqrt((meshes[e][0] ** 2).sum(axis=1).max())))
        self._pair_reach, self._pair_reach_ext = self._pair_reaches(n_links, vertex_radius)

        self.joint_names: Tuple[str, ...] = tuple(kin.joint_names)
        self._joint_index = {name: j for j, name in enumerate(self.joint_names)}
        self._derived_joints = frozenset(
            joint.name for joint in model.joints
            if joint.mimic is not None and joint.type != 'fixed')
        self.joint_limits: Dict[str, Tuple[float, float]] = {
            name: (float(kin.lower[j]), float(kin.upper[j]))
            for j, name in enumerate(self.joint_names)}

        is_scene = np.zeros(n_bodies, dtype=np.int64)
        is_scene[n_links:] = 1
        T_world_body = np.tile(np.eye(4), (n_bodies, 1, 1))
        for s, obj in enumerate(scene):
            T_world_body[n_links + s] = obj.T_world_object
        n_joints = len(self.joint_names)
        n_pairs = len(self.checked_pairs)
        # Each variable's pairs (those with it on their path), as one list cut per variable.
        on_path = pair_path.T.nonzero()
        joint_pairs_start = np.searchsorted(on_path[0], np.arange(n_joints + 1))
        # Each variable's links (whose pose depends on it), and whether it drives a slider.
        depends = np.zeros((n_joints, n_links), dtype=bool)
        joint_prismatic = np.zeros(n_joints)
        for i in range(n_links):  # parents come first
            if kin.parent[i] >= 0:
                depends[:, i] = depends[:, kin.parent[i]]
            if kin.q_index[i] >= 0:
                depends[_variables(kin, i), i] = True
                joint_prismatic[kin.q_index[i]] += kin.joint_type[i] == JOINT_PRISMATIC
        joint_links = depends.nonzero()
        joint_links_start = np.searchsorted(joint_links[0], np.arange(n_joints + 1))
        depth = int(forest.depth.max()) if len(forest.depth) else 1
        # Each pair's front (cpp/query.cpp: trees_of_pair) gets the same number of rows; the
        # traversal's stack takes a front's node pairs, or a pair's root pairs, as seeds.
        front_rows = int(np.clip(engine.FRONT_POOL_ROWS // max(n_pairs, 1),
                                 engine.FRONT_ROWS_MIN, engine.FRONT_ROWS_MAX))
        elements = self._body_elem_end - self._body_elem_start
        seeds = max([front_rows] + [int(elements[a] * elements[b])
                                    for a, b in zip(self._pair_a, self._pair_b)])
        f = forest
        # Everything the engine reads or keeps, in two flat buffers (see array_pack): static
        # model data and the carried state (q_ref, poses, statuses) alike.
        scalars = np.zeros(engine.N_SCALARS)
        scalars[engine.S_TOLERANCE] = self.config.motion_tolerance
        floats = dict(
            scalars=scalars, q_last=kin.neutral(), q_ref=kin.neutral(),
            T_parent_joint=kin.T_parent_joint, axis=kin.axis,
            multiplier=kin.multiplier, offset=kin.offset, T_world_body=T_world_body,
            body_boxes=box_table(self._body_center, self._body_axes, self._body_half),
            boxes=box_table(f.center, f.axes, f.half), volume=f.volume, gain=f.gain,
            tris=f.tris, elem_solid=elem_solid,
            subtree_boxes=np.zeros((max(n_links, 1), BOX_WIDTH)),
            clearance=np.zeros(n_pairs), q_eval=np.zeros((n_pairs, n_joints)),
            reach=self._pair_reach, reach_ext=self._pair_reach_ext, travel=np.zeros((n_pairs, 2)),
            front_until=np.zeros((n_pairs + 1) * front_rows), front_travel=np.zeros(n_pairs))
        ints = dict(
            header=np.zeros(engine.HEADER_SIZE), parent=kin.parent, joint_type=kin.joint_type,
            q_index=kin.q_index,
            is_scene=is_scene, body_elem_start=self._body_elem_start,
            body_elem_end=self._body_elem_end, roots=f.roots, nodes=node_table(f),
            pair_a=self._pair_a, pair_b=self._pair_b, joint_pairs_start=joint_pairs_start,
            joint_pairs=on_path[1], joint_links_start=joint_links_start,
            joint_links=joint_links[1], joint_prismatic=joint_prismatic,
            status=np.zeros(n_pairs), witness=np.full((n_pairs, 2), -1),
            moved=np.zeros(n_joints), stale=np.zeros(n_bodies), chain=np.zeros(max(n_links, 1)),
            pending=np.zeros(n_pairs), todo=np.zeros(n_pairs),
            scene_culled=np.zeros((len(scene), max(n_links, 1))),
            stack=np.zeros((seeds + 2 * depth + 8, 3)),
            counters=np.zeros(engine.N_COUNTERS), front=np.zeros(((n_pairs + 1) * front_rows, 3)),
            front_state=np.zeros((n_pairs, 2)))
        self._F, self._F_layout, float_views = self._pack(np.float64, engine.FLOAT_SLOTS, floats)
        self._I, self._I_layout, int_views = self._pack(np.int64, engine.INT_SLOTS, ints)
        # The forest is only a view of the engine's tables: nothing is held twice (scenario 4).
        self.forest = forest_view(float_views['boxes'], int_views['nodes'],
                                  float_views['volume'], float_views['gain'],
                                  float_views['tris'], int_views['roots'], forest.depth)
        self._views = {**float_views, **int_views}
        del forest, f, floats, ints
        self._write_header(n_links)
        self._engine = engine.Engine(self._F, self._I)
        self._q_ref = float_views['q_ref']
        self._T_world_body = float_views['T_world_body']
        self._status = int_views['status']
        self.counters = int_views['counters']  # work done, see traversal.COUNT_* (benchmarks)
        # The joint vector of the last call; the engine writes it (read-only for Python).
        self._q = float_views['q_last']
        self._result = CheckResult(False, (), 0)
        self._results: Dict[bytes, Tuple[Pair, ...]] = {}
        self._query = self._engine.query

    @classmethod
    def from_urdf(cls, urdf, srdf=None, package_paths: Optional[Mapping[str, str]] = None,
                  scene=None, config=None, xacro_args=None) -> 'CollisionChecker':
        """Load a robot, optionally its SRDF and a static scene, and build the checker.

        :param urdf: path to a URDF file, or the URDF's XML text.
        :param srdf: path or XML text of an SRDF, or None.
        :param package_paths: ``{package_name: directory}`` for ``package://`` mesh URIs.
        :param scene: path to a scene YAML file (or its parsed mapping), or None.
        :param config: mapping of settings (see :mod:`collision_sensor.checker_config`).
        :param xacro_args: ``{name: value}`` for a ``.xacro`` ``urdf``'s ``$(arg name)``.
        :return: the checker; its ``load_warnings`` (tuple of str) are the oddities loading
            tolerated, one line each (each document's also issued as a ``LoadWarning``).
        :raises CollisionSensorError: naming the file, link or setting at fault.
        """
        settings = CheckerConfig.from_mapping(config)
        model = load_urdf(urdf, package_paths, primitive_sections=settings.primitive_sections,
                          xacro_args=xacro_args)
        srdf_model = None
        if srdf is not None:
            srdf_model = load_srdf_for_model(srdf, model)
        objects = ()
        if scene is not None:
            objects = load_scene(scene, package_paths,
                                 primitive_sections=settings.primitive_sections)
        checker = cls(model, srdf_model, objects, settings)
        # What loading tolerated (also issued as LoadWarning), for a caller's own logger.
        checker.load_warnings = tuple(f'URDF: {line}' for line in model.warnings) + tuple(
            f'SRDF: {line}' for line in (srdf_model.warnings if srdf_model else ()))
        return checker

    # ------------------------------------------------------------------ set-up helpers
    @staticmethod
    def _pack(dtype, slots, arrays):
        pack = ArrayPack(dtype)
        for name in slots:  # the order of the engine's slots (cpp/query.hpp)
            pack.add(name, arrays[name])
        return pack.pack()

    def packed_array(self, name: str) -> np.ndarray:
        """Return the engine's array ``name`` (``cpp/query.hpp``: CS_FLOAT_SLOTS, CS_INT_SLOTS)
        as a view of the buffer the engine reads and writes in place: for tests, benchmarks and
        inspection (writing to it changes what the engine sees)."""
        return self._views[name]

    def _solid_row(self, solid, faces, T_body_element) -> np.ndarray:
        """The engine's row for one element (``cpp/query.hpp``: SOLID_*): what it fills, in
        its body's frame. Primitives are solid; a closed mesh is with ``mesh_containment``."""
        row = np.zeros(engine.SOLID_WIDTH)
        if solid is None and self.config.mesh_containment and is_closed_surface(faces):
            solid = Solid(SOLID_CLOSED_MESH)
        if solid is not None:
            row[0] = solid.kind
            row[1:4] = solid.size
            row[4:13] = T_body_element[:3, :3].ravel()
            row[13:16] = T_body_element[:3, 3]
        return row

    def _write_header(self, n_links: int) -> None:
        """Fill the int buffer's header (cpp/query.hpp: H_*) once, after packing."""
        I, e = self._I, engine
        I[e.H_N_LINKS], I[e.H_BOX_METHOD], I[e.H_EXPANSION] = (
            n_links, self.config.box_test_code, self.config.expansion_code)
        I[e.H_CHECKED_ONCE], I[e.H_RESYNC_COUNTDOWN] = 0, e.TRAVEL_RESYNC_CALLS
        I[e.H_LAYOUTS:e.H_I_LAYOUT] = self._F_layout.ravel()
        I[e.H_I_LAYOUT:e.HEADER_SIZE] = self._I_layout.ravel()

    def _exception_list(self, srdf: Optional[Srdf], link_names: List[str]) -> Dict[Pair, str]:
        excluded: Dict[Pair, str] = {}
        if self.config.ignore_adjacent:
            parents = {link: None for link in link_names}
            for joint in self.model.joints:
                parents[joint.child] = joint.parent
            for pair in adjacent_pairs(parents, self.link_names):
                excluded[pair] = 'adjacent'
        if srdf is not None:
            for entry in srdf.disabled_pairs:
                pair = sorted_pair(entry.link1, entry.link2)
                excluded.setdefault(pair, f'srdf: {entry.reason}' if entry.reason else 'srdf')
        known = set(link_names) | set(self.scene_object_names)
        for pair in parse_pair_strings(self.config.allowed_collisions, known):
            excluded.setdefault(pair, 'allowed_collisions')
        return excluded

    def _pair_paths(self, n_links: int) -> np.ndarray:
        """(P, J) uint8: variable j drives a joint on the tree path between the pair's bodies."""
        kin = self.kinematics
        n_joints = len(kin.joint_names)
        above = []  # links from each link up to (excluding) the root
        for i in range(n_links):
            chain, k = set(), i
            while k > 0:
                chain.add(k)
                k = int(kin.parent[k])
            above.append(chain)
        path = np.zeros((len(self._pair_a), n_joints), dtype=np.int64)
        for p, (a, b) in enumerate(zip(self._pair_a, self._pair_b)):
            links = above[a] ^ (above[b] if b < n_links else set())
            for k in links:
                if kin.q_index[k] >= 0:
                    path[p, _variables(kin, k)] = 1
        return path

    def _pair_reaches(self, n_links: int, vertex_radius: np.ndarray) -> np.ndarray:
        """Return ``reach, reach_ext`` (P, J) float64: how far a point of either body can move,
        relative to the other, per unit of variable j: ``reach + reach_ext * E``, where E is
        the sum of |value| of every prismatic joint at the current state (0 off the path).

        A joint k on the path moves the body on its side (relative to the pair's common
        ancestor). Revolute: every point of body x below k stays within the distance from
        k's origin (on its axis) to x's origin, at most the sum of the joint offsets
        ``|t_parent_joint|`` from k down to x plus the extensions of the prismatic joints
        between them (at most E), plus x's vertex radius around its origin. Prismatic: 1.
        Both times |multiplier|, summed over the joints variable j drives. E is taken at the
        new state: moving the prismatic variables first, then the others, is a path from the
        old state along which every bound holds.

        Planar and floating joints translate, then rotate about the translated origin (their
        child frame's). Translation variables: 1, as a prismatic joint. Planar theta: as a
        revolute joint about the child frame's origin, so the joint's own translation is not
        in its lever arm, and translation variables do not count in E. Quaternion components:
        QUATERNION_REACH (any move re-checks). A rotating joint k with a planar or floating
        joint between it and x would have that joint's translation in its lever arm; such a
        k gets QUATERNION_REACH too (rare: multi-DOF joints are mostly the root's), so E stays
        the prismatic joints' sum. Below both bodies' common ancestor (a floating base under
        self-collision pairs) a joint moves nothing relative, and is skipped.
        """
        kin = self.kinematics
        n_joints = len(kin.joint_names)
        offset_norm = np.linalg.norm(kin.T_parent_joint[:, :3, 3], axis=1)
        reach = np.zeros((len(self._pair_a), n_joints))
        reach_ext = np.zeros((len(self._pair_a), n_joints))
        for p, (a, b) in enumerate(zip(self._pair_a, self._pair_b)):
            chains = {}
            for x in (a, b) if b < n_links else (a,):
                chain, k = [], int(x)
                while k > 0:
                    chain.append(k)  # x and its ancestors, up to (excluding) the root
                    k = int(kin.parent[k])
                chains[int(x)] = chain
            for x, chain in chains.items():
                other = chains.get(int(b) if x == a else int(a), [])
                for depth, k in enumerate(chain):
                    if k in other or kin.q_index[k] < 0:
                        continue  # above the common ancestor, or not driven
                    below = chain[:depth]  # from x up to, excluding, k
                    m = abs(kin.multiplier[k]) * (1.0 + 1e-9)
                    j = kin.q_index[k]
                    kind = kin.joint_type[k]
                    if kind == JOINT_PRISMATIC:
                        reach[p, j] += m
                        continue
                    lever = float(offset_norm[below].sum()) + vertex_radius[x]
                    if any(kin.joint_type[c] in _VARIABLE_COUNT for c in below):
                        lever = QUATERNION_REACH   # a multi-DOF translation in the lever arm
                    if kind == JOINT_PLANAR:
                        reach[p, j:j + 2] += m   # x, y
                        j += 2                   # theta: below, as a revolute joint
                    elif kind == JOINT_FLOATING:
                        reach[p, j:j + 3] += m   # trans_x, trans_y, trans_z
                        reach[p, j + 3:j + 7] = QUATERNION_REACH
                        continue
                    reach[p, j] = min(reach[p, j] + m * lever, QUATERNION_REACH)
                    if any(kin.joint_type[c] == JOINT_PRISMATIC for c in below):
                        reach_ext[p, j] += m
        return reach, reach_ext

    # ------------------------------------------------------------------ queries
    def _merged(self, positions: Positions) -> np.ndarray:
        """Return the current joint vector with ``positions`` applied.

        Finiteness (and what else the engine cannot honour) is checked by the engine, before it
        changes anything.
        """
        if (isinstance(positions, np.ndarray) and positions.shape == self._q.shape
                and positions.dtype == np.float64):
            return np.ascontiguousarray(positions)  # the engine copies it before keeping it
        q = self._q.copy()
        if isinstance(positions, Mapping):
            unknown = [name for name in positions
                       if name not in self._joint_index and name not in self._derived_joints]
            if unknown:
                raise JointStateError(
                    f'unknown joint name(s) {", ".join(map(str, unknown))} for robot '
                    f'"{self.model.name}"; movable joints are {", ".join(self.joint_names)}')
            for name, value in positions.items():
                try:
                    number = float(value)
                except (TypeError, ValueError):
                    raise JointStateError(
                        f'joint "{name}": position {value!r} is not a number') from None
                if not math.isfinite(number):
                    raise JointStateError(f'joint "{name}": position {number} is not finite; '
                                          'send a finite value (nothing was changed)')
                j = self._joint_index.get(name)
                if j is not None:  # a mimic joint follows its source; its own value is unused
                    q[j] = number
            return q
        try:
            values = np.asarray(positions, dtype=np.float64)
        except (TypeError, ValueError):
            raise JointStateError(f'positions must be a mapping joint -> value or a sequence of '
                                  f'{len(q)} numbers, got {type(positions).__name__}') from None
        if values.shape != q.shape:
            raise JointStateError(
                f'expected {len(q)} positions in the order of joint_names '
                f'({", ".join(self.joint_names)}), got shape {values.shape}')
        return np.ascontiguousarray(values)

    def _run(self, positions: Positions, full: bool) -> CheckResult:
        # A float64 C-contiguous array of the right length goes to the engine as it is (it
        # copies the values before keeping them); the engine tells anything else apart. This
        # is every joint-state message's path: a Python call costs here about what the
        # engine's own check of a Panda costs, so it stays flat (check and update take the
        # commonest answer, nothing changed, without even this call).
        return self._settle(self._query(positions, full), positions, full)

    def _settle(self, code: int, positions: Positions, full: bool) -> CheckResult:
        """Return the answer for the engine's ``code`` (``cpp/query.hpp``: Engine::query)."""
        if code > 0:
            if code & 1:
                # The engine reports whether any status changed, so the pair names are
                # gathered only then (and found again by the statuses' bytes).
                hits = self._results.get(self._status.tobytes())
                if hits is None:
                    hits = self._pair_names_now()
                result = self._result = CheckResult(bool(hits), hits, code >> 1)
                return result
            if code >> 1 != self._result.rechecked_pairs:
                result = self._result
                self._result = CheckResult(result.in_collision, result.colliding_pairs,
                                           code >> 1)
            return self._result
        if code == 0:
            if self._result.rechecked_pairs:
                result = self._result
                self._result = CheckResult(result.in_collision, result.colliding_pairs, 0)
            return self._result  # nothing moved: the same answer
        if code == _NOT_AN_ARRAY:
            return self._run(self._merged(positions), full)
        raise JointStateError(self._unusable_message(-1 - code, positions))

    def _unusable_message(self, j: int, q: np.ndarray, row: Optional[int] = None) -> str:
        """The message for variable j of ``q``, which the engine refused (not finite, or
        moving a prismatic joint beyond the engine's range)."""
        where = f'configuration {row}, ' if row is not None else ''
        value = q[j]
        name = self.joint_names[j]
        if math.isfinite(value) and name.endswith('/rot_x'):
            joint = name[:-len('/rot_x')]
            values = ', '.join(f'{v:g}' for v in q[j:j + 4])
            return (f'{where}floating joint "{joint}": quaternion (rot_x, rot_y, rot_z, rot_w) '
                    f'= ({values}) is zero (norm below {engine.QUATERNION_NORM_MIN:g}); send a '
                    'unit quaternion, (0, 0, 0, 1) for no rotation (nothing was changed)')
        if math.isfinite(value):
            why = (f'moves a joint out of the engine\'s range (a prismatic joint, or a planar or '
                   f'floating joint\'s translation, by more than '
                   f'{engine.PRISMATIC_VALUE_MAX:g} m, or a value that overflows); send a '
                   'value within the joint\'s limits')
        else:
            why = 'is not finite; send a finite value'
        return (f'{where}joint "{self.joint_names[j]}": position {value} {why} '
                '(nothing was changed)')

    def check(self, positions: Positions) -> CheckResult:
        """Check every pair from scratch at ``positions``; trust nothing carried over.

        :param positions: ``{joint: value}`` (joints not given keep their last value, zero at
            start; mimic joints' values are ignored, they follow their source), or an array
            in the order of :attr:`joint_names`.
        :raises JointStateError: on unknown names or non-finite values; nothing changes then.
        """
        code = self._query(positions, True)
        if code >= 0 and not code & 1 and code >> 1 == self._result.rechecked_pairs:
            return self._result  # no status changed: the last answer (see _settle)
        return self._settle(code, positions, True)

    def update(self, positions: Positions) -> CheckResult:
        """Check incrementally: re-check only pairs whose relative pose can have changed.

        A pair is re-checked only if a joint on the tree path between its two bodies moved by
        more than ``motion_tolerance`` since the state its status describes; every other
        status, and every pose not below a moved joint, carries over (paper sec. 4.2). A pair
        last found apart by ``update`` with a known clearance is not re-checked either while
        the joints on its path have not moved far enough, summed, to close that gap (see
        ``plan_update`` in ``cpp/query.cpp``).
        Same arguments and errors as :meth:`check`.
        """
        code = self._query(positions, False)
        if code >= 0 and not code & 1 and code >> 1 == self._result.rechecked_pairs:
            return self._result  # no status changed: the last answer (see _settle)
        return self._settle(code, positions, False)

    def check_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Check many configurations from scratch, in one compiled call; return (n, P) bool
        statuses, columns in the order of :attr:`checked_pairs`.

        The carried state is restored afterwards: the next :meth:`update` goes on from the
        positions of the last single call.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or a value that is not finite (naming the
            row and joint); nothing changes then.
        """
        saved = self._q.copy()
        statuses, _ = self._batch(configurations, full=True)
        self._run(saved, full=True)
        return statuses

    def update_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Run :meth:`update` on each row in turn, in one compiled call: a recorded path
        checked incrementally, without the interpreter between steps. Return (n, P) bool
        statuses after each row, columns in the order of :attr:`checked_pairs`.

        The state carries over as with single calls: afterwards the checker stands at the
        last row (``update`` goes on from there, :attr:`positions` is that row).

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: as :meth:`check_batch`; nothing changes then.
        """
        statuses, codes = self._batch(configurations, full=False)
        if len(codes):
            self._result = self._result_from_status(int(codes[-1]) >> 1)
        return statuses

    def _batch(self, configurations, full: bool) -> Tuple[np.ndarray, np.ndarray]:
        """Run the rows through the engine; return (n, P) bool statuses and (n,) codes."""
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names):
            raise JointStateError(f'expected configurations of shape (n, {len(self.joint_names)})'
                                  f' in the order of joint_names, got {Q.shape}')
        statuses = np.zeros((len(Q), len(self.checked_pairs)), dtype=np.uint8)
        codes = np.zeros(len(Q), dtype=np.int64)
        done = self._engine.batch(Q, full, statuses, codes)
        if done < 0:  # the engine validates every row before it runs any
            row, j = divmod(-1 - done, len(self.joint_names))
            raise JointStateError(self._unusable_message(j, Q[row], row))
        return statuses.view(bool), codes

    def proximity(self, positions: Positions,
                  max_distance: float = 0.1) -> List[ProximityRecord]:
        """Run :meth:`update` at ``positions``, then measure every checked pair nearer than
        ``max_distance``; return their records sorted by distance (colliding pairs first,
        distance 0).

        Same hierarchy and exception list as :meth:`check`; the engine descends both bodies'
        OBB trees with box distance lower bounds and stops a pair once its bound reaches
        ``max_distance`` or the best distance found (``cpp/distance.hpp``). A colliding pair
        (exactly the pairs :meth:`update` reports) has distance 0 and a point where the bodies
        meet; its penetration depth is not computed.

        :param positions: as for :meth:`check`.
        :param max_distance: only pairs closer than this (m; ``math.inf``: every pair).
        :raises JointStateError: as :meth:`check`.
        :raises ValueError: ``max_distance`` is NaN.
        """
        max_distance = float(max_distance)
        if math.isnan(max_distance):
            raise ValueError('max_distance is NaN; give a distance in metres (inf: all pairs)')
        q = self._merged(positions)
        n_pairs = len(self.checked_pairs)
        distance = np.empty(n_pairs)
        points = np.empty((n_pairs, 6))
        code = self._engine.proximity(q, max_distance, distance, points)
        if code < 0:
            raise JointStateError(self._unusable_message(-1 - code, q))
        self._result = self._result_from_status(code >> 1)
        return self._proximity_records(distance, points)

    def _proximity_records(self, distance: np.ndarray,
                           points: np.ndarray) -> List[ProximityRecord]:
        """Records for the pairs with a finite distance, sorted; points as named."""
        records = []
        body_a = self._pair_a
        for p in np.flatnonzero(np.isfinite(distance)):
            a, b = self.checked_pairs[p]
            row = points[p]
            if self._body_index[a] == body_a[p]:
                point_a, point_b = row[:3].copy(), row[3:].copy()
            else:  # the engine keeps a scene object second
                point_a, point_b = row[3:].copy(), row[:3].copy()
            records.append(ProximityRecord(a, b, float(distance[p]), point_a, point_b))
        records.sort(key=lambda r: (r.distance, r.link_a, r.link_b))
        return records

    def _pair_names_now(self) -> Tuple[Pair, ...]:
        """The colliding pairs' names for the current statuses (kept for reuse: the same pair
        set comes back again and again, mostly none or one or two pairs)."""
        names = self.checked_pairs
        hits = tuple([names[p] for p in np.flatnonzero(self._status)])
        if len(self._results) < RESULT_CACHE_SIZE:
            self._results[self._status.tobytes()] = hits
        return hits

    def _result_from_status(self, rechecked: int) -> CheckResult:
        hits = self._results.get(self._status.tobytes())
        if hits is None:
            hits = self._pair_names_now()
        return CheckResult(bool(hits), hits, rechecked)

    # ------------------------------------------------------------------ inspection
    @property
    def positions(self) -> Dict[str, float]:
        """The joint positions of the last check, by name."""
        return {name: float(v) for name, v in zip(self.joint_names, self._q)}

    def link_poses(self) -> Dict[str, np.ndarray]:
        """World poses (4, 4) of every link and scene object at the last checked state."""
        names = list(self.kinematics.link_names) + list(self.scene_object_names)
        T_world_body = self._poses()
        return {name: T_world_body[b].copy() for b, name in enumerate(names)}

    def _poses(self) -> np.ndarray:
        """(B, 4, 4) world poses of all bodies, brought up to date (``update`` computes a
        link's pose only when a pair it re-checks needs it)."""
        self._engine.poses()
        return self._T_world_body

    def collision_boxes(self, names: Iterable[str]) -> List[Tuple[str, np.ndarray, np.ndarray]]:
        """Return each sub-group's root box of the named bodies, in the world.

        :param names: link or scene object names; names without geometry give nothing.
        :return: list of ``(name, T_world_box (4, 4), half_extents (3,))``.
        """
        boxes = []
        f = self.forest
        T_world_body = self._poses()
        for name in names:
            b = self._body_index.get(name)
            if b is None:
                continue
            for e in range(self._body_elem_start[b], self._body_elem_end[b]):
                node = f.roots[e]
                T_body_box = np.eye(4)
                T_body_box[:3, :3] = f.axes[node]
                T_body_box[:3, 3] = f.center[node]
                boxes.append((name, T_world_body[b] @ T_body_box, f.half[node].copy()))
        return boxes


def _variables(kin: KinematicTree, k: int) -> slice:
    """The variables of q that the joint above link k reads (consecutive)."""
    j = int(kin.q_index[k])
    return slice(j, j + _VARIABLE_COUNT.get(int(kin.joint_type[k]), 1))


def _with_virtual_joint(model: RobotModel, srdf: Optional[Srdf]) -> RobotModel:
    """Return ``model`` with the SRDF's planar or floating virtual joint above its root link.

    The virtual joint's ``parent_frame`` becomes the root (a link without geometry) and the
    world frame; its variables come first in ``q``, as in MoveIt's variable order. A fixed
    virtual joint changes nothing (the root link already is the world frame). Only the first
    virtual joint is used (the SRDF loader keeps only those that reach the root link).

    :raises SrdfError: the parent frame is already a link of the robot.
    """
    moving = [joint for joint in (srdf.virtual_joints if srdf is not None else ())
              if joint.type != 'fixed']
    if not moving:
        return model
    virtual = moving[0]
    if model.root_link == virtual.parent_frame and any(
            joint.name == virtual.name for joint in model.joints):
        return model   # already added (a checker built on another checker's model)
    if virtual.parent_frame in model.links:
        raise SrdfError(f'SRDF "{srdf.source}": virtual joint "{virtual.name}" has parent_frame '
                        f'"{virtual.parent_frame}", which is a link of the robot; name the '
                        'world frame differently')
    if any(joint.name == virtual.name for joint in model.joints):
        raise SrdfError(f'SRDF "{srdf.source}": virtual joint "{virtual.name}" has the name of '
                        'a URDF joint; rename it')
    joint = Joint(name=virtual.name, type=virtual.type, parent=virtual.parent_frame,
                  child=virtual.child_link, T_parent_joint=np.eye(4),
                  axis=np.array([0.0, 0.0, 1.0]), lower=-math.inf, upper=math.inf,
                  velocity=0.0, effort=0.0, mimic=None)
    order = model.joint_document_order or tuple(j.name for j in model.joints)
    return dataclasses.replace(
        model, root_link=virtual.parent_frame, links=(virtual.parent_frame,) + model.links,
        joints=(joint,) + model.joints, joint_document_order=(virtual.name,) + order)
