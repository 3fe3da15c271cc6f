"""``collision_sensor_node``, the console script, run as a user runs it: a parameters file,
signals while starting, waiting and checking (clean exits), load warnings printed once, a name
that is not UTF-8, the Fast DDS profile it points at.
"""
import os
import signal
import subprocess
import time

import pytest
import yaml

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from collision_sensor.model.share import config_path  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    NODE_SCRIPT, Probe, assert_clean_exit, expected, frames, joint_state, node_process, pairs_of,
    panda, poses, ros, stamp_of, stop, wait_until_signals_are_handled)
from ros_helpers import reliable  # noqa: E402

pytestmark = pytest.mark.node_process


def test_console_script_with_params_file(ros, tmp_path, panda_urdf, panda_srdf, erd_share, poses):
    with open(config_path('collision_sensor.yaml')) as stream:
        document = yaml.safe_load(stream)
    document['/**']['ros__parameters'].update(
        urdf_path=panda_urdf, srdf_path=panda_srdf, joint_states_qos='reliable',
        package_paths=[f'example-robot-data={erd_share}'], check_motion=False)  # poses jump
    params = tmp_path / 'panda.yaml'
    params.write_text(yaml.safe_dump(document))
    process = subprocess.Popen(
        [NODE_SCRIPT, '--ros-args', '--params-file', str(params), '-r',
         f'__ns:={ros.namespace}'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        # The node subscribes once its robot is loaded; its first check may compile kernels.
        assert ros.spin_until(
            lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 60.0), \
            'the node process never subscribed to joint_states'
        probe = Probe(ros)
        assert probe.send(joint_state(poses['hit'], stamp=stamp_of(1)), timeout=60.0)[0]
        assert pairs_of(probe.pairs.last) == poses['hit_pairs']
        assert probe.pairs.last.header.stamp == stamp_of(1)
        assert probe.send(joint_state(poses['free'], stamp=stamp_of(2))) == (False, ())
    finally:
        process.send_signal(signal.SIGINT)
        try:
            output, _ = process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            output, _ = process.communicate()
            pytest.fail(f'the node did not stop on SIGINT:\n{output}')
    assert process.returncode == 0, output
    assert 'robot loaded from urdf_path' in output


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('delay', [0.0, 0.3, 1.0, 2.5], ids=lambda d: f'{d}s')
def test_signal_while_starting_exits_cleanly(ros, panda_urdf, panda_srdf, erd_share, signum,
                                             delay):
    # From its first statement the process imports rclpy and the engine, loads the Panda, builds
    # its trees and runs the query once: each delay lands in another phase.
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    wait_until_signals_are_handled(process)
    time.sleep(delay)
    status, output, _ = stop(process, signum)
    assert_clean_exit(status, output)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_while_waiting_for_robot_description_exits_cleanly(ros, signum):
    process = node_process(ros.namespace)
    # Its first /diagnostics: the node is spinning, waiting for a robot.
    name = f'{ros.namespace.strip("/")}/collision_sensor: collision sensor'
    diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
    assert ros.spin_until(lambda: any(status.name == name for msg in diagnostics.messages
                                      for status in msg.status), 60.0)
    status, output, seconds = stop(process, signum)
    assert_clean_exit(status, output)
    assert 'waiting for the robot on robot_description' in output and seconds < 5.0


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_ready_line_then_signal_while_checking_exits_cleanly(ros, panda_urdf, panda_srdf,
                                                             erd_share, poses, signum):
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    try:
        assert ros.spin_until(
            lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 120.0)
        probe = Probe(ros)
        assert probe.send(joint_state(poses['hit']), timeout=30.0)[0]
        # A stream while the signal arrives: the node is checking.
        states = [joint_state(poses[key]) for key in ('free', 'hit') * 200]
        for msg in states:
            probe.joint_states.publish(msg)
    finally:
        status, output, seconds = stop(process, signum)
    assert_clean_exit(status, output)
    lines = output.splitlines()
    # One "ready" line, after the robot was loaded, before any other line about joint states.
    ready = [i for i, line in enumerate(lines) if line.startswith('[INFO] ready: checking ')]
    loaded = [i for i, line in enumerate(lines) if 'robot loaded from urdf_path' in line]
    assert len(ready) == 1 and loaded and loaded[0] < ready[0], output
    assert f'{ros.namespace}/joint_states (reliable)' in lines[ready[0]]
    assert seconds < 5.0, output


def test_load_warnings_are_printed_once_by_the_console_script(ros, erd_share):
    """Issue 28: the SRDF's warning came twice, as a raw Python warning and as the log line."""
    robots = os.path.join(erd_share, 'robots', 'z1_description')
    process = node_process(
        ros.namespace, '-p', f'urdf_path:={os.path.join(robots, "urdf", "z1.urdf")}', '-p',
        f'srdf_path:={os.path.join(robots, "srdf", "z1.srdf")}', '-p',
        f'package_paths:=["example-robot-data={erd_share}"]')
    assert ros.spin_until(
        lambda: ros.probe.count_subscribers(f'{ros.namespace}/joint_states') > 0, 60.0)
    status, output, _ = stop(process, signal.SIGINT)
    assert status == 0, output
    assert 'LoadWarning' not in output
    assert output.count('base_link="base" is not a link of the robot') == 1, output
    assert output.count('[WARN] while loading the robot: SRDF: line 11: <chain> skipped') == 1


def test_console_script_survives_a_name_that_is_not_utf8(ros, panda_urdf, panda_srdf, erd_share,
                                                         poses):
    """The console script's executor (EventsExecutor) takes a joint state whose name is not
    UTF-8 (raw CDR from the wire): the node keeps answering and exits cleanly."""
    from rclpy.serialization import serialize_message
    process = node_process(ros.namespace, urdf=panda_urdf, srdf=panda_srdf, erd_share=erd_share)
    try:
        probe = Probe(ros, timeout=60.0)
        raw = serialize_message(JointState(name=['zzzzzz'], position=[0.0]))
        probe.joint_states.publish(raw.replace(b'zzzzzz', b'\xff\xfe\xfd\xfc\xfb\xfa'))
        # Decoded with the bytes replaced: a name of no joint, answered as such.
        assert ros.spin_until(lambda: len(probe.pairs) == 1, 10.0)
        assert pairs_of(probe.pairs.last) == (('waiting_for_joints',),)
        assert probe.send(joint_state(poses['free']), timeout=10.0) == (False, ())
        assert process.poll() is None
    finally:
        status, output, _ = stop(process, signal.SIGINT)
    assert_clean_exit(status, output)


def test_console_script_points_fast_dds_at_the_shipped_profile_only_when_unconfigured(tmp_path,
                                                                                      monkeypatch):
    from lxml import etree

    from collision_sensor.ros.main import apply_dds_profile
    monkeypatch.chdir(tmp_path)
    environ = {}
    profile = apply_dds_profile(environ)
    assert profile == config_path('fastdds_node.xml')
    assert environ == {'FASTRTPS_DEFAULT_PROFILES_FILE': profile,
                       'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}
    ns = {'p': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    readers = etree.parse(profile).findall('p:data_reader', ns)
    assert [r.findtext('p:historyMemoryPolicy', namespaces=ns) for r in readers] == ['DYNAMIC']
    # Writers as rmw_fastrtps sets them without the profile: synchronous (Fast DDS's own
    # default, asynchronous, puts a thread between each verdict and the wire).
    writers = etree.parse(profile).findall('p:data_writer', ns)
    assert [(w.findtext('p:historyMemoryPolicy', namespaces=ns),
             w.findtext('p:qos/p:publishMode/p:kind', namespaces=ns)) for w in writers] == \
        [('PREALLOCATED_WITH_REALLOC', 'SYNCHRONOUS')]
    # A user's own Fast DDS configuration, another middleware or the switch: nothing changes.
    for environ in ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/mine.xml'},
                    {'FASTDDS_DEFAULT_PROFILES_FILE': '/mine.xml'},
                    {'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'},
                    {'RMW_FASTRTPS_PUBLICATION_MODE': 'ASYNCHRONOUS'},
                    {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
                    {'COLLISION_SENSOR_DDS_PROFILE': 'off'}):
        before = dict(environ)
        assert apply_dds_profile(environ) is None and environ == before
    (tmp_path / 'DEFAULT_FASTRTPS_PROFILES.xml').write_text('<profiles/>')
    environ = {}
    assert apply_dds_profile(environ) is None and environ == {}
