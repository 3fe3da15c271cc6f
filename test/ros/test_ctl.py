"""collision_sensor_ctl against a running node (the sensor of collision_sensor.testing, in this
process): each subcommand does what its ros2 counterpart does, checked on the node itself and
against a fresh CollisionChecker."""
import io
import os
import subprocess
import time

import pytest
import yaml

pytest.importorskip('rclpy')

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.model.example_robots import example_robot  # noqa: E402
from collision_sensor.model.sequences import read_sequence  # noqa: E402
from collision_sensor.ros import ctl  # noqa: E402
from collision_sensor.ros.console_scripts import console_command  # noqa: E402

ARM = [f'panda_joint{i}' for i in range(1, 8)]
READY = dict(zip(ARM, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]), panda_finger_joint1=0.02)
TABLE = {'objects': [{'name': 'table', 'box': {'size': [0.6, 1.0, 0.04]},
                      'pose': {'xyz': [0.55, 0.0, 0.3]}}]}


def run(*argv):
    """Run one command in this process; return (exit status, what it printed)."""
    import rclpy
    out = io.StringIO()
    status = ctl.main(list(argv) + ['--ros-args'], context=rclpy.Context(), out=out)
    return status, out.getvalue()


def oracle(scene=None):
    robot = example_robot('panda')
    return CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                      package_paths=robot.package_paths, scene=scene)


def test_param_set_get_list_as_ros2_param(collision_sensor):
    sensor = collision_sensor('panda')
    node = sensor.node.get_fully_qualified_name()
    assert run('param', 'set', node, 'warning_distance', '0.02') == (
        0, 'Set parameter successful\n')
    assert sensor.get_parameter('warning_distance') == 0.02
    assert run('param', 'get', node, 'warning_distance') == (0, 'warning_distance: 0.02\n')
    status, text = run('param', 'set', node, 'warning_distance', '-0.5')
    assert status == 1 and text.startswith('Setting parameter failed: ') and \
        'warning_distance' in text
    assert sensor.get_parameter('warning_distance') == 0.02
    status, text = run('param', 'set', node, 'warning_ignore', '[panda_link1:panda_link3]')
    assert status == 0 and sensor.get_parameter('warning_ignore') == [
        'panda_link1:panda_link3']
    assert run('param', 'get', node, 'no_such_parameter')[0] == 1
    status, text = run('param', 'list', node)
    assert status == 0 and '  padding\n' in text and '  urdf_path\n' in text
    status, _ = run('--timeout', '0.5', 'param', 'get', '/no/such_node', 'padding')
    assert status == 2


def test_echo_prints_the_verdicts_as_ros2_topic_echo(collision_sensor):
    sensor = collision_sensor('panda', scene=TABLE, parameters={'check_motion': False})
    touching = dict(READY, panda_joint2=0.6, panda_joint4=-1.4, panda_joint6=1.9)
    verdict = sensor.send_joint_state(touching)
    expected = oracle(TABLE).check(touching)
    assert verdict.contact and expected.in_collision
    status, text = run('echo', f'{sensor.namespace}/colliding_pairs', '--once')
    assert status == 0 and text.endswith('---\n')
    message = yaml.safe_load(text.split('---')[0])
    names = [f'{a}:{b}' for a, b in expected.colliding_pairs]
    assert [s['name'] for s in message['status']] == names
    status, text = run('echo', f'{sensor.namespace}/contact', '--count', '1')
    assert (status, yaml.safe_load(text.split('---')[0])) == (0, {'data': True})


def test_trajectory_from_a_yaml_file_is_answered(collision_sensor, tmp_path):
    sensor = collision_sensor('panda', scene=TABLE, parameters={'stale_timeout': 0.0,
                                                                'max_trajectory_bytes': 4096})
    sensor.send_joint_state(READY)
    topic = f'{sensor.namespace}/trajectory'
    for goal, expected in (([0.0, 0.6, 0.0, -1.4, 0.0, 1.9, 0.785], 'contact'),
                           ([0.8, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], 'valid')):
        path = tmp_path / f'{expected}.yaml'
        path.write_text(yaml.safe_dump({'joint_names': ARM, 'points': [
            {'positions': goal, 'time_from_start': {'sec': 2}}]}))
        status, text = run('trajectory', topic, str(path))
        assert status == (0 if expected == 'valid' else 1), text
        assert yaml.safe_load(text.split('\n', 1)[1])['kind'] == expected
    assert text.startswith(f'valid: relayed on {sensor.namespace}/trajectory_out')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('joint_names: [a]\npoints: [{position: [1.0]}]\n')
    assert run('trajectory', topic, str(bad))[0] == 2
    # Above max_trajectory_bytes: answered undecoded (no digest), matched by its header.
    large = tmp_path / 'large.yaml'
    large.write_text(yaml.safe_dump({'joint_names': ARM, 'points': [
        {'positions': [0.0] * 7, 'time_from_start': {'sec': k + 1}} for k in range(100)]}))
    status, text = run('trajectory', topic, str(large))
    assert status == 1 and text.startswith('refused (oversized): '), text


def test_scene_file_added_then_deleted(collision_sensor, tmp_path):
    sensor = collision_sensor('panda', parameters={'stale_timeout': 0.0,
                                                   'check_motion': False})
    reference = oracle()
    reference.check(READY)
    at = reference.link_poses()['panda_hand'][:3, 3]
    ball = {'objects': [{'name': 'ball', 'sphere': {'radius': 0.05},
                         'pose': {'xyz': [float(v) for v in at]}}]}
    path = tmp_path / 'ball.yaml'
    path.write_text(yaml.safe_dump(ball))
    topic = f'{sensor.namespace}/scene'
    assert run('scene', topic, str(path)) == (0, 'applied: 1 objects (ball)\n')
    expected = oracle(ball).check(READY)
    verdict = sensor.send_joint_state(READY)
    assert verdict.contact and set(verdict.pairs) == set(expected.colliding_pairs)
    status, text = run('scene', topic, str(path), '--frame', 'no_such_link')
    assert status == 1 and 'no_such_link' in text
    assert run('scene', topic, '--delete', 'ball') == (0, 'applied: 0 objects ()\n')
    assert not sensor.send_joint_state(READY).contact
    assert run('scene', topic)[0] == 2      # nothing to send


def test_record_writes_a_bag_the_offline_tools_read(collision_sensor, tmp_path):
    import threading
    sensor = collision_sensor('panda', parameters={'check_motion': False})
    bag = tmp_path / 'bag'
    topics = [f'{sensor.namespace}/joint_states', f'{sensor.namespace}/colliding_pairs']
    result = {}
    recorder = threading.Thread(target=lambda: result.update(
        zip(('status', 'text'), run('record', '-o', str(bag), '--duration', '3', *topics))))
    recorder.start()
    deadline = time.monotonic() + 30.0
    while sensor.client.count_subscribers(topics[0]) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    sent = [dict(READY, panda_joint1=0.1 * k) for k in range(10)]
    for q in sent:
        sensor.send_joint_state(q)
    recorder.join(60.0)
    assert result['status'] == 0 and f'{topics[0]} 10' in result['text'], result
    seq = read_sequence(str(bag), topic=topics[0])
    assert len(seq) == 10
    column = list(seq.joint_names).index('panda_joint1')
    assert seq.positions[:, column].tolist() == pytest.approx([0.1 * k for k in range(10)])


def test_the_console_script_runs(collision_sensor):
    sensor = collision_sensor('panda')
    run_script = subprocess.run(
        console_command('collision_sensor_ctl') + [
            'param', 'get', sensor.node.get_fully_qualified_name(), 'padding'],
        capture_output=True, text=True, timeout=120, env=dict(os.environ))
    assert (run_script.returncode, run_script.stdout) == (0, 'padding: 0.0\n'), \
        run_script.stderr
