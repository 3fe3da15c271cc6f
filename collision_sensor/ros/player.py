"""``collision_sensor_play``: publish a recorded joint-state sequence as JointState messages.

The topic is the relative name ``joint_states`` (remap it with ``--ros-args -r
joint_states:=/robot/joint_states``, or move the node with ``-r __ns:=/robot``). Each frame's
``header.stamp`` is the time of publishing (``--stamp now``, the default, right for a live
sensor), or the recorded time (``--stamp recorded``).

Timing, one of:

recorded (default)
    frame i is published at ``start + (t_i - t_0)``, wall clock.
``--rate HZ``
    frame i is published at ``start + i / HZ``, whatever the recorded times.
``--as-fast-as-possible``
    as fast as the subscribers keep up, without loss: frame i + 1 is published only when
    ``publisher.wait_for_all_acked()`` reports that every matched reliable subscription has
    acknowledged frame i. Why that loses nothing: a reliable reader acknowledges a frame once
    it holds it in its history, and the next frame is sent only then, so no frame is lost in
    transit; a ``KEEP_ALL`` subscription never evicts a frame it has not taken, so it receives
    every frame, in order (``test/ros/test_player.py`` checks this, with the node and the
    player in processes of their own). A ``KEEP_LAST`` subscription of depth N evicts its
    oldest frame when its callback falls N frames behind: it is lossless only while it keeps
    within N (DDS acknowledges receipt, not processing, so no publisher can do better).
    Best-effort subscriptions (``qos_profile_sensor_data``) never acknowledge and may lose any
    frame; the player warns when one is matched.

    The writer keeps a history of one frame here (:data:`FAST_QOS`), and that is what makes it
    fast across processes. A reliable reader acknowledges only in answer to the writer's
    HEARTBEAT. Fast DDS 2.14.5 (the Jazzy wheels) sends one every ``heartbeatPeriod`` (3 s by
    default), or along with a sample when the writer's history is full; ``wait_for_all_acked``
    itself asks for nothing (it does from Fast DDS 2.14.6 on, eProsima/Fast-DDS#6098). With a
    history of 1000 frames every frame waited for the periodic heartbeat: one frame per 3 s
    whenever the subscriber lived in another process (a reader in the same process is
    acknowledged at once, which is why a test with both in one process never saw it). A full
    history of one frame carries a heartbeat with every frame, and loses nothing: frame i is
    acknowledged before frame i + 1 replaces it.

Every timing waits for ``--wait-for-subscribers`` (default 1) matched subscriptions before the
first frame: a frame published before the subscriber is matched is lost to it. At recorded
timing the history holds ``QUEUE_DEPTH`` frames, so a frame the subscriber missed is resent
when it asks; the player counts a frame acknowledged once every matched reliable subscription
has acknowledged it. At the end it waits up to :data:`FINAL_ACK_TIMEOUT` for the last frames
(longer than Fast DDS's heartbeat period) and logs ``published N frames; M acknowledged``;
stopped with Ctrl-C (or SIGTERM) it logs the same, after waiting up to
:data:`STOP_ACK_TIMEOUT` for acknowledgements (a second Ctrl-C skips the wait).

Scene changes: a bag's ``scene`` arrays (:data:`~collision_sensor.model.sequences.SCENE_TOPIC`,
``--scene-topic``) are published on the relative topic ``scene`` (reliable, transient local,
as the node subscribes it), each just before the first frame at or after its time (the last
ones with the last frame). Two topics keep no order between them, so with
``--as-fast-as-possible`` the player keeps it by the node's answers on ``colliding_pairs``
(relative, remap it with the node's) and its ``scene`` status on ``/diagnostics`` (that of the
node in the player's namespace): before an array it waits for the verdicts on every frame
published so far, after it for the node's verdict on the array, or before the first frame
(nothing to answer with yet) for the status counting the array as applied or rejected.

Point clouds: a bag's ``sensor_msgs/PointCloud2`` topics (every one, or those of
``--cloud-topic``; ``--no-clouds`` for none) are published on the recorded topic made relative
(``/camera/points`` on ``camera/points``: a node with ``point_cloud_topics: [camera/points]``
in the player's namespace gets them; remap as any topic), reliable with a history of one cloud
(a best-effort subscription, as the node's sensor-data one, takes them too), ``header.stamp``
as ``--stamp`` says. At recorded timing each is published at its log time (when the recorder
got it: after its stamp by the camera's delay, so the node has the joint states around the
stamp to place it with, as live; a log time more than :data:`MAX_CLOUD_DELAY` after the stamp,
or before it, is taken as another clock's, and the cloud goes at its stamp); with ``--rate`` just after the first frame at or after its
stamp. With ``--as-fast-as-possible`` the same, kept in order with the frames by the node's
answers: before a cloud the player waits for the verdicts on every frame published so far,
after it for the node's verdict on the cloud (an accepted cloud is answered at once) or for
the node's status of that topic counting it (a refused one is not answered); the node's
answer on the cloud is then the offline checker's verdict on the frame it precedes
(``collision_sensor_check``, :mod:`collision_sensor.tools.recorded_clouds`). The clouds are read
from the bag one at a time as they are published.

The sequence is read before ROS starts, so a bad file fails fast with one line
``collision_sensor_play: error: ...`` on stderr and exit status 2.
"""
import argparse
import contextlib
import signal
import sys
import threading
import time
from typing import List, Optional, Sequence

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point
from sensor_msgs.msg import JointState, PointCloud2, PointField
from visualization_msgs.msg import Marker, MarkerArray

from collision_sensor.errors import CollisionSensorError, SequenceError
from collision_sensor.model.sequences import (
    DEFAULT_TOPIC, SCENE_TOPIC, JointSequence, SceneEvent, iter_cloud_messages, read_sequence)
from collision_sensor.ros.sensor_node import SCENE_QOS
from collision_sensor.tools.progress import MODES, ProgressBar

PROG = 'collision_sensor_play'
TOPIC = 'joint_states'
SCENE = 'scene'
QUEUE_DEPTH = 1000
ACK_TIMEOUT = 1.0        # s per wait; waiting goes on while subscribers are matched
SLOW_WARNING = 5.0       # s without an acknowledgement before the player says so
FINAL_ACK_TIMEOUT = 5.0  # s for the last frames' acknowledgements (Fast DDS heartbeat: 3 s)
STOP_ACK_TIMEOUT = 5.0   # s for them after Ctrl-C (a second Ctrl-C skips the wait)
_POLL = 0.05             # s between checks of the context while sleeping

#: Recorded timing and --rate: frames the writer keeps to resend (a subscriber that missed one).
PLAYBACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=QUEUE_DEPTH,
                          reliability=ReliabilityPolicy.RELIABLE)
#: --as-fast-as-possible: one frame, acknowledged before the next replaces it; a full history
#: makes Fast DDS ask for the acknowledgement with the frame itself (module docstring).
FAST_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                      reliability=ReliabilityPolicy.RELIABLE)
#: The node's verdicts, each one (the player counts them to keep scene arrays in order).
VERDICT_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
DIAGNOSTICS_DEPTH = 100
#: The scene status's counts that together count the arrays the node has handled.
SCENE_COUNTS = ('scene_arrays_applied_total', 'scene_arrays_rejected_total',
                'scene_arrays_dropped_total')
#: A point cloud status's counts that together count the clouds the node is done with (each
#: counted under the node's lock once the cloud is the obstacle, refused or passed over).
CLOUD_COUNTS = ('clouds_accepted_total', 'clouds_rejected_total', 'clouds_superseded_total',
                'clouds_dropped_total')
#: s to wait for the node's answer on a cloud with --as-fast-as-possible (its status on
#: /diagnostics, 1 Hz, answers a refused cloud), before the cloud is sent once more.
CLOUD_ANSWER_TIMEOUT = 3.0
#: s: a cloud logged later than this after its stamp is taken as logged on another clock.
MAX_CLOUD_DELAY = 1.0
#: s to wait for a subscriber on each cloud topic before the first frame.
CLOUD_MATCH_TIMEOUT = 5.0
#: Clouds: reliable (best-effort subscriptions take them too), one kept (each may be megabytes).
CLOUD_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE)


def frame_offsets(times: np.ndarray, rate: Optional[float] = None) -> np.ndarray:
    """Return when each frame is due, in seconds after playback starts.

    :param times: (n,) float recorded times, increasing.
    :param rate: frames per second, or None to follow the recorded times.
    :return: (n,) float, starting at 0.
    """
    times = np.asarray(times, dtype=np.float64)
    if rate is not None:
        return np.arange(len(times)) / float(rate)
    return times - times[0] if len(times) else times


def loop_period(offsets: np.ndarray) -> float:
    """Return the time from the first frame of one loop to the first of the next.

    The last frame stands as long as the median frame gap before the sequence restarts.
    """
    if len(offsets) < 2:
        return 1.0 if len(offsets) == 0 else max(float(offsets[-1]), 0.0) + 0.1
    return float(offsets[-1] + np.median(np.diff(offsets)))


def marker_message(marker) -> Marker:
    """Return an rclpy Marker with the fields the node reads taken from ``marker`` (a rosbags
    message read from a bag, or any object with visualization_msgs/Marker's fields)."""
    msg = Marker(ns=str(marker.ns), id=int(marker.id), type=int(marker.type),
                 action=int(marker.action), text=str(getattr(marker, 'text', '')),
                 mesh_resource=str(getattr(marker, 'mesh_resource', '')))
    msg.header.frame_id = str(marker.header.frame_id)
    position, orientation = marker.pose.position, marker.pose.orientation
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (
        float(position.x), float(position.y), float(position.z))
    msg.pose.orientation.x, msg.pose.orientation.y = float(orientation.x), float(orientation.y)
    msg.pose.orientation.z, msg.pose.orientation.w = float(orientation.z), float(orientation.w)
    msg.scale.x, msg.scale.y, msg.scale.z = (float(marker.scale.x), float(marker.scale.y),
                                             float(marker.scale.z))
    color = getattr(marker, 'color', None)
    if color is not None:
        msg.color.r, msg.color.g, msg.color.b, msg.color.a = (
            float(color.r), float(color.g), float(color.b), float(color.a))
    msg.points = [Point(x=float(p.x), y=float(p.y), z=float(p.z))
                  for p in getattr(marker, 'points', ())]
    return msg


def cloud_message(msg, stamp) -> PointCloud2:
    """Return an rclpy PointCloud2 with the fields of ``msg`` (a rosbags message read from a
    bag), stamped ``stamp``; the data are copied once."""
    out = PointCloud2(height=int(msg.height), width=int(msg.width),
                      fields=[PointField(name=str(f.name), offset=int(f.offset),
                                         datatype=int(f.datatype), count=int(f.count))
                              for f in msg.fields],
                      is_bigendian=bool(msg.is_bigendian), point_step=int(msg.point_step),
                      row_step=int(msg.row_step), is_dense=bool(msg.is_dense))
    out.header.stamp = stamp
    out.header.frame_id = str(msg.header.frame_id)
    out.data = np.asarray(msg.data, dtype=np.uint8).tobytes()
    return out


def cloud_after_frame(seq: JointSequence) -> np.ndarray:
    """Return, per cloud of ``seq``, the frame it is published after with ``--rate`` and
    ``--as-fast-as-possible``: the first frame at or after its stamp (the last frame for the
    later ones), -1 for those stamped before the first frame."""
    times = np.array([event.time for event in seq.clouds], dtype=np.float64)
    after = np.minimum(np.searchsorted(seq.times, times, side='left'), len(seq) - 1)
    return np.where(times < seq.times[0], -1, after)


def recorded_cloud_offsets(seq: JointSequence) -> np.ndarray:
    """Return when each cloud of ``seq`` is published at recorded timing, in seconds after
    the first frame: at its stamp plus the delay it was logged with (a log time before the
    stamp or more than :data:`MAX_CLOUD_DELAY` after it is another clock's, a bag of
    simulated time: no delay), never before the cloud before it."""
    stamps = np.array([e.time for e in seq.clouds], dtype=np.float64)
    delay = np.array([e.log_time for e in seq.clouds], dtype=np.float64) - stamps
    delay = np.where((delay >= 0.0) & (delay <= MAX_CLOUD_DELAY), delay, 0.0)
    return np.maximum.accumulate(stamps + delay - float(seq.times[0])) if len(stamps) \
        else stamps


def _stamp_from_seconds(seconds: float):
    from builtin_interfaces.msg import Time
    nanoseconds = int(round(seconds * 1e9))
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


class _Stop(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, named."""


class _Interrupts:
    """The player's SIGINT and SIGTERM handler: raises :class:`_Stop`, except while a frame is
    published and counted (:meth:`held`), where it waits for the end of that, so that the
    count printed on stopping is exactly what was published."""

    def __init__(self):
        self.holding = 0
        self.pending: Optional[str] = None

    def __call__(self, signum, frame):
        name = signal.Signals(signum).name
        if self.holding:
            self.pending = self.pending or name
            return
        raise _Stop(name)

    @contextlib.contextmanager
    def held(self):
        self.holding += 1
        try:
            yield
        finally:
            self.holding -= 1
            if not self.holding and self.pending:
                name, self.pending = self.pending, None
                raise _Stop(name)


_INTERRUPTS = _Interrupts()


class SequencePlayer:
    """Publishes the frames of a sequence from a node of its own.

    :param context: the rclpy context (initialised) the node lives in.
    :param fast: the writer of ``--as-fast-as-possible`` (:data:`FAST_QOS`), else
        :data:`PLAYBACK_QOS`.
    :ivar published: frames published.
    :ivar acknowledged: frames acknowledged by every reliable subscription matched when they
        were published (counted when :meth:`note_acknowledged` finds all acknowledged).
    :ivar unmatched: frames published while no subscription was matched (nobody got them).
    """

    def __init__(self, seq: JointSequence, context=None, stamp: str = 'now',
                 fast: bool = False):
        self.seq = seq
        self.context = context if context is not None else rclpy.get_default_context()
        self.node = Node('sequence_player', context=self.context)
        self.publisher = self.node.create_publisher(JointState, TOPIC,
                                                    FAST_QOS if fast else PLAYBACK_QOS)
        self.scene_publisher = (self.node.create_publisher(MarkerArray, SCENE, SCENE_QOS)
                                if seq.scene else None)
        self.cloud_publishers = {source: self.node.create_publisher(PointCloud2, source,
                                                                    CLOUD_QOS)
                                 for source in sorted({e.source for e in seq.clouds})}
        #: Clouds published, per source; clouds the node has handled, per topic (its status).
        self.clouds_published = {source: 0 for source in self.cloud_publishers}
        self.clouds_handled: dict = {}
        self._unheard: set = set()
        # The node's verdicts on frames (header frame_id empty) and on scene arrays (its root
        # frame), counted while scene arrays are played as fast as possible.
        self.frame_verdicts = self.scene_verdicts = 0
        #: Arrays the node has applied or rejected, from its scene status (None: none seen).
        self.scene_handled: Optional[int] = None
        self._executor = None
        if seq.scene or seq.clouds:
            self.node.create_subscription(DiagnosticArray, 'colliding_pairs', self._on_verdict,
                                          VERDICT_QOS)
            self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                          DIAGNOSTICS_DEPTH)
            self._executor = SingleThreadedExecutor(context=self.context)
            self._executor.add_node(self.node)
        self.stamp = stamp
        self.published = self.acknowledged = self.unmatched = 0
        self._names = list(seq.joint_names)
        self._scene_before = seq.scene_before()

    def destroy(self) -> None:
        """Destroy the node (and its publishers)."""
        if self._executor is not None:
            self._executor.shutdown()
        self.node.destroy_node()

    def _on_verdict(self, msg: DiagnosticArray) -> None:
        if msg.header.frame_id:
            self.scene_verdicts += 1
        else:
            self.frame_verdicts += 1

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        namespace = self.node.get_namespace().strip('/')
        for status in msg.status:
            node, _, kind = status.name.rpartition(': ')
            if node.rpartition('/')[0] != namespace:
                continue
            values = {item.key: item.value for item in status.values}
            if kind.startswith('point cloud '):
                try:
                    handled = sum(int(values[key]) for key in CLOUD_COUNTS)
                except (KeyError, ValueError):
                    continue
                topic = values.get('topic', '').lstrip('/')
                self.clouds_handled[topic] = max(handled, self.clouds_handled.get(topic, 0))
                continue
            if kind != 'scene':
                continue
            try:
                handled = sum(int(values[key]) for key in SCENE_COUNTS)
            except (KeyError, ValueError):
                continue
            self.scene_handled = max(handled, self.scene_handled or 0)

    def wait_for_verdicts(self, condition, timeout: Optional[float] = None) -> bool:
        """Spin the player's node until ``condition()`` holds (the node's answers counted);
        return False if ``timeout`` (s) passed first."""
        # Time is read from the clock: spin_once returns early for every message it takes.
        started, warned = time.monotonic(), False
        while not condition():
            self._ok()
            waited = time.monotonic() - started
            if timeout is not None and waited >= timeout:
                return False
            self._executor.spin_once(timeout_sec=_POLL)
            if waited >= SLOW_WARNING and not warned:
                self.node.get_logger().warning(
                    f'no verdict on colliding_pairs for {waited:.0f} s: is the node running, '
                    'and its colliding_pairs remapped as the player\'s (the node in the '
                    'player\'s namespace)?')
                warned = True
        return True

    def _ok(self) -> None:
        if not self.context.ok():
            raise ExternalShutdownException()

    def sleep_until(self, deadline: float) -> None:
        """Sleep until ``time.monotonic()`` reaches ``deadline``, watching for shutdown."""
        while True:
            self._ok()
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return
            time.sleep(min(remaining, _POLL))

    def wait_for_subscribers(self, count: int) -> None:
        """Block until ``count`` subscriptions are matched (0: return at once), then give each
        cloud topic up to :data:`CLOUD_MATCH_TIMEOUT` to be matched too (a cloud published
        before its best-effort subscriber is matched is lost to it)."""
        if count <= 0:
            return
        self._wait_for_joint_state_subscribers(count)
        deadline = time.monotonic() + CLOUD_MATCH_TIMEOUT
        waiting = dict(self.cloud_publishers)
        while waiting and time.monotonic() < deadline:
            waiting = {k: p for k, p in waiting.items() if not p.get_subscription_count()}
            self.sleep_until(time.monotonic() + _POLL)
        for publisher in waiting.values():
            self.node.get_logger().warning(f'no subscriber on {publisher.topic_name}: its clouds '
                                           'are published for nobody so far')

    def _wait_for_joint_state_subscribers(self, count: int) -> None:
        logged = False
        while self.publisher.get_subscription_count() < count:
            if not logged:
                self.node.get_logger().info(
                    f'waiting for {count} subscriber(s) on {self.publisher.topic_name}')
                logged = True
            self.sleep_until(time.monotonic() + _POLL)

    def warn_best_effort(self) -> None:
        """Warn about matched best-effort subscriptions (no delivery can be promised)."""
        infos = self.node.get_subscriptions_info_by_topic(self.publisher.topic_name)
        for info in infos:
            if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT:
                self.node.get_logger().warning(
                    f'subscriber "{info.node_namespace.rstrip("/")}/{info.node_name}" is '
                    'best-effort: it may miss frames; subscribe with reliable QoS')

    def publish_scene(self, event: SceneEvent) -> None:
        """Publish one recorded scene array on ``scene``."""
        self.scene_publisher.publish(MarkerArray(
            markers=[marker_message(marker) for marker in event.markers]))

    def play_scene_event(self, event: SceneEvent, in_order: bool,
                         timeout: Optional[float] = None) -> bool:
        """Publish a scene array; ``in_order``, wait for the node's answers that keep it in
        order with the frames (module doc). Return False if one did not come within
        ``timeout`` (s; each wait)."""
        if not in_order:
            self.publish_scene(event)
            return True
        if self.published:
            if not self.wait_for_verdicts(lambda: self.frame_verdicts >= self.published,
                                          timeout):
                return False
            answered = self.scene_verdicts
            self.publish_scene(event)
            return self.wait_for_verdicts(lambda: self.scene_verdicts > answered, timeout)
        # Before the first frame: the node's periodic status gives the count to wait beyond.
        if not self.wait_for_verdicts(lambda: self.scene_handled is not None, timeout):
            return False
        handled = self.scene_handled
        self.publish_scene(event)
        return self.wait_for_verdicts(lambda: self.scene_handled > handled, timeout)

    def publish_cloud(self, event, msg) -> None:
        """Publish one recorded cloud on its topic (made relative), stamped as ``--stamp``
        says."""
        stamp = (_stamp_from_seconds(event.time) if self.stamp == 'recorded'
                 else self.node.get_clock().now().to_msg())
        self.cloud_publishers[event.source].publish(cloud_message(msg, stamp))
        self.clouds_published[event.source] += 1

    def play_cloud(self, event, msg, in_order: bool, timeout: Optional[float] = None) -> bool:
        """Publish a cloud; ``in_order``, wait for the node's answers that keep it in order
        with the frames (module doc). Return False if one did not come within ``timeout``."""
        if msg is None:     # the bag's bytes did not deserialize: nothing to publish
            self.node.get_logger().warning(
                f'cloud on {event.source} at {event.time:.3f} s not published: {event.error}')
            return True
        publisher = self.cloud_publishers[event.source]
        if not in_order or not publisher.get_subscription_count():
            if in_order and event.source not in self._unheard:
                self._unheard.add(event.source)
                self.node.get_logger().warning(
                    f'no subscriber on {publisher.topic_name}: its clouds are published '
                    'without waiting for an answer (is the node\'s point_cloud_topics set to '
                    f'[{event.source}]?)')
            self.publish_cloud(event, msg)
            return True
        if self.published and not self.wait_for_verdicts(
                lambda: self.frame_verdicts >= self.published, timeout):
            return False
        if not self.published:
            self.publish_cloud(event, msg)
            return True     # before the first frame: the node drops it (no joint state yet)
        for attempt in range(2):
            answered = self.scene_verdicts
            self.publish_cloud(event, msg)
            count = self.clouds_published[event.source]
            if self.wait_for_verdicts(lambda: self.scene_verdicts > answered
                                      or self.clouds_handled.get(event.source, 0) >= count,
                                      CLOUD_ANSWER_TIMEOUT if timeout is None else timeout):
                return True
            # Best effort: a cloud the node's subscription never got (it had not yet matched
            # the player) is sent once more; one it got twice is the same obstacle again.
        self.node.get_logger().warning(
            f'no answer from the node on the cloud on {event.source} at {event.time:.3f} s '
            f'after {2 * CLOUD_ANSWER_TIMEOUT:g} s; going on (the order of the clouds and '
            'frames is not kept if it comes later)')
        return False

    def scene_events_before(self, index: int) -> list:
        """The scene events due before frame ``index`` (see JointSequence.scene_before)."""
        return self._scene_before[index]

    def publish_frame(self, index: int) -> None:
        """Publish frame ``index`` of the sequence."""
        msg = JointState()
        if self.stamp == 'recorded':
            msg.header.stamp = _stamp_from_seconds(float(self.seq.times[index]))
        else:
            msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.name = self._names
        msg.position = self.seq.positions[index].tolist()
        with _INTERRUPTS.held():    # a Ctrl-C here must not split publishing from counting
            if not self.publisher.get_subscription_count():
                self.unmatched += 1
            self.publisher.publish(msg)
            self.published += 1

    def note_acknowledged(self, timeout: float = 0.0) -> bool:
        """Wait up to ``timeout`` s for every frame so far to be acknowledged by every matched
        reliable subscription; count them acknowledged if so (not those published while no
        subscription was matched: nobody acknowledged them). Return whether they are."""
        delivered = self.published - self.unmatched
        if not self.publisher.wait_for_all_acked(Duration(seconds=timeout)):
            return False
        self.acknowledged = delivered
        return True

    def settle(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s, in short waits, for the frames not yet acknowledged."""
        deadline = time.monotonic() + timeout
        while not self.note_acknowledged(min(ACK_TIMEOUT / 10, max(0.0, deadline -
                                                                   time.monotonic()))):
            self._ok()
            if time.monotonic() >= deadline:
                return False
        return True

    def summary(self, stopped: Optional[str] = None) -> str:
        """Return what was published and acknowledged, in one line (``stopped``: by what)."""
        text = (f'published {self.published} frame{"s" * (self.published != 1)}; '
                f'{self.acknowledged} acknowledged by every matched reliable subscription')
        if self.context.ok():
            matched = self.publisher.get_subscription_count()
            text += f' ({matched} subscription{"s" * (matched != 1)} matched now)'
        if self.unmatched:
            text += (f'; {self.unmatched} published while no subscription was matched, '
                     'received by nobody')
        if self.acknowledged < self.published - self.unmatched:
            text += (f'; {self.published - self.unmatched - self.acknowledged} not '
                     'acknowledged (yet): a subscriber did not keep up, or left')
        return f'stopped ({stopped}): {text}' if stopped else text

    def wait_for_acknowledgement(self, publisher=None) -> None:
        """Block until every matched reliable subscription acknowledged all frames so far (or
        all messages of ``publisher``)."""
        waited = 0.0
        warned = False
        publisher = publisher or self.publisher
        delivered = self.published - self.unmatched
        while not publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)):
            self._ok()
            waited += ACK_TIMEOUT
            if waited >= SLOW_WARNING and not warned:
                self.node.get_logger().warning(
                    f'no acknowledgement for {waited:.0f} s: a subscriber is not keeping up')
                warned = True
        if publisher is self.publisher:
            self.acknowledged = delivered

    def play(self, rate: Optional[float] = None, fast: bool = False, loop: bool = False,
             progress_mode: str = 'auto') -> int:
        """Publish the whole sequence (forever with ``loop``); return frames published.

        :param rate: frames per second, or None for the recorded timing.
        :param fast: as fast as the subscribers acknowledge (``rate`` is ignored).
        """
        offsets = frame_offsets(self.seq.times, rate)
        period = loop_period(offsets)
        source = self.seq.source or 'sequence'
        round_index = 0
        start = time.monotonic()
        while True:
            label = f'{source.rsplit("/", 1)[-1]}' + (f' loop {round_index + 1}' if loop else '')
            clouds = _CloudCursor(self, offsets, rate, fast, start)
            with ProgressBar(len(self.seq), label=label, mode=progress_mode) as progress:
                for index in range(len(self.seq)):
                    clouds.play_before(index)
                    if fast:
                        self._ok()
                    else:
                        self.sleep_until(start + offsets[index])
                    for event in self.scene_events_before(index):
                        self.play_scene_event(event, fast)
                    self.publish_frame(index)
                    if fast:
                        self.wait_for_acknowledgement()
                    else:
                        self.note_acknowledged()
                    progress.update(index + 1)
                clouds.play_before(len(self.seq))
            if not loop:
                return self.published
            round_index += 1
            start = time.monotonic() if fast else start + period


class _CloudCursor:
    """The sequence's clouds in time order, read from the bag as they are published, each
    at its turn (module docstring): at recorded timing at its log time, else after the first
    frame at or after its stamp."""

    def __init__(self, player: SequencePlayer, offsets: np.ndarray, rate, fast: bool,
                 start: float):
        seq = player.seq
        self.player, self.fast, self.start = player, fast, start
        self.events = seq.clouds
        self.messages = iter_cloud_messages(seq.clouds) if seq.clouds else iter(())
        self.next = 0
        if rate is None and not fast and seq.clouds:
            self.when = recorded_cloud_offsets(seq)
            # (a cloud logged with a frame's time goes after it: the node then knows the state)
            self.due = lambda k, index: index >= len(offsets) or self.when[k] < offsets[index]
        else:
            after = cloud_after_frame(seq) if seq.clouds else np.zeros(0)
            self.when = np.array([offsets[max(a, 0)] for a in after.tolist()])
            self.due = lambda k, index: after[k] < index

    def play_before(self, index: int) -> None:
        """Publish the clouds due before frame ``index`` (``len(seq)``: the rest)."""
        player = self.player
        while self.next < len(self.events) and self.due(self.next, index):
            if not self.fast:
                player.sleep_until(self.start + self.when[self.next])
            event, msg = next(self.messages)
            player.play_cloud(event, msg, self.fast)
            self.next += 1


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before parsing)."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Publish a recorded joint-state sequence as sensor_msgs/JointState on '
                    '"joint_states" (remap with --ros-args -r joint_states:=NAME).',
        epilog='Timing: recorded (default), --rate, or --as-fast-as-possible: reliable QoS, '
               'waits for subscribers, and publishes each frame only after every matched '
               'reliable subscription acknowledged the previous one. Lossless for reliable '
               'KEEP_ALL subscriptions; a KEEP_LAST depth-N subscription loses frames only if '
               'it falls N frames behind; best-effort subscriptions get no promise. '
               'At the end, or on Ctrl-C, the player logs how many frames it published and '
               'how many every matched subscription acknowledged. '
               'Exit status: 0 done or interrupted, 2 error.')
    parser.add_argument('sequence', metavar='SEQUENCE',
                        help='CSV file or rosbag2 bag (directory, .mcap or .db3)')
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument('--rate', type=float, metavar='HZ', help='publish at a fixed rate')
    timing.add_argument('--as-fast-as-possible', action='store_true',
                        help='as fast as the subscribers acknowledge, without loss')
    parser.add_argument('--stamp', choices=('now', 'recorded'), default='now',
                        help='header.stamp: time of publishing (default) or recorded time')
    parser.add_argument('--loop', action='store_true', help='start again after the last frame')
    parser.add_argument('--start-delay', type=float, default=0.0, metavar='S',
                        help='seconds to wait before the first frame (after subscribers)')
    parser.add_argument('--wait-for-subscribers', type=int, default=1, metavar='N',
                        help='wait until N subscribers are matched before the first frame '
                             '(default %(default)s; 0: start at once, frames published before '
                             'a subscriber is matched are lost to it)')
    parser.add_argument('--joints', metavar='A,B,...',
                        help='the joints expected, comma-separated: CSV columns must be '
                             'exactly these; the message lists them in this order')
    parser.add_argument('--bag-topic', default=DEFAULT_TOPIC,
                        help='JointState topic to read from a bag (default %(default)s)')
    parser.add_argument('--scene-topic', default=SCENE_TOPIC,
                        help='MarkerArray topic of scene changes to read from a bag, '
                             'published on "scene" (default %(default)s)')
    parser.add_argument('--cloud-topic', metavar='TOPIC', action='append',
                        help='PointCloud2 topic to read from a bag and publish, made relative '
                             '(repeatable; default: every PointCloud2 topic of the bag)')
    parser.add_argument('--no-clouds', action='store_true',
                        help='publish none of the bag\'s point clouds')
    parser.add_argument('--progress', choices=MODES, default='auto',
                        help='progress bar on stderr: auto (on a terminal), always, never')
    return parser


def _error(message: str) -> int:
    print(f'{PROG}: error: {" ".join(str(message).split())}', file=sys.stderr)
    return 2


def main(argv: Optional[Sequence[str]] = None, context=None) -> int:
    """Run the player; return the exit status (0 done or interrupted, 2 error).

    :param argv: arguments without the program name (default ``sys.argv[1:]``), ROS
        arguments after ``--ros-args``.
    :param context: an rclpy Context to initialise and use (default: the global one).
    """
    argv: List[str] = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(remove_ros_args([PROG] + argv)[1:])
    except SystemExit as exit_request:
        return exit_request.code if isinstance(exit_request.code, int) else 2
    if args.rate is not None and not args.rate > 0.0:
        return _error(f'--rate {args.rate}: must be a positive number of frames per second')
    if args.start_delay < 0.0:
        return _error(f'--start-delay {args.start_delay}: must not be negative')
    joints = None
    if args.joints is not None:
        joints = [name.strip() for name in args.joints.split(',') if name.strip()]
        if not joints:
            return _error('--joints: give joint names separated by commas')
    if args.wait_for_subscribers < 0:
        return _error(f'--wait-for-subscribers {args.wait_for_subscribers}: must not be '
                      'negative (0: start at once)')
    if args.no_clouds and args.cloud_topic:
        return _error('--no-clouds and --cloud-topic contradict each other; give one')
    cloud_topics = () if args.no_clouds else (tuple(args.cloud_topic) if args.cloud_topic
                                              else None)
    try:
        seq = read_sequence(args.sequence, topic=args.bag_topic, joint_names=joints,
                            scene_topic=args.scene_topic, cloud_topics=cloud_topics)
    except SequenceError as err:
        return _error(str(err))

    # As a program (the default context, the main thread), Ctrl-C and SIGTERM are the
    # player's own: they raise KeyboardInterrupt with the context still up, so that the
    # acknowledgements can still be waited for and counted. rclpy's handlers would shut the
    # context down first, and a publisher of a shut-down context answers nothing.
    own_signals = context is None and threading.current_thread() is threading.main_thread()
    rclpy.init(args=[PROG] + argv, context=context,
               signal_handler_options=SignalHandlerOptions.NO if own_signals else None)
    if own_signals:
        signal.signal(signal.SIGINT, _INTERRUPTS)
        signal.signal(signal.SIGTERM, _INTERRUPTS)
    player = None
    try:
        player = SequencePlayer(seq, context=context, stamp=args.stamp,
                                fast=args.as_fast_as_possible)
        player.wait_for_subscribers(args.wait_for_subscribers)
        if args.as_fast_as_possible:
            player.warn_best_effort()
        player.sleep_until(time.monotonic() + args.start_delay)
        player.play(rate=args.rate, fast=args.as_fast_as_possible, loop=args.loop,
                    progress_mode=args.progress)
        # let reliable subscribers receive the last frames before the publisher goes away
        player.settle(FINAL_ACK_TIMEOUT)
        player.node.get_logger().info(player.summary())
    except (KeyboardInterrupt, ExternalShutdownException) as stop:
        if player is not None:
            _report_stop(player, stop)
    except CollisionSensorError as err:
        return _error(str(err))
    finally:
        if player is not None:
            player.destroy()
        rclpy.try_shutdown(context=context)
    return 0


def _report_stop(player: 'SequencePlayer', stop: BaseException) -> None:
    """Log what was published and acknowledged when playback was stopped."""
    stopped = (str(stop) or 'SIGINT') if isinstance(stop, KeyboardInterrupt) else 'shutdown'
    if player.context.ok():
        try:
            player.settle(STOP_ACK_TIMEOUT)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass            # stopped again: report what is known
    player.node.get_logger().info(player.summary(stopped))


if __name__ == '__main__':
    sys.exit(main())
