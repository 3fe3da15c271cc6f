"""The point cloud inputs: ``sensor_msgs/PointCloud2`` topics as obstacles.

One :class:`PointCloudSource` per entry of ``point_cloud_topics`` (sensor-data QoS); the source's
name is the topic as given, its obstacle ``cloud/<topic>`` (see
:mod:`collision_sensor.engine.point_clouds` for what a cloud becomes and what it can tell).

Each cloud is handled on a thread of the source's own, newest first (clouds that arrive while
one is filtered are superseded and counted): read
(:mod:`~collision_sensor.model.point_cloud_message`),
its ``header.frame_id`` checked (a link of the robot or its world frame: there is no tf2, camera
frames are links of the URDF), filtered and voxelised without holding the sensor, then handed to
the sensor, which swaps it in and answers at once by a verdict, like a scene change. The points
kept are published on ``~/filtered_points`` (world frame) when someone listens. A cloud that
cannot be taken (empty, every point NaN, fields missing or not float, inconsistent steps, an
unknown frame) is counted, named in one throttled log line and in the source's /diagnostics
status, and changes nothing: the last good cloud stays the obstacle.

The robot's pose used by the self-filter is the one at the cloud's ``header.stamp``: the
sensor keeps the complete states of the last ``point_cloud_state_window`` seconds and
interpolates between the two around the stamp (``Sensor.positions_at``); a cloud stamped after
the newest joint state takes the newest; a cloud older than the window is counted
(``clouds_too_old_total``) and dropped, not filtered with the wrong pose. Zero stamps are the
node's clock at arrival.

Timeout: no cloud accepted for ``point_cloud_timeout`` s (from the start on: a camera that never
publishes times out too) is an episode: with ``point_cloud_on_timeout: contact`` (the default,
as nav2's collision_monitor stops when a source goes quiet) every verdict is a failure entry
``point_cloud_timeout`` with contact true until a cloud comes; with ``ignore`` the cloud's last
voxels are removed (stale points never linger) and verdicts go on without it. /diagnostics says
ERROR either way.
"""
import threading
import time
from typing import Optional

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

from collision_sensor.engine.point_clouds import NO_STATS
from collision_sensor.errors import JointStateError, PointCloudError
from collision_sensor.ros.input_source import InputSource
from collision_sensor.sensor import Failure
from collision_sensor.sensor.model import root_link
from collision_sensor.sensor.parameters import CONTACT
from collision_sensor.model.point_cloud_message import (
    CloudMessageError, cdr_from_points, cloud_frame, cloud_from_cdr, cloud_rows,
    require_some_valid)
from collision_sensor.ros.work_queue import BACKGROUND_NICE, NewestFirstWorker
from collision_sensor.untrusted_text import printable

#: The ``colliding_pairs`` entry of a timed-out cloud source.
POINT_CLOUD_TIMEOUT = 'point_cloud_timeout'
#: The values of ``point_cloud_on_timeout``.
IGNORE = 'ignore'
ON_TIMEOUT_POLICIES = (CONTACT, IGNORE)
#: Clouds that may wait for the source's thread; more are dropped and counted (each may hold
#: megabytes).
MAX_CLOUD_BACKLOG = 4
#: Threads a cloud is filtered on: the source's own alone. The node's machine may have two
#: cores, one of them the joint states' answers'; a second cloud thread, niced like the first,
#: would still take that core's time slices while a cloud is filtered, and the joint states'
#: latency is what clouds must not move. The checker's ``threads`` setting stays the batches'.
CLOUD_THREADS = 1


class PointCloudSource(InputSource):
    """One PointCloud2 topic: subscription, reading, the self-filter's hand-over, the timeout,
    ``~/filtered_points`` and its /diagnostics status.

    :param node: the node the subscription and publisher belong to.
    :param sensor: the :class:`~collision_sensor.sensor.Sensor` the clouds go to.
    :param topic: the topic as given in ``point_cloud_topics`` (also the source's name).
    :param settings: the node's settings (``point_cloud_*``).
    :param log: the node's :class:`~collision_sensor.ros.node_log.NodeLog`.
    :param markers: the node's :class:`~collision_sensor.ros.markers.MarkerPublisher`.
    """

    def __init__(self, node, sensor, topic: str, settings, log, markers):
        self._node, self._sensor, self._log, self._markers = node, sensor, log, markers
        self._settings = settings
        self.topic = topic
        self.name = f'point cloud {printable(topic, 200)}'
        self._worker: Optional[NewestFirstWorker] = None
        self._filtered = None
        self._last_good = None      # (points, frame or None, positions): for a new checker
        self.stats = NO_STATS
        self.rejection = ''
        self.counts = {'received': 0, 'accepted': 0, 'rejected': 0, 'dropped': 0,
                       'superseded': 0, 'capped': 0, 'timeouts': 0, 'too_old': 0}
        self._period_accepted = 0
        self._period_start = time.monotonic()
        self.started: Optional[float] = None
        self.last_accepted: Optional[float] = None
        self.timed_out_now = False
        # Held while the timeout episode (timed_out_now, last_accepted) is read or changed: by
        # the cloud's thread when a cloud is accepted, by the node's poll when it times out.
        # Taken after the sensor's editing() and before its core, as everything else.
        self._episode = threading.Lock()

    # -- life cycle ---------------------------------------------------------------------------

    def start(self) -> None:
        node = self._node
        self.started = time.monotonic()
        self._worker = NewestFirstWorker(self._apply_batch, 'point cloud', 1,
                                         nice=BACKGROUND_NICE)
        self._filtered = node.create_publisher(PointCloud2, '~/filtered_points',
                                               qos_profile_sensor_data)
        # Serialized: read on the source's thread without copying the points
        # (point_cloud_message.cloud_from_cdr), not converted by rclpy on the executor's.
        node.create_subscription(PointCloud2, self.topic, self._on_cloud,
                                 qos_profile_sensor_data, raw=True,
                                 callback_group=MutuallyExclusiveCallbackGroup())

    def close(self) -> None:
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    def prepare_model(self, checker):
        """Filter the last good cloud again for ``checker``."""
        if self._last_good is None:
            return None
        points, frame, positions = self._last_good
        settings = self._settings
        try:
            prepared = checker.prepare_points(
                self.topic, points, frame, positions=positions,
                persistence=settings.point_cloud_persistence,
                max_range=settings.point_cloud_max_range, threads=CLOUD_THREADS)
        except (PointCloudError, JointStateError) as error:
            reason = printable(error, 500)

            def drop(notes: list) -> None:
                self._last_good = None
                notes.append(('error', None, f'{self.name}: the last cloud does not fit the new '
                              f'robot model and is dropped: {reason}'))
            return drop

        def commit(notes: list) -> None:
            checker.commit_points(prepared)
        return commit

    # -- the executor's thread ----------------------------------------------------------------

    def _on_cloud(self, msg: bytes) -> None:
        """Hand a cloud to the source's thread (nothing slow here)."""
        if self._worker.backlog() >= MAX_CLOUD_BACKLOG:
            self.counts['dropped'] += 1
            self._log.warn(f'cloud_dropped {self.topic}', f'{self.name}: cloud dropped, '
                               f'{MAX_CLOUD_BACKLOG} wait already (clouds_dropped_total)')
            return
        self._worker.put(msg)

    # -- the source's thread ------------------------------------------------------------------

    def _apply_batch(self, batch: list, newest_only: bool) -> None:
        notes = []
        self.counts['received'] += len(batch)
        self.counts['superseded'] += len(batch) - 1
        try:
            self._apply(batch[-1], notes)
        except Exception as error:  # noqa: B902 - one cloud must never stop the node
            if not self._node.context.ok():
                return
            notes.append(('error', None, f'{self.name}: cloud skipped after an internal error: '
                          f'{printable(repr(error), 300)}'))
        self._log.write(notes)

    def _apply(self, data: bytes, notes: list) -> None:
        sensor, settings = self._sensor, self._settings
        try:
            msg = cloud_from_cdr(data, self.topic)
            rows = cloud_rows(msg, self.topic)
        except CloudMessageError as error:
            self._reject(error.kind, str(error), notes)
            return
        stamp = msg.header.stamp
        if stamp.sec == 0 and stamp.nanosec == 0:
            seconds = self._node.get_clock().now().nanoseconds * 1e-9
        else:
            seconds = stamp.sec + stamp.nanosec * 1e-9
        listening = self._filtered.get_subscription_count() > 0
        # The scene and model held still from the filter to the swap.
        with sensor.editing() as checker:
            try:
                frame = cloud_frame(rows.frame, checker.kinematics.link_names,
                                    checker.world_frames, self.name)
            except CloudMessageError as error:
                self._reject(error.kind, str(error), notes)
                return
            positions = sensor.positions_at(seconds)
            if isinstance(positions, str):
                oldest, newest = sensor.window_bounds()
                self._reject('old', f'{self.name}: stamped {newest - seconds:.3f} s before the '
                             'newest joint state, older than the states kept '
                             f'(point_cloud_state_window {settings.point_cloud_state_window:g} s, '
                             f'oldest {newest - oldest:.3f} s back): dropped, not filtered with '
                             'a wrong pose; raise the window or publish clouds with less delay',
                             notes)
                return
            if positions is None:
                self._reject('waiting', f'{self.name}: no complete joint state yet, so the '
                             'robot\'s own points cannot be filtered out; the cloud is dropped',
                             notes)
                return
            try:
                prepared = checker.prepare_points(
                    self.topic, rows.points, frame, positions=positions,
                    persistence=settings.point_cloud_persistence,
                    max_range=settings.point_cloud_max_range, keep_points=listening,
                    threads=CLOUD_THREADS)
            except (PointCloudError, JointStateError) as error:
                self._reject('engine', f'{self.name}: {printable(error, 500)}', notes)
                return
            stats = prepared.stats
            try:
                require_some_valid(stats, self.name)
            except CloudMessageError as error:
                self._reject(error.kind, str(error), notes)
                return
            # Accepted from now on: a poll meanwhile cannot start a new episode on the old
            # age, nor leave this one failing after the cloud's verdict.
            with self._episode:
                self.last_accepted = time.monotonic()
                if self.timed_out_now:
                    self.timed_out_now = False
                    sensor.recover_source(self.name)
                    notes.append(('info', None, f'{self.name}: clouds resumed'))
            sensor.commit_points(prepared, (stamp.sec, stamp.nanosec))
            self._last_good = (rows.points, frame, positions)
        self.stats = stats
        self.rejection = ''
        self.counts['accepted'] += 1
        self.counts['capped'] += stats.capped > 0
        self._period_accepted += 1
        self._markers.scene_changed = True
        if stats.capped:
            notes.append(('warning', f'cloud_capped {self.topic}', f'{self.name}: '
                          f'{stats.points} points, more than point_cloud_max_points: every '
                          f'k-th taken, {stats.capped} left out (clouds_capped_total)'))
        if listening and prepared.kept is not None:
            self._publish_filtered(prepared.kept, msg.header.stamp, root_link(checker))

    def _reject(self, kind: str, reason: str, notes: list) -> None:
        """Count a cloud that cannot be taken and log it (throttled); nothing else changes."""
        text = printable(reason, 1000)
        self.counts['rejected'] += 1
        self.counts['too_old'] += kind == 'old'
        self.rejection = text
        notes.append(('warning', f'cloud_{kind} {self.topic}',
                      f'point cloud rejected, the last good one stays: {text}'))

    def _publish_filtered(self, kept: np.ndarray, stamp, frame: str) -> None:
        self._filtered.publish(cdr_from_points(kept, stamp.sec, stamp.nanosec, frame))

    # -- timeout ------------------------------------------------------------------------------

    def poll_timeout(self, now: float, stamp) -> None:
        """No cloud accepted for ``point_cloud_timeout`` (from the start on): with
        ``point_cloud_on_timeout`` contact every verdict answers this source's failure until a
        cloud comes; with ignore its last voxels are removed. Once per episode."""
        settings = self._settings
        timeout = settings.point_cloud_timeout
        policy = settings.point_cloud_on_timeout
        sensor = self._sensor
        with self._episode:
            if timeout <= 0.0 or self.timed_out_now or self.started is None:
                return
            last = self.last_accepted if self.last_accepted is not None else self.started
            if now - last <= timeout:
                return
            self.timed_out_now = True
            self.counts['timeouts'] += 1
            since = 'since the start' if self.last_accepted is None else \
                f'for {now - self.last_accepted:.1f} s'
            reason = (f'{self.name}: no cloud accepted {since} (point_cloud_timeout '
                      f'{timeout:g} s, point_cloud_on_timeout {policy})')
            if policy == CONTACT:
                failure = Failure(POINT_CLOUD_TIMEOUT, reason, CONTACT)
                sensor.fail_source(self.name, failure)
                sensor.answer_failure(failure, stamp)
        self._log.warn(f'cloud_timeout {self.topic}', reason)
        if policy == CONTACT:
            return
        with sensor.editing() as checker, self._episode:
            # Unless a cloud came meanwhile: its voxels are fresh.
            if self.timed_out_now and checker is not None and \
                    self.topic in checker.point_cloud_sources:
                sensor.clear_points(self.topic, stamp)
                self._last_good = None
                self._markers.scene_changed = True

    def timed_out(self) -> bool:
        return self.timed_out_now

    def apply_settings(self, settings) -> None:
        self._settings = settings

    # -- diagnostics --------------------------------------------------------------------------

    def status(self, now: float) -> DiagnosticStatus:
        """This source's status on /diagnostics."""
        stats, counts = self.stats, self.counts
        elapsed = max(now - self._period_start, 1e-9)
        rate = self._period_accepted / elapsed
        self._period_accepted, self._period_start = 0, now
        age = '' if self.last_accepted is None else f'{now - self.last_accepted:.3f}'
        level, message = DiagnosticStatus.OK, f'{stats.voxels} voxels from {stats.points} points'
        if self.rejection:
            level, message = DiagnosticStatus.WARN, f'last cloud rejected: {self.rejection}'
        if self.timed_out_now:
            level = DiagnosticStatus.ERROR
            message = (f'timed out: no cloud within point_cloud_timeout '
                       f'({self._settings.point_cloud_on_timeout})')
        values = {
            'topic': printable(self.topic, 200),
            'rate_hz': f'{rate:.2f}',
            'points_in': str(stats.points),
            'points_invalid': str(stats.invalid),
            'points_capped': str(stats.capped),
            'points_out_of_range': str(stats.out_of_range),
            'points_self_filtered': str(stats.self_filtered),
            'points_kept': str(stats.kept_points),
            'voxels_kept': str(stats.voxels),
            'voxels_persisted': str(stats.persisted),
            'age_s': age,
            'timed_out': str(self.timed_out_now).lower(),
            'timeouts_total': str(counts['timeouts']),
            'clouds_received_total': str(counts['received']),
            'clouds_accepted_total': str(counts['accepted']),
            'clouds_rejected_total': str(counts['rejected']),
            'clouds_superseded_total': str(counts['superseded']),
            'clouds_dropped_total': str(counts['dropped']),
            'clouds_capped_total': str(counts['capped']),
            'clouds_too_old_total': str(counts['too_old']),
            'last_rejection': self.rejection,
        }
        checker = self._sensor.checker
        return DiagnosticStatus(
            level=level, name=f'{self._node.get_fully_qualified_name().lstrip("/")}: {self.name}',
            message=printable(message, 1000),
            hardware_id=printable(root_link(checker) if checker is not None else ''),
            values=[KeyValue(key=key, value=value) for key, value in values.items()])

