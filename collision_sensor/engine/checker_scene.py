"""The checker's scene (a room of :class:`~collision_sensor.engine.checker.CollisionChecker`):
the world and attached objects, scene changes prepared and committed, and the engine laid out
anew by a structural change (:mod:`~collision_sensor.engine.scene_layout`), carrying over every
surviving pair's state.
"""
import dataclasses
from typing import Dict, Iterable, Optional, Tuple

import numpy as np

from collision_sensor.engine import array_pack
from collision_sensor.engine.checker_queries import _NO_ANSWER, Pair
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import (
    CLOUD_BLOCK, AddObject, PlacedObject, PreparedSceneChanges, RemoveObject, SceneChange,
    checked_pose, prepare_changes)
from collision_sensor.engine.motion import FREE, MotionResult
from collision_sensor.engine.obb_tree import forest_view
from collision_sensor.engine.scene_layout import SceneLayout, changed_objects
from collision_sensor.errors import PointCloudError, SceneError
from collision_sensor.model.scene import SceneObject


class CheckerScene:
    """:class:`~collision_sensor.engine.checker.CollisionChecker`'s scene: its objects, their
    changes, and the engine laid out anew for a structural one."""

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
        with array_pack.normal_pages():
            layout = SceneLayout(
                self._robot, self.kinematics, self._joints, prepared.objects,
                old.rows if old is not None else {},
                changed_objects(prepared.base, prepared.objects, prepared.moved,
                                prepared.rebuilt))
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

