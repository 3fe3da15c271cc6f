"""The node's configuration: the shipped parameters file, typed defaults, bad values refused
with a clear reason (in the process and from the console script), parameters that reach the
checker. Real rclpy, the real checker on the Panda of example-robot-data (``node_harness``).
"""
import math
import subprocess

import pytest
import yaml

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402

from collision_sensor import CollisionSensorError, ConfigError  # noqa: E402
from collision_sensor.model.share import config_path  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode  # noqa: E402
from collision_sensor.ros.node_parameters import (  # noqa: E402
    PARAMETERS, default_values, settings_from_values)
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    NODE_SCRIPT, panda_parameters, ros, start_node)


def test_params_file_lists_every_parameter_with_its_default():
    with open(config_path('collision_sensor.yaml')) as stream:
        document = yaml.safe_load(stream)
    values = document['/**']['ros__parameters']
    assert list(values) == [spec.name for spec in PARAMETERS]
    defaults = default_values()
    for name, value in values.items():
        assert value == defaults[name], name
    with open(config_path('collision_sensor.yaml')) as stream:
        text = stream.read()
    for spec in PARAMETERS:   # every parameter has a comment line just above it
        before = text.split(f'    {spec.name}:')[0].rstrip().splitlines()[-1]
        assert before.strip().startswith('#'), spec.name


def test_shipped_params_file_declares_typed_defaults(ros):
    node = ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context,
        cli_args=['--ros-args', '--params-file', config_path('collision_sensor.yaml')]))
    for spec in PARAMETERS:
        value = node.get_parameter_or(spec.name, None)
        if isinstance(spec.default, tuple):   # empty string arrays read as "not set"
            assert value is None or value.value in (None, [])
        else:
            assert value.value == spec.default and type(value.value) is type(spec.default)
    descriptor = node.describe_parameter('allowed_collisions')
    assert descriptor.type == Parameter.Type.STRING_ARRAY.value and not descriptor.read_only
    for spec in PARAMETERS:     # settable at run time: the dynamic ones only
        assert node.describe_parameter(spec.name).read_only is not spec.dynamic, spec.name
    result = node.set_parameters([Parameter('stale_timeout', value=5.0)])[0]
    assert not result.successful    # read-only: the node does not take it at run time


@pytest.mark.parametrize('overrides, words', [
    ({'urdf_path': '/no/such/robot.urdf'}, ['urdf_path', '/no/such/robot.urdf']),
    ({'joint_states_qos': 'fast'}, ['joint_states_qos', 'fast', 'sensor_data']),
    ({'package_paths': ['example-robot-data']}, ['package_paths', 'name=dir']),
    ({'stale_timeout': 1}, ['stale_timeout', '1.0']),
    ({'expansion': 'widest'}, ['expansion', 'widest']),
    ({'joint_limit_policy': 'wrap'}, ['joint_limit_policy', 'wrap', 'clamp']),
    ({'joint_limit_tolerance': -0.1}, ['joint_limit_tolerance', '>= 0']),
    ({'max_unknown_joints': -1}, ['max_unknown_joints', '>= 0']),
    ({'allowed_collisions': ['panda_link0']}, ['allowed_collisions', 'link_a:link_b']),
    ({'padding': -0.01}, ['padding', '>= 0']),
    ({'link_padding': ['panda_hand:0.02']}, ['link_padding', 'link=metres']),
    ({'link_padding': ['panda_hand=-1']}, ['link_padding', 'panda_hand=-1']),
    ({'link_padding': ['panda_hnad=0.02']}, ['link_padding', 'panda_hnad']),
    ({'warning_distance': math.inf}, ['warning_distance', '>= 0']),
])
def test_bad_configuration_fails_with_a_clear_reason(ros, panda_urdf, panda_srdf, erd_share,
                                                     overrides, words, capfd):
    with pytest.raises(CollisionSensorError) as raised:
        start_node(ros, panda_parameters(panda_urdf, panda_srdf, erd_share, **overrides))
    for word in words:
        assert word in str(raised.value)
    assert 'configuration failed' in capfd.readouterr().err    # logged before raising


@pytest.mark.node_process
def test_bad_configuration_exits_non_zero_from_the_console_script(tmp_path):
    params = tmp_path / 'bad.yaml'
    params.write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'urdf_path': str(tmp_path / 'missing.urdf')}}}))
    run = subprocess.run([NODE_SCRIPT, '--ros-args', '--params-file', str(params)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 1
    assert 'configuration failed' in run.stderr and 'missing.urdf' in run.stderr


def test_xacro_args_and_mesh_containment_parameters_reach_the_checker():
    from collision_sensor.ros.node_parameters import settings_from_values
    settings = settings_from_values({'xacro_args': ['arm_id:=panda', 'hand:=true'],
                                     'mesh_containment': True})
    assert settings.xacro_args == {'arm_id': 'panda', 'hand': 'true'}
    assert settings.checker_config['mesh_containment'] is True
    with pytest.raises(ConfigError, match='xacro_args.*"arm_id=panda".*name:=value'):
        settings_from_values({'xacro_args': ['arm_id=panda']})
