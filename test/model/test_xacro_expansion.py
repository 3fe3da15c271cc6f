"""xacro input: a .xacro urdf_path with xacro_args, $(find) through the package lookup."""
import pytest

from collision_sensor.errors import RobotDescriptionError
from collision_sensor.model.robot_model import load_urdf
from collision_sensor.model.xacro_expansion import expand_xacro, is_xacro_path

pytest.importorskip('xacro')

MACROS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="arm_link" params="name length">
    <link name="${name}">
      <collision><origin xyz="0 0 ${length / 2}"/>
        <geometry><box size="0.1 0.1 ${length}"/></geometry></collision>
    </link>
  </xacro:macro>
</robot>
"""

ROBOT = """<?xml version="1.0"?>
<robot name="xarm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="length" default="0.5"/>
  <xacro:arg name="prefix" default=""/>
  <xacro:include filename="$(find my_macros)/urdf/macros.xacro"/>
  <xacro:arm_link name="$(arg prefix)base" length="0.1"/>
  <xacro:arm_link name="$(arg prefix)upper" length="$(arg length)"/>
  <link name="$(arg prefix)tool">
    <collision><geometry><mesh filename="package://my_macros/meshes/tool.stl"/></geometry>
    </collision>
  </link>
  <joint name="$(arg prefix)shoulder" type="revolute">
    <parent link="$(arg prefix)base"/><child link="$(arg prefix)upper"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="$(arg prefix)flange" type="fixed">
    <parent link="$(arg prefix)upper"/><child link="$(arg prefix)tool"/>
  </joint>
</robot>
"""


@pytest.fixture
def xacro_robot(tmp_path):
    import trimesh
    package = tmp_path / 'macros_pkg'
    (package / 'urdf').mkdir(parents=True)
    (package / 'meshes').mkdir()
    (package / 'urdf' / 'macros.xacro').write_text(MACROS)
    trimesh.creation.box((0.1, 0.1, 0.1)).export(str(package / 'meshes' / 'tool.stl'))
    robot = tmp_path / 'robot.urdf.xacro'
    robot.write_text(ROBOT)
    return str(robot), {'my_macros': str(package)}


def test_xacro_file_with_arguments_and_find(xacro_robot):
    path, packages = xacro_robot
    assert is_xacro_path(path) and not is_xacro_path('<robot/>')
    model = load_urdf(path, packages, xacro_args={'length': 2.0, 'prefix': 'left_'})
    assert model.links == ('left_base', 'left_upper', 'left_tool')
    assert model.source == path
    upper = [e for e in model.elements if e.link == 'left_upper'][0]
    assert upper.vertices[:, 2].max() == pytest.approx(1.0)     # length 2, from $(arg length)
    tool = [e for e in model.elements if e.link == 'left_tool'][0]
    assert len(tool.faces) == 12                                 # the mesh, via package://
    default = load_urdf(path, packages)                          # the args' defaults
    assert default.links[0] == 'base'


def test_find_uses_the_ament_index_too(xacro_robot, tmp_path, monkeypatch):
    path, packages = xacro_robot
    prefix = tmp_path / 'install'
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / 'my_macros').write_text('')
    (prefix / 'share' / 'my_macros').symlink_to(packages['my_macros'])
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert 'link name="upper"' in expand_xacro(path).replace("'", '"')


def test_unresolved_find_names_package_and_places(xacro_robot, monkeypatch):
    path, _ = xacro_robot
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)
    with pytest.raises(RobotDescriptionError) as raised:
        load_urdf(path)
    message = str(raised.value)
    assert path in message and '$(find my_macros): package "my_macros" not found' in message
    assert 'package_paths (no entry "my_macros")' in message and 'AMENT_PREFIX_PATH' in message
    assert '--package-path my_macros=DIR' in message


def test_bad_xacro_names_the_file(tmp_path):
    path = tmp_path / 'bad.xacro'
    path.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro">'
                    '<link name="${undefined_property}"/></robot>')
    with pytest.raises(RobotDescriptionError, match=r'bad.xacro" \(xacro\) cannot be expanded'):
        load_urdf(str(path))
    with pytest.raises(RobotDescriptionError, match='not found'):
        load_urdf(str(tmp_path / 'missing.xacro'))
    path.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="$(arg nope)"/>'
                    '</robot>')
    with pytest.raises(RobotDescriptionError,
                       match=r'nope: the argument has no value.*xacro_args \(given: x\)'):
        load_urdf(str(path), xacro_args={'x': 1})
    with pytest.raises(RobotDescriptionError, match='not a .xacro file'):
        load_urdf('<robot name="r"><link name="a"/></robot>', xacro_args={'x': 1})


def test_xacro_arguments_from_the_command_line(xacro_robot, tmp_path, capsys):
    from collision_sensor.errors import ConfigError
    from collision_sensor.model.xacro_expansion import parse_xacro_args
    from collision_sensor.tools.offline_check import main
    assert parse_xacro_args(['prefix:=left_', 'length:=2', 'empty:=']) == {
        'prefix': 'left_', 'length': '2', 'empty': ''}
    for bad in (['prefix=left_'], [':=1'], ['a:=1', 'a:=2']):
        with pytest.raises(ConfigError, match='--xacro-arg'):
            parse_xacro_args(bad)
    path, packages = xacro_robot
    sequence = tmp_path / 'path.csv'
    sequence.write_text('time,left_shoulder\n0.0,0.0\n0.1,0.5\n')
    status = main([str(sequence), '--urdf', path, '--no-scene', '--progress', 'never',
                   '--package-path', f'my_macros={packages["my_macros"]}',
                   '--xacro-arg', 'prefix:=left_', '--xacro-arg', 'length:=2'])
    out = capsys.readouterr().out
    # The tool box sits inside the base's box: the expanded robot was loaded and checked.
    assert status == 1 and 'left_base -- left_tool' in out, out
