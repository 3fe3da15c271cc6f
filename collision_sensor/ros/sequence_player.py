"""The player's node: publishes a sequence's frames on ``joint_states``, its scene arrays on
``scene`` and its point clouds on their topics, each at its turn, and counts what every matched
subscription acknowledged (the rules: :mod:`collision_sensor.ros.player`).
"""
import contextlib
import signal
import time
from typing import Optional

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState, PointCloud2
from visualization_msgs.msg import MarkerArray

from collision_sensor.model.sequences import JointSequence, SceneEvent, iter_cloud_messages
from collision_sensor.ros.playback_messages import (
    cloud_message, marker_message, stamp_from_seconds)
from collision_sensor.ros.playback_schedule import (
    cloud_after_frame, frame_offsets, loop_period, recorded_cloud_offsets)
from collision_sensor.ros.scene_source import SCENE_QOS
from collision_sensor.tools.progress import ProgressBar

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
#: s to wait for a subscriber on each cloud topic before the first frame.
CLOUD_MATCH_TIMEOUT = 5.0
#: Clouds: reliable (best-effort subscriptions take them too), one kept (each may be megabytes).
CLOUD_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE)


class Stop(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, named."""


class Interrupts:
    """The player's SIGINT and SIGTERM handler: raises :class:`Stop`, except while a frame is
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
        raise Stop(name)

    @contextlib.contextmanager
    def held(self):
        self.holding += 1
        try:
            yield
        finally:
            self.holding -= 1
            if not self.holding and self.pending:
                name, self.pending = self.pending, None
                raise Stop(name)


#: The one handler of the player's process (installed by its command line).
INTERRUPTS = Interrupts()


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
        stamp = (stamp_from_seconds(event.time) if self.stamp == 'recorded'
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
            msg.header.stamp = stamp_from_seconds(float(self.seq.times[index]))
        else:
            msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.name = self._names
        msg.position = self.seq.positions[index].tolist()
        with INTERRUPTS.held():    # a Ctrl-C here must not split publishing from counting
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
