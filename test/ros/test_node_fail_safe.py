"""The node fails safe (issue 24, item 4; issue 28, item 3): an engine fault, silent input and a
refused joint state are answered as such, never as "clear", by the policies ``on_engine_error``,
``stale_policy`` and ``on_rejected_input``.

Real failures, seen as a subscriber sees them: the engine fault is injected into the sensor's
core (``inject_fault``): its check of one state fails half-way, the carried statuses
overwritten (as a fault inside the engine would leave them), so a node that kept the merge, or
went on from the carried state, would answer wrong; the references are fresh checkers.
"""
import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from std_msgs.msg import Bool, Float64  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from ros_helpers import reliable  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, expected, frames, joint_state, logged, panda, panda_parameters, pairs_of,
    poses, ros, stamp_of, start_node)


#: The message of the fault the tests inject.
FAULT = 'engine fault injected by the test'


def start_faulty(ros, panda_urdf, panda_srdf, erd_share, mark, **overrides):
    """Start the node on the Panda; its check of a state with ``panda_joint1 == mark`` fails
    after marking every pair in contact in the carried state."""
    # (no stale check unless a test asks: a loaded machine may pause longer than its default
    # between two of the test's states, and a stale answer is not what these tests read)
    overrides.setdefault('stale_timeout', 0.0)
    node = ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context,
        parameter_overrides=panda_parameters(panda_urdf, panda_srdf, erd_share, **overrides)))
    joint = node.checker.joint_names.index('panda_joint1')
    node.sensor.core.inject_fault(joint, mark, FAULT, True, True)
    return node


def entry_values(status):
    return {kv.key: kv.value for kv in status.values}


@pytest.fixture
def marked(panda, poses):
    """The colliding state, at which the engine fails: kept by mistake, it would show."""
    assert poses['free']['panda_joint1'] != poses['hit']['panda_joint1']
    return poses['hit']


def test_engine_fault_answers_contact_and_the_next_state_is_checked_from_scratch(
        ros, panda, panda_urdf, panda_srdf, erd_share, poses, marked, capfd):
    start_faulty(ros, panda_urdf, panda_srdf, erd_share, marked['panda_joint1'])
    probe = Probe(ros)
    free = poses['free']
    assert probe.send(joint_state(free, stamp=stamp_of(1))) == (False, ())
    # The fault: answered at once, contact true, the error named, for this joint state.
    assert probe.send(joint_state(marked, stamp=stamp_of(2))) == (True, (('engine_error',),))
    answer = probe.pairs.last
    assert answer.header.stamp == stamp_of(2)
    entry = answer.status[0]
    assert entry.level == DiagnosticStatus.ERROR
    assert FAULT in entry.message
    assert entry_values(entry)['policy'] == 'contact' and entry_values(entry)['kind'] == \
        'engine_error'
    status, values = probe.next_diagnostics(lambda v: v['engine_errors_total'] == '1')
    assert status.level == DiagnosticStatus.ERROR and values['engine_error']
    assert FAULT in status.message
    # The merge was undone (the state is the free one, not the marked collision) and the
    # corrupted carried state was not trusted: the gripper alone moves, and the verdict is a
    # fresh checker's on the free state with that gripper.
    gripper = {GRIPPER[0]: free[GRIPPER[0]] * 0.5}
    reference = panda.check(dict(free, **gripper))
    assert probe.send(joint_state(gripper, stamp=stamp_of(3))) == (
        reference.in_collision, tuple(reference.colliding_pairs))
    # Checked again: /diagnostics is back to OK. With check_motion (the default) that state
    # was an instant, a new motion: the carried state was not trusted to sweep from.
    status, values = probe.next_diagnostics(lambda v: v['engine_error'] == '')
    assert status.level == DiagnosticStatus.OK
    assert values['new_motions_engine_error'] == '1' and values['motion'] == 'sweeping'
    assert f'collision check failed: {FAULT}' in logged(ros, capfd, 'collision check failed')


def test_engine_fault_with_hold_repeats_the_last_verdict_and_reports_error(
        ros, panda_urdf, panda_srdf, erd_share, poses, marked):
    # Instants (check_motion off): the poses jump.
    start_faulty(ros, panda_urdf, panda_srdf, erd_share, marked['panda_joint1'],
                 on_engine_error='hold', check_motion=False)
    probe = Probe(ros)
    hit_elsewhere = dict(marked, panda_joint1=marked['panda_joint1'] + 1e-9)
    reference = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                           package_paths={'example-robot-data': erd_share})
    hit_pairs = tuple(reference.check(hit_elsewhere).colliding_pairs)
    assert probe.send(joint_state(hit_elsewhere)) == (True, hit_pairs)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    # hold: contact keeps the verdict of the state held (free), the error first.
    assert probe.send(joint_state(marked)) == (False, (('engine_error',),))
    assert entry_values(probe.pairs.last.status[0])['policy'] == 'hold'
    status, _ = probe.next_diagnostics(lambda v: v['engine_errors_total'] == '1')
    assert status.level == DiagnosticStatus.ERROR     # hold still says ERROR
    assert probe.send(joint_state(hit_elsewhere)) == (True, hit_pairs)


def test_warning_zone_follows_a_fail_safe_answer(ros, panda_urdf, panda_srdf, erd_share,
                                                 poses, marked):
    start_faulty(ros, panda_urdf, panda_srdf, erd_share, marked['panda_joint1'],
                 warning_distance=0.05)
    probe = Probe(ros)
    near = ros.record(Bool, 'near', reliable(1000, latched=True))
    minimum = ros.record(Float64, 'min_distance', reliable(1000, latched=True))
    near_pairs = ros.record(DiagnosticArray, 'near_pairs', reliable(1000, latched=True))
    probe.send(joint_state(poses['free']))
    assert ros.spin_until(lambda: len(near_pairs) == 1)
    probe.send(joint_state(marked, stamp=stamp_of(5)))
    assert ros.spin_until(lambda: len(near_pairs) == 2 and len(minimum) == 2 and len(near) == 2)
    assert near.last.data and minimum.last.data == -math.inf
    assert [s.name for s in near_pairs.last.status] == ['engine_error']
    assert near_pairs.last.header.stamp == stamp_of(5)


def test_stale_input_answers_contact_once_per_episode_logged_once(ros, panda_urdf, panda_srdf,
                                                                  erd_share, poses, capfd):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, stale_timeout=0.2))
    probe = Probe(ros)
    stale = (True, (('joint_states_stale',),))
    for episode in range(1, 4):
        assert probe.send(joint_state(poses['free'])) == (False, ())
        count = len(probe.pairs)
        assert ros.spin_until(lambda: len(probe.pairs) > count, 3.0), 'no stale answer'
        assert (probe.contact.last.data, pairs_of(probe.pairs.last)) == stale
        answer = probe.pairs.last
        assert answer.header.frame_id == 'panda_link0'
        assert 'stale_timeout 0.2 s' in answer.status[0].message
        ros.spin_for(0.3)
        assert len(probe.pairs) == count + 1     # once per episode
        status, values = probe.next_diagnostics(lambda v: v['stale'] == 'true')
        assert status.level == DiagnosticStatus.ERROR
        assert values['stale_episodes_total'] == str(episode)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    # Logged once per episode, with the count, at most once in 30 s (a pausing publisher).
    err = logged(ros, capfd, 'joint states resumed')
    assert err.count('joint states stale: none accepted for') == 1
    assert 'stale episode 1' in err and 'stale episode 2' not in err
    assert err.count('joint states resumed after') == 1


def test_stale_input_with_hold_publishes_nothing_but_says_error(ros, panda_urdf, panda_srdf,
                                                                erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, stale_timeout=0.2,
                                     stale_policy='hold'))
    probe = Probe(ros)
    assert probe.send(joint_state(poses['hit'])) == (True, poses['hit_pairs'])
    status, values = probe.next_diagnostics(lambda v: v['stale'] == 'true')
    assert status.level == DiagnosticStatus.ERROR and values['stale_policy'] == 'hold'
    assert len(probe.pairs) == 1 and len(probe.contact) == 1


def test_rejected_input_with_hold_repeats_the_state_held(ros, panda_urdf, panda_srdf, erd_share,
                                                         poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     on_rejected_input='hold', check_motion=False))
    probe = Probe(ros)
    # Nothing checked yet: nothing to hold, answered as contact.
    assert probe.send(joint_state({name: poses['free'][name] for name in ARM})) == \
        (True, (('waiting_for_joints',),))
    assert probe.send(joint_state(poses['hit'])) == (True, poses['hit_pairs'])
    bad = joint_state(dict(poses['free'], panda_joint2=math.nan))
    assert probe.send(bad) == (True, (('joint_state_rejected',),) + poses['hit_pairs'])
    entry = probe.pairs.last.status[0]
    assert entry.level == DiagnosticStatus.ERROR and 'not finite' in entry.message
    assert entry_values(entry)['policy'] == 'hold'
    assert probe.send(joint_state(poses['free'])) == (False, ())
    assert probe.send(bad) == (False, (('joint_state_rejected',),))
