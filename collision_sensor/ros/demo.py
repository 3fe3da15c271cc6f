"""``collision_sensor_demo`` (``make demo``): the collision sensor at work on the demo cell.

With no arguments it

1. starts ``collision_sensor_node`` as a process of its own on the bundled demo cell (the arm,
   its SRDF and the washer scene; ``joint_states_qos: reliable``), in the namespace
   ``/collision_sensor_demo``, and waits until it is ready: its ``ready:`` log line (the robot
   loaded, its trees built, the query run once) and its joint_states subscription matched.
   However long that takes (a large robot's trees, a busy machine) the demo waits, saying so
   every :data:`PROGRESS_PERIOD` seconds, as long as the node process lives; it fails, with
   the node's output above, only if the node exits, or after ``--timeout`` seconds when one is
   given;
2. plays the paper's experiment (``config/sequences/paper_experiment.csv``) into it with the
   player's :class:`~collision_sensor.ros.player.SequencePlayer`, at the recorded timing, header
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
"""
import argparse
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.errors import CollisionSensorError

PROG = 'collision_sensor_demo'
DEFAULT_SEQUENCE = 'paper_experiment'
DYNAMIC_SEQUENCE = 'moving_part'
MOTION_SEQUENCE = 'guard_rail_5hz'
CAMERA_SEQUENCE = 'person_in_path'
NAMESPACE = '/collision_sensor_demo'
NODE_NAME = 'collision_sensor'          # the node's default name
START_TIMEOUT = None    # s for the node to be ready; None: as long as the node process lives
PROGRESS_PERIOD = 15.0  # s between "still starting" lines while the node starts
READY_MARK = 'ready: checking '   # the node's one line once it subscribes to joint_states
VERDICT_TIMEOUT = 60.0  # s for one verdict (generous: a busy machine, a large robot)
DIAGNOSTICS_WAIT = 3.0  # s to wait at the end for the last /diagnostics period
STOP_TIMEOUT = 10.0     # s for the node to exit on SIGINT before it is killed
_POLL = 0.05            # s between checks while waiting

Pair = Tuple[str, str]


class DemoError(CollisionSensorError):
    """The demo could not run: the node did not come up, died, or gave no verdict."""


# -- the environment --------------------------------------------------------------------------

def set_ros_environment(environ=os.environ) -> List[str]:
    """Keep DDS local: SHM transport, and a random domain unless one is set.

    Changes ``environ`` in place (the node process inherits it) and returns what was chosen
    here, in words.
    """
    notes = []
    if not environ.get('FASTDDS_BUILTIN_TRANSPORTS'):
        environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'SHM'
        notes.append('the SHM transport')
    if not environ.get('ROS_DOMAIN_ID'):
        environ['ROS_DOMAIN_ID'] = str(random.SystemRandom().randint(1, 100))
        notes.append('a random ROS_DOMAIN_ID')
    return notes


def node_command() -> List[str]:
    """Return the command that runs ``collision_sensor_node`` of this very install (venv, pip
    or colcon: :func:`collision_sensor.ros.console_scripts.console_command`), never one that
    happens to be on PATH."""
    from collision_sensor.ros.console_scripts import console_command
    return console_command('collision_sensor_node')


def demo_cell_parameters(motion: bool = False, camera: bool = False) -> Dict[str, object]:
    """Return the node parameters that load the bundled demo cell, with reliable input and
    instant verdicts unless ``motion`` (``check_motion`` off: the demo's summary is compared
    with the offline check's, which checks each frame's instant); ``camera``: the node takes
    the demo camera's clouds (``point_cloud_topics``)."""
    from collision_sensor.model.share import config_path
    parameters = {'urdf_path': config_path('demo_arm.urdf'),
                  'srdf_path': config_path('demo_arm.srdf'),
                  'scene_path': config_path('demo_scene.yaml'),
                  'joint_states_qos': 'reliable', 'check_motion': motion}
    if camera:
        from collision_sensor.tools.demo_camera import CLOUD_TOPIC
        parameters['point_cloud_topics'] = f'[{CLOUD_TOPIC}]'
    return parameters


# -- the node process -------------------------------------------------------------------------

class NodeProcess:
    """``collision_sensor_node`` in a process of its own; its log lines are echoed, prefixed.

    :param parameters: ``{name: value}`` given as ``-p name:=value``.
    :param namespace: the node's namespace.
    :param echo: where the node's lines go (``None``: kept in :attr:`lines` only).
    """

    def __init__(self, parameters: Dict[str, str], namespace: str, echo=sys.stdout):
        command = node_command() + ['--ros-args', '-r', f'__ns:={namespace}']
        for name, value in parameters.items():
            command += ['-p', f'{name}:={value}']
        env = dict(os.environ)
        env.setdefault('RCUTILS_CONSOLE_OUTPUT_FORMAT', '[{severity}] {message}')
        env.setdefault('PYTHONUNBUFFERED', '1')
        self.lines: List[str] = []
        self.ready = threading.Event()
        self._echo = echo
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, env=env)
        self._reader = threading.Thread(target=self._read, name='node output', daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            line = line.rstrip('\n')
            self.lines.append(line)
            if READY_MARK in line:
                self.ready.set()
            if self._echo is not None:
                print(f'  node | {line}', file=self._echo, flush=True)

    def exited(self) -> Optional[int]:
        """Return the exit status if the process has ended, else None."""
        return self.process.poll()

    def stop(self) -> int:
        """Stop the node with SIGINT (as Ctrl-C would), killing it if it hangs; return status.

        What the node prints from here on is kept in :attr:`lines` but not echoed.
        """
        self._echo = None
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(2.0)
        return self.process.returncode


# -- what the node reports --------------------------------------------------------------------

@dataclass
class CheckTime:
    """The node's check times summed over /diagnostics periods."""

    checks: int = 0
    total_ms: float = 0.0
    max_ms: float = 0.0

    def add(self, values: Dict[str, str]) -> None:
        checks = int(values.get('checks', '0') or 0)
        if checks:
            self.checks += checks
            self.total_ms += checks * float(values.get('check_time_mean_ms', '0') or 0.0)
            self.max_ms = max(self.max_ms, float(values.get('check_time_max_ms', '0') or 0.0))


@dataclass
class Verdicts:
    """Verdicts and check times received by the listener, shared with the main thread.

    ``pairs`` holds the verdicts on frames (their header is the frame's, frame_id empty): the
    pairs in contact at the frame, and (with ``check_motion``) ``met`` those met on the way into
    it, with the fraction of the motion where (``first_contact``; ``None`` when none);
    ``scene_verdicts`` counts those the node gives on applying a scene array or a cloud
    (header frame_id: the robot's root frame), whose pairs are in ``root_pairs``. A failure
    entry (no pair: ``kind`` names it, e.g. ``point_cloud_timeout``) is not a pair: each
    verdict's are counted in ``failures``; a verdict of failures only on the root frame (a
    source timed out) is no answer to a scene array or cloud.
    ``cloud_status``: the values of the node's /diagnostics status named ``cloud_status_name``
    (a point cloud source), the last period's.
    """

    status_name: str
    cloud_status_name: str = ''
    pairs: List[Tuple[int, Tuple[Pair, ...]]] = field(default_factory=list)
    met: List[Tuple[Tuple[Pair, ...], Optional[float]]] = field(default_factory=list)
    scene_verdicts: int = 0
    root_pairs: List[Tuple[Pair, ...]] = field(default_factory=list)
    failures: Dict[str, int] = field(default_factory=dict)
    check_time: CheckTime = field(default_factory=CheckTime)
    cloud_status: Dict[str, str] = field(default_factory=dict)
    condition: threading.Condition = field(default_factory=threading.Condition)

    def on_colliding_pairs(self, msg) -> None:
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        now, met, at, failed = [], [], None, []
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if ':' not in status.name:
                failed.append(status.name)
                continue
            pair = tuple(status.name.split(':', 1))
            if 'first_contact' in values:
                met.append(pair)
                at = float(values['first_contact'])
            else:
                now.append(pair)
        with self.condition:
            for kind in failed:
                self.failures[kind] = self.failures.get(kind, 0) + 1
            if msg.header.frame_id:
                if now or not failed:
                    self.scene_verdicts += 1
                    self.root_pairs.append(tuple(now))
            else:
                self.pairs.append((stamp_ns, tuple(now)))
                self.met.append((tuple(met), at))
            self.condition.notify_all()

    def on_diagnostics(self, msg) -> None:
        for status in msg.status:
            if status.name == self.status_name:
                with self.condition:
                    self.check_time.add({kv.key: kv.value for kv in status.values})
                    self.condition.notify_all()
            elif self.cloud_status_name and status.name == self.cloud_status_name:
                with self.condition:
                    self.cloud_status = {kv.key: kv.value for kv in status.values}
                    self.condition.notify_all()

    def wait(self, predicate, timeout: float) -> bool:
        """Wait until ``predicate()`` holds (under the lock); False after ``timeout`` s."""
        with self.condition:
            return self.condition.wait_for(predicate, timeout)


def scene_lines(t: float, markers, shown: Dict[str, str]) -> List[str]:
    """Return the lines for one scene array at time ``t`` (s): what it changed, one per object
    that appears, is attached, dropped or removed. ``shown`` maps each object to its last
    state printed (updated); plain moves print nothing."""
    lines = []
    for marker in markers:
        name = marker.ns if marker.id == 0 else f'{marker.ns}/{marker.id}'
        if marker.action == 3:      # DELETEALL
            state, name = 'removed with everything from the topic', '*'
            shown.clear()
        elif marker.action == 2:
            state = 'removed'
            shown.pop(name, None)
        else:
            frame = marker.header.frame_id
            touch = f', may touch {marker.text}' if frame and marker.text else ''
            state = (f'attached to {frame}{touch}' if frame
                     else 'dropped in the world' if shown.get(name, '').startswith('attached')
                     else 'in the world')
            if shown.get(name) == state:
                continue
            shown[name] = state
        lines.append(f'  {t:7.3f} s  scene    {name}: {state}')
    return lines


def pairs_text(pairs: Sequence[Pair]) -> str:
    return ', '.join(f'{a} -- {b}' for a, b in pairs)


def change_lines(t: float, before: Sequence[Pair], after: Sequence[Pair]) -> List[str]:
    """Return the lines for a change of the colliding set at time ``t`` (s): one per pair."""
    entering = [pair for pair in after if pair not in before]
    leaving = [pair for pair in before if pair not in after]
    if not before and after:
        state = 'CONTACT'
    elif before and not after:
        state = 'clear'
    else:
        state = ''
    lines = []
    for sign, pair in [('+', p) for p in entering] + [('-', p) for p in leaving]:
        lines.append(f'  {t:7.3f} s  {state:<8} {sign} {pair[0]} -- {pair[1]}')
        state = ''
    return lines


def motion_line(t: float, now: Sequence[Pair], met: Sequence[Pair],
                first_contact: Optional[float]) -> str:
    """One frame side by side: the pairs in contact at it (what an instant check reports),
    then what the motion into it met on the way (``check_motion``)."""
    instant = f'CONTACT {pairs_text(now)}' if now else 'clear'
    if met:
        motion = f'CONTACT {pairs_text(met)} at {first_contact:.2f} of the way'
    else:
        motion = 'CONTACT (in contact at the frame)' if now else 'clear'
    return f'  {t:7.3f} s  {instant:<26} {motion}'


def motion_summary_lines(seq, verdicts: 'Verdicts') -> List[str]:
    """The motion summary: motions in contact, and those between two clear frames (which
    checks of the recorded states alone miss)."""
    n = len(seq)
    t0 = float(seq.times[0]) if n else 0.0
    frames = [pairs for _, pairs in verdicts.pairs[:n]]
    met = verdicts.met[:n]
    missed = [i for i in range(1, n) if met[i][0] and not frames[i - 1] and not frames[i]]
    lines = [f'summary of {seq.source}',
             f'  frames:                 {n}; in contact at the frame (instant checks): '
             f'{sum(bool(p) for p in frames)}',
             f'  motions between frames: {max(n - 1, 0)}; meeting contact on the way: '
             f'{sum(bool(m) for m, _ in met[1:])}, of which between two clear frames: '
             f'{len(missed)}']
    for i in missed:
        pairs, at = met[i]
        when = seq.times[i - 1] - t0 + at * (seq.times[i] - seq.times[i - 1])
        lines.append(f'    frames {i - 1} -> {i}: {pairs_text(pairs)} at {when:.3f} s '
                     '(missed by instant checks)')
    contact = any(frames) or any(m for m, _ in met)
    lines.append('  result: ' + ('COLLISION' if contact else 'clear')
                 + (' (on the way only)' if contact and not any(frames) else ''))
    return lines


# -- the camera (--camera) ---------------------------------------------------------------------

CLOUD_VERDICT_TIMEOUT = 10.0   # s for the node's verdict on one cloud (a lost or refused cloud)


@dataclass
class CameraRecord:
    """One verdict in camera mode: at ``t`` (s from the first frame), on the arm's state then,
    answering a frame (``cloud`` None) or cloud number ``cloud``; ``person``: how far the arm
    truly is from the person (m, <= 0 in contact; inf: more than 10 cm)."""

    t: float
    pairs: Tuple[Pair, ...]
    cloud: Optional[int]
    person: float


class CameraFeed:
    """The demo's depth camera: renders the cell (:class:`CameraCell`) at a cloud's time and
    publishes it as ``sensor_msgs/PointCloud2``; keeps what the sensor said beside the truth.

    :param seq: the sequence the arm plays (the clouds' times span it, ``rate`` per second).
    :param size: ``(width, height)`` pixels.
    :param rate: clouds per second of the recording.
    """

    def __init__(self, seq, size: Tuple[int, int], rate: float):
        from collision_sensor.tools.demo_camera import (
            CAMERA_OPTICAL_FRAME, CLOUD_TOPIC, CameraCell)
        self.cell = CameraCell(size)
        self.seq, self.rate, self.size = seq, float(rate), (int(size[0]), int(size[1]))
        self.topic, self.frame = CLOUD_TOPIC, CAMERA_OPTICAL_FRAME
        self.source = f'cloud/{CLOUD_TOPIC}'
        t0, t1 = float(seq.times[0]), float(seq.times[-1])
        self.times = t0 + np.arange(int(math.floor((t1 - t0) * self.rate + 1e-9)) + 1) / self.rate
        self.sent = 0
        self.render_seconds = 0.0
        self.valid_points = 0
        self.records: List[CameraRecord] = []
        self.publisher = None

    def start(self, node) -> None:
        """Create the publisher on ``node`` (sensor-data QoS, as the node subscribes)."""
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import PointCloud2
        self.publisher = node.create_publisher(PointCloud2, self.topic, qos_profile_sensor_data)

    def due(self, t: float) -> List[int]:
        """The clouds not sent yet whose time is at most ``t`` (s, recorded time)."""
        end = int(np.searchsorted(self.times, t + 1e-9, side='right'))
        return list(range(self.sent, max(end, self.sent)))

    def state_at(self, t: float) -> np.ndarray:
        """The arm's joint values at ``t`` (linear between frames, as the node places a
        cloud)."""
        seq = self.seq
        return np.array([np.interp(t, seq.times, seq.positions[:, j])
                         for j in range(len(seq.joint_names))])

    def publish(self, k: int) -> None:
        """Render cloud ``k`` and publish it, stamped with its time."""
        from sensor_msgs.msg import PointCloud2, PointField
        from std_msgs.msg import Header
        t = float(self.times[k])
        started = time.perf_counter()
        points = self.cell.render(self.seq.joint_names, self.state_at(t))
        self.render_seconds += time.perf_counter() - started
        self.valid_points += int(np.isfinite(points).all(axis=1).sum())
        width, height = self.size
        stamp_ns = _stamp_ns(t)
        header = Header(frame_id=self.frame)
        header.stamp.sec, header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        fields = [PointField(name=axis, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, axis in enumerate('xyz')]
        self.publisher.publish(PointCloud2(
            header=header, height=height, width=width, fields=fields, is_bigendian=False,
            point_step=12, row_step=12 * width,
            data=np.ascontiguousarray(points, dtype='<f4').tobytes(), is_dense=False))
        self.sent = k + 1

    def record(self, t: float, pairs: Tuple[Pair, ...], cloud: Optional[int], q,
               previous: Tuple[Pair, ...]) -> List[str]:
        """Keep one verdict at state ``q``; return the lines of its change of pairs."""
        person = self.cell.clearance(self.seq.joint_names, q).person
        self.records.append(CameraRecord(t, pairs, cloud, person))
        if pairs == previous:
            return []
        lines = change_lines(t, previous, pairs)
        by = 'frame' if cloud is None else f'cloud {cloud}'
        lines[0] += f'   ({by}; the arm {_person_text(person)})'
        return lines

    def summary_lines(self, played: float, verdicts: 'Verdicts', diagonal: float) -> List[str]:
        """The camera summary: clouds, the node's filter, contacts against the truth."""
        seq, records, n = self.seq, self.records, len(self.seq)
        frames = [r for r in records if r.cloud is None]
        clouds = [r for r in records if r.cloud is not None]
        width, height = self.size
        lines = [f'summary of {seq.source} (camera {width} x {height} at {self.rate:g} Hz in '
                 f'{self.frame}, clouds on {self.topic})',
                 f'  frames:              {n} played in {played:.2f} s, {len(frames)} verdicts',
                 f'  clouds:              {self.sent} rendered by ray casting (mean '
                 f'{1e3 * self.render_seconds / max(self.sent, 1):.1f} ms each, '
                 f'{self.valid_points / max(self.sent, 1):.0f} of {width * height} points, '
                 f'the rest NaN), sent, {len(clouds)} answered by a verdict at once']
        status = verdicts.cloud_status
        if status:
            lines.append(f'  the node\'s filter (/diagnostics, a cloud of the last period): '
                         f'{status.get("points_in")} points in, {status.get("points_invalid")} '
                         f'NaN, {status.get("points_self_filtered")} self-filtered (the arm\'s), '
                         f'{status.get("points_kept")} kept in {status.get("voxels_kept")} voxels'
                         f'; clouds accepted {status.get("clouds_accepted_total")}, rejected '
                         f'{status.get("clouds_rejected_total")}')
        spans: Dict[Pair, List[float]] = {}
        for r in records:
            for pair in r.pairs:
                span = spans.setdefault(pair, [r.t, r.t, 0])
                span[1], span[2] = r.t, span[2] + 1
        if spans:
            width_ = max(len(f'{a} -- {b}') for a, b in spans)
            lines.append('  pairs in contact (times from the first frame):')
            for (a, b), (first, last, count) in sorted(spans.items(), key=lambda s: s[1][0]):
                lines.append(f'    {a + " -- " + b:<{width_}}  first {first:7.3f} s  '
                             f'last {last:7.3f} s  {count:4d} verdicts')
        else:
            lines.append('  pairs in contact:    none')
        hits = [r for r in records if any(self.source in pair for pair in r.pairs)]
        touching = [r for r in frames if r.person <= 0.0]
        if touching:
            inside = [r for r in records if r.person <= 0.0]
            seen = sum(any(self.source in pair for pair in r.pairs) for r in inside)
            lines.append(f'  the person (in no scene file): the arm in contact at '
                         f'{len(touching)} frames, {touching[0].t:.3f} s to {touching[-1].t:.3f} s'
                         f'; contact with the cloud in {seen} of the {len(inside)} verdicts '
                         'meanwhile (the person\'s points within the self-filter\'s padding of '
                         'the arm go with the arm\'s: docs/point_clouds.md, what a cloud can '
                         'tell)')
        else:
            lines.append('  the person (in no scene file): the arm never touches it')
        if hits:
            first = hits[0]
            by = 'a frame' if first.cloud is None else f'cloud {first.cloud}'
            lines.append(f'  first contact with the cloud: {first.t:.3f} s ({by}\'s verdict), '
                         f'{pairs_text([p for p in first.pairs if self.source in p])}; the arm '
                         f'{_person_text(first.person)}')
        else:
            lines.append('  first contact with the cloud: none')
        away = [r for r in records if r.person > diagonal]
        false = [r for r in away if any(self.source in pair for pair in r.pairs)]
        lines.append(f'  the arm farther than {1e3 * diagonal:.0f} mm (a voxel\'s diagonal) from '
                     f'the person: {sum(r.cloud is None for r in away)} frame and '
                     f'{sum(r.cloud is not None for r in away)} cloud verdicts, '
                     f'{len(false)} of them with contact with the cloud'
                     + (': the self-filter kept the arm\'s own points out' if not false else
                        ' (points that are not the person\'s were kept)'))
        for kind, count in sorted(verdicts.failures.items()):
            lines.append(f'  fail-safe entries {kind}: {count} verdicts')
        if verdicts.check_time.checks:
            check = verdicts.check_time
            lines.append(f'  node check time (/diagnostics): mean '
                         f'{check.total_ms / check.checks:.3f} ms, max {check.max_ms:.3f} ms '
                         f'over {check.checks} checks')
        lines.append('  result: ' + ('COLLISION' if spans else 'clear')
                     + (' (with the camera\'s cloud only: no scene file holds the person)'
                        if spans and all(self.source in pair for pair in spans) else ''))
        return lines


def _person_text(distance: float) -> str:
    if distance <= 0.0:
        return 'touches the person'
    if math.isinf(distance):
        return 'more than 10 cm from the person'
    return f'{1e3 * distance:.0f} mm from the person'


# -- the run ----------------------------------------------------------------------------------

def summary_lines(seq, verdicts: Sequence[Tuple[Pair, ...]], played: float,
                  check_time: CheckTime) -> List[str]:
    """Return the summary: frames, frames in collision, each pair's span, the node's check time.

    :param verdicts: the colliding pairs the node reported, one tuple per frame of ``seq``.
    :param played: seconds the playing took.
    """
    from collision_sensor.tools.offline_check import FrameResult, pair_spans

    n = len(seq)
    t0 = float(seq.times[0]) if n else 0.0
    results = [FrameResult(i, float(seq.times[i]), bool(pairs), tuple(pairs), 0.0)
               for i, pairs in enumerate(verdicts)]
    colliding = sum(r.in_collision for r in results)
    lines = [f'summary of {seq.source}',
             f'  frames:              {n} played in {played:.2f} s, {len(results)} verdicts',
             f'  frames in collision: {colliding} of {n}'
             + (f' ({100.0 * colliding / n:.1f} %)' if n else '')]
    spans = pair_spans(results)
    if spans:
        width = max(len(f'{a} -- {b}') for a, b in (s.pair for s in spans))
        lines.append('  pairs in contact (times from the first frame):')
        for s in spans:
            name = f'{s.pair[0]} -- {s.pair[1]}'
            lines.append(f'    {name:<{width}}  first {s.first - t0:7.3f} s  '
                         f'last {s.last - t0:7.3f} s  {s.frames:4d} frames')
    else:
        lines.append('  pairs in contact:    none')
    if check_time.checks:
        lines.append(f'  node check time (/diagnostics): mean '
                     f'{check_time.total_ms / check_time.checks:.3f} ms, max '
                     f'{check_time.max_ms:.3f} ms over {check_time.checks} checks')
    else:
        lines.append('  node check time: no /diagnostics report received')
    lines.append('  result: ' + ('COLLISION' if colliding else 'clear'))
    return lines



def wait_until_ready(node, publisher, pairs_sub, timeout: Optional[float], say,
                     progress_period: float = PROGRESS_PERIOD) -> float:
    """Wait until the node is ready and matched both ways; return the seconds it took.

    Ready: the node logged its ``ready:`` line (it subscribes to joint_states only after the
    robot is loaded, its trees built and the query run once), ``publisher`` (joint_states) has
    a subscriber and ``pairs_sub`` (colliding_pairs) a publisher.

    :param node: the :class:`NodeProcess`.
    :param timeout: seconds, or ``None`` to wait as long as the node process lives.
    :param say: prints one line.
    :raises DemoError: the node exited first, or ``timeout`` passed.
    """
    started = time.monotonic()
    next_progress = started + progress_period
    while not (node.ready.is_set() and publisher.get_subscription_count() >= 1
               and pairs_sub.get_publisher_count() >= 1):
        status = node.exited()
        if status is not None:
            raise DemoError(f'collision_sensor_node exited with status {status} before it was '
                            'ready (its output is above)')
        now = time.monotonic()
        if timeout is not None and now - started > timeout:
            raise DemoError(f'collision_sensor_node did not subscribe to '
                            f'{publisher.topic_name} within {timeout:g} s (--timeout); it is '
                            'still starting: wait longer, or leave --timeout out to wait as '
                            'long as it runs')
        if now >= next_progress:
            next_progress += progress_period
            say(f'still waiting for collision_sensor_node to be ready ({now - started:.0f} s; '
                'the first start compiles the engine, which takes a minute or more on a busy '
                'machine) ...')
        time.sleep(_POLL)
    return time.monotonic() - started


def _stamp_ns(seconds: float) -> int:
    # as player._stamp_from_seconds rounds it
    return int(round(seconds * 1e9))


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

    from collision_sensor.ros.player import SequencePlayer, frame_offsets

    def say(text=''):
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
            if stamp_ns != _stamp_ns(float(seq.times[index])):
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


# -- the command line -------------------------------------------------------------------------

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
                        help='the camera\'s image in pixels (default %(default)s; ray casting '
                             '320x240 costs about four times as much)')
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
        return describe_panda()
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


# -- the Panda overview (--describe-panda) ----------------------------------------------------

_SHOWN_LINKS = ('panda_link4', 'panda_link7', 'panda_hand', 'panda_hand_tcp',
                'panda_leftfinger')


def describe_panda() -> int:
    """Load the Panda and print its tree, collision elements and a few link poses.

    :return: the exit status: 0 on success, 2 when example-robot-data is missing, 1 on a
        description error.
    """
    from collision_sensor.engine.kinematics import build_kinematic_tree
    from collision_sensor.model.example_robots import example_robot
    from collision_sensor.model.robot_model import load_urdf
    from collision_sensor.model.srdf import load_srdf_for_model

    try:
        panda = example_robot('panda')
    except CollisionSensorError as exc:  # example-robot-data is not installed
        print(f'{PROG}: {exc} (or `pip install -e ".[test]"`)', file=sys.stderr)
        return 2
    try:
        model = load_urdf(panda.urdf, panda.package_paths)
        tree = build_kinematic_tree(model)
        srdf = load_srdf_for_model(panda.srdf, model)
    except CollisionSensorError as exc:
        print(f'{PROG}: {exc}', file=sys.stderr)
        return 1

    print(f'robot "{model.name}" from {model.source}')
    print(f'{len(model.links)} links, {len(model.joints)} joints, '
          f'{len(tree.joint_names)} variables: {", ".join(tree.joint_names)}')
    print('\nkinematic tree:')
    _print_tree(model)

    print('\ncollision elements (one sub-group each):')
    for link in model.links:
        elements = [element for element in model.elements if element.link == link]
        if not elements:
            print(f'  {link}: none')
        for element in elements:
            print(f'  {link} [{element.index}] {element.name}: {element.source}, '
                  f'{len(element.faces)} triangles, {len(element.vertices)} vertices')
    total = sum(len(element.faces) for element in model.elements)
    print(f'  {len(model.elements)} elements, {total} triangles in all')

    state = srdf.group_states['default']
    q = np.array([state['joints'].get(name, 0.0) for name in tree.joint_names])
    T_world_link = tree.forward_kinematics(q)
    print(f'\nlink poses at SRDF group_state "default" (group "{state["group"]}"), in the '
          f'frame of "{model.root_link}":')
    print('  q = ' + ', '.join(f'{name}={value:g}' for name, value in zip(tree.joint_names, q)))
    np.set_printoptions(precision=4, suppress=True)
    for link in _SHOWN_LINKS:
        T = T_world_link[tree.link_names.index(link)]
        print(f'  {link}: position {T[:3, 3]}, z axis {T[:3, 2]}')
    print(f'\n{len(srdf.disabled_pairs)} link pairs disabled by the SRDF')
    return 0


def _print_tree(model):
    children = {}
    for joint in model.joints:
        children.setdefault(joint.parent, []).append(joint)

    def show(link, depth):
        for joint in children.get(link, []):
            indent = '  ' * (depth + 1)
            print(f'{indent}{joint.child}  <- {joint.name} ({joint.type}{_limits(joint)})')
            show(joint.child, depth + 1)

    print(f'  {model.root_link}')
    show(model.root_link, 1)


def _limits(joint):
    text = ''
    if joint.type in ('revolute', 'prismatic'):
        text = f' [{joint.lower:g}, {joint.upper:g}]'
    if joint.mimic is not None:
        text += (f', mimics {joint.mimic.joint} x{joint.mimic.multiplier:g} '
                 f'{joint.mimic.offset:+g}')
    return text


if __name__ == '__main__':
    sys.exit(main())
