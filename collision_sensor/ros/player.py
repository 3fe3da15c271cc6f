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
    as fast as the subscribers keep up, without loss. The publisher is reliable (depth
    ``QUEUE_DEPTH``), playback starts once ``--wait-for-subscribers`` (default 1)
    subscriptions are matched, and frame i + 1 is published only when
    ``publisher.wait_for_all_acked()`` reports that every matched reliable subscription has
    acknowledged frame i. Why that loses nothing: a reliable reader acknowledges a frame once
    it holds it in its history, and the next frame is sent only then, so no frame is lost in
    transit; a ``KEEP_ALL`` subscription never evicts a frame it has not taken, so it receives
    every frame, in order (``test/test_player.py`` checks this). A ``KEEP_LAST`` subscription
    of depth N evicts its oldest frame when its callback falls N frames behind: it is lossless
    only while it keeps within N (DDS acknowledges receipt, not processing, so no publisher can
    do better). Best-effort subscriptions (``qos_profile_sensor_data``) never acknowledge and
    may lose any frame; the player warns when one is matched.

The sequence is read before ROS starts, so a bad file fails fast with one line
``collision_sensor_play: error: ...`` on stderr and exit status 2.
"""
import argparse
import sys
import time
from typing import List, Optional, Sequence

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState

from collision_sensor.errors import CollisionSensorError, SequenceError
from collision_sensor.model.sequences import DEFAULT_TOPIC, JointSequence, read_sequence
from collision_sensor.tools.progress import MODES, ProgressBar

PROG = 'collision_sensor_play'
TOPIC = 'joint_states'
QUEUE_DEPTH = 1000
ACK_TIMEOUT = 1.0        # s per wait; waiting goes on while subscribers are matched
SLOW_WARNING = 5.0       # s without an acknowledgement before the player says so
FINAL_ACK_TIMEOUT = 2.0  # s granted to subscribers for the last frames before exiting
_POLL = 0.05             # s between checks of the context while sleeping

PLAYBACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=QUEUE_DEPTH,
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


def _stamp_from_seconds(seconds: float):
    from builtin_interfaces.msg import Time
    nanoseconds = int(round(seconds * 1e9))
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


class SequencePlayer:
    """Publishes the frames of a sequence from a node of its own.

    :param context: the rclpy context (initialised) the node lives in.
    """

    def __init__(self, seq: JointSequence, context=None, stamp: str = 'now'):
        self.seq = seq
        self.context = context if context is not None else rclpy.get_default_context()
        self.node = Node('sequence_player', context=self.context)
        self.publisher = self.node.create_publisher(JointState, TOPIC, PLAYBACK_QOS)
        self.stamp = stamp
        self.published = 0
        self._names = list(seq.joint_names)

    def destroy(self) -> None:
        """Destroy the node (and its publisher)."""
        self.node.destroy_node()

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
        """Block until ``count`` subscriptions are matched (0: return at once)."""
        if count <= 0:
            return
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

    def publish_frame(self, index: int) -> None:
        """Publish frame ``index`` of the sequence."""
        msg = JointState()
        if self.stamp == 'recorded':
            msg.header.stamp = _stamp_from_seconds(float(self.seq.times[index]))
        else:
            msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.name = self._names
        msg.position = self.seq.positions[index].tolist()
        self.publisher.publish(msg)
        self.published += 1

    def wait_for_acknowledgement(self) -> None:
        """Block until every matched reliable subscription acknowledged all frames so far."""
        waited = 0.0
        warned = False
        while not self.publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)):
            self._ok()
            waited += ACK_TIMEOUT
            if waited >= SLOW_WARNING and not warned:
                self.node.get_logger().warning(
                    f'no acknowledgement for {waited:.0f} s: a subscriber is not keeping up')
                warned = True

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
            with ProgressBar(len(self.seq), label=label, mode=progress_mode) as progress:
                for index in range(len(self.seq)):
                    if fast:
                        self._ok()
                    else:
                        self.sleep_until(start + offsets[index])
                    self.publish_frame(index)
                    if fast:
                        self.wait_for_acknowledgement()
                    progress.update(index + 1)
            if not loop:
                return self.published
            round_index += 1
            start = time.monotonic() if fast else start + period


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
    parser.add_argument('--wait-for-subscribers', type=int, default=None, metavar='N',
                        help='wait until N subscribers are matched (default: 1 with '
                             '--as-fast-as-possible, else 0)')
    parser.add_argument('--joints', metavar='A,B,...',
                        help='the joints expected, comma-separated: CSV columns must be '
                             'exactly these; the message lists them in this order')
    parser.add_argument('--bag-topic', default=DEFAULT_TOPIC,
                        help='JointState topic to read from a bag (default %(default)s)')
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
    try:
        seq = read_sequence(args.sequence, topic=args.bag_topic, joint_names=joints)
    except SequenceError as err:
        return _error(str(err))
    subscribers = args.wait_for_subscribers
    if subscribers is None:
        subscribers = 1 if args.as_fast_as_possible else 0

    rclpy.init(args=[PROG] + argv, context=context)
    player = None
    try:
        player = SequencePlayer(seq, context=context, stamp=args.stamp)
        player.wait_for_subscribers(subscribers)
        if args.as_fast_as_possible:
            player.warn_best_effort()
        player.sleep_until(time.monotonic() + args.start_delay)
        count = player.play(rate=args.rate, fast=args.as_fast_as_possible, loop=args.loop,
                            progress_mode=args.progress)
        # let reliable subscribers receive the last frames before the publisher goes away
        player.publisher.wait_for_all_acked(Duration(seconds=FINAL_ACK_TIMEOUT))
        player.node.get_logger().info(f'published {count} frames')
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except CollisionSensorError as err:
        return _error(str(err))
    finally:
        if player is not None:
            player.destroy()
        rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
