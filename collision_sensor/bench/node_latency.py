"""Drive the node with joint states at a fixed rate and measure drops and latency.

Run ``python -m collision_sensor.bench.node_latency --rate 1000 --duration 30``. The node runs
as a user runs it: a separate process started from its console script with a params file
(the Panda of example-robot-data, ``joint_states_qos: reliable``). This process publishes
``sensor_msgs/JointState`` over reliable QoS from a pacing thread, each stamped with the wall
clock at publication, and receives the node's ``colliding_pairs`` (published right after
``contact``, and carrying the joint state's stamp), so for every message:

- dropped: published joint states whose stamp never came back;
- latency: wall clock at reception minus the stamp (publish -> verdict received, both
  processes on this machine's clock), reported as p50 / p99 / max;
- wrong: verdicts that differ from ``CollisionChecker.check`` on the same configuration here.

After the main run, a few short runs find the highest rate sustained without a drop: the
``--steps`` rates upwards until one drops, or, if the main run dropped, 75, 50 and 25 % of it. This is a benchmark, not a test: it asserts nothing. DDS stays in shared memory
(``FASTDDS_BUILTIN_TRANSPORTS=SHM``) in ``ROS_DOMAIN_ID`` (a random one if unset).
"""
import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid

import numpy as np

os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))

N_CONFIGURATIONS = 1000     # distinct configurations, cycled through by every run


def _node_command(params_file: str, namespace: str):
    script = os.path.join(os.path.dirname(sys.executable), 'collision_sensor_node')
    program = [script] if os.path.exists(script) else [sys.executable, '-m',
                                                       'collision_sensor.node']
    return program + ['--ros-args', '--params-file', params_file, '-r', f'__ns:={namespace}',
                      '--log-level', 'warn']


def _write_params(directory: str, robot) -> str:
    import yaml
    values = {'urdf_path': robot.urdf, 'srdf_path': robot.srdf,
              'package_paths': [f'{name}={path}' for name, path in robot.package_paths.items()],
              'joint_states_qos': 'reliable', 'stale_timeout': 0.0}
    path = os.path.join(directory, 'node_latency.yaml')
    with open(path, 'w') as stream:
        yaml.safe_dump({'/**': {'ros__parameters': values}}, stream)
    return path


class Driver:
    """The bench's side of the DDS link: a pacing publisher and a verdict recorder."""

    def __init__(self, namespace: str, joint_names, configurations, expected):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        # A lean node: no parameter or type-description services in its wait set.
        self.node = Node('node_latency_driver', namespace=namespace, context=self.context,
                         start_parameter_services=False, enable_rosout=False,
                         parameter_overrides=[Parameter('start_type_description_service',
                                                        value=False)])
        # No executor: the receive loop waits on the one subscription itself (as the node does
        # with its input), so this side stays cheap and does not perturb the measurement.
        self._wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, self.context.handle)
        # Deep histories on both sides: the bench must not be the one that drops.
        self.publisher = self.node.create_publisher(
            JointState, 'joint_states',
            QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self.subscription = self.node.create_subscription(
            DiagnosticArray, 'colliding_pairs', lambda msg: None,
            QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self.namespace = namespace
        self.joint_names = list(joint_names)
        self.configurations = [list(map(float, q)) for q in configurations]
        self.expected = expected
        self._msg_type = JointState
        self.received = []      # (receive wall ns, stamp ns, pair names "a:b")
        self.sent = {}          # stamp ns -> configuration index

    def receive(self, timeout: float) -> None:
        """Wait up to ``timeout`` s for verdicts and record every one that is waiting."""
        subscription, wait_set = self.subscription, self._wait_set
        with subscription.handle:
            wait_set.clear_entities()
            wait_set.add_subscription(subscription.handle)
            wait_set.wait(int(timeout * 1e9))
            while True:
                taken = subscription.handle.take_message(subscription.msg_type, False)
                if taken is None:
                    break
                stamp = taken[0].header.stamp
                self.received.append((time.time_ns(),
                                      stamp.sec * 1_000_000_000 + stamp.nanosec,
                                      tuple(status.name for status in taken[0].status)))

    def spin_until(self, condition, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.receive(0.05)
        return True

    def wait_for_node(self, timeout: float) -> bool:
        topic = f'{self.namespace}/joint_states'
        return self.spin_until(
            lambda: self.node.count_subscribers(topic) > 0
            and self.publisher.get_subscription_count() > 0
            and self.node.count_publishers(f'{self.namespace}/colliding_pairs') > 0, timeout)

    def _message(self, index: int, stamp_ns: int):
        msg = self._msg_type()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        msg.name = self.joint_names
        msg.position = self.configurations[index % len(self.configurations)]
        return msg

    def run(self, rate: float, duration: float, first_index: int = 0) -> dict:
        """Publish at ``rate`` for ``duration`` seconds while spinning; return the figures."""
        self.received.clear()
        self.sent.clear()
        count = int(round(rate * duration))
        period_ns = int(1e9 / rate)
        late = [0]

        def publish_all():
            start = time.monotonic_ns() + 20_000_000
            for i in range(count):
                target = start + i * period_ns
                delay = target - time.monotonic_ns()
                if delay > 0:
                    time.sleep(delay / 1e9)
                elif delay < -period_ns:
                    late[0] += 1
                stamp = time.time_ns()
                index = first_index + i
                self.sent[stamp] = index % len(self.configurations)
                self.publisher.publish(self._message(index, stamp))

        publisher = threading.Thread(target=publish_all, name='pacer')
        began = time.monotonic()
        publisher.start()
        while publisher.is_alive():
            self.receive(0.01)
        publish_seconds = time.monotonic() - began
        # Stragglers: up to 2 s after the last publication.
        self.spin_until(lambda: len(self.received) >= count, 2.0)
        return self._figures(rate, count, publish_seconds, late[0])

    def _figures(self, rate, count, publish_seconds, late):
        latencies, wrong = [], 0
        seen = set()
        for received_ns, stamp_ns, names in self.received:
            index = self.sent.get(stamp_ns)
            if index is None:   # a verdict for a message of an earlier run
                continue
            seen.add(stamp_ns)
            latencies.append((received_ns - stamp_ns) / 1e6)
            if names != self.expected[index]:
                wrong += 1
        latencies = np.array(latencies) if latencies else np.array([np.nan])
        return {
            'rate_hz': rate, 'published': count,
            'achieved_publish_rate_hz': count / publish_seconds,
            'late_publications': late, 'received': len(seen),
            'dropped': count - len(seen), 'wrong': wrong,
            'p50_ms': float(np.percentile(latencies, 50)),
            'p99_ms': float(np.percentile(latencies, 99)),
            'max_ms': float(np.max(latencies)),
        }

    def close(self):
        import rclpy
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


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


def _print_figures(label: str, figures: dict):
    print(f'{label:>10}: rate {figures["rate_hz"]:7.0f} Hz (published at '
          f'{figures["achieved_publish_rate_hz"]:7.1f} Hz, {figures["late_publications"]} late)'
          f'  sent {figures["published"]:6d}  dropped {figures["dropped"]:5d}'
          f'  wrong {figures["wrong"]:3d}  latency p50 {figures["p50_ms"]:7.3f} ms'
          f'  p99 {figures["p99_ms"]:7.3f} ms  max {figures["max_ms"]:8.3f} ms', flush=True)


def main(argv=None) -> int:
    """Run the benchmark; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=1000.0, help='Hz of the main run')
    parser.add_argument('--duration', type=float, default=30.0, help='s of the main run')
    parser.add_argument('--steps', default='2000,3000,5000,8000',
                        help='comma-separated rates (Hz) of the search for the highest rate '
                             'without drops; empty: skip')
    parser.add_argument('--step-duration', type=float, default=5.0, help='s of each step')
    parser.add_argument('--robot', default='panda', help='example robot: panda or ur5')
    parser.add_argument('--seed', type=int, default=1)
    args = parser.parse_args(argv)

    from collision_sensor import CollisionChecker
    from collision_sensor.example_robots import example_robot

    robot = example_robot(args.robot)
    print(f'node_latency: robot {robot.name}, ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, '
          f'FASTDDS_BUILTIN_TRANSPORTS={os.environ["FASTDDS_BUILTIN_TRANSPORTS"]}, '
          f'{os.cpu_count()} cores', flush=True)
    checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                         package_paths=robot.package_paths)
    configurations, expected = _configurations(checker, N_CONFIGURATIONS, args.seed)
    colliding = sum(1 for pairs in expected if pairs)
    print(f'{N_CONFIGURATIONS} random configurations, {colliding} colliding', flush=True)

    directory = tempfile.mkdtemp(prefix='node_latency_')
    namespace = f'/node_latency_{uuid.uuid4().hex[:8]}'
    command = _node_command(_write_params(directory, robot), namespace)
    log_path = os.path.join(directory, 'node.log')
    log = open(log_path, 'w')
    node = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    driver = None
    try:
        driver = Driver(namespace, checker.joint_names, configurations, expected)
        if not driver.wait_for_node(120.0):
            print(f'the node did not come up; its log: {log_path}', file=sys.stderr)
            return 1
        # Warm-up: the node's first checks load (or, with a cold cache, compile) its kernels.
        warm = driver.run(100.0, 2.0)
        driver.spin_until(lambda: len(driver.received) >= warm['published'], 120.0)
        _print_figures('warm-up', warm)
        main_run = driver.run(args.rate, args.duration, first_index=200)
        _print_figures('main', main_run)
        best = main_run['rate_hz'] if main_run['dropped'] == 0 else None
        steps = [float(step) for step in args.steps.split(',') if step.strip()]
        if best is None:     # search downwards instead
            steps = [args.rate * fraction for fraction in (0.75, 0.5, 0.25)]
        else:
            steps = sorted(rate for rate in steps if rate > best)
        for rate in steps:
            figures = driver.run(rate, args.step_duration)
            _print_figures('step', figures)
            if figures['dropped'] == 0:
                best = max(best or 0.0, rate)
            if (figures['dropped'] == 0) != (main_run['dropped'] == 0):
                break   # upwards: the first rate that drops; downwards: the first that does not
        print(f'highest rate sustained without drops: '
              f'{"none of the rates tried" if best is None else f"{best:.0f} Hz"}', flush=True)
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
