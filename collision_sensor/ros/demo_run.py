"""One run of the demo: start the node, play a sequence into it frame by frame (each answered
before the next), print what it reports, then the summary.
"""
import math
import os
import signal
import sys
import threading
import time
from typing import Dict, Optional, Tuple

from collision_sensor.ros.demo_camera_feed import CLOUD_VERDICT_TIMEOUT, CameraFeed
from collision_sensor.ros.demo_node_process import (
    OUTPUT_LOCK, START_TIMEOUT, DemoError, NodeProcess, demo_cell_parameters, wait_until_ready)
from collision_sensor.ros.demo_verdicts import (
    Pair, Verdicts, change_lines, motion_line, motion_summary_lines, scene_lines,
    stamp_nanoseconds,
    summary_lines)

PROG = 'collision_sensor_demo'
NAMESPACE = '/collision_sensor_demo'
NODE_NAME = 'collision_sensor'          # the node's default name
VERDICT_TIMEOUT = 60.0  # s for one verdict (generous: a busy machine, a large robot)
DIAGNOSTICS_WAIT = 3.0  # s to wait at the end for the last /diagnostics period


def run_demo(seq, namespace: str = NAMESPACE, rate: Optional[float] = None, fast: bool = False,
             start_timeout: float = START_TIMEOUT, verdict_timeout: float = VERDICT_TIMEOUT,
             out=sys.stdout, motion: bool = False,
             camera: Optional[CameraFeed] = None) -> int:
    """Start the node, play ``seq`` into it, print contacts and the summary; return 0.

    :param seq: the :class:`~collision_sensor.model.sequences.JointSequence` to play.
    :param rate: frames per second instead of the recorded timing.
    :param fast: no timing: each frame as soon as the previous verdict is in.
    :param motion: the node checks the motion into each frame (``check_motion``); each frame
        is printed with the instant's verdict beside the motion's.
    :param camera: the depth camera (``--camera``): its clouds go to the node between the
        frames, each answered before the next frame.
    :raises DemoError: the node did not come up, died or gave no verdict in time.
    """
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    from collision_sensor.ros.playback_schedule import frame_offsets
    from collision_sensor.ros.sequence_player import SequencePlayer

    def say(text=''):
        with OUTPUT_LOCK:
            print(text, file=out, flush=True)

    n = len(seq)
    t0 = float(seq.times[0]) if n else 0.0
    node_status = (f'{namespace.strip("/")}/{NODE_NAME}' if namespace.strip('/')
                   else NODE_NAME)
    verdicts = Verdicts(status_name=f'{node_status}: collision sensor',
                        cloud_status_name=(f'{node_status}: point cloud {camera.topic}'
                                           if camera is not None else ''))
    every_verdict = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                               reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL)
    diagnostics_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                                 reliability=ReliabilityPolicy.RELIABLE)

    say(f'starting collision_sensor_node on the demo cell (namespace {namespace}) ...')
    node = NodeProcess(demo_cell_parameters(motion, camera is not None), namespace, echo=out)
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '-r', f'__ns:={namespace}'], context=context)
    executor = SingleThreadedExecutor(context=context)
    player = listener = spinner = None
    try:
        listener = rclpy.create_node('collision_sensor_demo', context=context)
        pairs_sub = listener.create_subscription(DiagnosticArray, 'colliding_pairs',
                                                 verdicts.on_colliding_pairs, every_verdict)
        listener.create_subscription(DiagnosticArray, '/diagnostics', verdicts.on_diagnostics,
                                     diagnostics_qos)
        executor.add_node(listener)

        def spin():
            try:
                executor.spin()
            except ExternalShutdownException:
                pass
        spinner = threading.Thread(target=spin, name='demo executor', daemon=True)
        spinner.start()
        player = SequencePlayer(seq, context=context, stamp='recorded')
        if camera is not None:
            camera.start(listener)

        started = time.monotonic()
        wait_until_ready(node, player.publisher, pairs_sub, start_timeout, say)
        if camera is not None:
            wait_until_ready(node, camera.publisher, pairs_sub, start_timeout, say)
        timing = ('as fast as the node answers' if fast else f'{rate:g} frames/s' if rate
                  else 'recorded timing')
        say(f'node up after {time.monotonic() - started:.1f} s; playing '
            f'{os.path.basename(seq.source)} ({n} frames, {seq.duration:.2f} s, {timing})')
        say()
        if camera is not None:
            width, height = camera.size
            say(f'camera: {width} x {height} depth image at {camera.rate:g} Hz from '
                f'{camera.frame}, clouds on {listener.resolve_topic_name(camera.topic)}; '
                'a person the scene file does not hold stands in the arm\'s path')
        if motion:
            say('     time  the frame alone (instant)  the motion into it (check_motion)')
        else:
            say('     time  state    change of the colliding pairs (as the node reports them)')

        offsets = frame_offsets(seq.times, rate)
        start = time.monotonic()
        previous: Tuple[Pair, ...] = ()
        shown: Dict[str, str] = {}
        for index in range(n):
            if not fast:
                player.sleep_until(start + offsets[index])
            for event in player.scene_events_before(index):
                # In order with the frames: the node answers each array before the next frame.
                if not player.play_scene_event(event, in_order=True, timeout=verdict_timeout):
                    raise DemoError(f'collision_sensor_node did not answer the scene array at '
                                    f'{event.time - t0:.3f} s within {verdict_timeout:g} s')
                for line in scene_lines(event.time - t0, event.markers, shown):
                    say(line)
            player.publish_frame(index)
            if not verdicts.wait(lambda: len(verdicts.pairs) > index, verdict_timeout):
                status = node.exited()
                reason = (f'exited with status {status}' if status is not None
                          else f'gave no verdict within {verdict_timeout:g} s')
                raise DemoError(f'collision_sensor_node {reason} on frame {index} '
                                f'(t = {seq.times[index] - t0:.3f} s) of {seq.source}')
            stamp_ns, pairs = verdicts.pairs[index]
            if stamp_ns != stamp_nanoseconds(float(seq.times[index])):
                raise DemoError(f'verdict {index} answers the frame stamped {stamp_ns * 1e-9:.9f}'
                                f' s, expected {seq.times[index]:.9f} s: verdicts out of order')
            if camera is not None:
                t = float(seq.times[index])
                for line in camera.record(t - t0, pairs, None, seq.positions[index], previous):
                    say(line)
                previous = pairs
                for k in camera.due(t):
                    # The cloud of time times[k] <= t: the node has the states around it.
                    answered = len(verdicts.root_pairs)
                    camera.publish(k)
                    if not verdicts.wait(lambda: len(verdicts.root_pairs) > answered,
                                         CLOUD_VERDICT_TIMEOUT):
                        status = node.exited()
                        if status is not None:
                            raise DemoError(f'collision_sensor_node exited with status '
                                            f'{status} on cloud {k}')
                        say(f'  {t - t0:7.3f} s  cloud {k}: no verdict within '
                            f'{CLOUD_VERDICT_TIMEOUT:g} s (lost or refused: see the node\'s '
                            'lines above)')
                        continue
                    pairs = verdicts.root_pairs[answered]
                    for line in camera.record(t - t0, pairs, k, seq.positions[index],
                                              previous):
                        say(line)
                    previous = pairs
            elif motion:
                met, at = verdicts.met[index]
                say(motion_line(float(seq.times[index]) - t0, pairs, met, at))
            elif pairs != previous:
                for line in change_lines(float(seq.times[index]) - t0, previous, pairs):
                    say(line)
                previous = pairs
        played = time.monotonic() - start
        # The check times of the last frames are in the next /diagnostics period.
        verdicts.wait(lambda: verdicts.check_time.checks >= n, DIAGNOSTICS_WAIT)

        say()
        # A cloud's contact reaches at most a voxel's diagonal beyond its points (the node's
        # default point_cloud_voxel_size).
        from collision_sensor.engine.checker_config import CheckerConfig
        diagonal = math.sqrt(3.0) * CheckerConfig().voxel_size
        lines = (camera.summary_lines(played, verdicts, diagonal) if camera is not None else
                 motion_summary_lines(seq, verdicts) if motion else
                 summary_lines(seq, [pairs for _, pairs in verdicts.pairs[:n]], played,
                               verdicts.check_time))
        for line in lines:
            say(line)
        if seq.scene:
            say(f'  scene arrays:        {len(seq.scene)} published, {verdicts.scene_verdicts} '
                'answered by a verdict at once')
        return 0
    finally:
        if player is not None:
            player.destroy()
        rclpy.try_shutdown(context=context)
        if spinner is not None:
            spinner.join(2.0)
        executor.shutdown()
        if listener is not None:
            listener.destroy_node()
        status = node.stop()
        if status not in (0, None, -signal.SIGINT):
            print(f'{PROG}: collision_sensor_node exited with status {status}', file=out)
