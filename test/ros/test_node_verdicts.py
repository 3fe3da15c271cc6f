"""The node's verdicts: a recorded Panda sequence answered as ``CollisionChecker.check`` (and
``check_motion``) answers it, partial states merged, overload, the checking thread, the
serialized messages. Real rclpy, the real checker (``node_harness``).
"""
import math
import os
import time

import numpy as np
import pytest

pytest.importorskip('rclpy')

from rclpy.serialization import serialize_message  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402

from collision_sensor.ros.node import LATCHED_QOS  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, N_FRAMES, Probe, expected, frames, joint_state, pairs_of, panda,
    panda_parameters, poses, ros, stamp_of, start_node)
from ros_helpers import reliable  # noqa: E402


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
    # What the hop does with a long backlog: every message merged, the newest answered.
    node.sensor.take_batch([serialize_message(m) for m in batch], True)
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
    node.sensor.take_batch([serialize_message(m) for m in batch], True)
    assert ros.spin_until(lambda: len(probe.pairs) == 1)
    ros.spin_for(0.2)
    assert len(probe.pairs) == 1 and probe.pairs.last.header.stamp == stamp_of(1)
    reference = panda.check(dict(zip(names, frames[1])))
    assert pairs_of(probe.pairs.last) == tuple(reference.colliding_pairs)
    _, values = probe.next_diagnostics(lambda values: values['verdicts_total'] == '1')
    assert values['skipped_superseded'] == '1' and values['skipped_rejected'] == '1'


def test_checking_thread_answers_each_message_unless_the_backlog_is_long():
    from collision_sensor.ros.work_queue import MAX_BACKLOG, NewestFirstWorker
    import threading
    calls, entered, release = [], threading.Event(), threading.Event()

    def handle(batch, newest_only):
        calls.append((list(batch), newest_only))
        entered.set()
        release.wait(5.0)

    worker = NewestFirstWorker(handle, 'test worker')
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
    Every module of the node, since it is split by concern. Two reads below the public API,
    each in one place and guarded: the names of the parameters given, which rclpy does not
    expose (node_parameters); and what the compiled hop needs to make its subscription on the
    node rclpy made (joint_state_source: the rcl handles' addresses and the message's type
    support, as rclpy hands them to rcl itself)."""
    import pathlib
    from collision_sensor import ros
    below = {'node_parameters.py': ["overrides = getattr(node, '_parameter_overrides', None)"],
             'joint_state_source.py': ['message_type.__class__.__import_type_support__()',
                                       'return message_type._TYPE_SUPPORT']}
    for path in pathlib.Path(ros.__file__).parent.glob('*.py'):
        source = path.read_text()
        assert 'rclpy.impl' not in source and 'take_message' not in source, path.name
        assert '_rclpy' not in source, path.name
        private = [line.strip() for line in source.splitlines()
                   if "'_parameter_overrides'" in line or 'node._' in line
                   or '_TYPE_SUPPORT' in line or '__import_type_support__' in line]
        assert private == below.get(path.name, []), path.name
        if path.name != 'joint_state_source.py':
            assert '.handle.pointer' not in source, path.name
