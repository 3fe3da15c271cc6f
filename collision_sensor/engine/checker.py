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

from collision_sensor.engine.array_pack import ArrayPack
from collision_sensor.engine.bounding_volumes import fit_obb
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import (
    MAX_COORDINATE, ROTATION_TOLERANCE, AddObject, MoveObject, PlacedObject, PreparedSceneChanges,
    RemoveObject, SceneChange, SceneChangeError, build_object_block, check_geometry, checked_pose,
    same_geometry, solid_row)
from collision_sensor.engine.motion import FREE, MotionResult, PathResult, motion_kinds
from collision_sensor.engine.trajectory import TrajectoryResult, check_trajectory
from collision_sensor.engine.kinematics import (JOINT_FIXED, JOINT_FLOATING, JOINT_PLANAR,
                                                JOINT_PRISMATIC, KinematicTree,
                                                build_kinematic_tree)
from collision_sensor.engine.obb_tree import (
    BOX_WIDTH, NODE_LEFT, NODE_RIGHT, box_table, build_forest, forest_view, node_table)
from collision_sensor.errors import ConfigError, JointStateError, SceneError, SrdfError
from collision_sensor.model.exception_list import adjacent_pairs, parse_pair_strings, sorted_pair
from collision_sensor.model.robot_model import Joint, RobotModel, load_urdf
from collision_sensor.model.scene import SceneObject, load_scene
from collision_sensor.model.srdf import Srdf, load_srdf_for_model

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
    :ivar distance: the distance between the two bodies' triangle surfaces minus their two
        paddings (m; without padding, the surfaces' distance); <= 0 exactly when the pair is
        in contact: 0 when the surfaces meet, without padding (no penetration depth is
        computed); with padding, the surfaces' distance minus the paddings (-padding when
        they meet, or when a body lies inside a solid primitive).
    :ivar point_a: (3,) float, a nearest point of ``link_a``'s padded geometry (on its
        surface, moved towards ``point_b`` by its padding), in the world (root link) frame;
        in contact, one point of both padded bodies: where the surfaces meet (or a vertex
        inside a solid primitive), or, padded, the point between the surfaces' nearest points
        that splits their segment in the ratio of the two paddings.
    :ivar point_b: (3,) float, the nearest point of ``link_b``'s padded geometry
        (``point_a`` in contact). Apart, ``|point_b - point_a| == distance``.
    """

    link_a: str
    link_b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray


class _RobotBlock(NamedTuple):
    """What the engine reads of the robot that no scene change alters (built once).

    Trees (``boxes (N, BOX_WIDTH)``, ``nodes (N, NODE_WIDTH)``, ``volume, gain (N,)``,
    ``tris (T, 3, 3)``, ``roots (E,)``, ``depth``, ``elem_solid (E, SOLID_WIDTH)``), each
    link's element range ``elem_start, elem_end (L,)``, box ``body_boxes (L, BOX_WIDTH)``,
    vertex radius ``radius (L,)`` and padding ``padding (L,)`` (metres; its boxes are grown by
    it, see :func:`_grow_boxes`), and the self-collision pairs checked.
    """

    boxes: np.ndarray
    nodes: np.ndarray
    volume: np.ndarray
    gain: np.ndarray
    tris: np.ndarray
    roots: np.ndarray
    depth: int
    elem_solid: np.ndarray
    elem_start: np.ndarray
    elem_end: np.ndarray
    body_boxes: np.ndarray
    radius: np.ndarray
    padding: np.ndarray
    pairs: Tuple[Pair, ...]


class _EngineTree(NamedTuple):
    """The engine's kinematic arrays: the robot's links, then each attached object as a link
    on a fixed joint below its own (``T_parent_joint`` its pose in that link's frame)."""

    parent: np.ndarray
    joint_type: np.ndarray
    q_index: np.ndarray
    multiplier: np.ndarray
    T_parent_joint: np.ndarray


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
    without touching its surface is not reported (see README, "Contact rule"). With padding
    (``padding``, ``link_padding`` in the config), each link's geometry is grown by its padding
    (a sphere swept over it): contact means the surfaces come within the two paddings' sum.
    """

    def __init__(self, model: RobotModel, srdf: Optional[Srdf] = None,
                 scene: Sequence[SceneObject] = (), config=None):
        """Build the hierarchies and the exception list; prefer :meth:`from_urdf`.

        :param scene: world objects at the start (:meth:`add_object` adds more at any time).
        :raises CollisionSensorError: on a bad scene, configuration or exception list.
        """
        self.config = CheckerConfig.from_mapping(config)
        model = self.model = _with_virtual_joint(model, srdf)
        self.kinematics: KinematicTree = build_kinematic_tree(model)
        scene = tuple(scene)
        self._link_index = {name: i for i, name in enumerate(self.kinematics.link_names)}
        self._motion_kinds = motion_kinds(model, self.kinematics.joint_names)
        #: Frames a world object's pose may be given in: the root link, and the parent frame of
        #: an SRDF fixed virtual joint (MoveIt's "world" above the robot).
        self.world_frames = frozenset([model.root_link] + [
            joint.parent_frame for joint in (srdf.virtual_joints if srdf is not None else ())
            if joint.type == 'fixed' and joint.child_link == model.root_link])

        # The stages: the robot's trees, link boxes and pairs (built once, never again), the
        # joints' tables, then the scene's objects and the engine's buffers (rebuilt by every
        # scene change, see _install).
        self._robot = self._build_robot_block(srdf, [obj.name for obj in scene])
        self._build_joint_tables()
        self._objects: Dict[str, PlacedObject] = {}
        # Counts committed scene changes and moves: prepared changes must be prepared again
        # once it has changed.
        self._scene_version = 0
        # Each pair's (path, reach, reach_ext) rows (see _pair_rows), kept across scene changes.
        self._rows: Dict[Pair, Tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._views: Optional[Dict[str, np.ndarray]] = None
        self._result = CheckResult(False, (), 0)
        self._results: Dict[bytes, CheckResult] = {}
        try:
            prepared = self.prepare_scene_changes([AddObject(obj) for obj in scene])
        except SceneChangeError as error:
            raise SceneError(f'scene: {error.reason}') from None
        self._install(prepared)

    def _build_robot_block(self, srdf: Optional[Srdf], object_names: List[str]
                           ) -> '_RobotBlock':
        """Build one OBB tree per collision element (the paper's per-link sub-groups, in link
        frames, grown by the link's padding), each link's box over its elements (sec. 2.1:
        computed once) and the self-collision pairs; set :attr:`link_names` and the exception
        list. Everything here is what the engine reads that no scene change alters."""
        model, kin = self.model, self.kinematics
        link_names = list(kin.link_names)
        n_links = len(link_names)
        meshes, owners, solids = [], [], []
        for element in model.elements:
            meshes.append((_transformed(element.T_link_element, element.vertices),
                           element.faces))
            owners.append(self._link_index[element.link])
            solids.append(self._solid_row(element.solid, element.faces,
                                          element.T_link_element))
        order = np.argsort(np.asarray(owners, dtype=np.int64), kind='stable')
        meshes = [meshes[i] for i in order]
        elem_solid = (np.array([solids[i] for i in order]) if solids
                      else np.zeros((0, engine.SOLID_WIDTH)))
        owners = np.asarray(owners, dtype=np.int64)[order]
        forest = build_forest(meshes, leaf_size=self.config.leaf_size,
                              fit=self.config.obb_fit_code)
        counts = np.bincount(owners, minlength=n_links) if len(owners) else np.zeros(
            n_links, dtype=np.int64)
        elem_end = np.cumsum(counts).astype(np.int64)
        elem_start = (elem_end - counts).astype(np.int64)
        padding = self._link_padding(link_names, object_names)
        _grow_boxes(forest.half, forest.roots, padding[owners])

        center, axes, half = np.zeros((n_links, 3)), np.tile(np.eye(3), (n_links, 1, 1)), \
            np.zeros((n_links, 3))
        vertex_radius = np.zeros(n_links)
        for b in range(n_links):
            chunk = [meshes[e][0] for e in range(elem_start[b], elem_end[b])]
            if chunk:
                points = np.concatenate(chunk)
                faces = np.concatenate([meshes[e][1] + sum(len(c) for c in chunk[:k])
                                        for k, e in enumerate(range(elem_start[b],
                                                                    elem_end[b]))])
                center[b], axes[b], half[b] = fit_obb(points, self.config.obb_fit_code,
                                                      faces=faces)
                half[b] += padding[b]   # the padded link (see _grow_boxes)
                vertex_radius[b] = float(np.sqrt((points ** 2).sum(axis=1).max()))

        self.link_names: Tuple[str, ...] = tuple(
            name for b, name in enumerate(link_names) if counts[b] > 0)
        self._base_exclusions: Dict[Pair, str] = self._exception_list(
            srdf, link_names, object_names)
        robot = list(self.link_names)
        robot_pairs = [sorted_pair(a, b) for i, a in enumerate(robot) for b in robot[i + 1:]]
        return _RobotBlock(
            boxes=box_table(forest.center, forest.axes, forest.half),
            nodes=node_table(forest), volume=forest.volume, gain=forest.gain,
            tris=forest.tris, roots=forest.roots, depth=int(forest.depth.max(initial=1)),
            elem_solid=elem_solid, elem_start=elem_start, elem_end=elem_end,
            body_boxes=box_table(center, axes, half), radius=vertex_radius, padding=padding,
            pairs=tuple(sorted(pair for pair in robot_pairs
                               if pair not in self._base_exclusions)))

    def _build_joint_tables(self) -> None:
        """Set the joints' names, limits and mimic set, and for each variable the links whose
        pose depends on it and whether it drives a slider (the incremental rule's inputs)."""
        kin = self.kinematics
        n_links = len(kin.link_names)
        self.joint_names: Tuple[str, ...] = tuple(kin.joint_names)
        self._joint_index = {name: j for j, name in enumerate(self.joint_names)}
        self._derived_joints = frozenset(
            joint.name for joint in self.model.joints
            if joint.mimic is not None and joint.type != 'fixed')
        self.joint_limits: Dict[str, Tuple[float, float]] = {
            name: (float(kin.lower[j]), float(kin.upper[j]))
            for j, name in enumerate(self.joint_names)}
        n_joints = len(self.joint_names)
        depends = np.zeros((n_joints, n_links), dtype=bool)
        joint_prismatic = np.zeros(n_joints, dtype=np.int64)
        for i in range(n_links):  # parents come first
            if kin.parent[i] >= 0:
                depends[:, i] = depends[:, kin.parent[i]]
            if kin.q_index[i] >= 0:
                depends[_variables(kin, i), i] = True
                joint_prismatic[kin.q_index[i]] += kin.joint_type[i] == JOINT_PRISMATIC
        self._link_depends = depends
        self._joint_prismatic = joint_prismatic

    @classmethod
    def from_urdf(cls, urdf, srdf=None, package_paths: Optional[Mapping[str, str]] = None,
                  scene=None, config=None, xacro_args=None) -> 'CollisionChecker':
        """Load a robot, optionally its SRDF and a static scene, and build the checker.

        :param urdf: path to a URDF file, or the URDF's XML text.
        :param srdf: path or XML text of an SRDF, or None.
        :param package_paths: ``{package_name: directory}`` for ``package://`` mesh URIs.
        :param scene: path to a scene YAML file (or its parsed mapping), or None.
        :param config: mapping of settings (see :mod:`collision_sensor.engine.checker_config`).
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
        """The engine's row for one element (see :func:`dynamic_scene.solid_row`)."""
        return solid_row(solid, faces, T_body_element, self.config.mesh_containment,
                         engine.SOLID_WIDTH)

    def _write_header(self, I: np.ndarray, F_layout: np.ndarray, I_layout: np.ndarray,
                      n_links: int) -> None:
        """Fill the int buffer's header (cpp/query.hpp: H_*), after packing."""
        e = engine
        I[e.H_N_LINKS], I[e.H_BOX_METHOD], I[e.H_EXPANSION] = (
            n_links, self.config.box_test_code, self.config.expansion_code)
        I[e.H_CHECKED_ONCE], I[e.H_RESYNC_COUNTDOWN] = 0, e.TRAVEL_RESYNC_CALLS
        I[e.H_LAYOUTS:e.H_I_LAYOUT] = F_layout.ravel()
        I[e.H_I_LAYOUT:e.HEADER_SIZE] = I_layout.ravel()

    def _link_padding(self, link_names: List[str], object_names: List[str]) -> np.ndarray:
        """(L,) float64: each robot link's padding (m), from ``padding`` and
        ``link_padding``; scene objects are never padded.

        :raises ConfigError: ``link_padding`` names something that is not a link of the robot.
        """
        padding = np.full(len(link_names), float(self.config.padding))
        index = {name: i for i, name in enumerate(link_names)}
        for name, metres in self.config.link_padding:
            if name not in index:
                what = ('is a scene object; only robot links are padded'
                        if name in object_names else
                        f'is not a link of robot "{self.model.name}"; links: '
                        + ', '.join(link_names))
                raise ConfigError(f'setting link_padding: "{name}" {what}')
            padding[index[name]] = metres
        return padding

    def _exception_list(self, srdf: Optional[Srdf], link_names: List[str],
                        object_names: List[str]) -> Dict[Pair, str]:
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
        known = set(link_names) | set(object_names)
        for pair in parse_pair_strings(self.config.allowed_collisions, known):
            excluded.setdefault(pair, 'allowed_collisions')
        return excluded

    def _pair_rows(self, tree: '_EngineTree', vertex_radius: np.ndarray, pair_a: np.ndarray,
                   pair_b: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``path, reach, reach_ext``, each (n, J), for the pairs of bodies
        ``(pair_a[i], pair_b[i])`` (engine body indices; a world object second).

        ``path[i, j]`` is 1 iff variable j drives a joint on the tree path between the two
        bodies (int64). ``reach, reach_ext`` (float64): how far a point of either body can
        move, relative to the other, per unit of variable j: ``reach + reach_ext * E``, where
        E is the sum of |value| of every prismatic joint at the current state (0 off the path).

        A joint k on the path moves the body on its side (relative to the pair's common
        ancestor). Revolute: every point of body x below k stays within the distance from
        k's origin (on its axis) to x's origin, at most the sum of the joint offsets
        ``|t_parent_joint|`` from k down to x plus the extensions of the prismatic joints
        between them (at most E), plus x's vertex radius around its origin. Prismatic: 1.
        Both times |multiplier|, summed over the joints variable j drives. E is taken at the
        new state: moving the prismatic variables first, then the others, is a path from the
        old state along which every bound holds. An attached object is a link on a fixed
        joint whose offset is its pose in its link's frame: it enters the lever arms so.

        Planar and floating joints translate, then rotate about the translated origin (their
        child frame's). Translation variables: 1, as a prismatic joint. Planar theta: as a
        revolute joint about the child frame's origin, so the joint's own translation is not
        in its lever arm, and translation variables do not count in E. Quaternion components:
        QUATERNION_REACH (any move re-checks). A rotating joint k with a planar or floating
        joint between it and x would have that joint's translation in its lever arm; such a
        k gets QUATERNION_REACH too (rare: multi-DOF joints are mostly the root's), so E stays
        the prismatic joints' sum. Below both bodies' common ancestor (a floating base under
        self-collision pairs) a joint moves nothing relative, and is skipped.

        Padding does not enter: a padded pair's clearance is a bound of its surfaces' distance
        minus a constant (the paddings), which moves exactly as much as that distance does.
        """
        n_links, n_joints = len(tree.parent), len(self.joint_names)
        offset_norm = np.linalg.norm(tree.T_parent_joint[:, :3, 3], axis=1)
        path = np.zeros((len(pair_a), n_joints), dtype=np.int64)
        reach = np.zeros((len(pair_a), n_joints))
        reach_ext = np.zeros((len(pair_a), n_joints))
        for p, (a, b) in enumerate(zip(pair_a, pair_b)):
            chains = {}
            for x in (a, b) if b < n_links else (a,):
                chain, k = [], int(x)
                while k > 0:
                    chain.append(k)  # x and its ancestors, up to (excluding) the root
                    k = int(tree.parent[k])
                chains[int(x)] = chain
            for x, chain in chains.items():
                other = chains.get(int(b) if x == a else int(a), [])
                for depth, k in enumerate(chain):
                    if k in other or tree.q_index[k] < 0:
                        continue  # above the common ancestor, or not driven
                    path[p, _variables(tree, k)] = 1
                    below = chain[:depth]  # from x up to, excluding, k
                    m = abs(tree.multiplier[k]) * (1.0 + 1e-9)
                    j = tree.q_index[k]
                    kind = tree.joint_type[k]
                    if kind == JOINT_PRISMATIC:
                        reach[p, j] += m
                        continue
                    lever = float(offset_norm[below].sum()) + vertex_radius[x]
                    if any(tree.joint_type[c] in _VARIABLE_COUNT for c in below):
                        lever = QUATERNION_REACH   # a multi-DOF translation in the lever arm
                    if kind == JOINT_PLANAR:
                        reach[p, j:j + 2] += m   # x, y
                        j += 2                   # theta: below, as a revolute joint
                    elif kind == JOINT_FLOATING:
                        reach[p, j:j + 3] += m   # trans_x, trans_y, trans_z
                        reach[p, j + 3:j + 7] = QUATERNION_REACH
                        continue
                    reach[p, j] = min(reach[p, j] + m * lever, QUATERNION_REACH)
                    if any(tree.joint_type[c] == JOINT_PRISMATIC for c in below):
                        reach_ext[p, j] += m
        return path, reach, reach_ext

    @property
    def paddings(self) -> Dict[str, float]:
        """Each body's padding (m): the robot's links with geometry, and the scene objects
        (never padded: 0)."""
        link_padding = dict(zip(self.kinematics.link_names, self._robot.padding))
        return {**{name: float(link_padding[name]) for name in self.link_names},
                **{name: 0.0 for name in self.scene_object_names}}

    # ------------------------------------------------------------------ the scene
    @property
    def object_names(self) -> Tuple[str, ...]:
        """Names of the scene's objects, world and attached, in the order they were added."""
        return self.scene_object_names

    @property
    def scene_objects(self) -> Tuple[SceneObject, ...]:
        """The objects of :attr:`scene_object_names`, each with ``T_world_object`` its world
        pose (an attached object's at the last checked state)."""
        poses = None
        objects = []
        for placed in self._objects.values():
            T = placed.pose
            if placed.attach_to is not None:
                poses = self._poses() if poses is None else poses
                T = poses[self._body_index[placed.name]].copy()
            objects.append(placed.obj if placed.obj.T_world_object is T
                           else dataclasses.replace(placed.obj, T_world_object=T))
        return tuple(objects)

    @property
    def attachments(self) -> Dict[str, Tuple[str, Tuple[str, ...]]]:
        """``{object: (link, touch links)}`` for every attached object."""
        return {name: (placed.attach_to, placed.touch_links)
                for name, placed in self._objects.items() if placed.attach_to is not None}

    def object_pose(self, name: str) -> np.ndarray:
        """Return object ``name``'s pose as last set: (4, 4), in the world frame, or in its
        link's frame when attached.

        :raises SceneError: no such object.
        """
        placed = self._objects.get(name)
        if placed is None:
            raise SceneError(f'no object "{name}"; objects are {", ".join(self._objects)}')
        return placed.pose.copy()

    def object_triangles(self, name: str) -> int:
        """Return how many triangles object ``name`` has (its tree's).

        :raises SceneError: no such object.
        """
        placed = self._objects.get(name)
        if placed is None:
            raise SceneError(f'no object "{name}"; objects are {", ".join(self._objects)}')
        return placed.block.triangles

    def add_object(self, obj: SceneObject, attach_to: Optional[str] = None,
                   touch_links: Iterable[str] = (), pose=None) -> None:
        """Add ``obj`` to the scene, or replace the object of the same name.

        A replacement with the same triangles, link and touch links only moves the object.
        The change takes effect at the next :meth:`check` or :meth:`update`, which re-checks
        the object's pairs whatever the joints did.

        :param obj: the object (its triangles in its own frame, and its name).
        :param attach_to: a link of the robot: the object moves with it and is never checked
            against it; None (or a name of :attr:`world_frames`): fixed in the world.
        :param touch_links: further links the attached object is never checked against.
        :param pose: (4, 4) the object's pose in the world or, attached, in the link's frame;
            default ``obj.T_world_object``.
        :raises SceneError: naming what is wrong (the name is a link's, an unknown link, a
            pose that is not a rigid transform, no triangles ...); nothing changes then.
        """
        self.apply_scene_changes([AddObject(obj, attach_to, tuple(touch_links), pose)])

    def move_object(self, name: str, pose) -> None:
        """Give object ``name`` a new pose, (4, 4), in the world or, when attached, in its
        link's frame. The next :meth:`update` re-checks its pairs only (and what the joints
        moved).

        :raises SceneError: no such object, or a pose that is not a rigid transform.
        """
        # apply_scene_changes([MoveObject(name, pose)]), without its bookkeeping: this is the
        # call a moving object makes at every step. An object fixed in the world moves in one
        # engine call (the pose checked there as checked_pose checks it); anything the engine
        # refuses takes the long way, which names the fault.
        old = self._objects.get(name)
        if old is None:
            raise SceneError(f'no object "{name}" to move; add it first (objects: '
                             f'{", ".join(self._objects) or "none"})')
        T = None
        if old.attach_to is None:
            try:
                T = np.array(pose, dtype=np.float64)
            except (TypeError, ValueError):
                pass
            if T is None or T.shape != (4, 4) or self._engine.move_world_body(
                    self._body_index[name], T, MAX_COORDINATE, ROTATION_TOLERANCE):
                T = None
            else:
                T.setflags(write=False)
        if T is None:
            T = checked_pose(pose, f'object "{name}"')
            placed = PlacedObject(old.obj, old.block, old.attach_to, old.touch_links, T)
            self._move_in_place(placed)
        else:
            placed = PlacedObject(old.obj, old.block, None, old.touch_links, T)
        self._objects[name] = placed
        self._scene_version += 1

    def remove_object(self, name: str) -> None:
        """Remove object ``name`` from the scene.

        :raises SceneError: no such object.
        """
        self.apply_scene_changes([RemoveObject(name)])

    def apply_scene_changes(self, changes: Iterable[SceneChange]) -> None:
        """Apply scene changes in order, all or nothing (see
        :mod:`collision_sensor.engine.dynamic_scene`): :meth:`prepare_scene_changes`, then
        :meth:`commit_scene_changes`.

        :raises SceneError: naming the change at fault; the checker is then unchanged.
        """
        self.commit_scene_changes(self.prepare_scene_changes(changes))

    def prepare_scene_changes(self, changes: Iterable[SceneChange]) -> PreparedSceneChanges:
        """Validate ``changes`` against the current scene and build the new objects' trees,
        without changing the checker.

        This is the slow part of adding objects; it reads only what queries never change, so
        it may run on another thread while this checker answers queries.

        :param changes: :class:`AddObject`, :class:`MoveObject`, :class:`RemoveObject`, in
            the order they apply.
        :return: the result, for :meth:`commit_scene_changes`.
        :raises SceneChangeError: the first change that cannot apply (``index``), naming the
            object and the fix.
        """
        version, base = self._scene_version, self._objects
        objects = dict(base)
        moved, rebuilt = set(), set()
        structural = False
        for k, change in enumerate(changes):
            try:
                if isinstance(change, AddObject):
                    placed, same = self._placed(change, objects)
                    objects[placed.name] = placed
                    (moved if same else rebuilt).add(placed.name)
                    structural |= not same
                elif isinstance(change, (MoveObject, RemoveObject)):
                    name = change.name
                    old = objects.get(name)
                    if old is None:
                        verb = 'move' if isinstance(change, MoveObject) else 'remove'
                        raise SceneError(f'no object "{name}" to {verb}; add it first '
                                         f'(objects: {", ".join(objects) or "none"})')
                    if isinstance(change, MoveObject):
                        pose = checked_pose(change.pose, f'object "{name}"')
                        objects[name] = PlacedObject(old.obj, old.block, old.attach_to,
                                                     old.touch_links, pose)
                        moved.add(name)
                    else:
                        del objects[name]
                        moved.discard(name)
                        rebuilt.discard(name)
                        structural = True
                else:
                    raise SceneError(f'{type(change).__name__} is not a scene change; give '
                                     'AddObject, MoveObject or RemoveObject')
            except SceneError as error:
                raise SceneChangeError(k, str(error)) from None
        return PreparedSceneChanges(self, base, objects, structural,
                                    frozenset(moved - rebuilt), frozenset(rebuilt), version)

    def _placed(self, change: AddObject,
                objects: Mapping[str, PlacedObject]) -> Tuple[PlacedObject, bool]:
        """The object ``change`` adds, and whether it only moves the one of its name."""
        obj = change.obj
        name = getattr(obj, 'name', None)
        if not isinstance(name, str) or not name:
            raise SceneError('the object has no name; give it a unique name')
        owner = f'object "{name}"'
        if name in self._link_index or name in self.world_frames:
            raise SceneError(f'{owner} has the name of a link or frame of robot '
                             f'"{self.model.name}"; rename the object')
        check_geometry(obj, owner)
        attach_to = None if change.attach_to in self.world_frames else change.attach_to
        touch_links = tuple(dict.fromkeys(change.touch_links))
        if attach_to is not None and attach_to not in self._link_index:
            raise SceneError(f'{owner}: "{attach_to}" is not a link of robot '
                             f'"{self.model.name}"; attach it to one of its links, or to '
                             f'{" or ".join(sorted(self.world_frames))} (the world)')
        unknown = [link for link in touch_links if link not in self._link_index]
        if unknown or (touch_links and attach_to is None):
            why = (f'touch link "{unknown[0]}" is not a link of robot "{self.model.name}"'
                   if unknown else 'touch links are given for an object fixed in the world')
            raise SceneError(f'{owner}: {why}; give touch links of the robot, and only for an '
                             'object attached to a link other than the root')
        pose = checked_pose(obj.T_world_object if change.pose is None else change.pose, owner)
        old = objects.get(name)
        if (old is not None and old.attach_to == attach_to and old.touch_links == touch_links
                and same_geometry(old.obj, obj)):
            return PlacedObject(obj, old.block, attach_to, touch_links, pose), True
        block = build_object_block(obj, self.config, engine.SOLID_WIDTH)
        return PlacedObject(obj, block, attach_to, touch_links, pose), False

    def commit_scene_changes(self, prepared: PreparedSceneChanges) -> None:
        """Make the scene ``prepared`` describes this checker's: moves write poses (cheap);
        added or removed objects put the engine's tables together again from the robot's and
        the objects' trees (nothing is rebuilt), keeping every surviving pair's state.

        :raises SceneError: ``prepared`` was made for another checker, or another scene change
            was committed since it was prepared; nothing changes then.
        """
        if prepared.checker is not self or prepared.version != self._scene_version:
            raise SceneError('these scene changes were prepared for another checker or scene '
                             '(another change was committed since); prepare them again')
        self._scene_version += 1
        if prepared.structural:
            self._install(prepared)
            return
        for name in prepared.moved:
            self._move_in_place(prepared.objects[name])
        self._objects = prepared.objects

    def _move_in_place(self, placed: PlacedObject) -> None:
        """Write an object's new pose into the engine's tables and force its pairs."""
        views, pairs = self._views, self._object_pairs[placed.name]
        b = self._body_index[placed.name]
        if placed.attach_to is None:
            views['T_world_body'][b] = placed.pose
        else:
            # The fixed joint's origin, and the reach bounds whose lever arms run through it.
            views['T_parent_joint'][b] = placed.pose
            views['stale'][b] = 1
            _, reach, reach_ext = self._pair_rows(self._engine_tree(), self._radius,
                                                  self._pair_a[pairs], self._pair_b[pairs])
            views['reach'][pairs] = reach
            views['reach_ext'][pairs] = reach_ext
            for row, p in enumerate(pairs):
                path = self._rows[self.checked_pairs[p]][0]
                self._rows[self.checked_pairs[p]] = (path, reach[row], reach_ext[row])
        views['forced'][pairs] = 1
        self._I[engine.H_FORCED] = 1

    def _engine_tree(self) -> '_EngineTree':
        """The engine's kinematic arrays (robot links, then attached objects)."""
        v = self._views
        return _EngineTree(v['parent'], v['joint_type'], v['q_index'], v['multiplier'],
                           v['T_parent_joint'])

    def _install(self, prepared: PreparedSceneChanges) -> None:
        """Put the engine's buffers together for the scene ``prepared`` describes, carrying
        over the state of every pair that survives, and swap them in.

        Bodies: the robot's links, the attached objects (links on fixed joints below theirs),
        the world objects. Trees: the robot's block, then each object's, indices shifted.
        Every new pair, and every pair of an object added or moved, is forced; a pair that
        survives keeps its status, clearance, travel and witness (its triangles moved by
        its object's shift), not its front (the front rows are sized anew).
        """
        kin, robot, objects = self.kinematics, self._robot, prepared.objects
        n_robot = len(kin.link_names)
        attached = [p for p in objects.values() if p.attach_to is not None]
        world = [p for p in objects.values() if p.attach_to is None]
        placed = attached + world
        body_names = list(kin.link_names) + [p.name for p in placed]
        n_links, n_bodies, n_attached = n_robot + len(attached), len(body_names), len(attached)
        body_index = {name: b for b, name in enumerate(body_names)}
        attach_links = np.array([self._link_index[p.attach_to] for p in attached],
                                dtype=np.int64)
        tree = _EngineTree(
            parent=np.concatenate([kin.parent, attach_links]),
            joint_type=np.concatenate([kin.joint_type, np.full(n_attached, JOINT_FIXED)]),
            q_index=np.concatenate([kin.q_index, np.full(n_attached, -1)]),
            multiplier=np.concatenate([kin.multiplier, np.ones(n_attached)]),
            T_parent_joint=np.concatenate(
                [kin.T_parent_joint, np.reshape([p.pose for p in attached], (-1, 4, 4))]))

        # The forest: the robot's trees, then one per object (node and triangle indices
        # shifted by what comes before it).
        node_start = len(robot.boxes) + np.cumsum(
            [0] + [len(p.block.boxes) for p in placed], dtype=np.int64)
        tri_start = len(robot.tris) + np.cumsum([0] + [p.block.triangles for p in placed],
                                                dtype=np.int64)
        nodes = [robot.nodes]
        for p, n0, t0 in zip(placed, node_start, tri_start):
            shifted = p.block.nodes + np.array([n0, n0, t0, 0], dtype=np.int64)
            leaf = p.block.nodes[:, NODE_LEFT] < 0
            shifted[leaf, NODE_LEFT:NODE_RIGHT + 1] = -1
            nodes.append(shifted)
        n_elements = len(robot.roots) + len(placed)
        elem_solid = np.concatenate([robot.elem_solid] + [p.block.solid_row[None] for p in placed]
                                    + [np.zeros((0 if n_elements else 1, engine.SOLID_WIDTH))])
        first_object_element = len(robot.roots) + np.arange(len(placed), dtype=np.int64)
        body_elem_start = np.concatenate([robot.elem_start, first_object_element])
        body_elem_end = np.concatenate([robot.elem_end, first_object_element + 1])
        radius = np.concatenate([robot.radius, [p.block.radius for p in placed]])

        checked, excluded, object_pairs = self._scene_pairs(attached, world)
        n_pairs, n_joints = len(checked), len(self.joint_names)
        pair_a = np.empty(n_pairs, dtype=np.int64)
        pair_b = np.empty(n_pairs, dtype=np.int64)
        for p, (a, b) in enumerate(checked):
            ia, ib = body_index[a], body_index[b]
            pair_a[p], pair_b[p] = (ib, ia) if ia >= n_links else (ia, ib)  # world object second
        # Each pair's rows, computed once and kept while its bodies keep their place.
        changed = prepared.rebuilt | (prepared.base.keys() - objects.keys()) | {
            name for name in prepared.moved if objects[name].attach_to is not None}
        rows = {pair: row for pair, row in self._rows.items()
                if pair[0] not in changed and pair[1] not in changed}
        missing = [p for p, pair in enumerate(checked) if pair not in rows]
        for p, path, reach, reach_ext in zip(missing, *self._pair_rows(
                tree, radius, pair_a[missing], pair_b[missing])):
            rows[checked[p]] = (path, reach, reach_ext)
        rows = {pair: rows[pair] for pair in checked}
        path = np.reshape([rows[pair][0] for pair in checked], (n_pairs, n_joints))
        reach = np.reshape([rows[pair][1] for pair in checked], (n_pairs, n_joints))
        reach_ext = np.reshape([rows[pair][2] for pair in checked], (n_pairs, n_joints))
        # Each variable's pairs (those with it on their path), as one list cut per variable;
        # each variable's links (whose pose depends on it), attached objects with their link.
        on_path = path.T.nonzero()
        joint_pairs_start = np.searchsorted(on_path[0], np.arange(n_joints + 1))
        depends = np.concatenate([self._link_depends, self._link_depends[:, attach_links]],
                                 axis=1)
        joint_links = depends.nonzero()
        joint_links_start = np.searchsorted(joint_links[0], np.arange(n_joints + 1))
        depth = max([robot.depth] + [p.block.depth for p in placed])
        # Each pair's front (cpp/query.cpp: trees_of_pair) gets the same number of rows; the
        # traversal's stack takes a front's node pairs, or a pair's root pairs, as seeds.
        front_rows = int(np.clip(engine.FRONT_POOL_ROWS // max(n_pairs, 1),
                                 engine.FRONT_ROWS_MIN, engine.FRONT_ROWS_MAX))
        elements = body_elem_end - body_elem_start
        seeds = max([front_rows] + list(elements[pair_a] * elements[pair_b]))

        is_scene = np.zeros(n_bodies, dtype=np.int64)
        is_scene[n_links:] = 1
        T_world_body = np.tile(np.eye(4), (n_bodies, 1, 1))
        stale = np.zeros(n_bodies, dtype=np.int64)
        stale[:n_links] = 1
        for b, p in enumerate(world, start=n_links):
            T_world_body[b] = p.pose
        scalars = np.zeros(engine.N_SCALARS)
        scalars[engine.S_TOLERANCE] = self.config.motion_tolerance
        floats = dict(
            scalars=scalars, q_last=kin.neutral(), q_ref=kin.neutral(),
            T_parent_joint=tree.T_parent_joint, axis=np.concatenate(
                [kin.axis, np.tile([0.0, 0.0, 1.0], (n_attached, 1))]),
            multiplier=tree.multiplier,
            offset=np.concatenate([kin.offset, np.zeros(n_attached)]),
            T_world_body=T_world_body,
            body_boxes=np.concatenate([robot.body_boxes] + [p.block.boxes[:1] for p in placed]),
            boxes=np.concatenate([robot.boxes] + [p.block.boxes for p in placed]),
            volume=np.concatenate([robot.volume] + [p.block.volume for p in placed]),
            gain=np.concatenate([robot.gain] + [p.block.gain for p in placed]),
            tris=np.concatenate([robot.tris] + [p.block.tris for p in placed]),
            elem_solid=elem_solid,
            subtree_boxes=np.zeros((max(n_links, 1), BOX_WIDTH)),
            padding=np.concatenate([robot.padding, np.zeros(len(placed))]),
            clearance=np.zeros(n_pairs), q_eval=np.zeros((n_pairs, n_joints)),
            reach=reach, reach_ext=reach_ext, travel=np.zeros((n_pairs, 2)),
            front_until=np.zeros((n_pairs + 1) * front_rows), front_travel=np.zeros(n_pairs))
        ints = dict(
            header=np.zeros(engine.HEADER_SIZE), parent=tree.parent,
            joint_type=tree.joint_type, q_index=tree.q_index,
            is_scene=is_scene, body_elem_start=body_elem_start,
            body_elem_end=body_elem_end,
            roots=np.concatenate([robot.roots, node_start[:-1]]),
            nodes=np.concatenate(nodes), pair_a=pair_a, pair_b=pair_b,
            joint_pairs_start=joint_pairs_start, joint_pairs=on_path[1],
            joint_links_start=joint_links_start, joint_links=joint_links[1],
            joint_prismatic=self._joint_prismatic,
            status=np.zeros(n_pairs), witness=np.full((n_pairs, 2), -1),
            moved=np.zeros(n_joints), stale=stale, chain=np.zeros(max(n_links, 1)),
            pending=np.zeros(n_pairs), todo=np.zeros(n_pairs),
            scene_culled=np.zeros((len(world), max(n_links, 1))),
            stack=np.zeros((seeds + 2 * depth + 8, 3)),
            counters=np.zeros(engine.N_COUNTERS), front=np.zeros(((n_pairs + 1) * front_rows, 3)),
            front_state=np.zeros((n_pairs, 2)), nearest=np.full((n_pairs, 2), -1),
            forced=np.ones(n_pairs))
        tri_starts = {p.name: int(t0) for p, t0 in zip(placed, tri_start)}
        forced_names = prepared.rebuilt | prepared.moved
        if self._views is not None:
            self._carry_state(floats, ints, checked, body_index, tri_starts, forced_names)
        F, F_layout, float_views = self._pack(np.float64, engine.FLOAT_SLOTS, floats)
        I, I_layout, int_views = self._pack(np.int64, engine.INT_SLOTS, ints)
        self._write_header(I, F_layout, I_layout, n_links)
        if self._views is not None:
            I[engine.H_CHECKED_ONCE] = self._I[engine.H_CHECKED_ONCE]
            I[engine.H_RESYNC_COUNTDOWN] = self._I[engine.H_RESYNC_COUNTDOWN]
        I[engine.H_FORCED] = int(int_views['forced'].any())
        new_engine = engine.Engine(F, I)
        new_engine.set_motion_kinds(self._motion_kinds)

        # Nothing above changed the checker; from here on, nothing can fail.
        self._F, self._I, self._views = F, I, {**float_views, **int_views}
        self._engine, self._query = new_engine, new_engine.query
        # The forest is only a view of the engine's tables: nothing is held twice (scenario 4).
        self.forest = forest_view(float_views['boxes'], int_views['nodes'],
                                  float_views['volume'], float_views['gain'],
                                  float_views['tris'], int_views['roots'],
                                  np.array([robot.depth] + [p.block.depth for p in placed]))
        self._q_ref = float_views['q_ref']
        self._T_world_body = float_views['T_world_body']
        self._status = int_views['status']
        self.counters = int_views['counters']  # work done, see traversal.COUNT_* (benchmarks)
        # The joint vector of the last call; the engine writes it (read-only for Python).
        self._q = float_views['q_last']
        self._pair_reach, self._pair_reach_ext = float_views['reach'], float_views['reach_ext']
        self._body_names, self._body_index, self._radius = tuple(body_names), body_index, radius
        self._body_elem_start, self._body_elem_end = body_elem_start, body_elem_end
        self._pair_a, self._pair_b = int_views['pair_a'], int_views['pair_b']
        self._n_links = n_links
        self.checked_pairs: Tuple[Pair, ...] = checked
        self.excluded_pairs: Dict[Pair, str] = excluded
        self.scene_object_names: Tuple[str, ...] = tuple(objects)
        self._objects, self._rows, self._object_pairs = objects, rows, object_pairs
        self._keep_views_of_trees(float_views, int_views, placed, node_start, tri_start)
        self._tri_starts = tri_starts
        self._results = {}
        self._result = self._result_from_status(0)

    def _keep_views_of_trees(self, float_views, int_views, placed, node_start, tri_start):
        """Point the robot's block and every object's block at their rows of the engine's
        buffers, in place of their own arrays: nothing is held twice (scenario 4). Node tables
        of objects stay their own (the buffer holds them shifted); the next scene change
        reads the trees from these views, which keep the previous buffers alive until then."""
        robot = self._robot
        n_nodes, n_tris = len(robot.boxes), len(robot.tris)
        self._robot = robot._replace(
            boxes=float_views['boxes'][:n_nodes], nodes=int_views['nodes'][:n_nodes],
            volume=float_views['volume'][:n_nodes], gain=float_views['gain'][:n_nodes],
            tris=float_views['tris'][:n_tris])
        objects = dict(self._objects)
        for p, n0, n1, t0, t1 in zip(placed, node_start[:-1], node_start[1:], tri_start[:-1],
                                     tri_start[1:]):
            block = dataclasses.replace(
                p.block, boxes=float_views['boxes'][n0:n1],
                volume=float_views['volume'][n0:n1], gain=float_views['gain'][n0:n1],
                tris=float_views['tris'][t0:t1])
            objects[p.name] = p._replace(block=block)
        self._objects = objects

    def _scene_pairs(self, attached: Sequence[PlacedObject], world: Sequence[PlacedObject]):
        """Return the checked pairs (sorted), the exception list and ``{object: its pairs'
        indices}`` for a scene of these objects (see
        :mod:`collision_sensor.engine.dynamic_scene`)."""
        excluded = dict(self._base_exclusions)
        pairs = list(self._robot.pairs)
        for i, placed in enumerate(attached):
            name, link = placed.name, placed.attach_to
            for other in self.link_names:
                pair = sorted_pair(name, other)
                if other == link:
                    excluded.setdefault(pair, f'attached to {link}')
                elif other in placed.touch_links:
                    excluded.setdefault(pair, 'touch link')
                elif pair not in excluded:
                    pairs.append(pair)
            for other in attached[i + 1:]:
                pair = sorted_pair(name, other.name)
                if other.attach_to in (link,) + placed.touch_links or (
                        link in other.touch_links):
                    excluded.setdefault(pair, 'attached to the same or touching links')
                elif pair not in excluded:
                    pairs.append(pair)
        movers = list(self.link_names) + [placed.name for placed in attached]
        for placed in world:
            pairs.extend(pair for pair in (sorted_pair(placed.name, other) for other in movers)
                         if pair not in excluded)
        checked = tuple(sorted(pairs))
        object_pairs = {name: [] for name in [p.name for p in attached] + [p.name for p in world]}
        for p, (a, b) in enumerate(checked):
            for name in (a, b):
                if name in object_pairs:
                    object_pairs[name].append(p)
        return checked, excluded, {name: np.asarray(indices, dtype=np.int64)
                                   for name, indices in object_pairs.items()}

    def _carry_state(self, floats, ints, checked, body_index, tri_starts, forced_names) -> None:
        """Copy the current state into the arrays of a new layout (see :meth:`_install`)."""
        old = self._views
        old_index = {pair: p for p, pair in enumerate(self.checked_pairs)}
        for name in ('scalars', 'q_last', 'q_ref'):
            floats[name] = old[name].copy()
        ints['counters'] = old['counters'].copy()
        n_robot = len(self.kinematics.link_names)
        floats['T_world_body'][:n_robot] = old['T_world_body'][:n_robot]
        ints['stale'][:n_robot] = old['stale'][:n_robot]
        for name, b in body_index.items():
            old_b = self._body_index.get(name)
            if n_robot <= b < self._n_links and old_b is not None and (
                    old_b < self._n_links and name not in forced_names):
                floats['T_world_body'][b] = old['T_world_body'][old_b]
                ints['stale'][b] = old['stale'][old_b]
        new, kept = [], []
        for p, pair in enumerate(checked):
            o = old_index.get(pair)
            if o is not None:
                new.append(p)
                kept.append(o)
        new, kept = np.asarray(new, dtype=np.int64), np.asarray(kept, dtype=np.int64)
        for name in ('clearance', 'q_eval', 'travel'):
            floats[name][new] = old[name][kept]
        ints['status'][new] = old['status'][kept]
        # A witness names a triangle of each body: shifted with its object's triangles.
        shift = {name: start - self._tri_starts[name] for name, start in tri_starts.items()
                 if name in self._tri_starts and name not in forced_names}
        witness = ints['witness']
        for p, o in zip(new, kept):
            a, b = checked[p]
            w = old['witness'][o]
            names = (a, b) if body_index[a] == ints['pair_a'][p] else (b, a)
            if w[0] >= 0 and all(n in shift or n not in tri_starts for n in names):
                witness[p] = (w[0] + shift.get(names[0], 0), w[1] + shift.get(names[1], 0))
        # Forced: new pairs, pairs of objects added or moved, and those still forced.
        forced = ints['forced']
        forced[:] = 0
        forced[new] = old['forced'][kept]
        forced[[p for p, pair in enumerate(checked)
                if pair not in old_index or pair[0] in forced_names
                or pair[1] in forced_names]] = 1


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
                # The engine reports whether any status changed, so the answer is looked up
                # (by the statuses' bytes) or made only then.
                result = self._results.get(self._status.tobytes())
                if result is None or result.rechecked_pairs != code >> 1:
                    result = self._result_from_status(code >> 1)
                self._result = result
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
        ``max_distance``; return their records sorted by distance (pairs in contact first,
        distance <= 0).

        Same hierarchy and exception list as :meth:`check`; the engine descends both bodies'
        OBB trees with distance lower bounds (the boxes', and each node's extent along the
        nearest points' direction) and stops a pair once its bound reaches ``max_distance``
        or the best distance found, starting from the triangles that were nearest at the last
        call (``cpp/distance.hpp``). Distances are padded (see :class:`ProximityRecord`); a
        pair in contact (exactly the pairs :meth:`update` reports) has distance <= 0 and a
        point in both padded bodies; penetration depth is not computed.

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

    # ------------------------------------------------------------------ motion
    def check_motion(self, q_from: Positions, q_to: Positions) -> MotionResult:
        """Check the straight motion from ``q_from`` to ``q_to``: certified, never sampled.

        Revolute and prismatic joints move linearly, continuous joints (and a planar joint's
        theta) the shorter way round, planar and floating joints their translation linearly
        and their rotation along the shorter arc; mimic joints follow (MoveIt's
        interpolation, :mod:`collision_sensor.engine.motion`). A motion reported free has no
        state in contact; a reported ``first_contact`` t is in contact or within
        :data:`~collision_sensor.engine.motion.TOUCH_TOLERANCE` of it, and no earlier state is
        in contact beyond that tolerance. Padding, the exception list, world and attached
        objects count as in :meth:`check`. The carried incremental state is left as it was.

        :param q_from: the start, as ``positions`` of :meth:`check` (joints not given keep
            their current value).
        :param q_to: the end, the same way.
        :raises JointStateError: as :meth:`check`, naming the end at fault; nothing changes.
        """
        ends = []
        for end, positions in (('q_from', q_from), ('q_to', q_to)):
            try:
                ends.append(self._merged(positions))
            except JointStateError as error:
                raise JointStateError(f'{end}: {error}') from None
        q0, q1 = ends
        pairs = np.zeros(len(self.checked_pairs), dtype=np.uint8)
        code, t = self._engine.motion(q0, q1, pairs)
        if code < 0:
            j = -1 - code
            end, q = ('q_from', q0) if j < len(q0) else ('q_to', q1)
            raise JointStateError(f'{end}: ' + self._unusable_message(j % len(q0), q))
        return self._motion_result(code, t, pairs)

    def update_motion(self, positions: Positions) -> MotionResult:
        """Check the motion from the current state to ``positions`` (as :meth:`check_motion`),
        then move the state there as :meth:`update` does: what a stream of joint states
        needs. Before any state was checked there is no motion: the answer is ``positions``'
        own instant.

        :raises JointStateError: as :meth:`check`; nothing changes then.
        """
        q = self._merged(positions)
        pairs = np.zeros(len(self.checked_pairs), dtype=np.uint8)
        code, t, query_code = self._engine.update_motion(q, pairs)
        if code < 0:
            raise JointStateError(self._unusable_message(-1 - code, q))
        self._settle(query_code, q, False)
        return self._motion_result(code, t, pairs)

    def check_path(self, configurations: np.ndarray) -> PathResult:
        """Check the straight motions between consecutive waypoints, in one compiled call,
        until one is not free (a single waypoint: its instant). The carried state is left as
        it was.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or an unusable value (naming the row and
            joint); nothing changes then.
        """
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names):
            raise JointStateError(f'expected waypoints of shape (n, {len(self.joint_names)}) '
                                  f'in the order of joint_names, got {Q.shape}')
        pairs = np.zeros(len(self.checked_pairs), dtype=np.uint8)
        code, segment, t = self._engine.path(Q, pairs)
        if code < 0:
            row, j = divmod(-1 - code, len(self.joint_names))
            raise JointStateError(self._unusable_message(j, Q[row], row))
        if code == 0:
            return PathResult(None, FREE)
        return PathResult(int(segment), self._motion_result(code, t, pairs))

    def check_spline(self, coefficients: np.ndarray) -> PathResult:
        """Check polynomial path segments in turn, in one compiled call, until one is not free:
        segment i is ``q_j(t) = sum_k coefficients[i, j, k] t^k`` for t in [0, 1] (degree at
        most 5; planar and floating joints constant). ``first_contact`` is a fraction of the
        segment. The carried state is left as it was.

        :param coefficients: (S, J, 6) float, variables in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape, or a segment the engine cannot take (not
            finite, moving a planar or floating joint, or an unusable value at an end).
        """
        coef = np.ascontiguousarray(coefficients, dtype=np.float64)
        if coef.ndim != 3 or coef.shape[1:] != (len(self.joint_names), 6):
            raise JointStateError(f'expected coefficients of shape (S, {len(self.joint_names)},'
                                  f' 6), got {coef.shape}')
        pairs = np.zeros(len(self.checked_pairs), dtype=np.uint8)
        code, segment, t = self._engine.spline(coef, pairs)
        if code < 0:
            raise JointStateError(
                f'segment {-1 - code}: a coefficient is not finite, a planar or floating joint '
                'moves, or an end is beyond the engine\'s range; give finite polynomials of '
                'the 1-DOF joints')
        if code == 0:
            return PathResult(None, FREE)
        return PathResult(int(segment), self._motion_result(code, t, pairs))

    def check_trajectory(self, joint_names, points, start=None,
                         limit_tolerance: float = 0.0) -> TrajectoryResult:
        """Check a planned trajectory (``trajectory_msgs/JointTrajectory``'s joint names and
        points) along the path joint_trajectory_controller will follow, from ``start``
        (default: the current positions): see :mod:`collision_sensor.engine.trajectory`.
        A malformed trajectory is invalid with its reason; nothing changes in the checker."""
        return check_trajectory(self, joint_names, points, start, limit_tolerance)

    def _motion_result(self, code: int, t: float, pairs: np.ndarray) -> MotionResult:
        if code == 0:
            return FREE
        names = self.checked_pairs
        return MotionResult(True, float(t), tuple(names[p] for p in np.flatnonzero(pairs)))

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

    def _result_from_status(self, rechecked: int) -> CheckResult:
        """The answer for the current statuses. Answers are kept for reuse, by statuses: the
        same pair set comes back again and again (mostly none, one or two pairs), and every
        ``check`` re-checks the same number of pairs, so its answer object itself recurs."""
        key = self._status.tobytes()
        known = self._results.get(key)
        if known is not None:
            return CheckResult(known.in_collision, known.colliding_pairs, rechecked)
        names = self.checked_pairs
        hits = tuple([names[p] for p in np.flatnonzero(self._status)])
        result = CheckResult(bool(hits), hits, rechecked)
        if len(self._results) < RESULT_CACHE_SIZE:
            self._results[key] = result
        return result

    # ------------------------------------------------------------------ inspection
    @property
    def positions(self) -> Dict[str, float]:
        """The joint positions of the last check, by name."""
        return {name: float(v) for name, v in zip(self.joint_names, self._q)}

    def link_poses(self) -> Dict[str, np.ndarray]:
        """World poses (4, 4) of every link and scene object at the last checked state."""
        T_world_body = self._poses()
        return {name: T_world_body[b].copy() for b, name in enumerate(self._body_names)}

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


def _grow_boxes(half: np.ndarray, roots: np.ndarray, padding: np.ndarray) -> None:
    """Grow every box of tree e by ``padding[e]`` in each half extent, in place.

    A padded element is its geometry swept by a sphere of radius ``padding`` (the Minkowski
    sum); its box grown by the padding along each axis holds that, so every box test and box
    gap of the engine is one of the padded geometry, and only the triangle tests at the leaves
    need the padding itself (``cpp/traversal.hpp``: triangles_within). Trees are contiguous
    node ranges starting at their roots.

    :param half: (N, 3) float64 half extents of the forest's boxes.
    :param roots: (E,) int64 root node of each tree; ``padding``: (E,) float64 metres.
    """
    ends = list(roots[1:]) + [len(half)]
    for start, end, pad in zip(roots, ends, padding):
        if pad > 0.0:
            half[start:end] += pad


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
