"""Fuzz the running node with hostile joint states and check every verdict it gives.

Run ``python -m benchmarks.fuzz --messages 20000``. The node runs as a user runs it:
``collision_sensor_node`` in a process of its own on the Panda of example-robot-data
(``joint_states_qos: reliable``, the joint-limit policy of ``--joint-limit-policy``). This
process publishes ``--messages`` joint states at ``--rate``, half valid (random full states
within the limits) and half malformed, cycling through :data:`MALFORMED`: length mismatch,
duplicate names, NaN and inf, huge values (1e9, 9.2e18, 1.7e308), unknown names (a few, floods
of ``--flood`` new names, names with newlines and control characters that try to forge a log
line), empty and velocity-only messages, and oversized ones (:data:`OVERSIZED_NAMES` new names,
above the node's ``max_joint_state_bytes``: rejected before decoding). The node runs with
``overload_policy: every``: every accepted message must get its verdict, so one superseded on
a busy machine counts as lost here.

Each message carries a unique header stamp, which the node copies into its answer: every
message is answered. This process keeps its own
:class:`~benchmarks.joint_state_oracle.JointStateMerger` with the node's settings to
know what the node must answer: for an accepted message that completes the state, the node's
colliding pairs are compared with a fresh ``CollisionChecker.check`` here, on the merged state,
followed by the pairs met on the way that ``CollisionChecker.check_motion`` finds from the state
checked before (the node's default ``check_motion``);
a rejected one (or one the engine refuses) must be answered by a ``joint_state_rejected`` entry,
one that cannot be checked yet by ``waiting_for_joints``, and one that changes nothing (no
position, no joint of the robot) by the verdict of the state held. It reports, per message
class: sent, answers expected, of them verdicts of a checked state, received, lost (expected,
never came), unexpected (came for no message sent) and wrong (answer differs); the node's
resident memory (``VmRSS`` of ``/proc/PID/status``, sampled every 0.1 s), its own counters from
``/diagnostics`` (every message received, skipped ones counted by reason), its output checked
for forged log lines (every line must start as rcutils writes a log line, and none may start
the way the injected names do), and its exit status after SIGINT.

Exit status 0 when nothing was lost, unexpected, wrong or forged and the node exited cleanly,
else 1. ``--json PATH`` writes the report. DDS stays in shared memory
(``FASTDDS_BUILTIN_TRANSPORTS=SHM``) in ``ROS_DOMAIN_ID`` (a random one if unset).
"""
import argparse
import collections
import json
import math
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from collision_sensor.ros.console_scripts import console_command
from collision_sensor.ros.node_parameters import MAX_JOINT_STATE_BYTES

os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))

#: The malformed classes, in the order they are cycled through.
MALFORMED = ('length_mismatch', 'duplicate_names', 'nan', 'inf', 'huge_1e9', 'huge_9.2e18',
             'huge_1.7e308', 'unknown_names', 'unknown_flood', 'control_char_names',
             'only_control_char_names', 'empty', 'velocity_only', 'oversized')
#: New unknown names in an ``oversized`` message: far above the node's max_joint_state_bytes.
OVERSIZED_NAMES = 20_000
#: The node's answers to a message it refuses, and to one it cannot check yet (their
#: ``colliding_pairs`` failure entries, see ``collision_sensor.ros.verdicts``).
REJECTED = (('joint_state_rejected',),)
WAITING = (('waiting_for_joints',),)
#: What an injected name tries to make the node print as a line of its own.
FORGED_PREFIX = '[ERROR] [0.000000000] [collision_sensor]: FORGED'
#: How rcutils starts every line it writes (the default RCUTILS_CONSOLE_OUTPUT_FORMAT).
LOG_LINE = re.compile(r'^\[(DEBUG|INFO|WARN|ERROR|FATAL)\] \[\d+\.\d+\] \[[^\]\n]+\]: ')
READY_MARK = 'ready: checking '
VERDICT_WAIT = 30.0     # s without a new verdict before the missing ones count as lost


@dataclass
class ClassStats:
    """Counts of one message class."""

    sent: int = 0
    expected: int = 0
    checked: int = 0
    received: int = 0
    lost: int = 0
    unexpected: int = 0
    wrong: int = 0


@dataclass
class Report:
    """What one fuzz run found; see the module docstring."""

    messages: int
    policy: str
    classes: Dict[str, ClassStats] = field(default_factory=dict)
    wrong_examples: List[dict] = field(default_factory=list)
    rss_kib: List[int] = field(default_factory=list)
    rss_at_ready_kib: Optional[int] = None
    diagnostics: Dict[str, str] = field(default_factory=dict)
    forged_lines: List[str] = field(default_factory=list)
    foreign_lines: List[str] = field(default_factory=list)
    node_exit_status: Optional[int] = None
    node_output_tail: List[str] = field(default_factory=list)
    seconds: float = 0.0

    def total(self, name: str) -> int:
        return sum(getattr(stats, name) for stats in self.classes.values())

    @property
    def clean_exit(self) -> bool:
        text = '\n'.join(self.node_output_tail)
        return self.node_exit_status == 0 and 'Traceback' not in text

    @property
    def ok(self) -> bool:
        return (self.total('lost') == 0 and self.total('unexpected') == 0
                and self.total('wrong') == 0 and not self.forged_lines
                and not self.foreign_lines and self.clean_exit)

    def as_dict(self) -> dict:
        return {
            'messages': self.messages, 'policy': self.policy, 'seconds': self.seconds,
            'classes': {name: vars(stats) for name, stats in self.classes.items()},
            'totals': {name: self.total(name) for name in
                       ('sent', 'expected', 'checked', 'received', 'lost', 'unexpected',
                        'wrong')},
            'wrong_examples': self.wrong_examples,
            'rss_kib': {'at_ready': self.rss_at_ready_kib,
                        'first': self.rss_kib[0] if self.rss_kib else None,
                        'max': max(self.rss_kib) if self.rss_kib else None,
                        'last': self.rss_kib[-1] if self.rss_kib else None,
                        'samples': len(self.rss_kib),
                        'every_second': self.rss_kib[::10]},
            'diagnostics': self.diagnostics,
            'forged_lines': self.forged_lines, 'foreign_lines': self.foreign_lines,
            'node_exit_status': self.node_exit_status, 'clean_exit': self.clean_exit,
            'ok': self.ok,
        }


# -- the messages -------------------------------------------------------------------------------

class MessageMaker:
    """Build the seeded stream of (class, names, positions, velocities) tuples.

    :param joint_names: the robot's movable joints.
    :param limits: joint name -> (lower, upper).
    :param flood: new unknown names per ``unknown_flood`` message.
    """

    def __init__(self, joint_names, limits, seed: int, flood: int):
        self.rng = np.random.default_rng(seed)
        self.joints = list(joint_names)
        self.lower = np.array([limits[name][0] for name in self.joints])
        self.upper = np.array([limits[name][1] for name in self.joints])
        self.flood = flood
        self._unknown = 0
        self._forged = 0

    def valid(self) -> Tuple[List[str], List[float]]:
        q = self.rng.uniform(self.lower, self.upper)
        return list(self.joints), [float(v) for v in q]

    def _fresh_names(self, count: int) -> List[str]:
        start, self._unknown = self._unknown, self._unknown + count
        return [f'fuzz_unknown_{i}' for i in range(start, start + count)]

    def _forging_names(self) -> List[str]:
        self._forged += 1
        k = self._forged
        return [f'j{k}\n{FORGED_PREFIX} newline {k}', f'j{k}\r{FORGED_PREFIX} return {k}',
                f'j{k}\x1b[2K\r{FORGED_PREFIX} ansi {k}', f'j{k}\u2028{FORGED_PREFIX} ls {k}',
                f'j{k}\x00nul', 'x' * 5000 + str(k)]

    def malformed(self, kind: str):
        names, values = self.valid()
        velocities = []
        pick = int(self.rng.integers(len(names)))
        if kind == 'length_mismatch':
            values = values[:-1]
        elif kind == 'duplicate_names':
            names, values = names + [names[pick]], values + [values[pick]]
        elif kind == 'nan':
            values[pick] = math.nan
        elif kind == 'inf':
            values[pick] = -math.inf if self.rng.random() < 0.5 else math.inf
        elif kind.startswith('huge_'):
            values[pick] = float(kind[5:]) * (1.0 if self.rng.random() < 0.5 else -1.0)
        elif kind == 'unknown_names':
            extra = self._fresh_names(3)
            names, values = names + extra, values + [1e308, -1e9, 0.0]
        elif kind == 'unknown_flood':
            extra = self._fresh_names(self.flood)
            names, values = names + extra, values + [0.0] * len(extra)
        elif kind == 'oversized':
            extra = self._fresh_names(OVERSIZED_NAMES)
            names, values = names + extra, values + [0.0] * len(extra)
        elif kind == 'control_char_names':
            extra = self._forging_names()
            names, values = names + extra, values + [0.0] * len(extra)
        elif kind == 'only_control_char_names':
            names = self._forging_names()
            values = [0.0] * len(names)
        elif kind == 'empty':
            names, values = [], []
        elif kind == 'velocity_only':
            velocities, values = [1.0] * len(names), []
        else:
            raise ValueError(f'unknown message class {kind!r}')
        return names, values, velocities

    def stream(self, count: int):
        """Yield ``(kind, names, positions, velocities)``: even indices valid, odd malformed."""
        for index in range(count):
            if index % 2 == 0:
                names, values = self.valid()
                yield 'valid', names, values, []
            else:
                kind = MALFORMED[(index // 2) % len(MALFORMED)]
                yield (kind, *self.malformed(kind))


# -- the node process ---------------------------------------------------------------------------

class NodeUnderTest:
    """``collision_sensor_node`` on the Panda, its output kept line by line."""

    def __init__(self, robot, namespace: str, policy: str):
        program = console_command('collision_sensor_node')
        package_paths = ','.join(f'"{name}={path}"' for name, path in
                                 robot.package_paths.items())
        command = program + [
            '--ros-args', '-r', f'__ns:={namespace}',
            '-p', f'urdf_path:={robot.urdf}', '-p', f'srdf_path:={robot.srdf}',
            '-p', f'package_paths:=[{package_paths}]', '-p', 'joint_states_qos:=reliable',
            '-p', f'joint_limit_policy:={policy}', '-p', 'stale_timeout:=0.0',
            '-p', 'overload_policy:=every',
            '-p', f'max_joint_state_bytes:={MAX_JOINT_STATE_BYTES}']
        env = dict(os.environ, PYTHONUNBUFFERED='1')
        env.pop('RCUTILS_CONSOLE_OUTPUT_FORMAT', None)    # the default format, checked below
        self.lines: List[str] = []
        self.ready = threading.Event()
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, env=env,
                                        errors='backslashreplace')
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.append(line.rstrip('\n'))
            if READY_MARK in line:
                self.ready.set()

    def rss_kib(self) -> Optional[int]:
        try:
            with open(f'/proc/{self.process.pid}/status') as stream:
                for line in stream:
                    if line.startswith('VmRSS:'):
                        return int(line.split()[1])
        except OSError:
            return None
        return None

    def stop(self, timeout: float = 20.0) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(5.0)
        return self.process.returncode


def check_output_lines(lines: List[str]) -> Tuple[List[str], List[str]]:
    """Return (forged, foreign): lines that start as an injected name would make them, and
    lines that do not start as rcutils writes a log line."""
    forged = [line for line in lines if FORGED_PREFIX in line and not LOG_LINE.match(line)]
    forged += [line for line in lines if line.startswith(FORGED_PREFIX)]
    foreign = [line for line in lines if not LOG_LINE.match(line)]
    return forged, foreign


# -- the run ------------------------------------------------------------------------------------

def run_fuzz(messages: int, seed: int = 1, rate: float = 500.0, policy: str = 'reject',
             flood: int = 1000, out=sys.stdout) -> Report:
    """Start the node, send the stream, compare every verdict; return the report."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from collision_sensor import CollisionChecker, JointStateError
    from collision_sensor.model.example_robots import example_robot
    from benchmarks.joint_state_oracle import (
        DEFAULT_LIMIT_TOLERANCE, JointStateMerger, joint_spans, jumped)

    def say(text=''):
        print(text, file=out, flush=True)

    robot = example_robot('panda')
    reference = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                           package_paths=robot.package_paths)
    mimic = frozenset(joint.name for joint in reference.model.joints
                      if getattr(joint, 'mimic', None) is not None)
    mirror = JointStateMerger(reference.joint_names, mimic, limits=dict(reference.joint_limits),
                              limit_policy=policy)
    maker = MessageMaker(reference.joint_names, reference.joint_limits, seed, flood)
    report = Report(messages=messages, policy=policy)
    namespace = f'/fuzz_{uuid.uuid4().hex[:8]}'
    say(f'starting collision_sensor_node on the Panda (namespace {namespace}, '
        f'joint_limit_policy {policy}) ...')
    node = NodeUnderTest(robot, namespace, policy)
    context = rclpy.Context()
    rclpy.init(args=[], context=context)
    executor = SingleThreadedExecutor(context=context)
    sampling = threading.Event()
    started = time.monotonic()
    try:
        probe = rclpy.create_node('fuzz', namespace=namespace, context=context)
        every = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
        publisher = probe.create_publisher(
            JointState, 'joint_states',
            QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
        verdicts: Dict[int, Tuple[Tuple[str, str], ...]] = {}
        duplicates = collections.Counter()
        lock = threading.Lock()

        def on_pairs(msg):
            key = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            pairs = tuple(tuple(status.name.split(':', 1)) for status in msg.status)
            with lock:
                if key in verdicts:
                    duplicates[key] += 1
                verdicts[key] = pairs

        status_name = f'{namespace.strip("/")}/collision_sensor: collision sensor'

        def on_diagnostics(msg):
            for status in msg.status:
                if status.name == status_name:
                    report.diagnostics = {kv.key: kv.value for kv in status.values}

        pairs_sub = probe.create_subscription(DiagnosticArray, 'colliding_pairs', on_pairs,
                                              every)
        probe.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics,
                                  QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
        executor.add_node(probe)
        def spin():
            try:
                executor.spin()
            except ExternalShutdownException:  # the run is over: the context was shut down
                pass
        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()

        def sample_rss():
            while not sampling.wait(0.1):
                value = node.rss_kib()
                if value is not None:
                    report.rss_kib.append(value)
        threading.Thread(target=sample_rss, daemon=True).start()

        while not (node.ready.is_set() and publisher.get_subscription_count() >= 1
                   and pairs_sub.get_publisher_count() >= 1):
            if node.process.poll() is not None:
                raise RuntimeError('collision_sensor_node exited with status '
                                   f'{node.process.returncode} before it was ready:\n'
                                   + '\n'.join(node.lines[-20:]))
            time.sleep(0.05)
        report.rss_at_ready_kib = node.rss_kib()
        say(f'node ready after {time.monotonic() - started:.1f} s; sending {messages} joint '
            f'states at {rate:g} Hz')

        expected: Dict[int, Tuple[str, Tuple[Tuple[str, ...], ...]]] = {}
        held = None     # the verdict of the last state checked, which an ignored one gets
        last_checked = None     # that state
        # A jump farther than a joint's range is no motion: the node checks the instant.
        spans = joint_spans(reference, DEFAULT_LIMIT_TOLERANCE)
        period = 1.0 / rate
        t0 = time.monotonic()
        for index, (kind, names, values, velocities) in enumerate(maker.stream(messages)):
            stats = report.classes.setdefault(kind, ClassStats())
            stats.sent += 1
            msg = JointState(name=names, position=values, velocity=velocities)
            msg.header.stamp.sec, msg.header.stamp.nanosec = index + 1, index
            msg.header.frame_id = 'fuzz'
            key = 1_000_000_000 * (index + 1) + index     # sec = index + 1, nanosec = index
            # The node rejects an oversized message before decoding it: the mirror never sees it.
            oversized = len(serialize_message(msg)) > MAX_JOINT_STATE_BYTES
            outcome = None if oversized else mirror.merge(names, values)
            if outcome is None or outcome.problem is not None:
                answer = REJECTED
            elif not outcome.accepted:
                answer = WAITING if held is None else held
            elif not mirror.complete:
                answer = WAITING
            else:
                positions = dict(mirror.positions)
                try:
                    result = reference.check(positions)
                except JointStateError:  # the node's engine refuses it too
                    mirror.undo(outcome)
                    answer = REJECTED
                else:
                    # check_motion (the node's default): the pairs in contact, then those met
                    # on the way from the state checked before.
                    now, met = tuple(result.colliding_pairs), ()
                    q = np.array([positions[name] for name in reference.joint_names])
                    if last_checked is not None and not jumped(spans, last_checked, q):
                        found = reference.check_motion(last_checked, q)
                        met = tuple(pair for pair in found.colliding_pairs if pair not in now)
                    answer = held = now + met
                    last_checked = q
                    stats.checked += 1
            stats.expected += 1
            expected[key] = (kind, answer)
            delay = t0 + index * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            publisher.publish(msg)
        say(f'sent in {time.monotonic() - t0:.1f} s; waiting for the verdicts ...')

        last_count, last_change = -1, time.monotonic()
        while time.monotonic() - last_change < VERDICT_WAIT:
            with lock:
                count = sum(1 for key in expected if key in verdicts)
            if count == len(expected):
                break
            if count != last_count:
                last_count, last_change = count, time.monotonic()
            time.sleep(0.1)
        # One more /diagnostics period, so that the node's counters include the last messages.
        deadline = time.monotonic() + 3.0
        while (time.monotonic() < deadline
               and report.diagnostics.get('received_total') != str(messages)):
            time.sleep(0.1)

        with lock:
            got = dict(verdicts)
        for key, (kind, pairs) in expected.items():
            stats = report.classes[kind]
            if key not in got:
                stats.lost += 1
                continue
            stats.received += 1
            if got[key] != pairs:
                stats.wrong += 1
                if len(report.wrong_examples) < 10:
                    report.wrong_examples.append({
                        'message': key // 1_000_000_000 - 1, 'class': kind,
                        'node': [list(p) for p in got[key]], 'check': [list(p) for p in pairs]})
        unexpected = set(got) - set(expected)
        for key in unexpected:
            index = key // 1_000_000_000 - 1
            kind = 'valid' if index % 2 == 0 else MALFORMED[(index // 2) % len(MALFORMED)]
            report.classes.setdefault(kind, ClassStats()).unexpected += 1
    finally:
        sampling.set()
        report.seconds = time.monotonic() - started
        rclpy.try_shutdown(context=context)
        executor.shutdown()
        report.node_exit_status = node.stop()
    report.forged_lines, report.foreign_lines = check_output_lines(node.lines)
    report.forged_lines = report.forged_lines[:20]
    report.foreign_lines = report.foreign_lines[:20]
    report.node_output_tail = node.lines[-30:]
    return report


def summary_lines(report: Report) -> List[str]:
    """Return the summary table and the checks below it."""
    lines = ['', f'{"class":<26}{"sent":>7}{"expected":>10}{"checked":>9}{"received":>10}'
             f'{"lost":>7}{"unexpected":>12}{"wrong":>7}']
    rows = ['valid'] + [kind for kind in MALFORMED if kind in report.classes]
    for kind in rows + ['total']:
        if kind == 'total':
            values = [report.total(name) for name in
                      ('sent', 'expected', 'checked', 'received', 'lost', 'unexpected',
                       'wrong')]
        elif kind in report.classes:
            stats = report.classes[kind]
            values = [stats.sent, stats.expected, stats.checked, stats.received, stats.lost,
                      stats.unexpected, stats.wrong]
        else:
            continue
        lines.append(f'{kind:<26}{values[0]:>7}{values[1]:>10}{values[2]:>9}{values[3]:>10}'
                     f'{values[4]:>7}{values[5]:>12}{values[6]:>7}')
    for example in report.wrong_examples[:3]:
        lines.append(f'  wrong: message {example["message"]} ({example["class"]}): node '
                     f'{example["node"]}, check {example["check"]}')
    d = report.diagnostics
    lines.append('')
    if report.rss_kib and report.rss_at_ready_kib:
        lines.append(f'node RSS: at ready {report.rss_at_ready_kib / 1024:.1f} MiB, max after '
                     f'{max(report.rss_kib) / 1024:.1f} MiB, last {report.rss_kib[-1] / 1024:.1f} '
                     f'MiB ({len(report.rss_kib)} samples every 0.1 s)')
    lines.append(f'node /diagnostics: received_total {d.get("received_total", "?")}, '
                 f'verdicts_total {d.get("verdicts_total", "?")}, skipped_total '
                 f'{d.get("skipped_total", "?")} (rejected {d.get("skipped_rejected", "?")}, '
                 f'ignored {d.get("skipped_ignored", "?")}), lost_total '
                 f'{d.get("lost_total", "?")}, unknown names remembered '
                 f'{d.get("unknown_joints_count", "?")} + not remembered '
                 f'{d.get("unknown_joints_not_remembered", "?")}')
    lines.append(f'node output: {len(report.forged_lines)} forged lines, '
                 f'{len(report.foreign_lines)} lines not in the log format')
    for line in (report.forged_lines + report.foreign_lines)[:5]:
        lines.append(f'  {line[:200]!r}')
    lines.append(f'node exit: status {report.node_exit_status}'
                 + ('' if report.clean_exit else ' (not clean)'))
    lines.append(f'result: {"OK" if report.ok else "FAILED"} ({report.seconds:.1f} s)')
    return lines


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='python -m benchmarks.fuzz',
        description='Fuzz collision_sensor_node (Panda) with hostile joint states and compare '
                    'every verdict with CollisionChecker.check.')
    parser.add_argument('--messages', type=int, default=20_000,
                        help='joint states to send, half valid (default %(default)s)')
    parser.add_argument('--rate', type=float, default=500.0,
                        help='messages per second (default %(default)g)')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--flood', type=int, default=1000,
                        help='new unknown names per flood message (default %(default)s)')
    parser.add_argument('--joint-limit-policy', default='reject',
                        choices=('reject', 'clamp', 'accept'),
                        help='the node parameter, mirrored here (default %(default)s)')
    parser.add_argument('--json', metavar='PATH', help='write the report as JSON')
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.messages < 1 or not args.rate > 0:
        print('fuzz: --messages and --rate must be positive', file=sys.stderr)
        return 2
    print(f'DDS: ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, '
          f'FASTDDS_BUILTIN_TRANSPORTS={os.environ["FASTDDS_BUILTIN_TRANSPORTS"]}', flush=True)
    report = run_fuzz(args.messages, seed=args.seed, rate=args.rate,
                      policy=args.joint_limit_policy, flood=args.flood)
    for line in summary_lines(report):
        print(line)
    if args.json:
        with open(args.json, 'w') as stream:
            json.dump(report.as_dict(), stream, indent=1)
    return 0 if report.ok else 1


if __name__ == '__main__':
    sys.exit(main())
