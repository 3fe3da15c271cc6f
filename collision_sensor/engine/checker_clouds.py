"""The checker's point clouds (a room of
:class:`~collision_sensor.engine.checker.CollisionChecker`): a source's cloud prepared off the
checker's lock, committed as the obstacle ``cloud/<source>``, cleared.
"""
import math
import time
from typing import Optional, Tuple

import numpy as np

from collision_sensor.engine.checker_queries import Positions
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import CLOUD_BLOCK, AddCloud, RemoveObject
from collision_sensor.engine.point_clouds import (
    NO_STATS, PointCloudStats, PreparedPoints, cloud_arguments, cloud_name, cloud_threads,
    points_array)
from collision_sensor.errors import JointStateError, PointCloudError
from collision_sensor.untrusted_text import quoted


class CheckerClouds:
    """:class:`~collision_sensor.engine.checker.CollisionChecker`'s point clouds: each source's
    cloud filtered, voxelised and made an obstacle (see
    :mod:`collision_sensor.engine.point_clouds`)."""

    def set_points(self, source: str, points, frame: Optional[str] = None, *,
                   positions: Optional[Positions] = None, stamp: Optional[float] = None,
                   persistence: float = 0.0, max_range: float = math.inf,
                   threads: Optional[int] = None) -> int:
        """Make ``points`` the obstacle ``cloud/<source>``: filtered, voxelised, checked
        against every robot link and attached object from the next :meth:`update` on (see
        :mod:`collision_sensor.engine.point_clouds`, which says what a cloud can tell).

        The source's next cloud replaces this one in place (only the cloud's pairs are
        re-checked); its first adds the object (pairs of ``cloud/<source>`` and each link, which
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

