"""``check_motion`` on the running node (issue 25, item 2), with real rclpy, read as a subscriber
reads it; the oracle a fresh ``CollisionChecker`` with the same scene (``check_motion`` from the
state before, ``check`` at the state).

The case (test/motion_cases.py): the Panda's elbow move sampled at 5 Hz at 0.3, 0.5 and 0.8 of
the way, every state clear, a 2 mm plate from the ``scene`` topic crossed between the last two.
"""
import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from collision_sensor.ros.node import quaternion_from_matrix  # noqa: E402
from ros_helpers import reliable  # noqa: E402
from motion_cases import PLATE, crossing  # noqa: E402,F401 - the case's fixture
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, joint_state, panda_parameters, ros, start_node)

NAMES = ARM + GRIPPER
PERIOD = 0.2    # s between two joint states: 5 Hz


def plate_marker(crossing) -> Marker:
    """The plate as a CUBE on the scene topic, where the oracle has it."""
    T = crossing.oracle.link_poses()['plate']
    marker = Marker(ns='plate', id=0, type=Marker.CUBE, action=Marker.ADD)
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = map(float, T[:3, 3])
    (marker.pose.orientation.x, marker.pose.orientation.y, marker.pose.orientation.z,
     marker.pose.orientation.w) = quaternion_from_matrix(T[:3, :3])
    marker.scale.x, marker.scale.y, marker.scale.z = PLATE
    return marker


def entries(msg):
    """The verdict's statuses: ``(in contact now, met on the way as (pair, first_contact))``."""
    now, met = [], []
    for status in msg.status:
        values = {kv.key: kv.value for kv in status.values}
        assert status.level == DiagnosticStatus.ERROR
        pair = (values['link_a'], values['link_b'])
        if 'first_contact' in values:
            met.append((pair, float(values['first_contact'])))
        else:
            assert not met, 'the pairs in contact now come first'
            now.append(pair)
    return tuple(now), tuple(met)


def assert_motion_verdict(probe, oracle, q_from, q_to):
    """The last verdict is the motion q_from -> q_to's: the pairs in contact at q_to, then
    those met on the way (at the first contact) and not in contact at q_to."""
    found = oracle.check_motion(q_from, q_to)
    now_expected = oracle.check(q_to).colliding_pairs
    now, met = entries(probe.pairs.last)
    assert probe.contact.last.data == (found.in_collision or bool(now_expected))
    assert now == now_expected
    assert tuple(pair for pair, _ in met) == tuple(
        pair for pair in found.colliding_pairs if pair not in now_expected)
    for _, first in met:
        assert first == pytest.approx(found.first_contact, abs=1e-4)
    return now, met


class MotionProbe(Probe):
    """Sends the case's states by name, at 5 Hz."""

    def state(self, q, pace=True):
        if pace:
            self.ros.spin_for(PERIOD)
        return self.send(joint_state(q, names=NAMES))

    def scene(self, markers):
        """Publish a scene array; wait for the verdict that answers it (now, root frame)."""
        publisher = getattr(self, '_scene', None) or self.ros.publisher(
            MarkerArray, 'scene', reliable(10, latched=True))
        self._scene = publisher
        assert self.ros.wait_for_subscribers(publisher)
        count = len(self.pairs)
        publisher.publish(MarkerArray(markers=markers))
        assert self.ros.spin_until(lambda: len(self.pairs) > count, 10.0), 'no scene verdict'
        assert self.pairs.last.header.frame_id == 'panda_link0'

    def status(self, condition):
        return self.next_diagnostics(condition, timeout=5.0)[1]


def set_parameter(node, probe, **values):
    """Set parameters on the node in this process; wait for the verdict answering them."""
    count = len(probe.pairs)
    results = node.set_parameters([Parameter(k, value=v) for k, v in values.items()])
    assert all(result.successful for result in results), results
    assert probe.ros.spin_until(lambda: len(probe.pairs) > count, 60.0), 'not applied'


#: s: a stale_timeout no loaded machine reaches between two states of one test: the motion is
#: swept however slow the machine (the tests of the stale gap set their own).
STEADY = 300.0


def test_a_sparse_stream_crossing_a_thin_plate_says_contact_on_the_way(ros, crossing, panda_urdf,
                                                                      panda_srdf, erd_share):
    """On (the default): every state clear, yet the motion between the last two crosses the
    plate: contact, with the pairs met on the way (first_contact). Off at run time: the same
    stream says clear; on again: the motion back across the plate is caught."""
    a, b, c = crossing.q0, crossing.q_half, crossing.q1
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                            stale_timeout=STEADY))
    probe = MotionProbe(ros)
    assert probe.state(a, pace=False) == (False, ())       # the first state: an instant
    assert probe.state(b) == (False, ())                   # swept, free
    probe.scene([plate_marker(crossing)])       # the plate arrives: the state held, re-checked
    assert probe.contact.last.data is False
    contact, _ = probe.state(c)                             # clear at c, not on the way
    assert contact and not crossing.oracle.check(c).in_collision
    now, met = assert_motion_verdict(probe, crossing.oracle, b, c)
    assert now == () and any('plate' in pair for pair, _ in met)
    for status in probe.pairs.last.status:
        assert ' met ' in status.message and 'on the way' in status.message
    values = probe.status(lambda v: v['motion_contacts_on_the_way_total'] == '1')
    assert values['check_motion'] == 'true' and values['motion'] == 'sweeping'
    assert values['new_motions_first_state'] == '1' and int(values['motions_swept_total']) >= 2
    # Off at run time: instants, every one clear.
    set_parameter(node, probe, check_motion=False)
    for q in (b, c, b):
        assert probe.state(q) == (False, ())
    assert probe.status(lambda v: v['motion'] == 'off')['check_motion'] == 'false'
    # On again: from b (the state held) to c, across the plate.
    set_parameter(node, probe, check_motion=True)
    assert probe.state(c)[0]
    assert_motion_verdict(probe, crossing.oracle, b, c)


def test_pairs_in_contact_at_the_end_and_met_on_the_way_are_told_apart(ros, crossing,
                                                                       panda_urdf, panda_srdf,
                                                                       erd_share):
    """A motion that ends in contact with one pair and met another first: the pair in contact
    keeps the usual entry, the other has first_contact."""
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                            stale_timeout=STEADY))
    assert node.settings.check_motion     # the default
    probe = MotionProbe(ros)
    b = crossing.q_half
    into = b + 0.2 * (crossing.q1 - crossing.q_half) / 0.3     # 0.7 of the way: in contact
    assert crossing.oracle.check(into).in_collision
    probe.state(b, pace=False)
    probe.scene([plate_marker(crossing)])   # answered at once (the state held exists)
    assert probe.state(into)[0]
    now, met = assert_motion_verdict(probe, crossing.oracle, b, into)
    assert now and met and not set(now) & {pair for pair, _ in met}


def test_a_gap_longer_than_stale_timeout_starts_a_new_motion(ros, crossing, panda_urdf,
                                                             panda_srdf, erd_share):
    b, c = crossing.q_half, crossing.q1
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, stale_timeout=1.0,
                                     stale_policy='hold'))
    probe = MotionProbe(ros)
    probe.state(b, pace=False)
    probe.scene([plate_marker(crossing)])
    probe.state(b)
    ros.spin_for(1.5)                                       # stale: no sweep across the gap
    assert probe.state(c, pace=False) == (False, ())       # the instant at c
    values = probe.status(lambda v: v['new_motions_stale_gap'] == '1')
    assert int(values['stale_episodes_total']) >= 1
    assert probe.state(b)[0]                                # within the timeout: swept back
    assert_motion_verdict(probe, crossing.oracle, c, b)


def test_a_parameter_change_keeps_the_motion_across_the_new_checker(ros, crossing, panda_urdf,
                                                                    panda_srdf, erd_share):
    """padding set at run time: a new checker replaces the one in use; the next state's motion
    is still swept from the state before (the new checker's own state is its build's)."""
    b, c = crossing.q_half, crossing.q1
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                            stale_timeout=STEADY))
    probe = MotionProbe(ros)
    probe.state(b, pace=False)
    probe.scene([plate_marker(crossing)])
    set_parameter(node, probe, padding=0.001)
    assert probe.state(c)[0]
    assert_motion_verdict(probe, crossing.make(padding=0.001), b, c)
    values = probe.status(lambda v: v['parameter_changes_applied_total'] == '1')
    assert values['new_motions_new_checker'] == '0' and values['motion'] == 'sweeping'
