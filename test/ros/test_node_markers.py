"""The node's markers: they appear at a contact and clear; the quaternion they carry against
random rotations.
"""
import numpy as np
import pytest

pytest.importorskip('rclpy')

from visualization_msgs.msg import Marker  # noqa: E402

from collision_sensor.ros.node import quaternion_from_matrix  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    Probe, expected, frames, joint_state, panda, panda_parameters, poses, ros, start_node)


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
