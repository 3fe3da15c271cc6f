"""The node's joint-state input: partial, missing, malformed, unknown, oversized, out-of-limit
and stale joint states; engine errors. Each is refused or reported and changes nothing it
should not. Real rclpy, the real checker on the Panda (``node_harness``).
"""
import math

import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402

from collision_sensor import CollisionChecker, ConfigError  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from collision_sensor.ros.node_parameters import default_values, settings_from_values  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    ARM, GRIPPER, Probe, expected, frames, joint_state, logged, pairs_of, panda, panda_parameters,
    poses, ros, stamp_of, start_node)


def test_require_all_joints_off_checks_partial_states(collision_sensor, panda, poses):
    sensor = collision_sensor('panda', parameters={'require_all_joints': False,
                                                   'check_motion': False})
    for pose in ('hit', 'free'):
        arm = {name: poses[pose][name] for name in ARM}
        # Joints never heard keep the checker's start value, 0 (the gripper closed).
        reference = panda.check(dict(arm, panda_finger_joint1=0.0))
        verdict = sensor.send_joint_state(arm)
        assert (verdict.contact, verdict.pairs) == (reference.in_collision,
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
    err = logged(ros, capfd, '"panda_finger_joint1"=nan')
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
    err = logged(ros, capfd, '(+1495 more)')
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
    err = logged(ros, capfd, 'above max_joint_state_bytes (4096)')
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
    err = logged(ros, capfd, 'by more than joint_limit_tolerance 0.01')
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


#: The state (panda_joint1) at which the tests' injected faults fire.
MARK = 0.123


def test_engine_errors_are_logged_and_the_node_keeps_running(ros, panda_urdf, panda_srdf,
                                                             erd_share, poses, capfd):
    node = ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context,
        parameter_overrides=panda_parameters(panda_urdf, panda_srdf, erd_share)))
    joint = node.checker.joint_names.index('panda_joint1')
    node.sensor.core.inject_fault(joint, MARK, 'engine fault injected by the test', True)
    node.sensor.core.inject_fault(joint, -MARK, 'engine error injected by the test', False)
    probe = Probe(ros)
    free = poses['free']
    assert probe.send(joint_state(free)) == (False, ())
    # Answered, fail safe (on_engine_error contact): contact true, the error named.
    assert probe.send(joint_state(dict(free, panda_joint1=MARK))) == \
        (True, (('engine_error',),))
    assert probe.send(joint_state(dict(free, panda_joint1=-MARK))) == \
        (True, (('engine_error',),))
    assert 'engine error injected by the test' in probe.pairs.last.status[0].message
    assert probe.send(joint_state(free)) == (False, ())
    err = logged(ros, capfd, 'collision check failed: engine error injected by the test')
    assert 'collision check failed: engine fault injected by the test' in err
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
