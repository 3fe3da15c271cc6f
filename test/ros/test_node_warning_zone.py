"""The node's proximity outputs: padding and the warning zone against python-fcl's distances,
off by default, markers joining the nearest points, parameters that reach the checker.
"""
import math

import numpy as np
import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from std_msgs.msg import Bool, Float64  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.ros.node_parameters import settings_from_values  # noqa: E402
from engine_oracles import FclOracle  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, expected, frames, joint_state, pairs_of, panda, panda_parameters, poses,
    ros, stamp_of, start_node)
from ros_helpers import reliable  # noqa: E402


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
