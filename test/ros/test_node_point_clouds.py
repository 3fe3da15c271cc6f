"""The node's point cloud topics (issue 29, items 2 and 4), with real rclpy (no launch).

A Panda node with ``point_cloud_topics: [camera/points]``; the probe publishes joint states and
PointCloud2 messages. References: a checker of the test's own given the same clouds
(``set_points``, whose answers test_point_clouds checks against python-fcl and brute force).
Every cloud is answered at once; each bad cloud of item 4 is refused by name and the last good
cloud stays the obstacle; a silent camera fails safe (``contact``) or is dropped (``ignore``).
"""
import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from std_msgs.msg import Header  # noqa: E402

from collision_sensor.errors import ConfigError  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, frames, expected, joint_state, panda, panda_parameters, pairs_of,
    poses, ros, start_node)
from ros_helpers import WAIT  # noqa: E402

TOPIC = 'camera/points'
CLOUD = 'cloud/' + TOPIC


def parameters(panda_urdf, panda_srdf, erd_share, **overrides):
    """The Panda with the camera topic; joint states come only when a test sends one, so the
    joint-state staleness check is off (its answer would race the verdict a test waits for)."""
    values = {'point_cloud_topics': [TOPIC], 'point_cloud_timeout': 0.0, 'stale_timeout': 0.0}
    values.update(overrides)
    return panda_parameters(panda_urdf, panda_srdf, erd_share, **values)


def cloud_message(points, frame='panda_link0', dtype='<f4'):
    points = np.ascontiguousarray(points, dtype=dtype)
    item = points.dtype.itemsize
    datatype = PointField.FLOAT32 if item == 4 else PointField.FLOAT64
    return PointCloud2(
        header=Header(frame_id=frame), height=1, width=len(points),
        fields=[PointField(name=a, offset=k * item, datatype=datatype, count=1)
                for k, a in enumerate('xyz')],
        is_bigendian=False, point_step=3 * item, row_step=3 * item * len(points),
        data=points.tobytes(), is_dense=False)


class CloudProbe(Probe):
    def __init__(self, ros):
        super().__init__(ros)
        self.clouds = ros.publisher(PointCloud2, TOPIC, qos_profile_sensor_data)
        self.filtered = ros.record(PointCloud2, 'collision_sensor/filtered_points',
                                   qos_profile_sensor_data)
        assert ros.wait_for_subscribers(self.clouds, timeout=10.0)

    def send_cloud(self, msg, answered=True, timeout=WAIT):
        """Publish a cloud; when ``answered``, wait for its verdict."""
        count = len(self.pairs)
        self.clouds.publish(msg)
        if not answered:
            return None
        assert self.ros.spin_until(lambda: len(self.pairs) > count, timeout), 'no cloud verdict'
        return self.contact.last.data, pairs_of(self.pairs.last)

    def cloud_status(self, condition=lambda values: True, timeout=WAIT):
        name = f'{self.ros.namespace.strip("/")}/collision_sensor: point cloud {TOPIC}'
        found = []

        def ready():
            while self.diagnostics.messages:
                for status in self.diagnostics.messages.pop(0).status:
                    values = {kv.key: kv.value for kv in status.values}
                    if status.name == name and condition(values):
                        found.append((status, values))
            return bool(found)

        assert self.ros.spin_until(ready, timeout), 'no matching point cloud status'
        return found[0]


def reference_verdict(checker, positions, points, frame=None):
    checker.set_points(TOPIC, points, frame, positions=positions)
    result = checker.check(positions)
    return result.in_collision, tuple(result.colliding_pairs)


def near_hand(panda, positions, rng, offset):
    """A 6 cm cube of points ``offset`` beyond the hand's origin along its z axis."""
    panda.check(positions)
    T = panda.link_poses()['panda_hand']
    centre = T[:3, 3] + offset * T[:3, 2]
    return centre + rng.uniform(-0.03, 0.03, (3000, 3))


def test_clouds_are_answered_at_once_as_the_engine_says(ros, panda, panda_urdf, panda_srdf,
                                                        erd_share, poses):
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.0))
    probe = CloudProbe(ros)
    free = poses['free']
    assert probe.send(joint_state(free)) == (False, ())
    rng = np.random.default_rng(29)
    seen = set()
    for offset in (0.12, 0.5, 0.09, 1.5):
        points = near_hand(panda, free, rng, offset)
        verdict = probe.send_cloud(cloud_message(points))
        assert verdict == reference_verdict(panda, free, points), offset
        seen.update(verdict[1])
        # The next joint state keeps the cloud.
        assert probe.send(joint_state(free)) == verdict
    assert any(CLOUD in pair for pair in seen)
    status, values = probe.cloud_status(lambda v: v['clouds_accepted_total'] == '4')
    assert status.level == DiagnosticStatus.OK
    stats = panda.point_cloud_stats(TOPIC)
    assert values['points_in'] == str(stats.points)
    assert values['voxels_kept'] == str(stats.voxels)
    assert values['points_kept'] == str(stats.kept_points)


def test_filtered_points_are_what_survived_in_the_world_frame(ros, panda, panda_urdf,
                                                              panda_srdf, erd_share, poses):
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.0))
    probe = CloudProbe(ros)
    free = poses['free']
    probe.send(joint_state(free))
    assert ros.spin_until(lambda: ros.probe.count_publishers(
        f'{ros.namespace}/collision_sensor/filtered_points') > 0, 5.0)
    ros.spin_for(0.3)   # the node's publisher sees the probe's subscription too
    rng = np.random.default_rng(3)
    panda.check(free)
    T = panda.link_poses()['panda_hand']
    # Points in the hand's frame: half on the hand (the robot's own), half a box 30 cm away.
    own = T[:3, 3] + rng.uniform(-0.01, 0.01, (500, 3))
    away = T[:3, 3] + np.array([0.3, 0.0, 0.0]) + rng.uniform(-0.02, 0.02, (500, 3))
    world = np.concatenate([own, away])
    in_hand = (world - T[:3, 3]) @ T[:3, :3]
    count = len(probe.filtered)
    probe.send_cloud(cloud_message(in_hand, frame='panda_hand', dtype='<f8'))
    assert ros.spin_until(lambda: len(probe.filtered) > count, 5.0)
    msg = probe.filtered.last
    kept = np.frombuffer(bytes(msg.data), dtype='<f4').reshape(-1, 3)
    assert msg.header.frame_id == 'panda_link0'
    prepared = panda.prepare_points(TOPIC, in_hand, 'panda_hand', positions=free,
                                    keep_points=True)
    np.testing.assert_allclose(np.sort(kept, axis=0), np.sort(prepared.kept, axis=0),
                               atol=1e-5)
    assert 0 < len(kept) <= 500


def bad_clouds(good):
    """(name, message, words in its rejection) for each bad input of issue 29 item 4."""
    empty = cloud_message(np.zeros((0, 3)))
    nan = cloud_message(np.full((100, 3), np.nan))
    ints = cloud_message(good)
    for f in ints.fields:
        f.datatype = PointField.INT32
    no_z = cloud_message(good)
    no_z.fields = no_z.fields[:2]
    steps = cloud_message(good)
    steps.row_step = 5
    short = cloud_message(good)
    short.height = 2
    frame = cloud_message(good, frame='camera_optical\n\x1b[31m')
    return [('empty', empty, 'empty cloud'), ('nan', nan, 'NaN or infinite'),
            ('ints', ints, 'INT32'), ('no_z', no_z, 'no "z" field'),
            ('steps', steps, 'row_step 5'), ('short', short, 'bytes of data'),
            ('frame', frame, 'is no link of the robot')]


def test_bad_clouds_are_refused_by_name_and_the_last_good_one_stays(
        ros, panda, panda_urdf, panda_srdf, erd_share, poses):
    # (No timeout here: a refused cloud is no data, and would time the camera out.)
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.0))
    probe = CloudProbe(ros)
    free = poses['free']
    probe.send(joint_state(free))
    rng = np.random.default_rng(5)
    good = near_hand(panda, free, rng, 0.09)
    verdict = probe.send_cloud(cloud_message(good))
    assert verdict == reference_verdict(panda, free, good) and verdict[0]
    for k, (name, msg, words) in enumerate(bad_clouds(good)):
        probe.send_cloud(msg, answered=False)
        status, values = probe.cloud_status(
            lambda v, k=k: v['clouds_rejected_total'] == str(k + 1), timeout=5.0)
        assert status.level == DiagnosticStatus.WARN, name
        assert words in values['last_rejection'], (name, values['last_rejection'])
        assert '\x1b' not in values['last_rejection'] and '\n' not in values['last_rejection']
        # The last good cloud is still the obstacle.
        assert probe.send(joint_state(free)) == verdict, name
    # A good cloud again: accepted, and OK.
    far = good + 2.0
    assert probe.send_cloud(cloud_message(far)) == reference_verdict(panda, free, far)
    status, values = probe.cloud_status(lambda v: v['last_rejection'] == '')
    assert status.level == DiagnosticStatus.OK


def test_huge_clouds_are_capped_and_counted(ros, panda, panda_urdf, panda_srdf, erd_share,
                                            poses):
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_max_points=1000,
                                     point_cloud_timeout=0.0))
    probe = CloudProbe(ros)
    probe.send(joint_state(poses['free']))
    points = np.random.default_rng(1).uniform(2.0, 3.0, (20_000, 3))
    probe.send_cloud(cloud_message(points))
    status, values = probe.cloud_status(lambda v: v['clouds_capped_total'] == '1')
    assert values['points_capped'] == '19000' and values['points_kept'] == '1000'


def test_a_silent_camera_fails_safe_until_a_cloud_comes(ros, panda, panda_urdf, panda_srdf,
                                                        erd_share, poses):
    # (a timeout a loaded machine cannot overrun between a cloud and the joint state after it)
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=2.0))
    probe = CloudProbe(ros)
    free = poses['free']
    # No cloud ever: after the timeout (from the start on), every verdict is the failure.
    status, values = probe.cloud_status(lambda v: v['timed_out'] == 'true')
    assert status.level == DiagnosticStatus.ERROR and values['timeouts_total'] == '1'
    assert probe.send(joint_state(free)) == (True, (('point_cloud_timeout',),))
    assert 'point_cloud_timeout 2 s' in probe.pairs.last.status[0].message
    assert probe.send(joint_state(free)) == (True, (('point_cloud_timeout',),))
    # A cloud: the verdict is the engine's again.
    far = np.random.default_rng(2).uniform(2.0, 3.0, (100, 3))
    assert probe.send_cloud(cloud_message(far)) == (False, ())
    assert probe.send(joint_state(free)) == (False, ())
    # Silent again: a second episode.
    probe.cloud_status(lambda v: v['timeouts_total'] == '2')
    assert probe.send(joint_state(free)) == (True, (('point_cloud_timeout',),))


def test_ignore_drops_a_silent_cameras_voxels(ros, panda, panda_urdf, panda_srdf, erd_share,
                                              poses):
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.5,
                                     point_cloud_on_timeout='ignore'))
    probe = CloudProbe(ros)
    free = poses['free']
    probe.send(joint_state(free))
    good = near_hand(panda, free, np.random.default_rng(7), 0.09)
    verdict = probe.send_cloud(cloud_message(good))
    assert verdict[0] and any(CLOUD in pair for pair in verdict[1])
    # Silent: the stale voxels go, the verdict goes on without them.
    assert ros.spin_until(lambda: pairs_of(probe.pairs.last) == (), 5.0)
    assert probe.send(joint_state(free)) == (False, ())
    status, values = probe.cloud_status(lambda v: v['timed_out'] == 'true')
    assert status.level == DiagnosticStatus.ERROR


@pytest.mark.parametrize('name,value,words', [
    ('point_cloud_on_timeout', 'hold', 'point_cloud_on_timeout'),
    ('point_cloud_timeout', -1.0, 'point_cloud_timeout'),
    ('point_cloud_voxel_size', 0.0, 'point_cloud_voxel_size'),
    ('point_cloud_topics', ['a', 'a'], 'point_cloud_topics'),
])
def test_bad_point_cloud_parameters_fail_configuration(ros, panda_urdf, panda_srdf, erd_share,
                                                       name, value, words):
    with pytest.raises(ConfigError, match=words):
        CollisionSensorNode(namespace=ros.namespace, context=ros.context,
                            parameter_overrides=panda_parameters(
                                panda_urdf, panda_srdf, erd_share, **{name: value}))


def test_clouds_are_filtered_with_the_pose_at_their_stamp(ros, panda, panda_urdf, panda_srdf,
                                                          erd_share, poses):
    """Two joint states 0.1 s apart, the arm turned between them: the hand's own points as
    seen at the first are removed when the cloud is stamped then, seen as an obstacle when it
    is stamped at the second (the hand has left them), and a cloud older than the window is
    counted and dropped."""
    import trimesh
    from builtin_interfaces.msg import Time
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.0,
                                     point_cloud_state_window=0.5))
    probe = CloudProbe(ros)
    first = dict(poses['free'])
    second = dict(first, panda_joint1=first['panda_joint1'] + 0.8)
    probe.send(joint_state(first, stamp=Time(sec=1000, nanosec=0)))
    probe.send(joint_state(second, stamp=Time(sec=1000, nanosec=100_000_000)))
    panda.check(first)
    T = panda.link_poses()['panda_hand']
    hand = [e for e in panda.model.elements if e.link == 'panda_hand']
    points = []
    for element in hand:
        mesh = trimesh.Trimesh(element.vertices, element.faces, process=False)
        sample, _ = trimesh.sample.sample_surface(mesh, 2000, seed=1)
        Te = T @ element.T_link_element
        points.append(sample @ Te[:3, :3].T + Te[:3, 3])
    points = np.concatenate(points)

    def kept_after(stamp):
        msg = cloud_message(points)
        msg.header.stamp = stamp
        probe.send_cloud(msg)
        return probe.cloud_status(lambda v: v['clouds_accepted_total'] == str(
            kept_after.accepted + 1))[1]
    kept_after.accepted = 0
    values = kept_after(Time(sec=1000, nanosec=0))
    assert values['points_kept'] == '0'
    kept_after.accepted = 1
    values = kept_after(Time(sec=1000, nanosec=100_000_000))
    assert int(values['points_kept']) > 0.9 * len(points)
    # Between the two: the interpolated pose (half-way) keeps some, not all.
    kept_after.accepted = 2
    values = kept_after(Time(sec=1000, nanosec=2_000_000))
    assert int(values['points_kept']) < 0.5 * len(points)
    # Older than the window (0.5 s before the newest state): dropped and counted.
    old = cloud_message(points)
    old.header.stamp = Time(sec=999, nanosec=0)
    probe.send_cloud(old, answered=False)
    status, values = probe.cloud_status(lambda v: v['clouds_too_old_total'] == '1')
    assert 'older than the states kept' in values['last_rejection']


def test_markers_show_the_voxels_near_the_robot(ros, panda, panda_urdf, panda_srdf, erd_share,
                                                poses):
    from visualization_msgs.msg import Marker, MarkerArray
    from ros_helpers import reliable
    start_node(ros, parameters(panda_urdf, panda_srdf, erd_share, publish_markers=True,
                                     point_cloud_topics=[TOPIC], point_cloud_timeout=0.0))
    probe = CloudProbe(ros)
    markers = ros.record(MarkerArray, 'collision_sensor/markers', reliable(100))
    free = poses['free']
    probe.send(joint_state(free))
    rng = np.random.default_rng(8)
    near = near_hand(panda, free, rng, 0.12)
    far = np.array([3.0, 3.0, 3.0]) + rng.uniform(-0.05, 0.05, (300, 3))
    points = np.concatenate([near, far])
    probe.send_cloud(cloud_message(points))
    reference_verdict(panda, free, points)
    centres, size = panda.cloud_voxels(TOPIC)

    def cloud_marker():
        for msg in reversed(markers.messages):
            for marker in msg.markers:
                if marker.ns == CLOUD and marker.type == Marker.CUBE_LIST:
                    return marker
        return None

    assert ros.spin_until(lambda: cloud_marker() is not None, 5.0)
    marker = cloud_marker()
    drawn = np.array([[p.x, p.y, p.z] for p in marker.points])
    assert marker.scale.x == pytest.approx(size)
    voxels = {tuple(v) for v in np.round(centres, 6)}
    assert {tuple(v) for v in np.round(drawn, 6)} <= voxels
    assert np.linalg.norm(drawn - 3.0, axis=1).min() > 0.5     # the far ones are not drawn
    near_voxels = {tuple(v) for v in np.round(np.floor(near / size) * size + size / 2, 6)}
    assert len({tuple(v) for v in np.round(drawn, 6)} & near_voxels) > 0.5 * len(
        near_voxels & voxels)
