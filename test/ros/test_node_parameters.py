"""The node's parameters as a user gives them (issue 28, items 2 and 7): a name the node does
not have stops it at start-up, naming the closest; the dynamic ones are set while it runs, from
another node through rclpy's parameter service client (what ``ros2 param set`` uses), and the
next verdict is a fresh checker's built with the new value.
"""
import math
import subprocess

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.parameter_client import AsyncParameterClient  # noqa: E402
from std_msgs.msg import Bool, Float64  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from collision_sensor import CollisionChecker, ConfigError  # noqa: E402
from collision_sensor.ros.node_parameters import (  # noqa: E402
    DYNAMIC, closest_name, settings_from_values)
from ros_helpers import reliable  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, NODE_SCRIPT, Probe, assert_clean_exit, expected, frames, joint_state, logged,
    node_process, pairs_of, panda, panda_parameters, poses, ros, start_node, stop)

# -- names the node does not have ---------------------------------------------------------------


def test_closest_names():
    assert closest_name('warning_distnace') == 'warning_distance'
    assert closest_name('srdf') == 'srdf_path'
    assert closest_name('urdf') == 'urdf_path'
    with pytest.raises(ConfigError, match=r'"paddding" \(did you mean padding\?\)'):
        settings_from_values({'paddding': 0.1})


@pytest.mark.node_process
def test_unknown_names_stop_the_node_naming_the_closest(tmp_path, panda_urdf, panda_srdf,
                                                        erd_share):
    """As in issue 28: ``-p srdf:=...`` and a misspelled warning_distance in a params file; ROS's
    own use_sim_time passes, and so does a section of the file meant for another node."""
    params = tmp_path / 'params.yaml'
    params.write_text(yaml.safe_dump({
        '/**': {'ros__parameters': {'warning_distnace': 0.05, 'use_sim_time': False}},
        'other_node': {'ros__parameters': {'anything': 1}}}))
    run = subprocess.run(
        [NODE_SCRIPT, '--ros-args', '-p', f'urdf_path:={panda_urdf}', '-p',
         f'srdf:={panda_srdf}', '-p', f'package_paths:=["example-robot-data={erd_share}"]',
         '--params-file', str(params)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 1, run.stderr
    assert ('unknown parameter(s): "srdf" (did you mean srdf_path?); "warning_distnace" (did '
            'you mean warning_distance?)') in run.stderr
    assert '-p name:=value argument or a --params-file' in run.stderr
    assert 'use_sim_time' not in run.stderr and 'anything' not in run.stderr


def test_ros_own_parameters_pass(ros, panda_urdf, panda_srdf, erd_share):
    node = start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                            use_sim_time=True))
    assert node.get_parameter('use_sim_time').value is True
    with pytest.raises(ConfigError, match='did you mean joint_states_qos'):
        start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share,
                                         joint_state_qos='reliable'))


# -- parameters set at run time -----------------------------------------------------------------


class Parameters:
    """The probe's parameter client of the node under test."""

    def __init__(self, ros):
        self.ros = ros
        self.client = AsyncParameterClient(ros.probe, f'{ros.namespace}/collision_sensor')
        assert self.client.wait_for_services(timeout_sec=60.0)

    def set(self, **values):
        """Set ``values`` at once; return (successful, reason)."""
        parameters = [Parameter(name, Parameter.Type.STRING_ARRAY, value)
                      if isinstance(value, list) else Parameter(name, value=value)
                      for name, value in values.items()]
        future = self.client.set_parameters_atomically(parameters)
        assert self.ros.spin_until(future.done, 30.0)
        result = future.result().result
        return result.successful, result.reason


def set_and_wait(parameters, probe, **values):
    """Set ``values``; wait for the verdict the node answers the change with (the time, the
    root frame: the current state checked with them), once the values are in use."""
    count = len(probe.pairs)
    assert parameters.set(**values) == (True, '')
    assert probe.ros.spin_until(lambda: len(probe.pairs) > count, 60.0), 'not applied'
    assert probe.pairs.last.header.frame_id == 'panda_link0'


def reference(panda_urdf, panda_srdf, erd_share, **config):
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths={'example-robot-data': erd_share},
                                      config=config)


def verdict(checker, state):
    result = checker.check(state)
    return result.in_collision, tuple(result.colliding_pairs)


@pytest.mark.node_process
def test_dynamic_parameters_set_from_another_node_reach_the_next_verdict(
        ros, panda_urdf, panda_srdf, erd_share, frames, expected):
    """Each dynamic parameter in turn on a node process: the verdicts that follow equal a fresh
    checker's built with the new value, on configurations near contact."""
    # Instants (check_motion off): the frames jump; test_node_motion.py sets check_motion.
    process = node_process(ros.namespace, '-p', 'stale_timeout:=0.0', '-p',
                           'check_motion:=false', urdf=panda_urdf, srdf=panda_srdf,
                           erd_share=erd_share)
    try:
        probe = Probe(ros, markers=True, timeout=60.0)
        parameters = Parameters(ros)
        names = ARM + GRIPPER
        states = [dict(zip(names, map(float, q))) for q in frames[:40]]
        assert probe.send(joint_state(states[0]), timeout=30.0)

        def assert_verdicts(checker):
            for state in states:
                assert probe.send(joint_state(state)) == verdict(checker, state)

        # padding: a new checker is built; the current state is answered once it is in use.
        set_and_wait(parameters, probe, padding=0.03)
        padded = reference(panda_urdf, panda_srdf, erd_share, padding=0.03)
        assert_verdicts(padded)
        # link_padding, with padding back to 0, at once.
        plain = reference(panda_urdf, panda_srdf, erd_share)

        def differ(checker):
            return any(verdict(checker, s) != verdict(plain, s) for s in states)

        assert differ(padded)
        set_and_wait(parameters, probe, padding=0.0, link_padding=['panda_hand=0.1'])
        hand = reference(panda_urdf, panda_srdf, erd_share, link_padding={'panda_hand': 0.1})
        assert_verdicts(hand)
        assert differ(hand)
        # allowed_collisions: the pairs seen colliding are no longer checked.
        seen = sorted({pair for hit, pairs in expected[:40] for pair in pairs})
        assert seen
        allowed = [f'{a}:{b}' for a, b in seen[:2]]
        set_and_wait(parameters, probe, link_padding=[], allowed_collisions=allowed)
        fewer = reference(panda_urdf, panda_srdf, erd_share, allowed_collisions=allowed)
        assert_verdicts(fewer)
        assert differ(fewer)
        set_and_wait(parameters, probe, allowed_collisions=[])
        assert_verdicts(plain)

        # warning_distance: from 0 the zone's topics appear; they follow a fresh proximity.
        near_pairs = ros.record(DiagnosticArray, 'near_pairs', reliable(1000, latched=True))
        minimum = ros.record(Float64, 'min_distance', reliable(1000, latched=True))
        set_and_wait(parameters, probe, warning_distance=0.08)

        def assert_zone(checker, distance, ignore=()):
            for state in states[:15]:
                count = len(near_pairs)
                probe.send(joint_state(state))
                assert ros.spin_until(lambda: len(near_pairs) > count and
                                      len(minimum) >= len(near_pairs))
                records = [r for r in checker.proximity(
                    np.array([state[j] for j in checker.joint_names]), distance)
                    if f'{r.link_a}:{r.link_b}' not in ignore]
                assert pairs_of(near_pairs.last) == tuple((r.link_a, r.link_b) for r in records)
                assert minimum.last.data == pytest.approx(
                    records[0].distance if records else math.inf, abs=1e-9)

        assert ros.spin_until(lambda: len(near_pairs) >= 1)
        assert_zone(plain, 0.08)
        # warning_ignore: a pair left out of the zone, still checked for contact.
        nearest = next(records for records in (
            plain.proximity(np.array([s[j] for j in plain.joint_names]), 0.08)
            for s in states[:15]) if records)
        ignored = [f'{nearest[0].link_a}:{nearest[0].link_b}']
        set_and_wait(parameters, probe, warning_ignore=ignored)
        assert_zone(plain, 0.08, ignored)
        assert_verdicts(plain)

        # publish_markers: on, then off.
        count = len(probe.markers)
        set_and_wait(parameters, probe, publish_markers=True)
        hit = next(s for s, (h, _) in zip(states, expected) if h)
        probe.send(joint_state(hit))
        assert ros.spin_until(lambda: len(probe.markers) > count)
        set_and_wait(parameters, probe, publish_markers=False)
        ros.spin_for(0.2)
        count = len(probe.markers)
        assert_verdicts(plain)
        assert len(probe.markers) == count

        # joint_limit_policy: a value beyond its limit, refused, then clamped to it.
        beyond = dict(states[1], panda_joint4=0.5)     # limits [-3.0718, -0.0698]
        assert probe.send(joint_state(beyond)) == (True, (('joint_state_rejected',),))
        set_and_wait(parameters, probe, joint_limit_policy='clamp')
        assert probe.send(joint_state(beyond)) == verdict(plain, dict(beyond,
                                                                      panda_joint4=-0.0698))
    finally:
        status, output, _ = stop(process, 2)
    assert_clean_exit(status, output)
    assert 'parameters applied: warning_distance = 0.08' in output
    assert 'parameters set: padding = 0.03; building a new checker' in output


def test_bad_values_set_at_run_time_are_refused_with_the_reason(ros, panda_urdf, panda_srdf,
                                                                erd_share, poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share))
    probe = Probe(ros)
    parameters = Parameters(ros)
    assert probe.send(joint_state(poses['hit'])) == (True, poses['hit_pairs'])
    for values, words in [
            ({'padding': -0.01}, ['padding', '>= 0']),
            ({'warning_distance': math.nan}, ['warning_distance']),
            ({'link_padding': ['panda_hnad=0.02']}, ['link_padding', 'panda_hnad', 'panda_hand']),
            ({'allowed_collisions': ['panda_link0']}, ['allowed_collisions', 'link_a:link_b']),
            ({'warning_ignore': ['panda_link0:panda_link0']}, ['warning_ignore', 'twice']),
            ({'joint_limit_policy': 'wrap'}, ['joint_limit_policy', 'clamp']),
            ({'stale_timeout': 5.0}, ['stale_timeout']),
            ({'padding': 0.02, 'joint_limit_policy': 'wrap'}, ['joint_limit_policy'])]:
        successful, reason = parameters.set(**values)
        assert not successful, values
        for word in words:
            assert word in reason, (values, reason)
    # Nothing changed: not even the valid half of the last request.
    assert probe.send(joint_state(poses['hit'])) == (True, poses['hit_pairs'])
    _, values = probe.next_diagnostics(lambda v: True)
    assert values['parameter_changes_applied_total'] == '0'
    assert DYNAMIC == {'warning_distance', 'padding', 'link_padding', 'allowed_collisions',
                       'warning_ignore', 'publish_markers', 'joint_limit_policy',
                       'check_motion'}


def test_markers_off_and_on_withdraws_nothing_else(ros, panda_urdf, panda_srdf, erd_share,
                                                   poses):
    start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, publish_markers=True,
                                     check_motion=False))     # instants: the poses jump
    probe = Probe(ros, markers=True)
    parameters = Parameters(ros)
    assert probe.send(joint_state(poses['hit']))[0]
    assert ros.spin_until(lambda: len(probe.markers) > 0)
    set_and_wait(parameters, probe, publish_markers=False)
    names = {name for name, _ in ros.probe.get_topic_names_and_types()}
    assert f'{ros.namespace}/contact' in names
    near = ros.record(Bool, 'near', reliable(10, latched=True))
    set_and_wait(parameters, probe, warning_distance=0.05)
    assert ros.spin_until(lambda: len(near) > 0)
    set_and_wait(parameters, probe, warning_distance=0.0)   # the zone's topics withdrawn
    assert ros.spin_until(lambda: ros.probe.count_publishers(f'{ros.namespace}/near') == 0,
                          10.0)
    count = len(probe.markers)
    assert probe.send(joint_state(poses['free'])) == (False, ())
    ros.spin_for(0.2)
    assert len(probe.markers) == count and isinstance(probe.markers.last, MarkerArray)
