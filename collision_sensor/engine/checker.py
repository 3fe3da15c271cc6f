"""The collision checker: a robot and a static scene, checked on every joint-state update.

This is the API the node, the command-line tools and the benchmarks build on::

    checker = CollisionChecker.from_urdf(urdf, srdf=None, package_paths=None, scene=None,
                                         config=None)
    result = checker.check(positions)    # full check, trusts nothing carried over
    result = checker.update(positions)   # incremental: re-checks only what the motion changed
    result.in_collision, result.colliding_pairs

Everything between ``positions`` and the pair statuses runs in one call into the compiled
engine (``cpp/engine.hpp``: ``Engine::query``, C++17); this module turns files into flat arrays
once, and names back into answers.
"""
import dataclasses
import math
import time
from typing import Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.engine import array_pack
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import (
    CLOUD_BLOCK, AddCloud, AddObject, PlacedObject, PreparedSceneChanges, RemoveObject,
    SceneChange, SceneChangeError, checked_pose, prepare_changes)
from collision_sensor.engine.kinematics import KinematicTree, build_kinematic_tree
from collision_sensor.engine.motion import FREE, MotionResult, PathResult
from collision_sensor.engine.trajectory import TrajectoryResult, check_trajectory
from collision_sensor.engine.obb_tree import forest_view
from collision_sensor.engine.point_clouds import (
    NO_STATS, PointCloudStats, PreparedPoints, cloud_arguments, cloud_name, cloud_threads,
    points_array)
from collision_sensor.engine.robot_block import (
    allowed_names_to_come, build_robot_block, joint_tables, with_virtual_joint, world_frames)
from collision_sensor.engine.scene_layout import SceneLayout, changed_objects
from collision_sensor.errors import JointStateError, PointCloudError, SceneError, warn_load
from collision_sensor.model.robot_model import RobotModel, load_urdf
from collision_sensor.model.scene import SceneObject, load_scene
from collision_sensor.model.srdf import Srdf, load_srdf_for_model
from collision_sensor.untrusted_text import quoted

Pair = Tuple[str, str]
#: CollisionChecker._answer before any: no answer of the engine is this object.
_NO_ANSWER = object()
#: numpy's float64 (one object: an identity test is cheaper than ``==``, which converts).
_FLOAT64 = np.dtype(np.float64)
#: Distinct colliding-pair sets whose answer tuples are kept for reuse (a robot in use meets
#: few of them; the bound keeps a random stream from growing the cache without end).
RESULT_CACHE_SIZE = 4096
Positions = Union[Mapping[str, float], Sequence[float], np.ndarray]


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


class CollisionChecker:
    """Self-collision and robot-versus-scene checking for one robot.

    Bodies are the robot's links and the scene objects. The world frame, in which scene poses
    are given, is the root link's frame; with an SRDF whose ``virtual_joint`` is planar or
    floating, it is the virtual joint's ``parent_frame`` (added as a link without geometry above
    the URDF root), and the robot stands where the joint's variables place it. Pairs
    are every two bodies with geometry, robot-robot and robot-scene, minus the exception list
    (adjacent links, SRDF ``disable_collisions``, ``allowed_collisions``). Contact means the
    two bodies' triangle surfaces share a point (touching counts); a body wholly inside another
    without touching its surface is not reported (see docs/engine.md, "Contact rule"). With padding
    (``padding``, ``link_padding`` in the config), each link's geometry is grown by its padding
    (a sphere swept over it): contact means the surfaces come within the two paddings' sum.

    The checker answers; what it answers from lives in rooms of their own: the robot block
    (:mod:`~collision_sensor.engine.robot_block`, built once), the scene laid out for the
    engine (:mod:`~collision_sensor.engine.scene_layout`, by every structural scene change),
    the scene changes (:mod:`~collision_sensor.engine.dynamic_scene`) and the engine itself
    (``cpp/engine.hpp``).
    """

    def __init__(self, model: RobotModel, srdf: Optional[Srdf] = None,
                 scene: Sequence[SceneObject] = (), config=None):
        """Build the hierarchies and the exception list; prefer :meth:`from_urdf`.

        :param scene: world objects at the start (:meth:`add_object` adds more at any time).
        :raises CollisionSensorError: on a bad scene, configuration or exception list.
        """
        self.config = CheckerConfig.from_mapping(config)
        model = self.model = with_virtual_joint(model, srdf)
        self.kinematics: KinematicTree = build_kinematic_tree(model)
        scene = tuple(scene)
        #: Frames a world object's pose may be given in: the root link, and the parent frame of
        #: an SRDF fixed virtual joint (MoveIt's "world" above the robot).
        self.world_frames = world_frames(model, srdf)
        # The robot's trees, link boxes and pairs, and the joints' tables: built once, never
        # again. The scene is laid out by every structural scene change (_install).
        self._robot = build_robot_block(model, self.kinematics, self.config, srdf,
                                        [obj.name for obj in scene])
        self.link_names: Tuple[str, ...] = self._robot.link_names
        self._allowed_to_come, self.config_warnings = allowed_names_to_come(
            self.config, model, self._robot.link_names, [obj.name for obj in scene])
        for line in self.config_warnings:
            warn_load(line)
        self._joints = joint_tables(model, self.kinematics)
        self.joint_names: Tuple[str, ...] = self._joints.names
        self._link_index = {name: i for i, name in enumerate(self.kinematics.link_names)}
        self.joint_limits: Dict[str, Tuple[float, float]] = self._joints.limits
        self._scene: Optional[SceneLayout] = None
        # Counts committed scene changes and moves: prepared changes must be prepared again
        # once it has changed.
        self._scene_version = 0
        self._result = CheckResult(False, (), 0)
        self._results: Dict[bytes, CheckResult] = {}
        # The engine's status_version when _result was made: _result holds while it is the
        # same, whoever ran queries on the engine in between. _answer: the engine's answer
        # object _result was last settled from (the engine gives the same object again for an
        # answer with the same fields).
        self._version = 0
        self._answer = _NO_ANSWER
        # Point clouds: {object name: the engine's VoxelCloud}, and each one's last stats.
        self._clouds: Dict[str, object] = {}
        self._cloud_stats: Dict[str, PointCloudStats] = {}
        try:
            prepared = self.prepare_scene_changes([AddObject(obj) for obj in scene])
        except SceneChangeError as error:
            raise SceneError(f'scene: {error.reason}') from None
        self._install(prepared)

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
            f'SRDF: {line}' for line in (srdf_model.warnings if srdf_model else ())) + \
            checker.config_warnings
        return checker

    @property
    def pending_allowed_names(self) -> Tuple[str, ...]:
        """Names ``allowed_collisions`` gives that are no link and no scene object (yet): their
        pairs apply once an object of that name is added; sorted."""
        return tuple(sorted(name for name in self._allowed_to_come
                            if name not in self._scene.objects))

    # ------------------------------------------------------------------ the engine's arrays
    def packed_array(self, name: str) -> np.ndarray:
        """Return the engine's array ``name`` (``cpp/layout.hpp``: CS_FLOAT_SLOTS,
        CS_INT_SLOTS) as a view of the buffer the engine reads and writes in place: for tests,
        benchmarks and inspection (writing to it changes what the engine sees)."""
        return self._views[name]

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
        """The objects of :attr:`scene_object_names` but the point clouds, each with
        ``T_world_object`` its world pose (an attached object's at the last checked state)."""
        poses = None
        objects = []
        for placed in self._scene.objects.values():
            if placed.block is CLOUD_BLOCK:
                continue    # a point cloud: its voxels, not triangles (cloud_voxels)
            T = placed.pose
            if placed.attach_to is not None:
                poses = self._poses() if poses is None else poses
                T = poses[self._scene.body_index[placed.name]].copy()
            objects.append(placed.obj if placed.obj.T_world_object is T
                           else dataclasses.replace(placed.obj, T_world_object=T))
        return tuple(objects)

    @property
    def attachments(self) -> Dict[str, Tuple[str, Tuple[str, ...]]]:
        """``{object: (link, touch links)}`` for every attached object."""
        return {name: (placed.attach_to, placed.touch_links)
                for name, placed in self._scene.objects.items() if placed.attach_to is not None}

    def object_pose(self, name: str) -> np.ndarray:
        """Return object ``name``'s pose as last set: (4, 4), in the world frame, or in its
        link's frame when attached.

        :raises SceneError: no such object.
        """
        placed = self._scene.objects.get(name)
        if placed is None:
            raise SceneError(f'no object "{name}"; objects are {", ".join(self._scene.objects)}')
        return placed.pose.copy()

    def object_triangles(self, name: str) -> int:
        """Return how many triangles object ``name`` has (its tree's).

        :raises SceneError: no such object.
        """
        placed = self._scene.objects.get(name)
        if placed is None:
            raise SceneError(f'no object "{name}"; objects are {", ".join(self._scene.objects)}')
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
        old = self._scene.objects.get(name)
        if old is None:
            raise SceneError(f'no object "{name}" to move; add it first (objects: '
                             f'{", ".join(self._scene.objects) or "none"})')
        if old.block is CLOUD_BLOCK:
            raise SceneError(f'object "{name}" is a point cloud: it is never moved; give its '
                             'next cloud (set_points)')
        T = None
        if old.attach_to is None:
            try:
                T = np.array(pose, dtype=np.float64)
            except (TypeError, ValueError):
                pass
            if T is None or T.shape != (4, 4) or not self._engine.move_world_body(
                    self._scene.body_index[name], T):
                T = None
            else:
                T.setflags(write=False)
        if T is None:
            T = checked_pose(pose, f'object "{name}"')
            placed = PlacedObject(old.obj, old.block, old.attach_to, old.touch_links, T)
            self._move_in_place(placed)
        else:
            placed = PlacedObject(old.obj, old.block, None, old.touch_links, T)
        self._scene.objects[name] = placed
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
    # ------------------------------------------------------------------ point clouds
    def set_points(self, source: str, points, frame: Optional[str] = None, *,
                   positions: Optional[Positions] = None, stamp: Optional[float] = None,
                   persistence: float = 0.0, max_range: float = math.inf,
                   threads: Optional[int] = None) -> int:
        """Make ``points`` the obstacle ``cloud/<source>``: filtered, voxelised, checked
        against every robot link and attached object from the next :meth:`update` on (see
        :mod:`collision_sensor.engine.point_clouds`, which says what a cloud can tell).

        The source's next cloud replaces this one in place (only the cloud's pairs are
        re-checked); its first adds the object (pairs ``link:cloud/<source>``, which
        ``allowed_collisions`` may name).

        :param source: the sensor's name (a topic): the object is ``cloud/<source>``.
        :param points: (n, 3) float, x y z rows in ``frame``; rows with NaN or inf dropped.
            float32 and float64 arrays are read as they are (any row stride).
        :param frame: a link of the robot (a camera's), or None (or a world frame name) for
            the world frame.
        :param positions: the joint values at the cloud's time, for the self-filter and
            ``frame``'s pose (as :meth:`check` takes them); default: the current state.
        :param stamp: the cloud's time in s (persistence; default ``time.monotonic()``).
        :param persistence: keep voxels seen within this many seconds before ``stamp`` (by
            earlier clouds of the source) whose centre the robot does not now cover; 0: only
            this cloud.
        :param max_range: drop points farther than this (m) from ``frame``'s origin.
        :param threads: the passes over the rows, the filter's candidates and the near
            voxels' classes on up to this many threads (0: every hardware thread; default: the
            setting ``threads``); the voxels, the counts and the verdicts are the same on any
            number.
        :return: the number of occupied voxels kept.
        :raises PointCloudError: points not (n, 3) numbers, an unknown frame, a bad source or
            argument; nothing changes then.
        :raises JointStateError: ``positions`` as :meth:`check` refuses them.
        """
        return self.commit_points(self.prepare_points(
            source, points, frame, positions=positions, stamp=stamp, persistence=persistence,
            max_range=max_range, threads=threads))

    def prepare_points(self, source: str, points, frame: Optional[str] = None, *,
                       positions: Optional[Positions] = None, stamp: Optional[float] = None,
                       persistence: float = 0.0, max_range: float = math.inf,
                       keep_points: bool = False,
                       threads: Optional[int] = None) -> PreparedPoints:
        """Filter and voxelise a cloud (as :meth:`set_points`) without making it the obstacle:
        the slow part, in C++ with the interpreter released, reading only what queries never
        change, so it may run on another thread while this checker answers queries (one
        source's clouds one at a time). :meth:`commit_points` makes it the obstacle.

        :param keep_points: also return the points kept (``PreparedPoints.kept``, world frame).
        """
        name = cloud_name(source)
        try:
            array = points_array(points)
        except PointCloudError as error:
            raise PointCloudError(f'{name}: {error}') from None
        if frame is None or frame in self.world_frames:
            frame_index = -1
        elif frame in self._link_index:
            frame_index = self._link_index[frame]
        else:
            raise PointCloudError(
                f'{name}: frame {quoted(frame, 100)} is no link of robot "{self.model.name}" '
                f'and not the world frame ({" or ".join(sorted(self.world_frames))}); give the '
                'points in a link\'s frame (a camera frame is a link of the URDF) or in the '
                'world frame')
        if stamp is None:
            stamp = time.monotonic()
        max_range, persistence, stamp = cloud_arguments(max_range, persistence, stamp)
        try:
            threads = self.config.threads if threads is None else cloud_threads(threads)
        except PointCloudError as error:
            raise PointCloudError(f'{name}: {error}') from None
        q = self._q.copy() if positions is None else self._merged(positions)
        cloud = self._clouds.get(name)
        if cloud is None:
            cloud = self._clouds.setdefault(name, engine.VoxelCloud())
        config = self.config
        try:
            ticket, stats, kept = cloud.prepare(
                self._engine, array, frame_index, q, config.voxel_size,
                config.self_filter_padding, max_range, config.max_points, stamp, persistence,
                keep_points, threads)
        except JointStateError as error:
            raise JointStateError(self._unusable_message(error.variable, q)) from None
        return PreparedPoints(self, source, cloud, ticket, PointCloudStats(*stats), kept)

    def commit_points(self, prepared: PreparedPoints) -> int:
        """Make a prepared cloud its source's obstacle, in place: only its pairs are re-checked
        at the next query (its source's first cloud adds its object first). Return the number
        of occupied voxels.

        :raises PointCloudError: ``prepared`` was made for another checker, or another cloud
            of the source was prepared since (nothing changes then).
        """
        name = cloud_name(prepared.source)
        if prepared.checker is not self or self._clouds.get(name) is not prepared.cloud:
            raise PointCloudError(f'{name}: this cloud was prepared for another checker, or its '
                                  'source was cleared since; prepare it again')
        if name not in self._scene.objects:
            self.apply_scene_changes([AddCloud(name)])
        if not self._engine.commit_cloud(self._scene.body_index[name], prepared.ticket):
            raise PointCloudError(f'{name}: a newer cloud of this source was prepared since this '
                                  'one; commit that one')
        self._cloud_stats[name] = prepared.stats
        return prepared.stats.voxels

    def clear_points(self, source: str) -> None:
        """Remove the obstacle ``cloud/<source>`` (nothing if there is none)."""
        name = cloud_name(source)
        if name in self._scene.objects:
            self.apply_scene_changes([RemoveObject(name)])
        self._clouds.pop(name, None)
        self._cloud_stats.pop(name, None)

    @property
    def point_cloud_sources(self) -> Tuple[str, ...]:
        """The sources whose cloud is an obstacle, in the order they came."""
        prefix = len(cloud_name('x')) - 1
        return tuple(name[prefix:] for name, placed in self._scene.objects.items()
                     if placed.block is CLOUD_BLOCK)

    def point_cloud_stats(self, source: str) -> PointCloudStats:
        """What became of the rows of ``source``'s last cloud committed (zeros before any)."""
        return self._cloud_stats.get(cloud_name(source), NO_STATS)

    def cloud_voxels(self, source: str) -> Tuple[np.ndarray, float]:
        """Return the centres (V, 3) of the occupied voxels of ``source``'s obstacle (world
        frame) and the voxel size; (0, 3) when it has none."""
        cloud = self._clouds.get(cloud_name(source))
        if cloud is None:
            return np.zeros((0, 3)), self.config.voxel_size
        centres, _, size = cloud.voxels()
        return centres, (size or self.config.voxel_size)

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
        version = self._scene_version
        base = self._scene.objects if self._scene is not None else {}
        done = prepare_changes(changes, base, self.kinematics.link_names, self.world_frames,
                               self.model.name, self.config)
        return PreparedSceneChanges(self, base, done.objects, done.structural, done.moved,
                                    done.rebuilt, version)

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
        self._scene.objects = prepared.objects

    def _move_in_place(self, placed: PlacedObject) -> None:
        """Give an object its new pose in the engine, which forces its pairs."""
        b = self._scene.body_index[placed.name]
        if placed.attach_to is None:
            moved = self._engine.move_world_body(b, np.ascontiguousarray(placed.pose))
        else:
            # The fixed joint's origin, and the reach bounds whose lever arms run through it.
            pairs, reach, reach_ext = self._scene.attached_reach(placed.name, placed.pose,
                                                                 len(self.joint_names))
            moved = self._engine.place_attached_body(b, placed.pose, pairs, reach, reach_ext)
        if not moved:   # checked_pose and the engine check a pose with the same arithmetic
            raise SceneError(f'object "{placed.name}": the engine refused its pose; '
                             'report this as a bug')

    def _install(self, prepared: PreparedSceneChanges) -> None:
        """Lay the scene ``prepared`` describes out for a new engine, carrying over the state
        of every pair that survives (scene_layout.SceneLayout.carry), and swap it in."""
        old = self._scene
        layout = SceneLayout(
            self._robot, self.kinematics, self._joints, prepared.objects,
            old.rows if old is not None else {},
            changed_objects(prepared.base, prepared.objects, prepared.moved, prepared.rebuilt))
        if old is not None:
            layout.carry(old, prepared.rebuilt | prepared.moved)
        packed = array_pack.pack(layout.arrays)
        config = self.config
        new_engine = engine.Engine(packed.F, packed.F_layout, packed.I, packed.I_layout,
                                   box_test=config.box_test_code,
                                   expansion=config.expansion_code,
                                   motion_tolerance=config.motion_tolerance,
                                   threads=config.threads,
                                   min_chunk_us=config.min_chunk_us)
        new_engine.name_pairs(tuple(layout.checked_pairs), MotionResult, FREE)
        # Point clouds: the new engine shows each cloud's voxels (their pairs forced). A cloud
        # whose object this change removes is dropped; one prepared for a first commit is kept.
        removed = [name for name in self._clouds
                   if old is not None and name in old.objects and name not in layout.objects]
        for name, cloud in list(self._clouds.items()):
            if name in layout.objects and not new_engine.attach_cloud(layout.body_index[name],
                                                                      cloud):
                raise PointCloudError(f'{name}: the engine refused the point cloud\'s body; '
                                      'report this as a bug')

        # Nothing above changed the checker; from here on, nothing can fail.
        for name in removed:
            self._clouds.pop(name, None)
            self._cloud_stats.pop(name, None)
        views = self._views = packed.views
        self._robot = layout.take_views(self._robot, views)
        self._scene = layout
        # The engine's calls of every joint state, bound once.
        self._engine, self._query = new_engine, new_engine.query
        self._query_motion, self._motion = new_engine.update_motion, new_engine.motion
        # The forest is only a view of the engine's tables: nothing is held twice.
        self.forest = forest_view(views['boxes'], views['nodes'], views['volume'],
                                  views['gain'], views['tris'], views['roots'], layout.depths)
        self._T_world_body = views['T_world_body']
        self._status = views['status']
        self.counters = views['counters']  # work done, see traversal.COUNT_* (benchmarks)
        # The joint vector of the last call; the engine writes it (read-only for Python).
        self._q = views['q_last']
        self.checked_pairs: Tuple[Pair, ...] = layout.checked_pairs
        self.excluded_pairs: Dict[Pair, str] = layout.excluded_pairs
        self.scene_object_names: Tuple[str, ...] = tuple(layout.objects)
        self._results = {}
        self._version = new_engine.status_version
        self._answer = _NO_ANSWER
        self._result = self._result_from_status(0)

    # ------------------------------------------------------------------ queries
    def _merged(self, positions: Positions) -> np.ndarray:
        """Return the current joint vector with ``positions`` applied.

        Finiteness (and what else the engine cannot honour) is checked by the engine, before it
        changes anything.
        """
        if (isinstance(positions, np.ndarray) and positions.dtype is _FLOAT64
                and positions.shape == self._q.shape):
            # As the engine reads in place (a misaligned or strided one is copied); the engine
            # copies it before keeping it. flags.carray is the cheap test (np.require costs
            # 1.4 us even when it returns the array itself).
            if positions.flags.carray:
                return positions
            return np.require(positions, requirements=['C_CONTIGUOUS', 'ALIGNED'])
        q = self._q.copy()
        if isinstance(positions, Mapping):
            unknown = [name for name in positions
                       if name not in self._joints.index and name not in self._joints.derived]
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
                j = self._joints.index.get(name)
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

    def _run(self, q: np.ndarray, full: bool) -> CheckResult:
        """Run the query on ``q`` (an array the engine reads as it is: :meth:`_merged`)."""
        try:
            answer = self._query(q, full)
        except JointStateError as error:
            raise self._refused(error, q) from None
        return self._settle(answer, q, full)

    def _settle(self, answer, positions: Positions, full: bool) -> CheckResult:
        """Return the answer for the engine's ``answer`` (``cpp/engine.hpp``: QueryResult;
        None: ``positions`` is no array the engine reads as it is, converted here first).

        The answer is looked up (by the statuses' bytes) or made only when the statuses are
        not those ``_result`` was made from: the engine's status_version moved on (a status
        changed, in this query or in one another caller ran on the engine in between).
        """
        if answer is None:
            return self._run(self._merged(positions), full)
        self._answer = answer
        if answer.status_version != self._version:
            self._version = answer.status_version
            result = self._results.get(self._status.tobytes())
            if result is None or result.rechecked_pairs != answer.rechecked:
                result = self._result_from_status(answer.rechecked)
            self._result = result
            return result
        if answer.rechecked != self._result.rechecked_pairs:
            result = self._result
            self._result = CheckResult(result.in_collision, result.colliding_pairs,
                                       answer.rechecked)
        return self._result

    def _refused(self, error: JointStateError, q: np.ndarray,
                 row: Optional[int] = None) -> JointStateError:
        """The error naming the joint for a value the engine refused (``error.variable``)."""
        return JointStateError(self._unusable_message(error.variable, q, row))

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
        try:
            answer = self._query(positions, True)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if answer is self._answer:
            return self._result  # the last answer's fields: its statuses (see _settle)
        return self._settle(answer, positions, True)

    def update(self, positions: Positions) -> CheckResult:
        """Check incrementally: re-check only pairs whose relative pose can have changed.

        A pair is re-checked only if a joint on the tree path between its two bodies moved by
        more than ``motion_tolerance`` since the state its status describes; every other
        status, and every pose not below a moved joint, carries over (paper sec. 4.2). A pair
        last found apart by ``update`` with a known clearance is not re-checked either while
        the joints on its path have not moved far enough, summed, to close that gap (see
        ``cpp/planning.hpp``).
        Same arguments and errors as :meth:`check`.
        """
        try:
            answer = self._query(positions, False)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if answer is self._answer:
            return self._result  # the last answer's fields: its statuses (see _settle)
        return self._settle(answer, positions, False)

    def check_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Check many configurations from scratch, in one compiled call; return (n, P) bool
        statuses, columns in the order of :attr:`checked_pairs`.

        The rows run on :attr:`threads` threads (contiguous chunks of at least the setting
        ``min_chunk_us`` of work; the answers those of one thread), each in a copy of the
        carried state: the carried state is left as it was,
        and the next :meth:`update` goes on from the positions of the last single call.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or a value that is not finite (naming the
            row and joint); nothing changes then.
        :raises EngineWorkerError: a worker thread failed (memory); nothing changes then.
        """
        return self._batch(configurations, full=True)[0]

    def update_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Run :meth:`update` on each row in turn, in one compiled call: a recorded path
        checked incrementally, without the interpreter between steps. Return (n, P) bool
        statuses after each row, columns in the order of :attr:`checked_pairs`.

        The state carries over as with single calls: afterwards the checker stands at the
        last row (``update`` goes on from there, :attr:`positions` is that row).

        On :attr:`threads` threads when ``motion_tolerance`` is 0 (then a row's statuses are
        a full check's at that row, whatever the rows before): the first chunk of rows goes
        on from the carried state, each later chunk starts with a full check at its first row.
        The statuses are one thread's; what differs is the work (each later chunk's first
        row re-checks every pair) and so :attr:`CheckResult.rechecked_pairs` of the next
        answers. With a motion tolerance the rows run in turn on the calling thread.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: as :meth:`check_batch`; nothing changes then.
        :raises EngineWorkerError: a worker thread failed (memory); the state is then at some
            row of the batch (``check`` sets it anew).
        """
        statuses, rechecked, _ = self._batch(configurations, full=False)
        if len(rechecked):
            self._version = self._engine.status_version
            self._answer = _NO_ANSWER
            self._result = self._result_from_status(int(rechecked[-1]))
        return statuses

    @property
    def threads(self) -> int:
        """Threads :meth:`check_batch`, :meth:`update_batch`, :meth:`check_path` and
        :meth:`check_spline` run on: the setting ``threads`` resolved (0 there: the machine's
        hardware threads)."""
        return self._engine.threads

    def _batch(self, configurations,
               full: bool) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run the rows through the engine; return each row's answer: (n, P) bool statuses,
        (n,) pairs re-checked and (n,) bool changed (against the row before)."""
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names):
            raise JointStateError(f'expected configurations of shape (n, {len(self.joint_names)})'
                                  f' in the order of joint_names, got {Q.shape}')
        statuses = np.zeros((len(Q), len(self.checked_pairs)), dtype=np.uint8)
        rechecked = np.zeros(len(Q), dtype=np.int64)
        changed = np.zeros(len(Q), dtype=np.uint8)
        try:  # the engine validates every row before it runs any
            self._engine.batch(Q, full, statuses, rechecked, changed)
        except JointStateError as error:
            raise self._refused(error, Q[error.row], error.row) from None
        return statuses.view(bool), rechecked, changed.view(bool)

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
        try:
            answer = self._engine.proximity(q, max_distance, distance, points)
        except JointStateError as error:
            raise self._refused(error, q) from None
        self._settle(answer, q, False)
        return self._proximity_records(distance, points)

    # ------------------------------------------------------------------ motion
    @property
    def motion_kinds(self) -> np.ndarray:
        """(J,) int64: how each variable of :attr:`joint_names` moves along a motion
        (``engine.MOTION_*``; see :func:`collision_sensor.engine.motion.interpolate`)."""
        return self._joints.motion_kind

    def _check_motion(self, q_from: Positions, q_to: Positions) -> MotionResult:
        """Check the straight motion from ``q_from`` to ``q_to``: certified, never sampled.

        Revolute and prismatic joints move linearly, continuous joints (and a planar joint's
        theta) the shorter way round, planar and floating joints their translation linearly
        and their rotation along the shorter arc; mimic joints follow (MoveIt's
        interpolation, :mod:`collision_sensor.engine.motion`). A motion reported free has no
        state in contact; a reported ``first_contact`` t is in contact or within
        :data:`~collision_sensor.engine.motion.TOUCH_TOLERANCE` of it, and no earlier state is
        in contact. Padding, the exception list, world and attached objects count as in
        :meth:`check`. The carried incremental state is left as it was.

        :param q_from: the start, as ``positions`` of :meth:`check` (joints not given keep
            their current value).
        :param q_to: the end, the same way.
        :raises JointStateError: as :meth:`check`, naming the end at fault; nothing changes.
        """
        # check_motion (below the class) answers arrays the engine reads as they are in one
        # compiled call; it comes here for anything else (other sequences, mappings) and for
        # the values the engine refuses, which are named here.
        try:
            answer = self._motion(q_from, q_to)
        except JointStateError as error:
            raise self._refused_end(error, q_from, q_to) from None
        if answer is not None:
            return answer
        ends = []
        for end, positions in (('q_from', q_from), ('q_to', q_to)):
            try:
                ends.append(self._merged(positions))
            except JointStateError as error:
                raise JointStateError(f'{end}: {error}') from None
        try:
            return self._motion(*ends)
        except JointStateError as error:
            raise self._refused_end(error, *ends) from None

    def _refused_end(self, error: JointStateError, q_from: np.ndarray,
                     q_to: np.ndarray) -> JointStateError:
        """The error naming the end and joint of a motion the engine refused (``error.row``
        0: ``q_from``, 1: ``q_to``; ``error.variable``)."""
        end, q = ('q_from', q_from) if error.row == 0 else ('q_to', q_to)
        return JointStateError(f'{end}: ' + self._unusable_message(error.variable, q))

    def update_motion(self, positions: Positions) -> MotionResult:
        """Check the motion from the current state to ``positions`` (as :meth:`check_motion`),
        then move the state there as :meth:`update` does: what a stream of joint states
        needs, at about the cost of :meth:`update` (pairs its clearance keeps apart at both
        ends are apart all along). Before any state was checked there is no motion: the
        answer is ``positions``' own instant.

        :raises JointStateError: as :meth:`check`; nothing changes then.
        """
        try:
            step = self._query_motion(positions)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if step is not self._answer:   # else the same answer as last time (see _settle)
            if step is None:
                return self.update_motion(self._merged(positions))
            if (step.status_version != self._version
                    or step.rechecked != self._result.rechecked_pairs):
                self._settle(step, positions, False)
            self._answer = step
        return step.motion

    def check_path(self, configurations: np.ndarray) -> PathResult:
        """Check the straight motions between consecutive waypoints, in one compiled call,
        until one is not free (a single waypoint: its instant). The carried state is left as
        it was. The segments run on :attr:`threads` threads in contiguous chunks (a chunk
        stops once an earlier one met contact); the answer is one thread's.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or an unusable value (naming the row and
            joint); nothing changes then.
        """
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names) or not len(Q):
            raise JointStateError(f'expected waypoints of shape (n, {len(self.joint_names)}), '
                                  f'n >= 1, in the order of joint_names, got {Q.shape}')
        try:
            answer = self._engine.path(Q)
        except JointStateError as error:
            raise self._refused(error, Q[error.row], error.row) from None
        return PathResult(answer.segment if answer.segment >= 0 else None, answer.motion)

    def check_spline(self, coefficients: np.ndarray) -> PathResult:
        """Check polynomial path segments in turn, in one compiled call, until one is not free:
        segment i is ``q_j(t) = sum_k coefficients[i, j, k] t^k`` for t in [0, 1] (degree at
        most 5; planar and floating joints constant). ``first_contact`` is a fraction of the
        segment. The carried state is left as it was; segments run on :attr:`threads` threads
        as in :meth:`check_path`.

        :param coefficients: (S, J, 6) float, variables in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape, or a segment the engine cannot take (not
            finite, moving a planar or floating joint, or an unusable value at an end).
        """
        coef = np.ascontiguousarray(coefficients, dtype=np.float64)
        if coef.ndim != 3 or coef.shape[1:] != (len(self.joint_names), 6):
            raise JointStateError(f'expected coefficients of shape (S, {len(self.joint_names)},'
                                  f' 6), got {coef.shape}')
        try:
            answer = self._engine.spline(coef)
        except JointStateError as error:
            raise JointStateError(
                f'segment {error.row}: a coefficient is not finite, a planar or floating joint '
                'moves, or an end is beyond the engine\'s range; give finite polynomials of '
                'the 1-DOF joints') from None
        return PathResult(answer.segment if answer.segment >= 0 else None, answer.motion)

    def check_trajectory(self, joint_names, points, start=None,
                         limit_tolerance: float = 0.0) -> TrajectoryResult:
        """Check a planned trajectory (``trajectory_msgs/JointTrajectory``'s joint names and
        points) along the path joint_trajectory_controller will follow, from ``start``
        (default: the current positions): see :mod:`collision_sensor.engine.trajectory`.
        A malformed trajectory is invalid with its reason; nothing changes in the checker."""
        return check_trajectory(self, joint_names, points, start, limit_tolerance)

    def _proximity_records(self, distance: np.ndarray,
                           points: np.ndarray) -> List[ProximityRecord]:
        """Records for the pairs with a finite distance, sorted; points as named."""
        records = []
        body_a, body_index = self._scene.pair_a, self._scene.body_index
        for p in np.flatnonzero(np.isfinite(distance)):
            a, b = self.checked_pairs[p]
            row = points[p]
            if body_index[a] == body_a[p]:
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

    def cast_rays(self, origin, directions, max_range: float = math.inf) -> np.ndarray:
        """Cast rays against the robot and the scene objects at the last checked state (a
        simulated depth sensor: point clouds are not seen): ``origin + t directions[i]``.

        :param origin: (3,) world frame.
        :param directions: (n, 3) unit vectors, world frame.
        :return: (n,) the nearest hit's t (m), ``inf`` when nothing is hit within
            ``max_range``.
        """
        origin = np.ascontiguousarray(origin, dtype=np.float64)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        return self._engine.cast_rays(origin, directions, float(max_range))

    # ------------------------------------------------------------------ inspection
    @property
    def positions(self) -> Dict[str, float]:
        """The joint positions of the last check, by name."""
        return {name: float(v) for name, v in zip(self.joint_names, self._q)}

    def link_poses(self) -> Dict[str, np.ndarray]:
        """World poses (4, 4) of every link and scene object at the last checked state."""
        T_world_body = self._poses()
        return {name: T_world_body[b].copy() for b, name in enumerate(self._scene.body_names)}

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
            b = self._scene.body_index.get(name)
            if b is None:
                continue
            for e in range(self._scene.elem_start[b], self._scene.elem_end[b]):
                node = f.roots[e]
                T_body_box = np.eye(4)
                T_body_box[:3, :3] = f.axes[node]
                T_body_box[:3, 3] = f.center[node]
                boxes.append((name, T_world_body[b] @ T_body_box, f.half[node].copy()))
        return boxes


#: CollisionChecker.check_motion: a method of the class in the compiled engine's fast calling
#: convention (bind_engine.cpp: checker_check_motion), which answers from the checker's engine
#: in one call and leaves everything else to _check_motion (whose docstring it carries).
CollisionChecker.check_motion = engine.checker_motion_method(
    CollisionChecker, 'check_motion($self, q_from, q_to)\n--\n\n' +
    CollisionChecker._check_motion.__doc__)
