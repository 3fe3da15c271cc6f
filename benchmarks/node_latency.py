"""Drive the node with joint states at fixed rates from another process; measure drops,
latency and the node's memory.

Run ``python -m benchmarks.node_latency`` (1, 2, 3 and 5 kHz, 30 s each: ``--rate
1000,2000,3000,5000 --duration 30``), or ``--soak`` for ten minutes at the first rate (1 kHz)
in one-minute windows. The node runs as
a user runs it: a separate process started from its console script ``collision_sensor_node``
with a params file (the Panda of example-robot-data, ``joint_states_qos: reliable``). This
process publishes ``sensor_msgs/JointState`` over reliable QoS from its main thread, each
stamped with the wall clock at publication, and receives the node's ``colliding_pairs``
(published right after ``contact``, carrying the joint state's stamp) on an executor thread
of its own, so for every message:

- dropped: published joint states whose stamp never came back (lost, or skipped by the node
  under overload: its ``/diagnostics`` counters are printed at the end);
- latency: wall clock when the verdict reaches this process's callback minus the stamp
  (publish -> verdict received, both processes on this machine's clock), p50 / p99 / max;
- wrong: verdicts that differ from ``CollisionChecker.check`` on the same configuration here;
- the node's RSS (``/proc/<pid>/status``) after the warm-up and at the end, and its CPU time
  (user + system, ``/proc/<pid>/stat``) per message sent during each run: its cost, whatever
  else loads the machine.

``--check-motion true|false`` sets the node's ``check_motion`` (default: off for random
configurations, which jump; the node's default with ``--walk``); with it on, each verdict is
compared with ``CollisionChecker.check_motion`` from the configuration of the verdict received
before it. ``--walk STEP`` publishes a coherent walk instead of random configurations (straight
moves between random waypoints, the joint that moves most by STEP per message, forth then back,
so the cycle has no jump: a driver's stream, where random configurations are the worst case for
motion checks). ``--trajectories RATE`` publishes, during each run, planned trajectories of
``--trajectory-points`` points (cubic, within the limits) at RATE Hz on the node's
``trajectory`` topic, to measure the joint states' latency while trajectories are checked;
their results' count and latency are printed.

``--clouds RATE`` measures the joint states beside a depth camera (the target: their
p99 at most twice the same run's without clouds): the node subscribes to ``points``
(``point_cloud_topics``), and each rate runs ``--repeat`` times without clouds, then with
organised clouds (``--cloud-size``, 640 x 480 by default, NaN holes) published at RATE Hz by a
camera process (a DDS participant of its own, as a camera driver is; in this process the
clouds would queue the joint states behind them in the shared memory transport). The clouds
are rendered here by ray casting (:mod:`collision_sensor.tools.depth_camera`)
of bench scenario 12's cell (a table, a wall and a box nobody modelled: the node knows none of
them) with the robot at ``--cloud-renders`` of the configurations sent, spread over the cycle;
each tick the camera publishes the one whose configuration the driver sent last, stamped
with that joint state's stamp (which the driver writes to a small shared file), so the node's self-filter finds the robot where the camera saw it. The verdicts'
pairs with ``cloud/points`` are left out of the comparison with this process's checker (which
has no cloud); the runs without clouds come after a pause that lets the cloud time out
(``point_cloud_on_timeout: ignore``: its voxels are removed), so they check no cloud either.

``--per-call`` only times ``update`` against ``update_motion`` on the same configurations in
this process (the engine's part of a verdict, without the node); with ``--trajectories`` also
``check_trajectory`` on the planned trajectory of ``--trajectory-points`` points, whole and
its engine part (``check_spline``).

The highest rate of those tried that had no drop is reported. ``--executor`` sets
``COLLISION_SENSOR_EXECUTOR`` for the node (see
:func:`collision_sensor.ros.node.make_executor`) to compare executors. This is a
benchmark, not a test: it asserts nothing. DDS stays in shared memory
(``FASTDDS_BUILTIN_TRANSPORTS=SHM``) in ``ROS_DOMAIN_ID`` (a random one if unset).
"""
import argparse
import os
import random
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from typing import Optional

import numpy as np

from collision_sensor.ros.console_scripts import console_command

os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))

N_CONFIGURATIONS = 1000     # distinct configurations, cycled through by every run


def _node_command(params_file: str, namespace: str):
    return console_command('collision_sensor_node') + [
        '--ros-args', '--params-file', params_file, '-r', f'__ns:={namespace}',
        '--log-level', 'warn']


CLOUD_TOPIC = 'points'
#: s without a cloud after which the node drops the cloud's voxels (--clouds runs).
CLOUD_TIMEOUT = 0.5


def _write_params(directory: str, robot, check_motion: Optional[bool] = None,
                  clouds: bool = False) -> str:
    import yaml
    values = {'urdf_path': robot.urdf, 'srdf_path': robot.srdf,
              'package_paths': [f'{name}={path}' for name, path in robot.package_paths.items()],
              'joint_states_qos': 'reliable', 'stale_timeout': 0.0}
    if check_motion is not None:
        values['check_motion'] = check_motion
    if clouds:
        values.update(point_cloud_topics=[CLOUD_TOPIC], point_cloud_timeout=CLOUD_TIMEOUT,
                      point_cloud_on_timeout='ignore')
    path = os.path.join(directory, 'node_latency.yaml')
    with open(path, 'w') as stream:
        yaml.safe_dump({'/**': {'ros__parameters': values}}, stream)
    return path


class Driver:
    """The bench's side of the DDS link, in this process: a pacing publisher and a verdict
    recorder on rclpy's public API (the recorder spun by an executor on a thread of its own)."""

    def __init__(self, namespace: str, joint_names, configurations, expected,
                 trajectories=None, clouds: bool = False):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        from collision_sensor.ros.node import make_executor

        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        # A lean node: no parameter or type-description services to serve.
        self.node = Node('node_latency_driver', namespace=namespace, context=self.context,
                         start_parameter_services=False, enable_rosout=False,
                         parameter_overrides=[Parameter('start_type_description_service',
                                                        value=False)])
        # Deep histories on both sides: the bench must not be the one that drops.
        self.publisher = self.node.create_publisher(
            JointState, 'joint_states',
            QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self.subscription = self.node.create_subscription(
            DiagnosticArray, 'colliding_pairs', self._on_verdict,
            QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self.node_status = {}   # the node's last /diagnostics values
        self.cloud_status = {}  # ... and its cloud source's (--clouds)
        self._status_name = f'{namespace.strip("/")}/collision_sensor: collision sensor'
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      QoSProfile(depth=100,
                                                 reliability=ReliabilityPolicy.RELIABLE))
        self.namespace = namespace
        self.joint_names = list(joint_names)
        self.configurations = [list(map(float, q)) for q in configurations]
        self.expected = expected    # (previous index or None, index) -> pair names
        # Planned trajectories published meanwhile: (JointTrajectory, rate) or None.
        self.trajectories = trajectories
        self.trajectory_results = []    # (receive wall ns, stamp ns, valid)
        self._last_index = None     # the configuration published last, by the previous run
        if trajectories is not None:
            from trajectory_msgs.msg import JointTrajectory
            self.trajectory_publisher = self.node.create_publisher(
                JointTrajectory, 'trajectory',
                QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.VOLATILE))
            self.node.create_subscription(
                DiagnosticArray, 'trajectory_result', self._on_trajectory_result,
                QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.VOLATILE))
        # A camera process publishes clouds meanwhile: its pairs are left out of the comparison,
        # and the rendered configurations' stamps are written to its slot (set_camera).
        self.clouds = clouds
        self.camera_slot = None
        self.rendered = frozenset()
        self._msg_type = JointState
        self.received = []      # (receive wall ns, stamp ns, pair names "a:b")
        # Stamps answered already: a cloud's verdict carries the cloud's stamp, and the camera
        # stamps each cloud with a joint state's, so a second verdict of a stamp is a cloud's.
        self._answered_stamps = set()
        self.sent = {}          # stamp ns -> configuration index
        self.published_total = 0
        self._executor = make_executor(self.context)
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._spin, name='driver executor', daemon=True)
        self._spinner.start()

    def _spin(self):
        from rclpy.executors import ExternalShutdownException
        try:
            while self.context.ok():
                self._executor.spin_once(timeout_sec=0.1)
        except ExternalShutdownException:
            pass

    def _on_verdict(self, msg):
        # Time first: the latency ends when the verdict reaches this process's callback.
        now = time.time_ns()
        stamp = msg.header.stamp
        stamp_ns = stamp.sec * 1_000_000_000 + stamp.nanosec
        if stamp_ns in self._answered_stamps:
            return
        self._answered_stamps.add(stamp_ns)
        self.received.append((now, stamp_ns,
                              tuple(status.name for status in msg.status)))

    def _on_trajectory_result(self, msg):
        now = time.time_ns()
        stamp = msg.header.stamp
        values = {kv.key: kv.value for kv in msg.status[0].values} if msg.status else {}
        self.trajectory_results.append((now, stamp.sec * 1_000_000_000 + stamp.nanosec,
                                        values.get('valid') == 'true'))

    def _on_diagnostics(self, msg):
        for status in msg.status:
            if status.name == self._status_name:
                self.node_status = {kv.key: kv.value for kv in status.values}
            elif status.name == f'{self._status_name.split(":")[0]}: point cloud {CLOUD_TOPIC}':
                self.cloud_status = {kv.key: kv.value for kv in status.values}

    def spin_until(self, condition, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.01)
        return True

    def wait_for_node(self, timeout: float) -> bool:
        topic = f'{self.namespace}/joint_states'
        return self.spin_until(
            lambda: self.node.count_subscribers(topic) > 0
            and self.publisher.get_subscription_count() > 0
            and self.node.count_publishers(f'{self.namespace}/colliding_pairs') > 0, timeout)

    def set_camera(self, slot: 'StampSlot', rendered) -> None:
        """Write the stamp of each configuration of ``rendered`` sent to ``slot``."""
        self.camera_slot, self.rendered = slot, frozenset(rendered)

    def run(self, rate: float, duration: float, first_index: int = 0) -> dict:
        """Publish at ``rate`` for ``duration`` seconds; return the figures."""
        self.received = []
        self._answered_stamps = set()
        self.sent = {}
        self.trajectory_results = []
        trajectories_sent = 0
        trajectory_period_ns = (int(1e9 / self.trajectories[1]) if self.trajectories
                                else None)
        rendered, slot = self.rendered, self.camera_slot
        count = int(round(rate * duration))
        period_ns = int(1e9 / rate)
        late = 0
        # One message, reused: only its stamp and positions change.
        msg = self._msg_type()
        msg.name = self.joint_names
        configurations, n = self.configurations, len(self.configurations)
        stamp = msg.header.stamp
        began = time.monotonic()
        start = time.monotonic_ns() + 20_000_000
        for i in range(count):
            target = start + i * period_ns
            delay = target - time.monotonic_ns()
            if delay > 0:
                time.sleep(delay / 1e9)
            elif delay < -period_ns:
                late += 1
            index = (first_index + i) % n
            msg.position = configurations[index]
            now = time.time_ns()
            stamp.sec, stamp.nanosec = divmod(now, 1_000_000_000)
            self.sent[now] = index
            self.publisher.publish(msg)
            if index in rendered:
                slot.write(index, now)
            if trajectory_period_ns and target - start >= trajectories_sent * \
                    trajectory_period_ns:
                trajectory = self.trajectories[0]
                trajectory.header.stamp.sec, trajectory.header.stamp.nanosec = divmod(
                    time.time_ns(), 1_000_000_000)
                self.trajectory_publisher.publish(trajectory)
                trajectories_sent += 1
        publish_seconds = time.monotonic() - began
        self.published_total += count
        # Stragglers: up to 2 s after the last publication.
        self.spin_until(lambda: len(self.received) >= count, 2.0)
        figures = self._figures(rate, count, publish_seconds, late)
        if trajectory_period_ns:
            self.spin_until(lambda: len(self.trajectory_results) >= trajectories_sent, 60.0)
            waits = np.array([(received - stamp) / 1e6
                              for received, stamp, _ in self.trajectory_results] or [np.nan])
            figures['trajectories'] = (trajectories_sent, len(self.trajectory_results),
                                       sum(valid for _, _, valid in self.trajectory_results),
                                       float(np.median(waits)), float(np.max(waits)))
        return figures

    def _figures(self, rate, count, publish_seconds, late):
        latencies, wrong, first_wrong = [], 0, None
        seen = set()
        # The node answers in order, and checks the motion from the state it answered before
        # (states it skipped under overload are not swept through).
        previous = self._last_index
        for received_ns, stamp_ns, names in list(self.received):
            index = self.sent.get(stamp_ns)
            if index is None:   # a verdict for a message of an earlier run
                continue
            seen.add(stamp_ns)
            latencies.append((received_ns - stamp_ns) / 1e6)
            if self.clouds:
                names = tuple(name for name in names if f'cloud/{CLOUD_TOPIC}' not in name)
            expected = self.expected(previous, index)
            if names != expected:
                wrong += 1
                if first_wrong is None:
                    first_wrong = (previous, index, names, expected)
            previous = index
        self._last_index = previous
        latencies = np.array(latencies) if latencies else np.array([np.nan])
        return {
            'rate_hz': rate, 'published': count,
            'achieved_publish_rate_hz': count / publish_seconds,
            'late_publications': late, 'received': len(seen),
            'dropped': count - len(seen), 'wrong': wrong, 'first_wrong': first_wrong,
            'latencies_ms': latencies,
            'p50_ms': float(np.percentile(latencies, 50)),
            'p99_ms': float(np.percentile(latencies, 99)),
            'max_ms': float(np.max(latencies)),
        }

    def close(self):
        import rclpy
        rclpy.try_shutdown(context=self.context)
        self._spinner.join(2.0)
        self._executor.shutdown()
        self.node.destroy_node()


def cpu_seconds(pid: int) -> Optional[float]:
    """Return a process's CPU time so far (user + system, all threads, from ``/proc``), or
    None: per message, it is the node's cost whatever else loads the machine."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            fields = stat.read().rsplit(')', 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def rss_kib(pid: int) -> Optional[int]:
    """Return a process's resident set size (KiB) from ``/proc``, or None."""
    try:
        with open(f'/proc/{pid}/status') as status:
            for line in status:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _configurations(checker, count: int, seed: int):
    """Return (count, J) seeded random configurations within limits and their colliding pairs."""
    rng = np.random.default_rng(seed)
    names = checker.joint_names
    lower = np.array([checker.joint_limits[name][0] for name in names])
    upper = np.array([checker.joint_limits[name][1] for name in names])
    configurations = rng.uniform(lower, upper, size=(count, len(names)))
    expected = [tuple(f'{a}:{b}' for a, b in checker.check(dict(zip(names, q))).colliding_pairs)
                for q in configurations]
    return configurations, expected


def _walk(checker, count: int, step: float, seed: int):
    """Return (count, J) configurations of a coherent walk within the limits and their
    colliding pairs: straight moves between seeded random waypoints (each within 30 % of the
    joints' ranges of the last), the joint that moves most
    by ``step`` per configuration (a driver's stream during fast moves, in and out of contact),
    for ``count // 2``, then back the same way (cycled through, it has no jump)."""
    rng = np.random.default_rng(seed)
    names = checker.joint_names
    lower = np.array([checker.joint_limits[name][0] for name in names])
    upper = np.array([checker.joint_limits[name][1] for name in names])
    q = rng.uniform(lower, upper)
    forth = []
    while len(forth) < count // 2:
        target = np.clip(q + rng.uniform(-0.3, 0.3, len(q)) * (upper - lower), lower, upper)
        steps = max(1, int(np.ceil(np.max(np.abs(target - q)) / step)))
        forth.extend(q + (target - q) * (k / steps) for k in range(1, steps + 1))
        q = target
    forth = forth[:count // 2]
    configurations = np.array(forth + forth[::-1])
    expected = [tuple(f'{a}:{b}' for a, b in checker.check(q).colliding_pairs)
                for q in configurations]
    return configurations, expected


def motion_expectation(checker, configurations, instant):
    """Return ``expected(previous, index)``: the verdict's pair names when the node checks the
    motion from configuration ``previous`` (None: the instant) to ``index``, as the node lays
    them out (pairs in contact there, then those met on the way)."""
    cache = {}

    def expected(previous, index):
        if previous is None or previous == index:
            return instant[index]
        key = (previous, index)
        if key not in cache:
            found = checker.check_motion(configurations[previous], configurations[index])
            now = instant[index]
            met = tuple(f'{a}:{b}' for a, b in found.colliding_pairs
                        if f'{a}:{b}' not in now) if found.in_collision else ()
            cache[key] = now + met
        return cache[key]
    return expected


def planned_trajectory(checker, points: int, seed: int):
    """Return a ``JointTrajectory`` of ``points`` points (positions and velocities: cubic),
    0.01 s apart, a smooth path within the limits around the middle of the joints' ranges."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    rng = np.random.default_rng(seed)
    names = checker.joint_names
    lower = np.array([checker.joint_limits[name][0] for name in names])
    upper = np.array([checker.joint_limits[name][1] for name in names])
    middle, reach = 0.5 * (lower + upper), 0.2 * (upper - lower)
    speed = rng.uniform(0.5, 2.0, len(names))
    times = 0.01 * np.arange(1, points + 1)
    positions = middle + reach * np.sin(np.outer(times, speed))
    velocities = reach * speed * np.cos(np.outer(times, speed))
    msg = JointTrajectory(joint_names=list(names))
    for t, q, v in zip(times, positions, velocities):
        sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
        msg.points.append(JointTrajectoryPoint(
            positions=q.tolist(), velocities=v.tolist(),
            time_from_start=Duration(sec=sec, nanosec=nanosec)))
    return msg


def rendered_clouds(robot, checker, configurations, renders: int, size: str, seed: int):
    """Return {configuration index: serialized PointCloud2}: bench scenario 12's cell seen by a depth
    camera (``size`` 'WxH', 2 mm noise) with the robot at ``renders`` configurations spread over
    ``configurations``, organised, float32 x, y, z in 16-byte points (NaN where nothing is
    seen), in the robot's world frame."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import PointCloud2, PointField

    from collision_sensor import CollisionChecker
    from benchmarks.scenario_clouds import CAMERA_POSE, cell_changes
    from collision_sensor.tools.depth_camera import DepthCamera

    width, height = (int(v) for v in size.lower().split('x'))
    world = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                       package_paths=robot.package_paths)
    world.apply_scene_changes(cell_changes('node_latency'))
    camera = DepthCamera(width=width, height=height, noise=0.002)
    T_world_camera = CAMERA_POSE
    R, t = T_world_camera[:3, :3].T, T_world_camera[:3, 3]
    rng = np.random.default_rng(seed)
    fields = [PointField(name=axis, offset=4 * k, datatype=PointField.FLOAT32, count=1)
              for k, axis in enumerate('xyz')]
    frame = sorted(checker.world_frames)[0]
    out = {}
    step = max(1, len(configurations) // max(1, renders))
    for index in range(0, len(configurations), step)[:renders]:
        world.check(configurations[index])
        points = camera.points(world, T_world_camera, rng) @ R.astype(np.float32) + t
        data = np.zeros((len(points), 4), dtype=np.float32)
        data[:, :3] = points
        msg = PointCloud2(height=height, width=width, fields=fields, is_bigendian=False,
                          point_step=16, row_step=16 * width, is_dense=False)
        msg.header.frame_id = frame
        msg.data = data.tobytes()
        # Published serialized, its stamp written in place (write_stamp; rclpy takes about
        # 60 ms to serialize such a cloud: the camera would fall behind).
        out[index] = bytearray(serialize_message(msg))
    return out


def save_clouds(path: str, clouds: dict) -> None:
    """Write the rendered clouds for the camera process: their configurations' indices and the
    serialized clouds, back to back."""
    indices = sorted(clouds)
    blobs = [bytes(clouds[index]) for index in indices]
    np.savez(path, indices=np.asarray(indices, dtype=np.int64),
             sizes=np.array([len(b) for b in blobs], dtype=np.int64),
             data=np.frombuffer(b''.join(blobs), dtype=np.uint8))


class StampSlot:
    """The last rendered configuration sent and its stamp, from the driver to the camera
    process through a shared 24-byte file (a sequence number around the two values: a read
    that overlaps a write is retried)."""

    def __init__(self, path: str, create: bool = False):
        import mmap
        if create:
            with open(path, 'wb') as stream:
                stream.write(bytes(24))
        self._file = open(path, 'r+b')
        self._map = mmap.mmap(self._file.fileno(), 24)
        self._sequence = 0

    def write(self, index: int, stamp_ns: int) -> None:
        self._sequence += 1
        struct.pack_into('<q', self._map, 0, self._sequence)       # odd: being written
        struct.pack_into('<qq', self._map, 8, index, stamp_ns)
        self._sequence += 1
        struct.pack_into('<q', self._map, 0, self._sequence)

    def read(self):
        """Return (index, stamp ns), or None before the first write."""
        while True:
            before, index, stamp, = struct.unpack_from('<qqq', self._map, 0)
            if before == 0:
                return None
            if not before & 1 and struct.unpack_from('<q', self._map, 0)[0] == before:
                return index, stamp


class CameraProcess:
    """A depth camera as a process of its own (its own DDS participant, as a camera driver
    is): ``python -m benchmarks.node_latency --camera FILE`` publishes the clouds of
    FILE (:func:`save_clouds`) on the node's ``points`` at ``rate`` Hz, each the one whose
    configuration the driver sent last, stamped with that joint state's stamp
    (:class:`StampSlot`)."""

    def __init__(self, path: str, slot_path: str, namespace: str, rate: float):
        self.command = [sys.executable, '-m', 'benchmarks.node_latency', '--camera',
                        path, '--camera-slot', slot_path, '--camera-namespace', namespace,
                        '--clouds', str(rate)]
        self.process = None
        self.sent = None

    def start(self, timeout: float = 120.0) -> None:
        from collision_sensor.model.share import config_path
        environment = dict(os.environ)
        # Clouds larger than Fast DDS's 512 KB shared memory segment are not delivered over
        # shared memory alone: the camera's participant gets a large segment (its comment).
        environment.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE',
                               config_path('fastdds_large_data.xml'))
        self.process = subprocess.Popen(self.command, stdout=subprocess.PIPE, text=True,
                                        env=environment)
        deadline = time.monotonic() + timeout
        line = self.process.stdout.readline()
        if not line.startswith('ready') or time.monotonic() > deadline:
            self.stop()
            raise RuntimeError(f'the camera process did not start: {line!r}')

    def stop(self) -> Optional[int]:
        """Stop the camera; return the clouds it published."""
        if self.process is None:
            return None
        self.process.send_signal(signal.SIGTERM)
        try:
            out, _ = self.process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            out, _ = self.process.communicate()
        self.process = None
        sent = [int(line.split()[1]) for line in out.splitlines() if line.startswith('sent ')]
        return sent[-1] if sent else None


def camera_main(path: str, slot_path: str, namespace: str, rate: float) -> int:
    """The camera process (see :class:`CameraProcess`)."""
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import PointCloud2

    from collision_sensor.model.point_cloud_message import write_stamp

    saved = np.load(path)
    offsets = np.concatenate([[0], np.cumsum(saved['sizes'])])
    data = saved['data']
    clouds = {int(index): bytearray(data[offsets[k]:offsets[k + 1]].tobytes())
              for k, index in enumerate(saved['indices'])}
    slot = StampSlot(slot_path)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = Node('node_latency_camera', namespace=namespace, enable_rosout=False,
                start_parameter_services=False)
    publisher = node.create_publisher(PointCloud2, CLOUD_TOPIC, qos_profile_sensor_data)
    sent = 0
    try:
        deadline = time.monotonic() + 60.0
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        print('ready', flush=True)
        period = 1.0 / rate
        tick = time.monotonic()
        while not stop.wait(max(0.0, tick + period - time.monotonic())):
            tick += period
            last = slot.read()
            if last is None:
                continue
            cloud = clouds[last[0]]
            write_stamp(cloud, *divmod(last[1], 1_000_000_000))
            publisher.publish(bytes(cloud))
            sent += 1
    finally:
        print(f'sent {sent}', flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _print_figures(label: str, figures: dict, rss: Optional[int] = None):
    memory = f'  node RSS {rss / 1024:6.1f} MiB' if rss is not None else ''
    if 'clouds' in figures:
        memory += f'  clouds {figures["clouds"]}'
    if 'cloud_counts' in figures:
        memory += f' (the node, so far: {figures["cloud_counts"]})'
    if 'cpu_us' in figures:
        memory += f'  node CPU {figures["cpu_us"]:6.1f} us per message'
    if 'trajectories' in figures:
        sent, answered, valid, median, longest = figures['trajectories']
        memory += (f'  trajectories sent {sent} answered {answered} valid {valid} result '
                   f'latency median {median:.1f} ms max {longest:.1f} ms')
    print(f'{label:>10}: rate {figures["rate_hz"]:5.0f} Hz (published at '
          f'{figures["achieved_publish_rate_hz"]:7.1f} Hz, {figures["late_publications"]} late)'
          f'  sent {figures["published"]:6d}  dropped {figures["dropped"]:5d}'
          f'  wrong {figures["wrong"]:3d}  latency p50 {figures["p50_ms"]:6.3f} ms'
          f'  p99 {figures["p99_ms"]:6.3f} ms  max {figures["max_ms"]:7.3f} ms{memory}',
          flush=True)
    if figures.get('first_wrong'):
        previous, index, names, expected = figures['first_wrong']
        print(f'{"":>10}  first wrong verdict: configuration {index} (from {previous}): the node '
              f'said {list(names)}, CollisionChecker says {list(expected)}', flush=True)


def _soak(driver, rate: float, duration: float, window: float, pid: int) -> None:
    """Run ``duration`` s at ``rate`` in windows of ``window`` s; print each and the total."""
    rss_start = rss_kib(pid)
    print(f'soak: {duration:g} s at {rate:g} Hz in windows of {window:g} s; node RSS at start '
          f'{rss_start / 1024:.1f} MiB', flush=True)
    latencies, sent, dropped, wrong, index, elapsed = [], 0, 0, 0, 200, 0.0
    while elapsed < duration - 1e-9:
        length = min(window, duration - elapsed)
        figures = driver.run(rate, length, first_index=index)
        elapsed += length
        index += figures['published']
        sent += figures['published']
        dropped += figures['dropped']
        wrong += figures['wrong']
        latencies.append(figures['latencies_ms'])
        _print_figures(f'{elapsed:6.0f} s', figures, rss_kib(pid))
    rss_end = rss_kib(pid)
    every = np.concatenate(latencies)
    print(f'soak total: {duration:g} s at {rate:g} Hz  sent {sent}  dropped {dropped}  wrong '
          f'{wrong}  latency p50 {np.nanpercentile(every, 50):.3f} ms  p99 '
          f'{np.nanpercentile(every, 99):.3f} ms  max {np.nanmax(every):.3f} ms  node RSS '
          f'{rss_start / 1024:.1f} -> {rss_end / 1024:.1f} MiB '
          f'({100.0 * (rss_end - rss_start) / rss_start:+.1f} %)', flush=True)


def _with_and_without_clouds(driver, camera: CameraProcess, rates, duration: float,
                             repeat: int, pid: int) -> None:
    """Per rate, ``repeat`` times: a run without clouds, then one with the camera process
    publishing; print each and the medians' ratios (the target: p99 with clouds at most twice
    without)."""
    for rate in rates:
        p99 = {False: [], True: []}
        p50 = {False: [], True: []}
        for _ in range(repeat):
            for with_clouds in (False, True):
                if with_clouds:
                    camera.start()
                else:
                    time.sleep(3 * CLOUD_TIMEOUT)   # the last run's cloud times out: removed
                cpu = cpu_seconds(pid)
                try:
                    figures = driver.run(rate, duration, first_index=200)
                finally:
                    sent = camera.stop() if with_clouds else None
                if cpu is not None and cpu_seconds(pid) is not None:
                    figures['cpu_us'] = 1e6 * (cpu_seconds(pid) - cpu) / figures['published']
                if with_clouds:
                    figures['clouds'] = sent
                    before = dict(driver.cloud_status)
                    driver.spin_until(lambda: driver.cloud_status != before, 3.0)
                    d = driver.cloud_status
                    figures['cloud_counts'] = ', '.join(
                        f'{key} {d.get(f"clouds_{key}_total", "?")}' for key in (
                            'received', 'accepted', 'superseded', 'dropped', 'too_old'))
                _print_figures('clouds' if with_clouds else 'no clouds', figures, rss_kib(pid))
                p99[with_clouds].append(figures['p99_ms'])
                p50[with_clouds].append(figures['p50_ms'])
        ratio = float(np.median(p99[True]) / np.median(p99[False]))
        print(f'{rate:g} Hz joint states, {repeat} runs each: p99 without clouds '
              f'{min(p99[False]):.3f} / {np.median(p99[False]):.3f} / {max(p99[False]):.3f} ms '
              f'(min / median / max), with clouds {min(p99[True]):.3f} / '
              f'{np.median(p99[True]):.3f} / {max(p99[True]):.3f} ms: with / without '
              f'{ratio:.2f}x (target <= 2x); p50 {np.median(p50[False]):.3f} -> '
              f'{np.median(p50[True]):.3f} ms', flush=True)


def _per_call(checker, configurations, passes: int = 5) -> None:
    """Print the time per configuration of ``update`` and ``update_motion`` (each pass over
    every configuration in order, from a state checked at the first; min / median / max of the
    passes), and their ratio: what ``check_motion`` adds to the engine's part of a verdict."""
    rows = [np.ascontiguousarray(q) for q in configurations]
    times = {}
    for name in ('update', 'update_motion'):
        call = getattr(checker, name)
        per = []
        for _ in range(passes):
            checker.check(rows[0])
            started = time.perf_counter()
            for q in rows:
                call(q)
            per.append(1e6 * (time.perf_counter() - started) / len(rows))
        times[name] = sorted(per)
        print(f'{name:>14}: us per configuration min {per and min(per):7.2f}  median '
              f'{float(np.median(per)):7.2f}  max {max(per):7.2f}', flush=True)
    ratio = float(np.median(times['update_motion']) / np.median(times['update']))
    print(f'update_motion / update (medians): {ratio:.2f}', flush=True)


def _per_call_trajectory(checker, msg, passes: int = 5) -> None:
    """Print the time of ``check_trajectory`` on ``msg`` (a ``JointTrajectory``) and of its
    engine part, ``check_spline`` on the same segments (min / median / max of the passes)."""
    from collision_sensor.engine.trajectory import build_segments, check_trajectory
    from collision_sensor.ros.trajectory_source import points_of

    points = points_of(msg)
    start = checker.positions
    q_start = np.array([start[name] for name in checker.joint_names])
    coef, _ = build_segments(checker, msg.joint_names, points, q_start)
    for name, call in (('check_trajectory',
                        lambda: check_trajectory(checker, msg.joint_names, points, start)),
                       ('check_spline', lambda: checker.check_spline(coef))):
        per = []
        for _ in range(passes):
            started = time.perf_counter()
            call()
            per.append(1e3 * (time.perf_counter() - started))
        print(f'{name:>16}: ms per {len(points)}-point trajectory min {min(per):8.2f}  '
              f'median {float(np.median(per)):8.2f}  max {max(per):8.2f}', flush=True)


def main(argv=None) -> int:
    """Run the benchmark; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', default='1000,2000,3000,5000',
                        help='comma-separated rates (Hz), one run each; --soak: the first')
    parser.add_argument('--duration', type=float, default=None,
                        help='s of each run (default 30; --soak: 600)')
    parser.add_argument('--soak', action='store_true',
                        help='one long run at the first rate, reported per --window')
    parser.add_argument('--window', type=float, default=60.0, help='s per soak report line')
    parser.add_argument('--executor', default=None,
                        help='the node\'s executor: events (default), single or multi')
    parser.add_argument('--robot', default='panda', help='example robot: panda or ur5')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--check-motion', choices=('true', 'false'), default=None,
                        help='the node\'s check_motion (default: false for random '
                        'configurations, the node\'s default with --walk)')
    parser.add_argument('--walk', type=float, default=None, metavar='STEP',
                        help='publish a coherent walk, STEP rad per message at most, instead '
                        'of random configurations')
    parser.add_argument('--trajectories', type=float, default=None, metavar='RATE',
                        help='also publish planned trajectories at RATE Hz during each run')
    parser.add_argument('--trajectory-points', type=int, default=1000)
    parser.add_argument('--clouds', type=float, default=None, metavar='RATE',
                        help='also run each rate with depth-camera clouds at RATE Hz on the '
                        'node\'s point_cloud_topics, after --repeat runs without')
    parser.add_argument('--cloud-size', default='640x480', metavar='WxH')
    parser.add_argument('--cloud-renders', type=int, default=40,
                        help='configurations the clouds are rendered at (default 40)')
    parser.add_argument('--repeat', type=int, default=1,
                        help='with --clouds: runs without and with clouds, alternated, per rate')
    parser.add_argument('--camera', default=None, help=argparse.SUPPRESS)
    parser.add_argument('--camera-namespace', default=None, help=argparse.SUPPRESS)
    parser.add_argument('--camera-slot', default=None, help=argparse.SUPPRESS)
    parser.add_argument('--per-call', action='store_true',
                        help='only time update and update_motion per configuration on this '
                        'process\'s checker (no node), 5 passes each, and exit')
    args = parser.parse_args(argv)
    if args.camera:     # the camera process of a --clouds run
        return camera_main(args.camera, args.camera_slot, args.camera_namespace, args.clouds)
    rates = [float(rate) for rate in args.rate.split(',') if rate.strip()]
    duration = args.duration if args.duration is not None else (600.0 if args.soak else 30.0)

    from collision_sensor import CollisionChecker
    from collision_sensor.model.example_robots import example_robot

    robot = example_robot(args.robot)
    environment = dict(os.environ)
    if args.executor:
        environment['COLLISION_SENSOR_EXECUTOR'] = args.executor
    print(f'node_latency: robot {robot.name}, ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, '
          f'FASTDDS_BUILTIN_TRANSPORTS={os.environ["FASTDDS_BUILTIN_TRANSPORTS"]}, '
          f'{os.cpu_count()} cores, node executor '
          f'{environment.get("COLLISION_SENSOR_EXECUTOR", "default (events)")}', flush=True)
    checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                         package_paths=robot.package_paths)
    if args.walk is not None:
        configurations, instant = _walk(checker, 10 * N_CONFIGURATIONS, args.walk, args.seed)
        what = f'a walk of {len(configurations)} configurations ({args.walk:g} rad per step)'
    else:
        configurations, instant = _configurations(checker, N_CONFIGURATIONS, args.seed)
        what = f'{N_CONFIGURATIONS} random configurations'
    colliding = sum(1 for pairs in instant if pairs)
    if args.per_call:
        print(f'{what}, {colliding} colliding')
        _per_call(checker, configurations)
        if args.trajectories:
            checker.check(configurations[0])
            _per_call_trajectory(checker, planned_trajectory(checker, args.trajectory_points,
                                                             args.seed))
        return 0
    from collision_sensor.ros.node_parameters import default_values
    # Random configurations are jumps, no motion of a robot: by default they are checked as
    # instants; a walk with the node's default.
    motion = (args.check_motion == 'true' if args.check_motion is not None
              else args.walk is not None and default_values()['check_motion'])
    print(f'{what}, {colliding} colliding; check_motion {str(motion).lower()}', flush=True)
    expected = (motion_expectation(checker, configurations, instant) if motion
                else lambda previous, index: instant[index])
    trajectories = None
    if args.trajectories:
        trajectories = (planned_trajectory(checker, args.trajectory_points, args.seed),
                        args.trajectories)

    directory = tempfile.mkdtemp(prefix='node_latency_')
    namespace = f'/node_latency_{uuid.uuid4().hex[:8]}'
    camera = None
    if args.clouds:
        started = time.monotonic()
        rendered = rendered_clouds(robot, checker, configurations, args.cloud_renders,
                                   args.cloud_size, args.seed)
        path = os.path.join(directory, 'clouds.npz')
        save_clouds(path, rendered)
        slot_path = os.path.join(directory, 'camera_slot')
        slot = StampSlot(slot_path, create=True)
        camera = CameraProcess(path, slot_path, namespace, args.clouds)
        camera_rendered = sorted(rendered)
        print(f'{len(rendered)} clouds of {args.cloud_size} rendered in '
              f'{time.monotonic() - started:.0f} s; in each run with clouds a camera process '
              f'publishes one at {args.clouds:g} Hz', flush=True)
        del rendered
    command = _node_command(_write_params(directory, robot, motion, camera is not None),
                            namespace)
    log_path = os.path.join(directory, 'node.log')
    log = open(log_path, 'w')
    node = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=environment)
    driver = None
    try:
        driver = Driver(namespace, checker.joint_names, configurations, expected,
                        trajectories, camera is not None)
        if camera is not None:
            driver.set_camera(slot, camera_rendered)
        if not driver.wait_for_node(120.0):
            print(f'the node did not come up; its log: {log_path}', file=sys.stderr)
            return 1
        warm = driver.run(100.0, 2.0)
        driver.spin_until(lambda: len(driver.received) >= warm['published'], 10.0)
        _print_figures('warm-up', warm, rss_kib(node.pid))
        if args.soak:
            _soak(driver, rates[0], duration, args.window, node.pid)
        elif camera is not None:
            _with_and_without_clouds(driver, camera, rates, duration, max(1, args.repeat),
                                     node.pid)
        else:
            best = None
            for rate in rates:
                cpu = cpu_seconds(node.pid)
                figures = driver.run(rate, duration, first_index=200)
                if cpu is not None and cpu_seconds(node.pid) is not None:
                    figures['cpu_us'] = 1e6 * (cpu_seconds(node.pid) - cpu) / figures['published']
                _print_figures(f'{duration:g} s', figures, rss_kib(node.pid))
                if figures['dropped'] == 0:
                    best = max(best or 0.0, rate)
            print('highest rate without drops: '
                  f'{"none of the rates tried" if best is None else f"{best:.0f} Hz"} '
                  f'(tried {", ".join(f"{rate:g}" for rate in rates)} Hz)', flush=True)
        # The node's counters once they include every message sent (diagnostics: 1 Hz).
        driver.spin_until(lambda: int(driver.node_status.get('received_total', -1))
                          >= driver.published_total, 3.0)
        d = driver.node_status
        print('node counters: ' + ', '.join(f'{key} {d.get(key, "?")}' for key in (
            'received_total', 'verdicts_total', 'skipped_superseded', 'skipped_total',
            'lost_total', 'check_time_mean_ms')), flush=True)
        return 0
    finally:
        if driver is not None:
            driver.close()
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=20)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait()
        log.close()
        if node.returncode not in (0, -signal.SIGINT):
            print(f'node exited with {node.returncode}; log kept in {log_path}', file=sys.stderr)
        else:
            shutil.rmtree(directory, ignore_errors=True)


if __name__ == '__main__':
    raise SystemExit(main())
