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

    The writer keeps a history of one frame here
    (:data:`~collision_sensor.ros.sequence_player.FAST_QOS`), and that is what makes it fast
    across processes. A reliable reader acknowledges only in answer to the writer's HEARTBEAT.
    Fast DDS 2.14.5 (the Jazzy wheels) sends one every ``heartbeatPeriod`` (3 s by default), or
    along with a sample when the writer's history is full; ``wait_for_all_acked`` itself asks
    for nothing (it does from Fast DDS 2.14.6 on, eProsima/Fast-DDS#6098). With a longer
    history every frame would wait for the periodic heartbeat whenever the subscriber lives in
    another process (a reader in the same process is acknowledged at once). A full history of
    one frame carries a heartbeat with every frame, and loses nothing: frame i is acknowledged
    before frame i + 1 replaces it.

Every timing waits for ``--wait-for-subscribers`` (default 1) matched subscriptions before the
first frame: a frame published before the subscriber is matched is lost to it. At recorded
timing the history holds :data:`~collision_sensor.ros.sequence_player.QUEUE_DEPTH` frames, so a
frame the subscriber missed is resent when it asks; the player counts a frame acknowledged once
every matched reliable subscription has acknowledged it. At the end it waits up to
:data:`~collision_sensor.ros.sequence_player.FINAL_ACK_TIMEOUT` for the last frames (longer
than Fast DDS's heartbeat period) and logs ``published N frames; M acknowledged``; stopped with
Ctrl-C (or SIGTERM) it logs the same, after waiting up to
:data:`~collision_sensor.ros.sequence_player.STOP_ACK_TIMEOUT` for acknowledgements (a second
Ctrl-C skips the wait).

Scene changes: a bag's ``scene`` arrays (:data:`~collision_sensor.model.sequences.SCENE_TOPIC`,
``--scene-topic``) are published on the relative topic ``scene`` (reliable, transient local,
as the node subscribes it), each just before the first frame at or after its time (the last
ones with the last frame). Two topics keep no order between them, so with
``--as-fast-as-possible`` the player keeps it by the node's answers on ``colliding_pairs``
(relative, remap it with the node's) and its ``scene`` status on ``/diagnostics`` (that of the
node in the player's namespace): before an array it waits for the verdicts on every frame
published so far, after it for the node's verdict on the array, or before the first frame
(nothing to answer with yet) for the status counting the array as applied or rejected.

Point clouds: a bag's ``sensor_msgs/PointCloud2`` topics (every one, or those of ``--cloud-topic``;
``--no-clouds`` for none) are published on the recorded topic made relative (``/camera/points`` on
``camera/points``: a node with ``point_cloud_topics: [camera/points]`` in the player's namespace
gets them; remap as any topic), reliable with a history of one cloud (a best-effort subscription,
as the node's sensor-data one, takes them too), ``header.stamp`` as ``--stamp`` says. At recorded
timing each is published at its log time (when the recorder got it: after its stamp by the camera's
delay, so the node has the joint states around the stamp to place it with, as live; a log time more
than :data:`~collision_sensor.ros.playback_schedule.MAX_CLOUD_DELAY` after the stamp, or before it,
is taken as another clock's, and the cloud goes at its stamp); with ``--rate`` just after the first
frame at or after its stamp. With ``--as-fast-as-possible`` the same, kept in order with the frames
by the node's answers: before a cloud the player waits for the verdicts on every frame published so
far, after it for the node's verdict on the cloud (an accepted cloud is answered at once) or for
the node's status of that topic counting it (a refused one is not answered); the node's answer on
the cloud is then the offline checker's verdict on the frame it precedes
(``collision_sensor_check``, :mod:`collision_sensor.tools.recorded_clouds`). The clouds are read
from the bag one at a time as they are published.

The sequence is read before ROS starts, so a bad file fails fast with one line
``collision_sensor_play: error: ...`` on stderr and exit status 2.
"""
import argparse
import signal
import sys
import threading
import time
from typing import List, Optional, Sequence

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from collision_sensor.errors import CollisionSensorError, SequenceError
from collision_sensor.model.sequences import DEFAULT_TOPIC, SCENE_TOPIC, read_sequence
from collision_sensor.ros.sequence_player import (
    FINAL_ACK_TIMEOUT, INTERRUPTS, STOP_ACK_TIMEOUT, SequencePlayer)
from collision_sensor.tools.progress import MODES

PROG = 'collision_sensor_play'


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
        signal.signal(signal.SIGINT, INTERRUPTS)
        signal.signal(signal.SIGTERM, INTERRUPTS)
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
