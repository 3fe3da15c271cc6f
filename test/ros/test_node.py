"""The ROS 2 node, with real rclpy and the real checker on the Panda of example-robot-data.

No launch: each test makes its own Context, executor, namespace and probe node
(``ros_helpers.RosHarness``), starts the node in the test process (or, once, as a separate
process from its console script) and talks to it over DDS shared memory. The Panda is loaded
once for the module as the reference answer.
"""
import math
import os
import signal
import subprocess
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool, Float64, String  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from collision_sensor import CollisionChecker, CollisionSensorError, ConfigError  # noqa: E402
from collision_sensor.model.share import config_path  # noqa: E402
from collision_sensor.ros.console_scripts import console_script  # noqa: E402
from collision_sensor.ros.node import (  # noqa: E402
    LATCHED_QOS, CollisionSensorNode, quaternion_from_matrix)
from collision_sensor.ros.node_parameters import (  # noqa: E402
    PARAMETERS, default_values, settings_from_values)
from engine_oracles import FclOracle  # noqa: E402
from ros_helpers import RosHarness, reliable  # noqa: E402

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


# -- module fixtures: the reference robot and poses ---------------------------------------------

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


# -- helpers ------------------------------------------------------------------------------------

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

    def __init__(self, ros, markers=False, timeout=5.0):
        self.ros = ros
        self.joint_states = ros.publisher(JointState, 'joint_states', reliable(100))
        self.contact = ros.record(Bool, 'contact', reliable(1000, latched=True))
        self.pairs = ros.record(DiagnosticArray, 'colliding_pairs', reliable(1000, latched=True))
        self.diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
        self.markers = ros.record(MarkerArray, 'collision_sensor/markers', 100) if markers \
            else None
        assert ros.wait_for_subscribers(self.joint_states, timeout=timeout), \
            'the node never subscribed'

    def send(self, msg, wait=True, timeout=5.0):
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

    def next_diagnostics(self, condition=lambda values: True, timeout=3.0):
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


def logged(ros, capfd, text, timeout=15.0):
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


# -- parameters ---------------------------------------------------------------------------------

def test_params_file_lists_every_parameter_with_its_default():
    with open(config_path('collision_sensor.yaml')) as stream:
        document = yaml.safe_load(stream)
    values = document['/**']['ros__parameters']
    assert list(values) == [spec.name for spec in PARAMETERS]
    defaults = default_values()
    for name, value in values.items():
        assert value == defaults[name], name
    with open(config_path('collision_sensor.yaml')) as stream:
        text = stream.read()
    for spec in PARAMETERS:   # every parameter has a comment line just above it
        before = text.split(f'    {spec.name}:')[0].rstrip().splitlines()[-1]
        assert before.strip().startswith('#'), spec.name


def test_shipped_params_file_declares_typed_defaults(ros):
    node = ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context,
        cli_args=['--ros-args', '--params-file', config_path('collision_sensor.yaml')]))
    for spec in PARAMETERS:
        value = node.get_parameter_or(spec.name, None)
        if isinstance(spec.default, tuple):   # empty string arrays read as "not set"
            assert value is None or value.value in (None, [])
        else:
            assert value.value == spec.default and type(value.value) is type(spec.default)
    descriptor = node.describe_parameter('allowed_collisions')
    assert descriptor.type == Parameter.Type.STRING_ARRAY.value and not descriptor.read_only
    for spec in PARAMETERS:     # settable at run time: the dynamic ones only
        assert node.describe_parameter(spec.name).read_only is not spec.dynamic, spec.name
    result = node.set_parameters([Parameter('stale_timeout', value=5.0)])[0]
    assert not result.successful    # read-only: the node does not take it at run time


@pytest.mark.parametrize('overrides, words', [
    ({'urdf_path': '/no/such/robot.urdf'}, ['urdf_path', '/no/such/robot.urdf']),
    ({'joint_states_qos': 'fast'}, ['joint_states_qos', 'fast', 'sensor_data']),
    ({'package_paths': ['example-robot-data']}, ['package_paths', 'name=dir']),
    ({'stale_timeout': 1}, ['stale_timeout', '1.0']),
    ({'expansion': 'widest'}, ['expansion', 'widest']),
    ({'joint_limit_policy': 'wrap'}, ['joint_limit_policy', 'wrap', 'clamp']),
    ({'joint_limit_tolerance': -0.1}, ['joint_limit_tolerance', '>= 0']),
    ({'max_unknown_joints': -1}, ['max_unknown_joints', '>= 0']),
    ({'allowed_collisions': ['panda_link0']}, ['allowed_collisions', 'link_a:link_b']),
    ({'padding': -0.01}, ['padding', '>= 0']),
    ({'link_padding': ['panda_hand:0.02']}, ['link_padding', 'link=metres']),
    ({'link_padding': ['panda_hand=-1']}, ['link_padding', 'panda_hand=-1']),
    ({'link_padding': ['panda_hnad=0.02']}, ['link_padding', 'panda_hnad']),
    ({'warning_distance': math.inf}, ['warning_distance', '>= 0']),
])
def test_bad_configuration_fails_with_a_clear_reason(ros, panda_urdf, panda_srdf, erd_share,
                                                     overrides, words, capfd):
    with pytest.raises(CollisionSensorError) as raised:
        start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, **overrides))
    for word in words:
        assert word in str(raised.value)
    assert 'configuration failed' in capfd.readouterr().err    # logged before raising


def test_bad_configuration_exits_non_zero_from_the_console_script(tmp_path):
    params = tmp_path / 'bad.yaml'
    params.write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'urdf_path': str(tmp_path / 'missing.urdf')}}}))
    run = subprocess.run([NODE_SCRIPT, '--ros-args', '--params-file', str(params)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 1
    assert 'configuration failed' in run.stderr and 'missing.urdf' in run.stderr


# -- verdicts -----------------------------------------------------------------------------------

def motion_expected(panda, frames, expected):
    """What the node answers each frame with check_motion: (contact, pairs in contact at the
    frame, then (pair, first_contact) met on the way from the frame before), from a fresh
    ``check`` and ``check_motion``."""
    answers = []
    for k, (hit, pairs) in enumerate(expected):
        met, contact = (), hit
        if k > 0:
            found = panda.check_motion(frames[k - 1], frames[k])
            met = tuple((pair, found.first_contact) for pair in found.colliding_pairs
                        if pair not in pairs)
            contact = hit or found.in_collision
        answers.append((contact, pairs, met))
    return answers


@pytest.mark.parametrize('check_motion', [False, True], ids=['instants', 'motions'])
def test_recorded_sequence_matches_the_checker(ros, panda, panda_urdf, panda_srdf, erd_share,
                                               frames, expected, check_motion):
    """Off: each verdict is a fresh check() of the frame. On: the pairs in contact at the
    frame, then those met on the way from the frame before (check_motion), with first_contact;
    the random walk's jumps cross the robot's own links often."""
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     check_motion=check_motion))
    probe = Probe(ros)
    names = ARM + GRIPPER
    for k, q in enumerate(frames):
        msg = joint_state(q, stamp=stamp_of(k), names=names)
        msg.header.frame_id = 'recording'
        probe.send(msg)
    want = (motion_expected(panda, frames, expected) if check_motion
            else [(hit, pairs, ()) for hit, pairs in expected])
    assert [msg.data for msg in probe.contact.messages] == [hit for hit, _, _ in want]
    met_total = 0
    for k, msg in enumerate(probe.pairs.messages):
        now, met = [], []
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            assert status.level == DiagnosticStatus.ERROR
            assert status.name == f'{values["link_a"]}:{values["link_b"]}'
            assert values['link_a'] < values['link_b']
            pair = (values['link_a'], values['link_b'])
            if 'first_contact' in values:   # met on the way, after those in contact now
                assert ' met ' in status.message and 'on the way' in status.message
                met.append((pair, float(values['first_contact'])))
            else:
                assert not met, 'pairs in contact now come first'
                now.append(pair)
        assert tuple(now) == want[k][1], k
        assert [pair for pair, _ in met] == [pair for pair, _ in want[k][2]], k
        for (_, got), (_, first) in zip(met, want[k][2]):
            assert got == pytest.approx(first, abs=1e-4), k
        met_total += len(met)
        assert msg.header.stamp == stamp_of(k) and msg.header.frame_id == 'recording'
    assert (met_total > 5) == check_motion     # the motions do meet pairs the frames miss
    # A late subscriber gets the latest verdict at once (transient local). The node keeps the
    # last VERDICT_DEPTH verdicts for reliable readers; a depth-1 reader may be handed one or
    # two of the older ones on its way, and ends at the latest.
    late_contact = ros.record(Bool, 'contact', LATCHED_QOS)
    late_pairs = ros.record(DiagnosticArray, 'colliding_pairs', LATCHED_QOS)
    assert ros.spin_until(lambda: len(late_contact) and len(late_pairs))
    assert ros.spin_until(lambda: late_pairs.last.header.stamp == stamp_of(N_FRAMES - 1))
    ros.spin_for(0.2)
    assert late_contact.last.data == want[-1][0]
    assert late_pairs.last.header.stamp == stamp_of(N_FRAMES - 1)


def test_partial_states_from_two_publishers_merge(ros, panda, panda_urdf, panda_srdf, erd_share,
                                                  poses):
    # Instants (check_motion off): the poses jump; test_node_motion.py checks the motions.
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, check_motion=False))
    probe = Probe(ros)
    gripper = ros.publisher(JointState, 'joint_states', reliable(10))
    hit, free = poses['hit'], poses['free']
    # The arm alone cannot be checked yet: answered, contact true (on_rejected_input contact).
    assert probe.send(joint_state({name: hit[name] for name in ARM})) == \
        (True, (('waiting_for_joints',),))
    count = len(probe.pairs)
    gripper.publish(joint_state({name: hit[name] for name in GRIPPER}))
    assert ros.spin_until(lambda: len(probe.pairs) > count)
    assert probe.contact.last.data and pairs_of(probe.pairs.last) == poses['hit_pairs']
    # Each publisher now moves its own subset; the verdict is that of the merged state, which
    # the reference follows by being given the same subsets from the same full state.
    panda.check(hit)
    rng = np.random.default_rng(3)
    verdicts = set()
    for step in range(8):
        side = ARM if step % 2 == 0 else GRIPPER
        source = free if rng.random() < 0.5 else hit
        state = {name: source[name] for name in side}
        count = len(probe.pairs)
        (probe.joint_states if side is ARM else gripper).publish(joint_state(state))
        assert ros.spin_until(lambda: len(probe.pairs) > count)
        reference = panda.check(state)    # keeps the other joints from before, as the node
        assert probe.contact.last.data == reference.in_collision
        assert pairs_of(probe.pairs.last) == tuple(reference.colliding_pairs)
        verdicts.add(reference.in_collision)
    assert verdicts == {False, True}    # the sequence went through both


def test_overload_checks_the_newest_state_and_counts_the_rest(ros, panda, panda_urdf,
                                                             panda_srdf, erd_share, frames,
                                                             expected):
    """A backlog beyond MAX_BACKLOG: every message merged, only the newest answered, the
    others counted as skipped_superseded; a gripper-only message among them still counts."""
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    names = ARM + GRIPPER
    free = next(k for k, (hit, _) in enumerate(expected) if not hit)
    probe.send(joint_state(frames[free], stamp=stamp_of(free), names=names))
    count = len(probe.pairs)
    batch = [joint_state(frames[k], stamp=stamp_of(k), names=names) for k in range(5)]
    batch.append(joint_state({GRIPPER[0]: 0.0123}, stamp=stamp_of(5)))
    batch.append(joint_state(frames[6][:7], stamp=stamp_of(6), names=ARM))
    node._on_joint_states(batch, True)    # what the checking thread does with a long backlog
    ros.spin_for(0.3)
    assert len(probe.pairs) == count + 1 and len(probe.contact) == count + 1
    reference = panda.check(dict(zip(names, list(frames[6][:7]) + [0.0123])))
    assert probe.pairs.last.header.stamp == stamp_of(6)
    assert pairs_of(probe.pairs.last) == tuple(reference.colliding_pairs)
    assert probe.contact.last.data == reference.in_collision
    _, values = probe.next_diagnostics(lambda values: values['verdicts_total'] == '2')
    assert values['skipped_superseded'] == '6' and values['skipped_total'] == '6'
    assert values['received_total'] == '8'


def test_overload_whose_newest_message_is_rejected_answers_the_newest_accepted(
        ros, panda, panda_urdf, panda_srdf, erd_share, frames):
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    names = ARM + GRIPPER
    bad = joint_state(frames[2], stamp=stamp_of(2), names=names)
    bad.position[0] = math.nan
    batch = [joint_state(frames[k], stamp=stamp_of(k), names=names) for k in range(2)] + [bad]
    node._on_joint_states(batch, True)
    assert ros.spin_until(lambda: len(probe.pairs) == 1)
    ros.spin_for(0.2)
    assert len(probe.pairs) == 1 and probe.pairs.last.header.stamp == stamp_of(1)
    reference = panda.check(dict(zip(names, frames[1])))
    assert pairs_of(probe.pairs.last) == tuple(reference.colliding_pairs)
    _, values = probe.next_diagnostics(lambda values: values['verdicts_total'] == '1')
    assert values['skipped_superseded'] == '1' and values['skipped_rejected'] == '1'


def test_checking_thread_answers_each_message_unless_the_backlog_is_long():
    from collision_sensor.ros.sensor_node import MAX_BACKLOG, _NewestFirstWorker
    import threading
    calls, entered, release = [], threading.Event(), threading.Event()

    def handle(batch, newest_only):
        calls.append((list(batch), newest_only))
        entered.set()
        release.wait(5.0)

    worker = _NewestFirstWorker(handle, 'test worker')
    try:
        worker.put('first')
        assert entered.wait(5.0)
        for k in range(MAX_BACKLOG + 1):      # arrive while the first is being checked
            worker.put(k)
        release.set()
        deadline = time.monotonic() + 5.0
        while len(calls) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        worker.put('alone')
        while len(calls) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        release.set()
        worker.stop()
    assert calls == [(['first'], False), (list(range(MAX_BACKLOG + 1)), True),
                     (['alone'], False)]


def test_verdicts_published_serialized_are_the_messages_they_stand_for(ros):
    """VerdictPublisher writes its messages serialized, the stamp in place: each verdict read
    back by a plain subscriber is the DiagnosticArray built from scratch for that header and
    those pairs (header frames of every length modulo 4, pairs that come and go, a motion's
    pairs met on the way, the held verdict repeated)."""
    from collision_sensor.engine.checker import CheckResult
    from collision_sensor.ros.motion_stream import MotionVerdict
    from collision_sensor.ros.verdicts import VERDICT_QOS, VerdictPublisher
    from std_msgs.msg import Header
    from rclpy.node import Node
    host = ros.add(Node('verdicts', namespace=ros.namespace, context=ros.context))
    verdicts = VerdictPublisher(host)
    verdicts.forget('world')
    contacts = ros.record(Bool, 'contact', VERDICT_QOS)
    pairs = ros.record(DiagnosticArray, 'colliding_pairs', VERDICT_QOS)
    assert ros.spin_until(lambda: host.count_subscribers(f'{ros.namespace}/colliding_pairs'), 5)
    reference = VerdictPublisher.__new__(VerdictPublisher)   # its status builder, nothing sent
    reference.root_frame = 'world'
    cases = []
    sets = [(), (('hand', 'table'),), (('hand', 'table'), ('link3', 'link7')), ()]
    for k in range(12):
        header = Header(frame_id=['', 'a', 'ab', 'abc', 'base_link'][k % 5])
        header.stamp.sec, header.stamp.nanosec = 1700000000 + k, 1000 * k + 7
        colliding = sets[k % len(sets)]
        motion = (MotionVerdict(True, 0.25, (('elbow', 'shelf'),)) if k % 3 == 2
                  else MotionVerdict(False, None, ()))
        if k == 7:
            assert verdicts.publish_held(header)
            colliding, motion = cases[-1][1], cases[-1][2]
        else:
            verdicts.publish(header, CheckResult(bool(colliding), colliding, 0), motion)
        cases.append((header, colliding, motion))
    assert ros.spin_until(lambda: len(pairs) >= len(cases) and len(contacts) >= len(cases), 5)
    for (header, colliding, motion), got, contact in zip(cases, pairs.messages,
                                                        contacts.messages):
        want = DiagnosticArray(header=header,
                               status=reference._pair_statuses(colliding, motion))
        assert got == want
        assert contact.data == (bool(colliding) or motion.in_collision)


@pytest.mark.skipif(not os.path.isdir('/proc/self/task'), reason='Linux schedules threads')
def test_background_work_yields_the_cores_to_the_joint_states():
    """Point clouds and planned trajectories run on threads of lower priority (niceness +10),
    read back from the kernel's own record of each thread; the joint states' thread is not
    lowered."""
    import threading
    from collision_sensor.ros.work_queue import BACKGROUND_NICE, NewestFirstWorker

    def niceness(tid):
        with open(f'/proc/self/task/{tid}/stat') as stat:
            return int(stat.read().rsplit(')', 1)[1].split()[16])

    seen = {}

    def handle(batch, newest_only):
        tid = threading.get_native_id()
        seen[batch[0]] = (tid, niceness(tid))

    base = niceness(threading.get_native_id())
    workers = [NewestFirstWorker(handle, 'background', 1, nice=BACKGROUND_NICE),
               NewestFirstWorker(handle, 'joint states')]
    try:
        workers[0].put('background')
        workers[1].put('joint states')
        deadline = time.monotonic() + 5.0
        while len(seen) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        for worker in workers:
            worker.stop()
    assert seen['background'][1] == min(19, base + BACKGROUND_NICE)
    assert seen['joint states'][1] == base
    assert niceness(threading.get_native_id()) == base     # the caller's thread untouched


def test_node_uses_only_public_rclpy():
    """No private rclpy layer (``_rclpy``, ``take_message``): it changes between releases.
    Every module of the node, since it is split by concern; the one private read (the names
    of the parameters given, which rclpy does not expose) is in node_parameters, guarded."""
    import pathlib
    from collision_sensor import ros
    for path in pathlib.Path(ros.__file__).parent.glob('*.py'):
        source = path.read_text()
        assert 'rclpy.impl' not in source and 'take_message' not in source, path.name
        assert '_rclpy' not in source, path.name
        private = [line.strip() for line in source.splitlines()
                   if "'_parameter_overrides'" in line or 'node._' in line]
        assert private == ([] if path.name != 'node_parameters.py' else
                           ["overrides = getattr(node, '_parameter_overrides', None)"]), path.name


def test_require_all_joints_off_checks_partial_states(ros, panda, panda_urdf, panda_srdf,
                                                      erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     require_all_joints=False, check_motion=False))
    probe = Probe(ros)
    for pose in ('hit', 'free'):
        arm = {name: poses[pose][name] for name in ARM}
        # Joints never heard keep the checker's start value, 0 (the gripper closed).
        reference = panda.check(dict(arm, panda_finger_joint1=0.0))
        assert probe.send(joint_state(arm)) == (reference.in_collision,
                                                tuple(reference.colliding_pairs))


def test_waiting_for_joints_is_reported(ros, panda_urdf, panda_srdf, erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    status, values = probe.next_diagnostics()
    assert values['seconds_since_joint_state'] == '' and values['waiting_for_joints'] == 'true'
    assert status.level == DiagnosticStatus.WARN and 'waiting for joint states' in status.message
    assert probe.send(joint_state({name: poses['free'][name] for name in ARM})) == \
        (True, (('waiting_for_joints',),))
    entry = probe.pairs.last.status[0]
    assert entry.level == DiagnosticStatus.ERROR and 'panda_finger_joint1' in entry.message
    assert {kv.key: kv.value for kv in entry.values}['policy'] == 'contact'
    status, values = probe.next_diagnostics(lambda v: v['seconds_since_joint_state'] != '')
    assert values['missing_joints'] == 'panda_finger_joint1'
    assert values['waiting_for_joints'] == 'true'
    assert status.level == DiagnosticStatus.WARN and 'panda_finger_joint1' in status.message


def test_bad_joint_states_are_rejected_and_change_nothing(ros, panda_urdf, panda_srdf,
                                                          erd_share, poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    free, hit = poses['free'], poses['hit']
    assert probe.send(joint_state(free)) == (False, ())
    names = list(ARM + GRIPPER)
    hit_values = [hit[name] for name in names]
    bad = {
        'length': joint_state(hit_values[:-1], names=names),
        'duplicate': joint_state(hit_values + [0.0], names=names + ['panda_joint3']),
        'nan': joint_state(hit_values[:-1] + [math.nan], names=names),
        'inf': joint_state([math.inf] + hit_values[1:], names=names),
    }
    for k, msg in enumerate(bad.values()):
        # Each would make the robot collide if any of it were taken. Each is answered: contact
        # true (on_rejected_input contact), the reason as the one entry, the message's stamp.
        msg.header.stamp = stamp_of(k)
        assert probe.send(msg) == (True, (('joint_state_rejected',),))
        assert probe.pairs.last.header.stamp == stamp_of(k)
        assert probe.pairs.last.status[0].level == DiagnosticStatus.ERROR
    velocity_only = joint_state([], names=names)
    velocity_only.velocity = [1.0] * len(names)
    assert probe.send(velocity_only) == (False, ())    # ignored: the state held, its verdict
    # The known state is unchanged: a message moving nothing gives the free verdict again.
    assert probe.send(joint_state({'panda_joint1': free['panda_joint1']})) == (False, ())
    err = capfd.readouterr().err
    assert 'joint state rejected' in err and '8 names but 7 positions' in err   # throttled:
    # the first of a kind within a second is shown, so each kind appears once here.
    assert 'given more than once: "panda_joint3"' in err
    assert 'not finite' in err and '"panda_finger_joint1"=nan' in err
    _, values = probe.next_diagnostics(lambda v: int(v['rejected_total']) >= 4)
    assert values['rejected_total'] == '4'


def test_unknown_joints_are_ignored_with_one_summary_line(ros, panda_urdf, panda_srdf, erd_share,
                                                         poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    state = dict(poses['free'], ghost_joint=3.0, panda_finger_joint2=0.01)   # + a mimic joint
    for _ in range(3):
        assert probe.send(joint_state(state)) == (False, ())
    err = logged(ros, capfd, 'ghost_joint')
    assert err.count('ignoring 1 joint name(s) in joint_states that the robot model does not '
                     'move: ghost_joint') == 1
    assert 'panda_finger_joint2' not in err    # mimic joints follow their source silently
    _, values = probe.next_diagnostics(lambda v: v['unknown_joints'] != '')
    assert values['unknown_joints'] == 'ghost_joint' and values['unknown_joints_count'] == '1'


def test_a_flood_of_unknown_names_stays_bounded_and_forges_no_line(ros, panda_urdf, panda_srdf,
                                                                   erd_share, poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, max_unknown_joints=50))
    probe = Probe(ros)
    forged = 'evil\n[ERROR] [0.0] [collision_sensor]: FORGED\x1b[2J'
    for k in range(4):     # 4 x 1500 new names (under max_joint_state_bytes), then the forging one
        names = [f'ghost_{k}_{i}' for i in range(1500)]
        assert probe.send(joint_state(dict(poses['free'], **dict.fromkeys(names, 0.0)))) == \
            (False, ())
    assert probe.send(joint_state(dict(poses['free'], **{forged: 0.0}))) == (False, ())
    ros.spin_for(0.3)
    err = capfd.readouterr().err
    assert err.count('that the robot model does not move') <= 2     # throttled: one a second
    assert '(+1495 more)' in err
    for line in err.splitlines():
        assert not line.startswith('[ERROR] [0.0]') and 'FORGED' not in line.split(']: ')[0]
    _, values = probe.next_diagnostics(lambda v: v['unknown_joints_not_remembered'] != '0')
    assert values['unknown_joints_count'] == '50'
    assert values['unknown_joints_not_remembered'] == str(6000 - 50 + 1)
    assert values['unknown_joints'].endswith('(+40 more)')
    assert max(len(value) for value in values.values()) < 1000


def test_an_oversized_joint_state_is_rejected_before_decoding(ros, panda_urdf, panda_srdf,
                                                              erd_share, poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     max_joint_state_bytes=4096))
    probe = Probe(ros)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    # 400 names: about 8 KiB serialized, above the 4 KiB allowed. No verdict, state unchanged.
    huge = dict(poses['hit'], **{f'ghost_{i}': 0.0 for i in range(400)})
    huge = joint_state(huge, stamp=stamp_of(7))
    huge.header.frame_id = 'big'
    assert probe.send(huge) == (True, (('joint_state_rejected',),))
    # Not decoded, yet answered with its header (read from the first bytes) and the reason.
    assert probe.pairs.last.header.stamp == stamp_of(7)
    assert probe.pairs.last.header.frame_id == 'big'
    assert 'above max_joint_state_bytes (4096)' in probe.pairs.last.status[0].message
    assert probe.send(joint_state({'panda_joint1': poses['free']['panda_joint1']})) == \
        (False, ())
    assert probe.send(joint_state(poses['hit']))[0]     # the robot's own states still fit
    err = capfd.readouterr().err
    assert 'joint state rejected before decoding, state unchanged' in err
    assert 'above max_joint_state_bytes (4096)' in err
    _, values = probe.next_diagnostics(lambda v: v['rejected_oversized'] != '0')
    assert values['rejected_oversized'] == '1' and values['unknown_joints_count'] == '0'


def test_max_joint_state_bytes_refuses_a_cap_below_1024():
    values = dict(default_values(), urdf_path='', max_joint_state_bytes=1000)
    with pytest.raises(ConfigError, match='max_joint_state_bytes: 1000 is not an integer >= 1024'):
        settings_from_values(values)


def test_out_of_limit_joints_are_rejected_by_default(ros, panda_urdf, panda_srdf, erd_share,
                                                    poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    for value in (0.5, 1e9, 9.2e18, 1.7e308, -1.7e308):    # panda_joint4 in [-3.0718, -0.0698]
        assert probe.send(joint_state(dict(poses['hit'], panda_joint4=value))) == \
            (True, (('joint_state_rejected',),))
    assert probe.send(joint_state({'panda_joint1': poses['free']['panda_joint1']})) == \
        (False, ())     # the state is unchanged: still the free pose
    # Within the tolerance (0.01 rad) a value is taken as given.
    state = dict(poses['free'], panda_joint4=-0.0698 + 0.005)
    assert probe.send(joint_state(state))
    err = capfd.readouterr().err
    assert 'joint state rejected, state unchanged: joint "panda_joint4" at 0.5 outside its ' \
           'limits [-3.0718, -0.0698] by more than joint_limit_tolerance 0.01' in err
    assert 'joint_limit_policy to "clamp" or "accept"' in err
    _, values = probe.next_diagnostics(lambda v: v['rejected_out_of_limits'] != '0')
    assert values['rejected_out_of_limits'] == '5' and values['joint_limit_policy'] == 'reject'


def test_out_of_limit_joints_clamped_on_request(ros, panda, panda_urdf, panda_srdf, erd_share,
                                                poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     joint_limit_policy='clamp'))
    probe = Probe(ros)
    reference = panda.check(dict(poses['hit'], panda_joint4=-0.0698))
    assert probe.send(joint_state(dict(poses['hit'], panda_joint4=9.2e18))) == (
        reference.in_collision, tuple(reference.colliding_pairs))
    _, values = probe.next_diagnostics(lambda v: v['clamped_total'] != '0')
    assert values['clamped_total'] == '1'
    text = 'clamped to them (joint_limit_policy clamp): panda_joint4'
    assert text in logged(ros, capfd, text)


def test_out_of_limit_joints_accepted_on_request_are_checked_and_reported(
        ros, panda, panda_urdf, panda_srdf, erd_share, poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     joint_limit_policy='accept'))
    probe = Probe(ros)
    state = dict(poses['free'], panda_joint4=0.5)    # limit [-3.0718, -0.0698]
    reference = panda.check(state)
    assert probe.send(joint_state(state)) == (reference.in_collision,
                                              tuple(reference.colliding_pairs))
    text = 'joint "panda_joint4" at 0.5 is outside its limits'
    assert text in logged(ros, capfd, text)
    status, values = probe.next_diagnostics(lambda v: v['out_of_limit_joints'] != '')
    assert values['out_of_limit_joints'].startswith('panda_joint4=0.5 [')
    assert status.level >= DiagnosticStatus.WARN


class _FlakyChecker:
    """A real checker whose update fails at one marked configuration."""

    MARK = 0.123

    def __init__(self, checker):
        self._checker = checker

    def __getattr__(self, name):
        return getattr(self._checker, name)

    def _fault(self, positions):
        # A mapping, or (the node's fast path) an array in joint_names order.
        value = (positions.get('panda_joint1') if hasattr(positions, 'get')
                 else positions[self._checker.joint_names.index('panda_joint1')])
        if value == self.MARK:
            raise RuntimeError('engine fault injected by the test')
        if value == -self.MARK:
            raise ConfigError('engine error injected by the test')

    def update(self, positions):
        self._fault(positions)
        return self._checker.update(positions)

    def check(self, positions):     # after an engine error the node checks from scratch
        self._fault(positions)
        return self._checker.check(positions)


def test_engine_errors_are_logged_and_the_node_keeps_running(ros, panda_urdf, panda_srdf,
                                                             erd_share, poses, capfd):
    def factory(*args, **kwargs):
        return _FlakyChecker(CollisionChecker.from_urdf(*args, **kwargs))

    ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context, checker_factory=factory,
        parameter_overrides=panda_parameters(panda_urdf, panda_srdf, erd_share)))
    probe = Probe(ros)
    free = poses['free']
    assert probe.send(joint_state(free)) == (False, ())
    # Answered, fail safe (on_engine_error contact): contact true, the error named.
    assert probe.send(joint_state(dict(free, panda_joint1=_FlakyChecker.MARK))) == \
        (True, (('engine_error',),))
    assert probe.send(joint_state(dict(free, panda_joint1=-_FlakyChecker.MARK))) == \
        (True, (('engine_error',),))
    assert 'engine error injected by the test' in probe.pairs.last.status[0].message
    assert probe.send(joint_state(free)) == (False, ())
    err = capfd.readouterr().err
    assert 'engine fault injected by the test' in err
    assert 'collision check failed: engine error injected by the test' in err
    _, values = probe.next_diagnostics(lambda v: v['engine_errors_total'] != '0')
    assert values['engine_errors_total'] == '2'


def test_stale_joint_states_are_reported(ros, panda_urdf, panda_srdf, erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, stale_timeout=0.2))
    probe = Probe(ros)
    probe.send(joint_state(poses['free']))
    status, values = probe.next_diagnostics(lambda v: v['stale'] == 'true')
    assert status.level == DiagnosticStatus.ERROR and 'stale' in status.message
    # stale_policy contact (the default): contact true once, the reason as the entry.
    assert ros.spin_until(lambda: pairs_of(probe.pairs.last) == (('joint_states_stale',),))
    assert probe.contact.last.data
    # A stream of joint states again (20 Hz): the state is fresh.
    ros.probe.create_timer(0.05, lambda: probe.joint_states.publish(joint_state(poses['free'])))
    status, values = probe.next_diagnostics(lambda v: v['stale'] == 'false')
    assert float(values['seconds_since_joint_state']) < 0.2
    assert status.level == DiagnosticStatus.OK and status.message == 'no collision'
    assert float(values['input_rate_hz']) > 0.0
    assert float(values['check_time_max_ms']) >= 0.0 and 'input_rate_hz' in values


def test_markers_appear_and_clear(ros, panda_urdf, panda_srdf, erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, publish_markers=True))
    probe = Probe(ros, markers=True)
    probe.send(joint_state(poses['hit']))
    assert ros.spin_until(lambda: len(probe.markers))
    markers = probe.markers.last.markers
    assert markers[0].action == Marker.DELETEALL
    boxes = markers[1:]
    colliding_links = {name for pair in poses['hit_pairs'] for name in pair}
    assert boxes and {marker.ns for marker in boxes} == colliding_links
    for marker in boxes:
        assert marker.type == Marker.CUBE and marker.action == Marker.ADD
        assert marker.header.frame_id == 'panda_link0'
        assert marker.color.r == 1.0 and marker.color.g == 0.0 and marker.color.b == 0.0
        assert min(marker.scale.x, marker.scale.y, marker.scale.z) > 0.0
        q = marker.pose.orientation
        assert abs(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2 - 1.0) < 1e-9
    count = len(probe.markers)
    probe.send(joint_state(poses['free']))
    assert ros.spin_until(lambda: len(probe.markers) > count)
    assert [marker.action for marker in probe.markers.last.markers] == [Marker.DELETEALL]


def test_quaternion_from_matrix_against_random_rotations():
    rng = np.random.default_rng(5)
    matrices = [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
                np.diag([-1.0, -1.0, 1.0])]     # the branches where w is 0
    for _ in range(200):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        matrices.append(q * np.sign(np.linalg.det(q)))
    for R in matrices:
        x, y, z, w = quaternion_from_matrix(R)
        assert abs(x * x + y * y + z * z + w * w - 1.0) < 1e-12
        rebuilt = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        assert np.allclose(rebuilt, R, atol=1e-12), R.tolist()


# -- the robot from the robot_description topic -------------------------------------------------

def test_robot_from_topic_and_bad_description_rejected(ros, panda_urdf, erd_share, poses,
                                                       capfd):
    # No SRDF here: it would name Panda links that the second robot does not have. Instants
    # (check_motion off): the poses jump.
    start_node(ros, [Parameter('package_paths', value=[f'example-robot-data={erd_share}']),
                     Parameter('joint_states_qos', value='reliable'),
                     Parameter('check_motion', value=False)])
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    with open(panda_urdf) as stream:
        urdf_text = stream.read()
    description.publish(String(data=urdf_text))
    # The node subscribes joint_states only once it has a robot.
    probe = Probe(ros, timeout=60.0)
    # The reference: the same text, no SRDF.
    bare = CollisionChecker.from_urdf(urdf_text, package_paths={'example-robot-data': erd_share})

    def reference(state):
        result = bare.check(state)
        return result.in_collision, tuple(result.colliding_pairs)

    def verdict_for(state, timeout=30.0):
        count = len(probe.pairs)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:    # the node ignores joint states until loaded
            probe.joint_states.publish(joint_state(state))
            if ros.spin_until(lambda: len(probe.pairs) > count, 0.2):
                return probe.contact.last.data, pairs_of(probe.pairs.last)
        raise AssertionError('no verdict')

    panda_free = verdict_for(poses['free'])
    panda_hit = verdict_for(poses['hit'])
    assert panda_free == reference(poses['free']) and panda_hit == reference(poses['hit'])
    assert panda_hit[0] and set(poses['hit_pairs']) <= set(panda_hit[1])

    description.publish(String(data='<robot name="broken"><link name="a"></robot>'))
    seen = []
    assert ros.spin_until(lambda: seen.append(capfd.readouterr().err) or
                          'robot_description rejected' in ''.join(seen), 30.0)
    assert 'the current model stays' in ''.join(seen)
    assert verdict_for(poses['hit']) == panda_hit and verdict_for(poses['free']) == panda_free

    description.publish(String(data=SLIDER_URDF))
    # Until the slider has loaded, its joint is an unknown name to the Panda, whose verdict
    # answers it (the state held); wait for the slider.
    loaded = 'robot loaded from robot_description: 1 joints'
    assert loaded in logged(ros, capfd, loaded, 60.0)
    assert verdict_for({'slide': -0.95}) == (True, (('anchor', 'carriage'),))
    assert verdict_for({'slide': 0.0}) == (False, ())
    # The Panda's joints are now unknown names, ignored: answered by the state held.
    assert probe.send(joint_state(poses['free'])) == (False, ())


# -- the console script, as a user runs it ------------------------------------------------------

def test_console_script_with_params_file(ros, tmp_path, panda_urdf, panda_srdf, erd_share, poses):
    with open(config_path('collision_sensor.yaml')) as stream:
        document = yaml.safe_load(stream)
    document['/**']['ros__parameters'].update(
        urdf_path=panda_urdf, srdf_path=panda_srdf, joint_states_qos='reliable',
        package_paths=[f'example-robot-data={erd_share}'], check_motion=False)  # poses jump
    params = tmp_path / 'panda.yaml'
    params.write_text(yaml.safe_dump(document))
    process = subprocess.Popen(
        [NODE_SCRIPT, '--ros-args', '--params-file', str(params), '-r',
         f'__ns:={ros.namespace}'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        # The node subscribes once its robot is loaded; its first check may compile kernels.
        assert ros.spin_until(
            lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 60.0), \
            'the node process never subscribed to joint_states'
        probe = Probe(ros)
        assert probe.send(joint_state(poses['hit'], stamp=stamp_of(1)), timeout=60.0)[0]
        assert pairs_of(probe.pairs.last) == poses['hit_pairs']
        assert probe.pairs.last.header.stamp == stamp_of(1)
        assert probe.send(joint_state(poses['free'], stamp=stamp_of(2))) == (False, ())
    finally:
        process.send_signal(signal.SIGINT)
        try:
            output, _ = process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            output, _ = process.communicate()
            pytest.fail(f'the node did not stop on SIGINT:\n{output}')
    assert process.returncode == 0, output
    assert 'robot loaded from urdf_path' in output


# -- hostile robot_description ------------------------------------------------------------------

def test_robot_description_is_content_never_a_path(ros, tmp_path, panda_urdf, erd_share, capfd):
    def factory(urdf, **kwargs):
        opened.append(urdf)
        return CollisionChecker.from_urdf(urdf, **kwargs)

    opened = []
    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)      # reading it would block the loader for ever
    ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context, checker_factory=factory,
        parameter_overrides=[Parameter('package_paths',
                                       value=[f'example-robot-data={erd_share}'])]))
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
    texts = ('/etc/passwd', '/dev/zero', str(fifo), panda_urdf, 'x\n[ERROR] forged')
    for count, text in enumerate(texts, 1):
        description.publish(String(data=text))

        def rejected():
            for msg in diagnostics.messages:
                for status in msg.status:
                    values = {kv.key: kv.value for kv in status.values}
                    if values.get('robot_description_rejected_total') == str(count):
                        return True
            return False
        assert ros.spin_until(rejected, 5.0), text
    err = logged(ros, capfd, '')
    # Throttled: the first rejection is logged, the others counted.
    assert 'robot_description rejected: robot_description: not URDF XML text (it starts with ' \
           '"/etc/passwd")' in err and 'give a path with the urdf_path parameter' in err
    assert opened == []     # nothing reached the loader, let alone a file
    description.publish(String(data=SLIDER_URDF))
    assert 'ready: checking' in logged(ros, capfd, 'ready: checking', timeout=60.0)
    assert opened == [SLIDER_URDF.encode()]    # as bytes: parsed as the document, never a path


# -- start-up and stopping, as a process --------------------------------------------------------

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


def stop(process, signum, timeout=30.0):
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


def wait_until_signals_are_handled(process, timeout=30.0):
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


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('delay', [0.0, 0.3, 1.0, 2.5], ids=lambda d: f'{d}s')
def test_signal_while_starting_exits_cleanly(ros, panda_urdf, panda_srdf, erd_share, signum,
                                             delay):
    # From its first statement the process imports rclpy and the engine, loads the Panda, builds
    # its trees and runs the query once: each delay lands in another phase.
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    wait_until_signals_are_handled(process)
    time.sleep(delay)
    status, output, _ = stop(process, signum)
    assert_clean_exit(status, output)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_while_waiting_for_robot_description_exits_cleanly(ros, signum):
    process = node_process(ros.namespace)
    # Its first /diagnostics: the node is spinning, waiting for a robot.
    name = f'{ros.namespace.strip("/")}/collision_sensor: collision sensor'
    diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
    assert ros.spin_until(lambda: any(status.name == name for msg in diagnostics.messages
                                      for status in msg.status), 60.0)
    status, output, seconds = stop(process, signum)
    assert_clean_exit(status, output)
    assert 'waiting for the robot on robot_description' in output and seconds < 5.0


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_ready_line_then_signal_while_checking_exits_cleanly(ros, panda_urdf, panda_srdf,
                                                             erd_share, poses, signum):
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    try:
        assert ros.spin_until(
            lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 120.0)
        probe = Probe(ros)
        assert probe.send(joint_state(poses['hit']), timeout=30.0)[0]
        # A stream while the signal arrives: the node is checking.
        states = [joint_state(poses[key]) for key in ('free', 'hit') * 200]
        for msg in states:
            probe.joint_states.publish(msg)
    finally:
        status, output, seconds = stop(process, signum)
    assert_clean_exit(status, output)
    lines = output.splitlines()
    # One "ready" line, after the robot was loaded, before any other line about joint states.
    ready = [i for i, line in enumerate(lines) if line.startswith('[INFO] ready: checking ')]
    loaded = [i for i, line in enumerate(lines) if 'robot loaded from urdf_path' in line]
    assert len(ready) == 1 and loaded and loaded[0] < ready[0], output
    assert f'{ros.namespace}/joint_states (reliable)' in lines[ready[0]]
    assert seconds < 5.0, output


# -- robots with a floating base, load warnings (issue: every real robot loads) -----------------

def test_floating_base_robot_from_the_topic_needs_no_base_variables(ros, erd_share, capfd):
    """a1 (example-robot-data): URDF from robot_description, its SRDF's floating virtual joint
    "root_joint". The node does not wait for root_joint/* (robots rarely publish them in
    joint_states): the base sits at the world origin until a joint state names them, and the
    verdict is the reference checker's for that state."""
    robots = os.path.join(erd_share, 'robots', 'a1_description')
    urdf, srdf = os.path.join(robots, 'urdf', 'a1.urdf'), os.path.join(robots, 'srdf', 'a1.srdf')
    start_node(ros, [Parameter('package_paths', value=[f'example-robot-data={erd_share}']),
                     Parameter('srdf_path', value=srdf),
                     Parameter('joint_states_qos', value='reliable'),
                     Parameter('check_motion', value=False)])    # instants: the poses jump
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    with open(urdf) as stream:
        description.publish(String(data=stream.read()))
    reference = CollisionChecker.from_urdf(urdf, srdf=srdf,
                                           package_paths={'example-robot-data': erd_share})
    assert reference.joint_names[:7] == tuple(f'root_joint/{v}' for v in (
        'trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w'))
    probe = Probe(ros, timeout=60.0)
    legs = reference.joint_names[7:]
    rng = np.random.default_rng(9)
    base = dict(zip(reference.joint_names, reference.kinematics.neutral()))
    for _ in range(5):
        state = {name: float(rng.uniform(*reference.joint_limits[name])) for name in legs}
        count = len(probe.pairs)
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and len(probe.pairs) == count:
            probe.joint_states.publish(joint_state(state))   # until the model has loaded
            ros.spin_until(lambda: len(probe.pairs) > count, 0.3)
        expected = reference.check(dict(base, **state))
        assert (probe.contact.last.data, pairs_of(probe.pairs.last)) == (
            expected.in_collision, tuple(expected.colliding_pairs))
    # The base named in a joint state moves the robot: lifted 10 m, nothing changes inside.
    lifted = dict(state, **{'root_joint/trans_z': 10.0})
    assert probe.send(joint_state(lifted)) == (
        reference.check(dict(base, **lifted)).in_collision,
        tuple(reference.check(dict(base, **lifted)).colliding_pairs))


def test_load_warnings_reach_the_node_log(ros, erd_share, capfd):
    """z1's SRDF names a link "base" that this URDF lacks: loaded with the entry skipped, and
    the warning (file, line, element, fix) is logged by the node, not lost on stderr alone."""
    robots = os.path.join(erd_share, 'robots', 'z1_description')
    start_node(ros, [Parameter('urdf_path', value=os.path.join(robots, 'urdf', 'z1.urdf')),
                     Parameter('srdf_path', value=os.path.join(robots, 'srdf', 'z1.srdf')),
                     Parameter('package_paths', value=[f'example-robot-data={erd_share}'])])
    seen = []
    assert ros.spin_until(lambda: seen.append(capfd.readouterr().err) or
                          'while loading the robot' in ''.join(seen), 30.0), ''.join(seen)
    text = ''.join(seen)
    assert 'WARN' in text and 'base' in text and 'skipped' in text


def test_load_warnings_are_printed_once_by_the_console_script(ros, erd_share):
    """Issue 28: the SRDF's warning came twice, as a raw Python warning and as the log line."""
    robots = os.path.join(erd_share, 'robots', 'z1_description')
    process = node_process(
        ros.namespace, '-p', f'urdf_path:={os.path.join(robots, "urdf", "z1.urdf")}', '-p',
        f'srdf_path:={os.path.join(robots, "srdf", "z1.srdf")}', '-p',
        f'package_paths:=["example-robot-data={erd_share}"]')
    assert ros.spin_until(
        lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 60.0)
    status, output, _ = stop(process, signal.SIGINT)
    assert status == 0, output
    assert 'LoadWarning' not in output
    assert output.count('base_link="base" is not a link of the robot') == 1, output
    assert output.count('[WARN] while loading the robot: SRDF: line 11: <chain> skipped') == 1


def test_xacro_args_and_mesh_containment_parameters_reach_the_checker():
    from collision_sensor.ros.node_parameters import settings_from_values
    settings = settings_from_values({'xacro_args': ['arm_id:=panda', 'hand:=true'],
                                     'mesh_containment': True})
    assert settings.xacro_args == {'arm_id': 'panda', 'hand': 'true'}
    assert settings.checker_config['mesh_containment'] is True
    with pytest.raises(ConfigError, match='xacro_args.*"arm_id=panda".*name:=value'):
        settings_from_values({'xacro_args': ['arm_id=panda']})


def test_console_script_survives_a_name_that_is_not_utf8(ros, panda_urdf, panda_srdf, erd_share,
                                                         poses):
    """The console script's executor (EventsExecutor) takes a joint state whose name is not
    UTF-8 (raw CDR from the wire): the node keeps answering and exits cleanly."""
    from rclpy.serialization import serialize_message
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    try:
        probe = Probe(ros, timeout=60.0)
        raw = serialize_message(JointState(name=['zzzzzz'], position=[0.0]))
        probe.joint_states.publish(raw.replace(b'zzzzzz', b'\xff\xfe\xfd\xfc\xfb\xfa'))
        # Decoded with the bytes replaced: a name of no joint, answered as such.
        assert ros.spin_until(lambda: len(probe.pairs) == 1, 10.0)
        assert pairs_of(probe.pairs.last) == (('waiting_for_joints',),)
        assert probe.send(joint_state(poses['free']), timeout=10.0) == (False, ())
        assert process.poll() is None
    finally:
        status, output, _ = stop(process, signal.SIGINT)
    assert_clean_exit(status, output)


# -- the Fast DDS profile of the console script --------------------------------------------------

def test_console_script_points_fast_dds_at_the_shipped_profile_only_when_unconfigured(tmp_path,
                                                                                      monkeypatch):
    from lxml import etree

    from collision_sensor.ros.node import apply_dds_profile
    monkeypatch.chdir(tmp_path)
    environ = {}
    profile = apply_dds_profile(environ)
    assert profile == config_path('fastdds_node.xml')
    assert environ == {'FASTRTPS_DEFAULT_PROFILES_FILE': profile,
                       'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}
    ns = {'p': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    readers = etree.parse(profile).findall('p:data_reader', ns)
    assert [r.findtext('p:historyMemoryPolicy', namespaces=ns) for r in readers] == ['DYNAMIC']
    # Writers as rmw_fastrtps sets them without the profile: synchronous (Fast DDS's own
    # default, asynchronous, puts a thread between each verdict and the wire).
    writers = etree.parse(profile).findall('p:data_writer', ns)
    assert [(w.findtext('p:historyMemoryPolicy', namespaces=ns),
             w.findtext('p:qos/p:publishMode/p:kind', namespaces=ns)) for w in writers] == \
        [('PREALLOCATED_WITH_REALLOC', 'SYNCHRONOUS')]
    # A user's own Fast DDS configuration, another middleware or the switch: nothing changes.
    for environ in ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/mine.xml'},
                    {'FASTDDS_DEFAULT_PROFILES_FILE': '/mine.xml'},
                    {'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'},
                    {'RMW_FASTRTPS_PUBLICATION_MODE': 'ASYNCHRONOUS'},
                    {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
                    {'COLLISION_SENSOR_DDS_PROFILE': 'off'}):
        before = dict(environ)
        assert apply_dds_profile(environ) is None and environ == before
    (tmp_path / 'DEFAULT_FASTRTPS_PROFILES.xml').write_text('<profiles/>')
    environ = {}
    assert apply_dds_profile(environ) is None and environ == {}


# -- proximity: padding and the warning zone ------------------------------------------------------

WARNING_DISTANCE = 0.05
NODE_PADDING = {'padding': 0.01, 'link_padding': ['panda_hand=0.02', 'panda_link0=0.0']}


def _fcl_expectation(oracle, checker, q, paddings):
    """Independent answers at q (in checker.joint_names order): {pair: fcl distance - padding
    sum} for every checked pair (<= 0 where the meshes meet or fcl's distance is within the
    padding)."""
    poses = oracle.poses(q)
    out = {}
    for a, b in checker.checked_pairs:
        theirs = oracle.pair_distance(poses, a, b)
        if theirs <= 0 or oracle.contains(poses, a, b):
            theirs = 0.0
        out[a, b] = theirs - paddings[a] - paddings[b]
    return out


def test_warning_zone_outputs_match_fcl_with_padding(ros, panda_urdf, panda_srdf, erd_share,
                                                     erd_package_paths, frames):
    """Every verdict is followed by near, min_distance and near_pairs for the same joint state;
    all three agree with python-fcl distances (minus the paddings) on pinocchio's poses."""
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, check_motion=False,
                                     warning_distance=WARNING_DISTANCE, **NODE_PADDING))
    probe = Probe(ros)
    near = ros.record(Bool, 'near', reliable(1000, latched=True))
    minimum = ros.record(Float64, 'min_distance', reliable(1000, latched=True))
    near_pairs = ros.record(DiagnosticArray, 'near_pairs', reliable(1000, latched=True))
    reference = CollisionChecker.from_urdf(
        panda_urdf, srdf=panda_srdf, package_paths=erd_package_paths,
        config={'padding': 0.01, 'link_padding': {'panda_hand': 0.02, 'panda_link0': 0.0}})
    oracle = FclOracle(reference, panda_urdf)
    names = ARM + GRIPPER
    n = 60
    for k, q in enumerate(frames[:n]):
        probe.send(joint_state(q, stamp=stamp_of(k), names=names))
        assert ros.spin_until(lambda: len(near_pairs) > k and len(minimum) > k and len(near) > k)
    assert len(near) == len(minimum) == len(near_pairs) == len(probe.contact) == n
    judged = warned = contacts = 0
    for k, q in enumerate(frames[:n]):
        given = dict(zip(names, q))
        expected = _fcl_expectation(oracle, reference,
                                    np.array([given[j] for j in reference.joint_names]),
                                    reference.paddings)
        statuses = near_pairs.messages[k]
        assert statuses.header.stamp == stamp_of(k)
        got = {}
        for status in statuses.status:
            values = {kv.key: kv.value for kv in status.values}
            pair = (values['link_a'], values['link_b'])
            assert status.name == ':'.join(pair) and status.hardware_id == 'panda_link0'
            distance = float(values['distance'])
            assert status.level == (DiagnosticStatus.ERROR if distance <= 0
                                    else DiagnosticStatus.WARN)
            point_a = np.array(values['point_a'].split(), dtype=float)
            point_b = np.array(values['point_b'].split(), dtype=float)
            if distance > 0:
                assert np.linalg.norm(point_b - point_a) == pytest.approx(distance, abs=1e-7)
            got[pair] = distance
        assert [float(kv.value) for status in statuses.status for kv in status.values
                if kv.key == 'distance'] == sorted(got.values())
        contact_pairs = set(pairs_of(probe.pairs.messages[k]))
        assert {pair for pair, d in got.items() if d <= 0} == contact_pairs
        for pair, theirs in expected.items():
            if abs(theirs - WARNING_DISTANCE) < 1e-6 or (0 < abs(theirs) < 1e-6):
                continue   # at an edge: either answer is within rounding
            judged += 1
            assert (pair in got) == (theirs < WARNING_DISTANCE), (k, pair, theirs)
            if pair in got and theirs > 0:
                assert got[pair] == pytest.approx(theirs, abs=1e-6), (k, pair)
            elif pair in got:
                assert got[pair] <= 0
        assert near.messages[k].data == bool(got)
        assert minimum.messages[k].data == (min(got.values()) if got else math.inf)
        warned += bool(got)
        contacts += probe.contact.messages[k].data
    assert judged and 0 < warned < n and contacts


def test_warning_zone_off_by_default_advertises_nothing(ros, panda_urdf, panda_srdf, erd_share,
                                                         poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    probe.send(joint_state(poses['hit']))
    names = {name for name, _ in ros.probe.get_topic_names_and_types()}
    assert f'{ros.namespace}/contact' in names
    assert not {f'{ros.namespace}/{topic}' for topic in ('near', 'min_distance', 'near_pairs')
                } & names


def test_proximity_markers_join_the_nearest_points(ros, panda_urdf, panda_srdf, erd_share,
                                                   frames):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, publish_markers=True,
                                     warning_distance=WARNING_DISTANCE, **NODE_PADDING))
    probe = Probe(ros, markers=True)
    near_pairs = ros.record(DiagnosticArray, 'near_pairs', reliable(1000, latched=True))
    names = ARM + GRIPPER
    seen_lines = seen_spheres = False
    for k, q in enumerate(frames[:60]):
        probe.send(joint_state(q, stamp=stamp_of(k), names=names))
        assert ros.spin_until(lambda: len(near_pairs) > k)
        ros.spin_for(0.15)   # past MARKER_PERIOD: each state gets its own markers
        statuses = near_pairs.last.status
        if not statuses or not len(probe.markers):
            continue
        markers = probe.markers.last.markers
        assert markers[0].action == Marker.DELETEALL
        by_ns = {}
        for marker in markers[1:]:
            by_ns.setdefault(marker.ns, []).append(marker)
            assert marker.header.frame_id == 'panda_link0'
            assert marker.header.stamp == stamp_of(k)
        labels = by_ns.get('proximity/distance', [])
        assert len(labels) == len(statuses)
        assert all(label.type == Marker.TEXT_VIEW_FACING for label in labels)
        apart = [s for s in statuses if s.level == DiagnosticStatus.WARN]
        lines = [m for m in by_ns.get('proximity', []) if m.type == Marker.LINE_LIST]
        spheres = [m for m in by_ns.get('proximity', []) if m.type == Marker.SPHERE_LIST]
        assert sum(len(m.points) for m in lines) == 2 * len(apart)
        assert sum(len(m.points) for m in spheres) == len(statuses) - len(apart)
        seen_lines, seen_spheres = seen_lines or bool(lines), seen_spheres or bool(spheres)
        if seen_lines and seen_spheres:
            return
    pytest.fail('the states never showed both a near pair apart and one in contact')


def test_padding_and_warning_parameters_reach_the_checker():
    from collision_sensor.ros.node_parameters import settings_from_values
    settings = settings_from_values({'padding': 0.01, 'warning_distance': 0.05,
                                     'link_padding': ['panda_hand=0.02', ' panda_link0 = 0']})
    assert settings.checker_config['padding'] == 0.01
    assert settings.checker_config['link_padding'] == {'panda_hand': 0.02, 'panda_link0': 0.0}
    assert settings.warning_distance == 0.05
