"""``collision_sensor_demo`` (``make demo``): the collision sensor at work on the demo cell.

With no arguments it

1. starts ``collision_sensor_node`` as a process of its own on the bundled demo cell (the arm,
   its SRDF and the washer scene; ``joint_states_qos: reliable``), in the namespace
   ``/collision_sensor_demo``, and waits until it is ready: its ``ready:`` log line (the robot
   loaded, its trees built, the query run once) and its joint_states subscription matched.
   However long that takes (a large robot's trees, a busy machine) the demo waits, saying so
   every :data:`~collision_sensor.ros.demo_node_process.PROGRESS_PERIOD` seconds, as long as
   the node process lives; it fails, with the node's output above, only if the node exits, or
   after ``--timeout`` seconds when one is given;
2. plays the paper's experiment (``config/sequences/paper_experiment.csv``) into it with the
   player's :class:`~collision_sensor.ros.sequence_player.SequencePlayer`, at the recorded timing, header
   stamps set to the recorded times;
3. prints a line whenever the set of colliding pairs the node reports on ``colliding_pairs``
   changes (the time, the pairs entering ``+`` and leaving ``-``), and at the end a summary:
   frames, frames in collision, each pair's first and last time, and the node's own check time
   from ``/diagnostics``.

Lossless and in order: frame i + 1 is published only after the node's verdict on frame i has
arrived (the verdict topics are depth 1, so a faster publisher could make a listener miss
verdicts); when the recorded timing is slower than that, the timing wins. Every verdict is
matched to its frame by its header stamp.

DDS stays on this machine and out of the way: ``FASTDDS_BUILTIN_TRANSPORTS=SHM`` and a random
``ROS_DOMAIN_ID`` (1-100) unless they are set (the Makefile sets 42). The node inherits both.

``--dynamic`` plays the dynamic scene instead (``config/sequences/moving_part``, a bag of
joint states and ``scene`` arrays, made by ``scripts/demo_cell.py``):
each scene array is published on the node's ``scene`` topic before the frames it precedes, and
the next frame waits for the node's answer to it (as ``collision_sensor_play`` keeps the order);
a line says what it changed (an object appearing, attached to a link, dropped, removed; plain
moves are counted, not printed).

``--motion`` runs the node with ``check_motion`` on and plays ``guard_rail_5hz`` (a 5 Hz
recording of the arm swinging its tool over a 1 cm guard rail: every recorded frame is clear,
one motion between two of them goes through the rail) and prints, frame by frame, what the
frame alone says (the pairs in contact at the state, what an instant check reports) beside what
the motion into it says (the pairs met on the way, with where), then how many motions in
contact lay between two clear frames.

``--camera`` adds a depth camera to the cell and a person to the world: the camera is a fixed
link of the arm's URDF (``camera_optical_frame``, above and behind the base), the person a
cylinder standing in the arm's path that is in no scene file. The demo renders what the camera
sees by ray casting (:class:`~collision_sensor.tools.demo_camera.CameraCell`: the arm at its
state, the washer, the floor and the person; 160 x 120 at 15 Hz of the recording unless
``--camera-size`` and ``--camera-rate`` say otherwise) and publishes each organised cloud
(``sensor_msgs/PointCloud2``, x y z float32, NaN where nothing is within 4 m) in the camera's
frame on ``camera/depth/points``, the node's ``point_cloud_topics``, stamped with the time it
shows, while the arm plays ``person_in_path`` (``config/sequences/person_in_path.csv``, or
``--sequence``). A cloud at time
t is published once the joint states up to t are answered (the node places it with the state at
its stamp) and the next frame waits for the node's verdict on it. The lines say when pairs with
``cloud/camera/depth/points`` come and go, with how far the arm truly is from the person (the
rendering world's distance); the summary adds the clouds, the node's filter figures from
/diagnostics, the first contact with the cloud and what the sensor said while the arm was
farther from the person than a voxel's diagonal (where a contact with the cloud could only come
from the arm's own points, had the self-filter let them through).

Exit status: 0 done, 1 the node failed (did not come up, died, gave no verdict), 2 bad
arguments or sequence, 130 interrupted. ``--describe-panda`` keeps the first demo: the Panda's
kinematic tree, collision elements and a few link poses (needs example-robot-data).

The pieces: :mod:`~collision_sensor.ros.demo_node_process` (the node as a process),
:mod:`~collision_sensor.ros.demo_run` (one run), :mod:`~collision_sensor.ros.demo_verdicts`
(what the node reports and the lines about it), :mod:`~collision_sensor.ros.demo_camera_feed`
(``--camera``), :mod:`~collision_sensor.tools.robot_overview` (``--describe-panda``).
"""
import argparse
import os
import sys
from typing import Optional, Sequence, Tuple

from collision_sensor.errors import CollisionSensorError
from collision_sensor.ros.demo_camera_feed import CameraFeed
from collision_sensor.ros.demo_node_process import START_TIMEOUT, DemoError, set_ros_environment
from collision_sensor.ros.demo_run import NAMESPACE, PROG, run_demo

DEFAULT_SEQUENCE = 'paper_experiment'
DYNAMIC_SEQUENCE = 'moving_part'
MOTION_SEQUENCE = 'guard_rail_5hz'
CAMERA_SEQUENCE = 'person_in_path'


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Start collision_sensor_node on the bundled demo cell, play a recorded '
                    'sequence into it and print the contacts it reports.',
        epilog='DDS: FASTDDS_BUILTIN_TRANSPORTS=SHM and a random ROS_DOMAIN_ID unless set. '
               'Exit status: 0 done, 1 the node failed, 2 bad arguments, 130 interrupted.')
    parser.add_argument('--sequence', default=None, metavar='NAME|PATH',
                        help='a bundled sequence (paper_experiment, into_drum_clear, random, '
                             'moving_part, guard_rail_5hz, person_in_path) or a CSV file or bag '
                             f'of the demo arm (default {DEFAULT_SEQUENCE}, with --dynamic '
                             f'{DYNAMIC_SEQUENCE}, with --motion {MOTION_SEQUENCE}, with '
                             f'--camera {CAMERA_SEQUENCE})')
    parser.add_argument('--dynamic', action='store_true',
                        help='the dynamic scene: a crate on a conveyor picked up, carried and '
                             'dropped, a fixture in the way (objects on the node\'s scene '
                             f'topic); plays {DYNAMIC_SEQUENCE}')
    parser.add_argument('--motion', action='store_true',
                        help='the node checks the motion between frames (check_motion): each '
                             "frame's instant verdict beside the motion's; plays "
                             f'{MOTION_SEQUENCE}, a 5 Hz recording whose frames are all clear '
                             'while one motion goes through a guard rail')
    parser.add_argument('--camera', action='store_true',
                        help='a depth camera on a link of the arm renders the cell, a person '
                             'the scene file does not hold among it; its clouds go to the '
                             'node (point_cloud_topics): contact with cloud/... when the arm '
                             f'reaches the person, its own points filtered out; plays '
                             f'{CAMERA_SEQUENCE}')
    parser.add_argument('--camera-size', default='160x120', metavar='WxH',
                        help='the camera\'s image in pixels (default %(default)s; '
                             'the cost of rendering grows with the pixels)')
    parser.add_argument('--camera-rate', type=float, default=15.0, metavar='HZ',
                        help='clouds per second of the recording (default %(default)g)')
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument('--rate', type=float, metavar='HZ',
                        help='publish at a fixed rate instead of the recorded timing')
    timing.add_argument('--as-fast-as-possible', action='store_true',
                        help='publish each frame as soon as the verdict on the last one is in')
    parser.add_argument('--namespace', default=NAMESPACE,
                        help='namespace of the node and the demo (default %(default)s)')
    parser.add_argument('--timeout', type=float, default=START_TIMEOUT, metavar='S',
                        help='seconds for the node to be ready (default: as long as the node '
                             'process runs)')
    parser.add_argument('--describe-panda', action='store_true',
                        help='instead: print the Panda of example-robot-data as the robot '
                             'model layer reads it (tree, collision elements, poses)')
    return parser


def _camera_size(text: str) -> Optional[Tuple[int, int]]:
    """``'160x120'`` -> (160, 120); None when it is no size of 8 to 1280 pixels a side."""
    parts = text.lower().split('x')
    if len(parts) != 2 or not all(part.strip().isdigit() for part in parts):
        return None
    width, height = (int(part) for part in parts)
    return (width, height) if 8 <= width <= 1280 and 8 <= height <= 1280 else None


def _error(message: str, status: int) -> int:
    print(f'{PROG}: error: {" ".join(str(message).split())}', file=sys.stderr)
    return status


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the demo; return the exit status (0 done, 1 node failure, 2 bad input, 130 Ctrl-C)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_request:
        return exit_request.code if isinstance(exit_request.code, int) else 2
    if args.describe_panda:
        from collision_sensor.tools.robot_overview import describe_panda
        return describe_panda(PROG)
    if args.rate is not None and not args.rate > 0.0:
        return _error(f'--rate {args.rate}: must be a positive number of frames per second', 2)
    if sum((args.dynamic, args.motion, args.camera)) > 1:
        return _error('--dynamic, --motion and --camera are demos of their own: give one', 2)
    size = _camera_size(args.camera_size)
    if size is None:
        return _error(f'--camera-size {args.camera_size!r}: give width x height in pixels, '
                      'each 8 to 1280, e.g. 160x120', 2)
    if not 0.0 < args.camera_rate <= 100.0:
        return _error(f'--camera-rate {args.camera_rate:g}: give clouds per second, more than '
                      '0 and at most 100', 2)

    from collision_sensor.model.sequences import read_sequence
    from collision_sensor.tools.offline_check import bundled_sequence_path
    try:
        name = args.sequence or (DYNAMIC_SEQUENCE if args.dynamic else
                                 MOTION_SEQUENCE if args.motion else
                                 CAMERA_SEQUENCE if args.camera else DEFAULT_SEQUENCE)
        seq = read_sequence(bundled_sequence_path(name))
    except CollisionSensorError as err:
        return _error(str(err), 2)
    if len(seq) == 0:
        return _error(f'{seq.source}: no frames', 2)

    chosen = set_ros_environment()
    print(f'DDS: ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, '
          f'FASTDDS_BUILTIN_TRANSPORTS={os.environ["FASTDDS_BUILTIN_TRANSPORTS"]}'
          + (f' (set here: {", ".join(chosen)})' if chosen else ''), flush=True)
    try:
        camera = CameraFeed(seq, size, args.camera_rate) if args.camera else None
    except CollisionSensorError as err:
        return _error(str(err), 2)
    try:
        return run_demo(seq, namespace=args.namespace, rate=args.rate,
                        fast=args.as_fast_as_possible, start_timeout=args.timeout,
                        motion=args.motion, camera=camera)
    except DemoError as err:
        return _error(str(err), 1)
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
