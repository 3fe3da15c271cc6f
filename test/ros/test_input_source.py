"""The source abstraction (:mod:`collision_sensor.ros.input_source`): a kind of input added as
a class and one line in the node, with a timeout of its own; when its data stop, it has the
sensor fail safe by its policy, seen from a probe node as a user sees it."""
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402

from collision_sensor.ros.input_source import InputSource  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from collision_sensor.sensor import Failure  # noqa: E402
from node_harness import (  # noqa: E402,F401
    Probe, expected, frames, joint_state, pairs_of, panda, panda_parameters, poses, ros)


class HeartbeatSource(InputSource):
    """A std_msgs/Bool ``heartbeat`` that must come every 0.3 s (a stand-in for a point cloud
    with its own timeout policy)."""

    name = 'heartbeat'
    TIMEOUT = 0.3

    def __init__(self, node, sensor):
        self._node, self._sensor = node, sensor
        self.last, self.expired = None, False

    def start(self):
        self._node.create_subscription(Bool, 'heartbeat', self._on_heartbeat, 10)

    def _on_heartbeat(self, msg):
        self.last = time.monotonic()
        if self.expired:
            self.expired = False
            self._sensor.recover_source(self.name)

    def poll_timeout(self, now, stamp):
        if self.expired or self.last is None or now - self.last <= self.TIMEOUT:
            return
        self.expired = True
        failure = Failure('heartbeat_lost', f'no heartbeat for {self.TIMEOUT} s', 'contact')
        self._sensor.fail_source(self.name, failure)
        self._sensor.answer_failure(failure, stamp)

    def timed_out(self):
        return self.expired


class NodeWithHeartbeat(CollisionSensorNode):
    def _make_sources(self):
        return super()._make_sources() + [HeartbeatSource(self, self.sensor)]   # the one line


def test_a_source_with_its_own_timeout_fails_safe(ros, panda_urdf, panda_srdf, erd_share,
                                                  poses):
    ros.add(NodeWithHeartbeat(namespace=ros.namespace, context=ros.context,
                              parameter_overrides=panda_parameters(
                                  panda_urdf, panda_srdf, erd_share, stale_timeout=0.0)))
    probe = Probe(ros)
    heartbeat = ros.publisher(Bool, 'heartbeat', 10)
    assert ros.wait_for_subscribers(heartbeat)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    for _ in range(5):
        heartbeat.publish(Bool(data=True))
        ros.spin_for(0.05)
    count = len(probe.pairs)
    assert ros.spin_until(lambda: len(probe.pairs) > count, 3.0), 'no fail-safe answer'
    assert (probe.contact.last.data, pairs_of(probe.pairs.last)) == (True, (('heartbeat_lost',),))
    for _ in range(10):     # the statuses before the timeout may still be on their way
        status, _ = probe.next_diagnostics(lambda v: True)
        if status.level == DiagnosticStatus.ERROR:
            break
    assert status.level == DiagnosticStatus.ERROR and 'heartbeat' in status.message
    # The data back: the next joint state is checked as usual.
    heartbeat.publish(Bool(data=True))
    ros.spin_for(0.05)
    assert probe.send(joint_state(poses['free'])) == (False, ())
