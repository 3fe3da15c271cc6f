"""What the node's tests share: the Panda as the reference answer, a recorded sequence, the
probe that talks to a node, and the node as a process of its own.

No launch: each test makes its own Context, executor, namespace and probe node
(``ros_helpers.RosHarness``, the ``ros`` fixture), starts the node in the test process
(:func:`start_node`) or as a separate process from its console script (:func:`node_process`)
and talks to it over DDS shared memory. Test modules import the fixtures they use from here.
"""
import os
import signal
import subprocess
import time

import numpy as np
import pytest

pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.ros.console_scripts import console_script  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from ros_helpers import WAIT, RosHarness, reliable  # noqa: E402

ARM = tuple(f'panda_joint{i}' for i in range(1, 8))
GRIPPER = ('panda_finger_joint1',)
N_FRAMES = 200
NODE_SCRIPT = console_script('collision_sensor_node')

# A box on a slider next to a fixed box: a second robot to replace the Panda with.
SLIDER_URDF = """<?xml version="1.0"?>
<robot name="slider">
  <link name="base"/>
  <link name="anchor">
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <link name="carriage">
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="fix" type="fixed"><parent link="base"/><child link="anchor"/></joint>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="carriage"/>
    <origin xyz="1 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
"""



@pytest.fixture(scope='module')
def panda(panda_urdf, panda_srdf, erd_package_paths):
    """The reference checker (a separate instance from any node's)."""
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths)


@pytest.fixture(scope='module')
def frames(panda):
    """A recorded Panda sequence: (200, 8) positions in ARM + GRIPPER order, seeded.

    A random walk within the joint limits with jumps to fresh random configurations, so that
    runs of colliding and free frames alternate.
    """
    rng = np.random.default_rng(20240611)
    names = ARM + GRIPPER
    lower = np.array([panda.joint_limits[name][0] for name in names])
    upper = np.array([panda.joint_limits[name][1] for name in names])
    q = rng.uniform(lower, upper)
    out = []
    for _ in range(N_FRAMES):
        if rng.random() < 0.25:
            q = rng.uniform(lower, upper)
        else:
            q = np.clip(q + rng.normal(0.0, 0.15, len(names)) * (upper - lower) / 4, lower, upper)
        out.append(q.copy())
    return np.array(out)


@pytest.fixture(scope='module')
def expected(panda, frames):
    """``CollisionChecker.check`` on each frame: list of (in_collision, colliding_pairs)."""
    answers = []
    for q in frames:
        result = panda.check(dict(zip(ARM + GRIPPER, q)))
        answers.append((result.in_collision, tuple(result.colliding_pairs)))
    colliding = sum(in_collision for in_collision, _ in answers)
    assert 10 <= colliding <= N_FRAMES - 10, f'{colliding} colliding frames: re-seed'
    return answers


@pytest.fixture(scope='module')
def poses(frames, expected):
    """One free and one colliding configuration of the sequence, as {joint: value}."""
    free = next(i for i, (hit, _) in enumerate(expected) if not hit)
    hit = next(i for i, (hit, _) in enumerate(expected) if hit)
    as_dict = lambda i: dict(zip(ARM + GRIPPER, map(float, frames[i])))  # noqa: E731
    return {'free': as_dict(free), 'hit': as_dict(hit), 'hit_pairs': expected[hit][1]}


@pytest.fixture
def ros(request):
    harness = RosHarness(request.node.name)
    yield harness
    harness.close()



def panda_parameters(panda_urdf, panda_srdf, erd_share, **overrides):
    values = {'urdf_path': panda_urdf, 'srdf_path': panda_srdf,
              'package_paths': [f'example-robot-data={erd_share}'],
              'joint_states_qos': 'reliable'}
    values.update(overrides)
    return [Parameter(name, value=value) for name, value in values.items()]


def start_node(ros, parameters):
    node = CollisionSensorNode(namespace=ros.namespace, context=ros.context,
                               parameter_overrides=parameters)
    return ros.add(node)


def joint_state(positions, stamp=None, names=None):
    msg = JointState()
    msg.name = list(names if names is not None else positions)
    msg.position = [float(positions[name]) for name in msg.name] if names is None else list(
        positions)
    if stamp is not None:
        msg.header.stamp = stamp
    return msg


def stamp_of(k: int) -> Time:
    return Time(sec=1000 + k, nanosec=1000 * k)


class Probe:
    """The test side: publishes joint states, records the node's outputs."""

    def __init__(self, ros, markers=False, timeout=WAIT):
        self.ros = ros
        self.joint_states = ros.publisher(JointState, 'joint_states', reliable(100))
        self.contact = ros.record(Bool, 'contact', reliable(1000, latched=True))
        self.pairs = ros.record(DiagnosticArray, 'colliding_pairs', reliable(1000, latched=True))
        self.diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
        self.markers = ros.record(MarkerArray, 'collision_sensor/markers', 100) if markers \
            else None
        assert ros.wait_for_subscribers(self.joint_states, timeout=timeout), \
            'the node never subscribed'

    def send(self, msg, wait=True, timeout=WAIT):
        """Publish ``msg``; with ``wait``, spin until the verdict for it arrived."""
        count = len(self.pairs)
        self.joint_states.publish(msg)
        if wait:
            assert self.ros.spin_until(
                lambda: len(self.pairs) > count and len(self.contact) > count, timeout), \
                'no verdict'
            return self.contact.last.data, pairs_of(self.pairs.last)

    def no_verdict_for(self, msg, seconds=0.3):
        """Publish ``msg`` and check that no verdict follows."""
        count = len(self.pairs)
        self.joint_states.publish(msg)
        self.ros.spin_for(seconds)
        return len(self.pairs) == count

    def next_diagnostics(self, condition=lambda values: True, timeout=WAIT):
        """Spin until a /diagnostics status of this node satisfies ``condition(values)``."""
        found = []
        name = f'{self.ros.namespace.strip("/")}/collision_sensor: collision sensor'

        def ready():
            while self.diagnostics.messages:
                for status in self.diagnostics.messages.pop(0).status:
                    values = {kv.key: kv.value for kv in status.values}
                    if status.name == name and condition(values):
                        found.append((status, values))
            return bool(found)

        assert self.ros.spin_until(ready, timeout), 'no matching diagnostics'
        return found[0]


def logged(ros, capfd, text, timeout=WAIT):
    """Spin until the node has logged ``text`` (it logs after it published the verdict, once
    its lock is released); return everything captured on stderr since the last read.

    Polling peeks at the capture file through a descriptor of its own: ``readouterr`` reads
    and then truncates that file, so a line the node's thread writes in between would be lost.
    """
    seen = ['']

    def peek():
        with open('/proc/self/fd/2', 'rb') as stream:
            seen[0] = stream.read().decode(errors='replace')
        return text in seen[0]

    ros.spin_until(peek, timeout)
    capfd.readouterr()
    return seen[0]


def pairs_of(msg: DiagnosticArray):
    return tuple(tuple(status.name.split(':')) for status in msg.status)



def node_process(namespace, *extra, urdf=None, srdf=None, erd_share=None):
    args = [NODE_SCRIPT, '--ros-args', '-r', f'__ns:={namespace}', '-p',
            'joint_states_qos:=reliable']
    if urdf:
        args += ['-p', f'urdf_path:={urdf}', '-p', f'srdf_path:={srdf}', '-p',
                 f'package_paths:=["example-robot-data={erd_share}"]']
    env = dict(os.environ, RCUTILS_CONSOLE_OUTPUT_FORMAT='[{severity}] {message}',
               PYTHONUNBUFFERED='1')
    return subprocess.Popen(args + list(extra), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env)


def stop(process, signum, timeout=WAIT):
    """Send ``signum``; return (exit status, output, seconds to exit)."""
    started = time.monotonic()
    process.send_signal(signum)
    try:
        output, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        output, _ = process.communicate()
        pytest.fail(f'the node did not stop within {timeout} s of {signum!r}:\n{output}')
    return process.returncode, output, time.monotonic() - started


def assert_clean_exit(status, output):
    assert status == 0, output
    assert 'Traceback' not in output and 'core dumped' not in output, output
    assert 'Error' not in output and 'Exception' not in output, output


def wait_until_signals_are_handled(process, timeout=WAIT):
    """Wait until the process catches SIGTERM (bit 15 of SigCgt in /proc/PID/status).

    Before that the interpreter itself is starting (about 0.1 s, no package code has run):
    there a signal takes its default action, which no Python program can change.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with open(f'/proc/{process.pid}/status') as stream:
            caught = next(int(line.split()[1], 16) for line in stream
                          if line.startswith('SigCgt:'))
        if caught & (1 << (signal.SIGTERM - 1)):
            return
        time.sleep(0.002)
    pytest.fail('the node never installed its SIGTERM handler')
