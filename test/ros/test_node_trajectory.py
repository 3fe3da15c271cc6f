"""Planned trajectories on the running node (issue 25, item 3), with real rclpy, read as a planner
and a controller read them: each trajectory answered on ``trajectory_result``, valid ones relayed
unchanged on ``trajectory_out``, invalid ones never. The oracle: a fresh
``CollisionChecker.check_trajectory`` from the same start, with the same scene (a scene file)
and tolerance.

The case (test/motion_cases.py): the Panda's elbow move across a 2 mm plate; the robot stands at
0.5 of the way, a trajectory back to 0.3 is free, one on to 0.8 crosses the plate.
"""
import hashlib
import math
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Duration  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from collision_sensor.engine.trajectory import TrajectoryPoint  # noqa: E402
from collision_sensor.ros.trajectory_source import MAX_TRAJECTORY_BACKLOG  # noqa: E402
from collision_sensor.untrusted_text import printable  # noqa: E402
from ros_helpers import WAIT, node_status, reliable  # noqa: E402
from motion_cases import crossing, scene_of  # noqa: E402,F401 - the case's fixture
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, joint_state, panda_parameters, ros, start_node)

NAMES = ARM + GRIPPER
TOLERANCE = 0.01    # the node's joint_limit_tolerance (its default)


def trajectory(points, names=ARM, stamp=7):
    """A JointTrajectory of ``points``: ``(time_from_start, positions[, velocities])``."""
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp.sec, msg.header.frame_id = stamp, 'planner'
    for point in points:
        t, positions = point[0], point[1]
        sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
        msg.points.append(JointTrajectoryPoint(
            positions=[float(v) for v in positions],
            velocities=[float(v) for v in (point[2] if len(point) > 2 else ())],
            time_from_start=Duration(sec=sec, nanosec=nanosec)))
    return msg


def arm(q):
    return list(q[:len(ARM)])


class TrajectoryProbe(Probe):
    """A planner publishing trajectories, a controller receiving the relayed ones."""

    def __init__(self, ros, markers=False):
        super().__init__(ros, markers=markers)
        self.trajectories = ros.publisher(JointTrajectory, 'trajectory', reliable(100))
        self.results = ros.record(DiagnosticArray, 'trajectory_result', reliable(100))
        self.relayed = ros.record(JointTrajectory, 'trajectory_out', reliable(100))
        assert ros.wait_for_subscribers(self.trajectories)
        assert ros.spin_until(lambda: self.relayed_publishers() > 0)
        assert ros.spin_until(lambda: self.result_publishers() > 0)

    def trajectory_status(self, condition, timeout=WAIT):
        """The node's ``trajectory`` status on /diagnostics once ``condition(status,
        values)``."""
        return node_status(self.ros, self.diagnostics, 'trajectory', condition, timeout)

    def relayed_publishers(self):
        return self.ros.probe.count_publishers(f'{self.ros.namespace}/trajectory_out')

    def result_publishers(self):
        return self.ros.probe.count_publishers(f'{self.ros.namespace}/trajectory_result')

    def check(self, msg):
        """Publish ``msg`` (a JointTrajectory, or its bytes); return the result's values."""
        count = len(self.results)
        self.trajectories.publish(msg)
        assert self.ros.spin_until(lambda: len(self.results) > count, 30.0), 'no result'
        result = self.results.last
        assert len(result.status) == 1
        status = result.status[0]
        values = {kv.key: kv.value for kv in status.values}
        assert status.level == (DiagnosticStatus.OK if values['valid'] == 'true'
                                else DiagnosticStatus.ERROR)
        assert status.name.endswith('collision_sensor: trajectory')
        assert status.message == ('valid' if values['valid'] == 'true' else values['reason'])
        if not isinstance(msg, bytes):
            assert result.header == msg.header     # the trajectory's header
            assert values['trajectory_digest'] == (
                '' if values['kind'] in ('oversized', 'dropped') else digest_by_the_recipe(msg))
        return values


def digest_by_the_recipe(msg):
    """``trajectory_digest`` as docs/node.md's recipe says, written out again here."""
    def u32(n):
        return int(n).to_bytes(4, 'little')

    def i32(n):
        return int(n).to_bytes(4, 'little', signed=True)

    def text(value):
        data = value.encode('utf-8')
        return u32(len(data)) + data

    def floats(values):
        return u32(len(values)) + np.asarray(values, dtype='<f8').tobytes()

    out = i32(msg.header.stamp.sec) + u32(msg.header.stamp.nanosec) + text(msg.header.frame_id)
    out += u32(len(msg.joint_names)) + b''.join(text(name) for name in msg.joint_names)
    out += u32(len(msg.points))
    for p in msg.points:
        out += floats(p.positions) + floats(p.velocities) + floats(p.accelerations)
        out += floats(p.effort) + i32(p.time_from_start.sec) + u32(p.time_from_start.nanosec)
    return hashlib.sha256(out).hexdigest()


def oracle_says(checker, msg, start):
    """``check_trajectory`` on a fresh checker, from ``start``, as the node must answer."""
    points = [TrajectoryPoint(p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec,
                              list(p.positions), list(p.velocities), list(p.accelerations))
              for p in msg.points]
    return checker.check_trajectory(list(msg.joint_names), points,
                                    start=dict(zip(NAMES, start)), limit_tolerance=TOLERANCE)


def assert_answer(values, result):
    """The result's values say what the oracle's ``TrajectoryResult`` says."""
    assert values['valid'] == str(result.valid).lower()
    assert values['first_invalid_segment'] == ('' if result.first_invalid_segment is None
                                               else str(result.first_invalid_segment))
    if result.time_from_start is None:
        assert values['time_from_start'] == ''
    else:
        assert float(values['time_from_start']) == pytest.approx(result.time_from_start,
                                                                 rel=1e-8, abs=1e-9)
    pairs = result.colliding_pairs
    assert (values['link_a'], values['link_b']) == (pairs[0] if pairs else ('', ''))
    assert values['colliding_pairs'] == ', '.join(f'{a}:{b}' for a, b in pairs)
    assert values['reason'] == printable(result.reason, 1000)


@pytest.fixture
def scene_file(crossing, tmp_path):
    T = crossing.oracle.link_poses()['plate']
    path = tmp_path / 'plate.yaml'
    path.write_text(yaml.safe_dump(scene_of(T)))
    return str(path)


def test_valid_trajectories_relayed_unchanged_invalid_ones_answered_and_never_relayed(
        ros, crossing, scene_file, panda_urdf, panda_srdf, erd_share):
    # (no stale check: a loaded machine may take longer than its timeout between two calls)
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, scene_path=scene_file,
                                     publish_markers=True, stale_timeout=0.0))
    probe = TrajectoryProbe(ros, markers=True)
    a, b, c = crossing.q0, crossing.q_half, crossing.q1
    assert probe.send(joint_state(b, names=NAMES)) == (False, ())
    oracle = crossing.oracle

    # Valid: back to 0.3 of the way (linear), and a cubic through it and back, at rest at the
    # ends. Relayed unchanged, byte for byte.
    valid = [trajectory([(1.0, arm(a))]),
             trajectory([(1.0, arm(a), [0.0] * 7), (2.0, arm(b), [0.0] * 7)], stamp=8)]
    for msg in valid:
        count = len(probe.relayed)
        values = probe.check(msg)
        assert oracle_says(oracle, msg, b).valid
        assert_answer(values, oracle_says(oracle, msg, b))
        assert values['kind'] == 'valid' and values['points'] == str(len(msg.points))
        assert ros.spin_until(lambda: len(probe.relayed) > count)
        assert serialize_message(probe.relayed.last) == serialize_message(msg)

    # Invalid, each with its reason; none relayed.
    relayed = len(probe.relayed)
    beyond = np.array(arm(b))
    beyond[3] = 0.3     # panda_joint4's limits are [-3.0718, -0.0698]
    cases = {
        'contact': trajectory([(1.0, arm(c))]),
        'joint_limits': trajectory([(1.0, beyond)]),
        'unknown_joint': trajectory([(1.0, arm(a) + [0.0])],
                                    names=ARM + ('elbow\n[ERROR] [fake]: forged',)),
        'non_increasing_time': trajectory([(1.0, arm(a)), (1.0, arm(b))]),
        'nan': trajectory([(1.0, [math.nan] + arm(a)[1:])]),
        'mismatched_lengths': trajectory([(1.0, arm(a)[:6])]),
        'no_points': trajectory([]),
    }
    kinds = {'contact': 'contact', 'joint_limits': 'joint_limits'}
    for case, msg in cases.items():
        values = probe.check(msg)
        result = oracle_says(oracle, msg, b)
        assert not result.valid, case
        assert_answer(values, result)
        assert values['kind'] == kinds.get(case, 'malformed'), case
        assert '\n' not in values['reason']
    ros.spin_for(0.3)
    assert len(probe.relayed) == relayed
    # The contact: between the start and point 0, the plate, at the time the oracle says.
    contact = oracle_says(oracle, cases['contact'], b)
    assert contact.first_invalid_segment == 0
    assert any('plate' in pair for pair in contact.colliding_pairs)


def test_markers_show_the_links_at_the_first_contact(ros, crossing, scene_file, panda_urdf,
                                                     panda_srdf, erd_share):
    """~/markers: the boxes of the pairs' links where they are at the first contact (a fresh
    checker's boxes at that state), magenta, with a text; a valid trajectory clears them."""
    # (no stale check: a loaded machine may take longer than its timeout between two calls)
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, scene_path=scene_file,
                                     publish_markers=True, stale_timeout=0.0))
    probe = TrajectoryProbe(ros, markers=True)
    a, b, c = crossing.q0, crossing.q_half, crossing.q1
    probe.send(joint_state(b, names=NAMES))
    msg = trajectory([(2.0, arm(c))])
    count = len(probe.markers)
    values = probe.check(msg)
    assert values['kind'] == 'contact'
    assert ros.spin_until(lambda: any(m.ns == 'trajectory_contact' for array in
                                      probe.markers.messages[count:] for m in array.markers))
    shown = [m for array in probe.markers.messages[count:] for m in array.markers
             if m.ns == 'trajectory_contact' and m.action == Marker.ADD]
    boxes = [m for m in shown if m.type == Marker.CUBE]
    label = [m for m in shown if m.type == Marker.TEXT_VIEW_FACING]
    # Segment 0 is linear from the start (at rest) to the point over 2 s: the state at t.
    t = float(values['time_from_start'])
    q = b + (t / 2.0) * (c - b)
    reference = crossing.make()
    reference.check(q)
    linked = sorted({name for pair in oracle_says(crossing.oracle, msg, b).colliding_pairs
                     for name in pair})
    expected = reference.collision_boxes(linked)
    assert len(boxes) == len(expected) and label and 'first contact at' in label[0].text
    for marker, (name, T, half) in zip(boxes, expected):
        assert marker.text == name and marker.header.frame_id == 'panda_link0'
        position = [marker.pose.position.x, marker.pose.position.y, marker.pose.position.z]
        assert position == pytest.approx(T[:3, 3].tolist(), abs=1e-6)
        quat = np.array([marker.pose.orientation.x, marker.pose.orientation.y,
                         marker.pose.orientation.z, marker.pose.orientation.w])
        R = rotation(quat)
        assert np.allclose(R @ np.diag(half) @ R.T, T[:3, :3] @ np.diag(half) @ T[:3, :3].T,
                           atol=1e-6)   # the same box (axes up to sign)
        assert [marker.scale.x, marker.scale.y, marker.scale.z] == pytest.approx(
            (2 * half).tolist())
    # Not where the robot stands: the boxes of the carried state are elsewhere.
    here = crossing.make()
    here.check(b)
    assert not np.allclose(here.collision_boxes(linked)[0][1], expected[0][1], atol=1e-3)
    # A valid trajectory clears them.
    count = len(probe.markers)
    assert probe.check(trajectory([(1.0, arm(a))]))['valid'] == 'true'
    assert ros.spin_until(lambda: any(m.ns == 'trajectory_contact' and m.action == Marker.DELETE
                                      for array in probe.markers.messages[count:]
                                      for m in array.markers))


def rotation(quat):
    x, y, z, w = quat / np.linalg.norm(quat)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_no_start_or_a_stale_one_makes_a_trajectory_invalid(collision_sensor, crossing):
    """Fail safe: where the robot starts must be known."""
    sensor = collision_sensor('panda', parameters={'stale_timeout': 0.5, 'stale_policy': 'hold'})
    msg = trajectory([(1.0, arm(crossing.q0))])
    outcome = sensor.send_trajectory(msg)
    assert (outcome.valid, outcome.kind, outcome.relayed) == (False, 'no_start', False)
    assert 'no joint state accepted yet' in outcome.reason
    for _ in range(20):     # a loaded machine may take longer than stale_timeout between two
        sensor.send_joint_state(crossing.q_half, names=NAMES)
        outcome = sensor.send_trajectory(msg)
        if outcome.valid:
            break
    assert outcome.valid and outcome.relayed
    time.sleep(0.8)
    outcome = sensor.send_trajectory(msg)
    assert (outcome.valid, outcome.kind, outcome.relayed) == (False, 'no_start', False)
    assert 'stale' in outcome.reason and 'stale_timeout 0.5' in outcome.reason
    time.sleep(0.2)
    assert sensor.relays_of(outcome.digest) == 1   # the valid one only


def test_oversized_trajectories_are_refused_before_decoding(ros, crossing, panda_urdf,
                                                            panda_srdf, erd_share):
    """Above max_trajectory_bytes: answered ``oversized`` with the stamp read from the bytes,
    never relayed; bytes that could not even be decoded (a name list claiming 2^31 entries)
    get the same answer, so they were never decoded. A small one is still checked."""
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                     max_trajectory_bytes=4096, stale_timeout=0.0))
    probe = TrajectoryProbe(ros)
    probe.send(joint_state(crossing.q_half, names=NAMES))
    a = arm(crossing.q0)
    large = trajectory([(0.01 * (k + 1), a) for k in range(100)], stamp=11)
    assert len(serialize_message(large)) > 4096
    values = probe.check(large)
    assert (values['valid'], values['kind']) == ('false', 'oversized')
    assert 'max_trajectory_bytes (4096)' in values['reason']
    header = serialize_message(trajectory([], names=(), stamp=12))[:-8]   # then names, points
    undecodable = header + b'\xff\xff\xff\x7f' + bytes(8000)
    count = len(probe.results)
    probe.trajectories.publish(undecodable)
    assert ros.spin_until(lambda: len(probe.results) > count, 10.0)
    values = {kv.key: kv.value for kv in probe.results.last.status[0].values}
    assert values['kind'] == 'oversized' and probe.results.last.header.stamp.sec == 12
    assert probe.results.last.header.frame_id == 'planner'
    assert probe.check(trajectory([(1.0, a)]))['valid'] == 'true'
    ros.spin_for(0.2)
    assert len(probe.relayed) == 1
    _, values = probe.trajectory_status(lambda _, v: v['trajectories_total'] == '3')
    assert (values['oversized_total'], values['valid_total'], values['relayed_total']) == (
        '2', '1', '1')
    assert values['max_trajectory_bytes'] == '4096'
    # The period with the oversized ones said WARN.
    probe.trajectory_status(lambda status, _: status.level == DiagnosticStatus.WARN
                            and 'trajectories oversized' in status.message)


def test_a_burst_is_answered_in_order_the_excess_dropped_at_once(ros, crossing, panda_urdf,
                                                                 panda_srdf, erd_share):
    """More trajectories than may wait: every one answered, in arrival order (each result with
    its trajectory's stamp); those beyond the backlog as ``dropped``, at once and undecoded,
    never relayed. Memory stays bounded whatever a planner sends."""
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, stale_timeout=0.0))
    probe = TrajectoryProbe(ros)
    probe.send(joint_state(crossing.q_half, names=NAMES))
    a = arm(crossing.q0)
    points = [(0.01 * (k + 1), a) for k in range(1000)]
    points[-1] = (30.0, [math.nan] + a[1:])     # checked to its end: invalid, never relayed
    msg = trajectory(points)
    sent = 3 * MAX_TRAJECTORY_BACKLOG
    count = len(probe.results)
    for k in range(sent):
        msg.header.stamp.sec = 100 + k
        probe.trajectories.publish(msg)
    assert ros.spin_until(lambda: len(probe.results) >= count + sent, 120.0)
    results = probe.results.messages[count:]
    assert [r.header.stamp.sec for r in results] == list(range(100, 100 + sent))
    answers = [{kv.key: kv.value for kv in r.status[0].values} for r in results]
    kinds = [values['kind'] for values in answers]
    assert set(kinds) == {'malformed', 'dropped'}, kinds
    assert kinds.count('malformed') >= 1
    # Each decoded one names its trajectory by its digest; a dropped one, never decoded, by
    # its header alone.
    for k, values in enumerate(answers):
        msg.header.stamp.sec = 100 + k
        assert values['trajectory_digest'] == (digest_by_the_recipe(msg)
                                               if values['kind'] == 'malformed' else '')
    ros.spin_for(0.2)
    assert len(probe.relayed) == 0
    _, values = probe.trajectory_status(lambda _, v: v['trajectories_total'] == str(sent))
    assert values['dropped_total'] == str(kinds.count('dropped'))
    assert values['lost_total'] == '0'
    probe.trajectory_status(lambda status, _: status.level == DiagnosticStatus.WARN)


def test_each_client_matches_its_answers_and_a_late_one_takes_no_old_one(
        ros, crossing, scene_file, panda_urdf, panda_srdf, erd_share):
    """Planners send stamp 0: two trajectories in flight at once, both stamped 0 with the same
    frame, are told apart by the digest each client computes from what it sent. Answers are
    kept (transient local), so one given before a client's subscription was matched still
    reaches it; a client that joins later receives the older answers too, and by their index
    (above the node's trajectories_total when it sends) takes none of them for its own, even one
    to the very trajectory it then sends."""
    from rclpy.node import Node
    from collision_sensor.ros.answers import answers_it, trajectory_answer_from
    from collision_sensor.ros.trajectory_source import RESULT_QOS, trajectory_digest
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, scene_path=scene_file))
    probe = TrajectoryProbe(ros)
    a, b, c = crossing.q0, crossing.q_half, crossing.q1
    probe.send(joint_state(b, names=NAMES))
    free, through = trajectory([(1.0, arm(a))], stamp=0), trajectory([(1.0, arm(c))], stamp=0)
    assert free.header == through.header
    count = len(probe.results)
    probe.trajectories.publish(through)
    probe.trajectories.publish(free)
    assert ros.spin_until(lambda: len(probe.results) >= count + 2, 30.0)
    answers = {}
    for result in probe.results.messages[count:]:
        values = {kv.key: kv.value for kv in result.status[0].values}
        answers[values['trajectory_digest']] = values
    assert answers[trajectory_digest(free)]['kind'] == 'valid'
    assert answers[trajectory_digest(through)]['kind'] == 'contact'
    assert trajectory_digest(free) == digest_by_the_recipe(free)

    # A subscription made after the answers were published receives them.
    late = ros.add(Node('late_planner', namespace=ros.namespace, context=ros.context))
    heard = []
    late.create_subscription(DiagnosticArray, 'trajectory_result', heard.append, RESULT_QOS)
    sender = late.create_publisher(JointTrajectory, 'trajectory', reliable(100))
    assert ros.spin_until(lambda: sender.get_subscription_count() > 0 and len(heard) >= 2)
    old = [trajectory_answer_from(msg) for msg in heard]
    assert {answer.digest for answer in old} >= {trajectory_digest(free),
                                                  trajectory_digest(through)}
    assert sorted(answer.index for answer in old) == list(range(1, len(old) + 1))
    # None of them answers what it sends now, though one has the same digest: the node's
    # status says how many answers it has given.
    _, values = probe.trajectory_status(lambda _, v: v['trajectories_total'] == str(len(old)))
    answered_before = int(values['trajectories_total'])
    assert not any(answers_it(answer, trajectory_digest(through), answered_before)
                   for answer in old)
    sender.publish(through)
    assert ros.spin_until(lambda: len(heard) == len(old) + 1, 30.0)
    new = trajectory_answer_from(heard[-1])
    assert answers_it(new, trajectory_digest(through), answered_before)
    assert (new.kind, new.index) == ('contact', len(old) + 1)
