"""Loading URDFs: the real robots, small robots written here, and every kind of bad input."""
import math
import os

import warnings

import numpy as np
import pytest
import trimesh
from lxml import etree

from collision_sensor.errors import LoadWarning, MeshError, RobotDescriptionError
from collision_sensor.model.robot_model import load_urdf


def write(tmp_path, text, name='robot.urdf'):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def robot(body, name='r'):
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}\n</robot>\n'


TWO_LINKS = """
  <link name="base"/>
  <link name="arm"/>
  <joint name="j" type="{type}">
    <parent link="base"/> <child link="arm"/>
    <axis xyz="{axis}"/>
    <limit lower="-1" upper="1" effort="2" velocity="3"/>
  </joint>
"""


def two_links(joint_type='revolute', axis='0 0 1'):
    return robot(TWO_LINKS.format(type=joint_type, axis=axis))


# --- the real robots --------------------------------------------------------------------------

def test_panda(panda_urdf, erd_package_paths):
    model = load_urdf(panda_urdf, erd_package_paths)
    assert model.name == 'panda' and model.root_link == 'panda_link0'
    assert model.source == panda_urdf
    root = etree.parse(panda_urdf).getroot()
    assert set(model.links) == {link.get('name') for link in root.findall('link')}
    assert len(model.links) == 13
    assert [joint.name for joint in model.joints] == [
        f'panda_joint{i}' for i in range(1, 9)] + [
        'panda_hand_joint', 'panda_hand_tcp_joint', 'panda_finger_joint1', 'panda_finger_joint2']
    # Every <collision> element of the URDF text, and no <visual>, became one element.
    expected = [(link.get('name'), len(link.findall('collision'))) for link in root.iter('link')]
    for link, count in expected:
        assert sum(element.link == link for element in model.elements) == count
    assert len(model.elements) == 9 + 4 + 4
    meshes = [element for element in model.elements if element.source.startswith('mesh ')]
    assert [element.link for element in meshes] == [f'panda_link{i}' for i in range(8)] + [
        'panda_hand']
    assert all(element.source.endswith('.stl') and '/collision/' in element.source
               for element in meshes)
    fingers = [element for element in model.elements if element.link == 'panda_leftfinger']
    assert [element.index for element in fingers] == [0, 1, 2, 3]
    assert [element.name for element in fingers] == [f'panda_leftfinger/{i}' for i in range(4)]
    assert fingers[0].source == 'box 0.022 0.015 0.02'
    np.testing.assert_allclose(fingers[2].T_link_element[:3, 3], [0, 15.9e-3, 28.35e-3])
    for element in model.elements:
        assert len(element.vertices) > 0 and len(element.faces) > 0
        assert element.vertices.dtype == np.float64 and element.vertices.flags.c_contiguous
        assert element.faces.dtype == np.int64 and element.faces.flags.c_contiguous
    # The element order follows the link order.
    order = [model.links.index(element.link) for element in model.elements]
    assert order == sorted(order)
    finger = next(joint for joint in model.joints if joint.name == 'panda_finger_joint2')
    assert finger.type == 'prismatic' and finger.mimic.joint == 'panda_finger_joint1'
    assert (finger.mimic.multiplier, finger.mimic.offset) == (1.0, 0.0)
    np.testing.assert_allclose(finger.axis, [0, -1, 0])
    joint4 = next(joint for joint in model.joints if joint.name == 'panda_joint4')
    assert (joint4.lower, joint4.upper, joint4.effort, joint4.velocity) == (
        -3.0718, -0.0698, 87.0, 2.175)


def test_panda_meshes_found_without_package_paths(panda_urdf):
    # Walking up from the URDF finds example-robot-data's meshes.
    model = load_urdf(panda_urdf)
    assert len(model.elements) == 17


def test_ur5(ur5_urdf, erd_package_paths):
    model = load_urdf(ur5_urdf, erd_package_paths)
    assert model.root_link == 'world'
    assert model.links[:2] == ('world', 'base_link')
    root = etree.parse(ur5_urdf).getroot()
    assert [(element.link, element.index) for element in model.elements] == [
        (link, index) for link in model.links
        for index, _ in enumerate(root.find(f'link[@name="{link}"]').findall('collision'))]
    assert 'wrist_3_link' in {element.link for element in model.elements}


def test_robot_from_text_with_explicit_package_paths(panda_urdf, erd_package_paths):
    with open(panda_urdf) as stream:
        text = stream.read()
    model = load_urdf(text, erd_package_paths)
    assert model.source == '<robot_description text>' and len(model.elements) == 17


# --- small robots -----------------------------------------------------------------------------

def test_primitives_meshes_origins_and_names(tmp_path):
    mesh_path = tmp_path / 'meshes' / 'part.stl'
    mesh_path.parent.mkdir()
    trimesh.creation.box([1, 1, 1]).export(str(mesh_path))
    text = robot("""
  <link name="a">
    <visual><geometry><box size="9 9 9"/></geometry></visual>
    <collision name="hull">
      <origin xyz="1 2 3" rpy="0 0 1.5707963267948966"/>
      <geometry><mesh filename="../meshes/part.stl" scale="0.5 2 1"/></geometry>
    </collision>
    <collision><geometry><cylinder radius="0.1" length="0.4"/></geometry></collision>
    <collision><geometry><sphere radius="0.2"/></geometry></collision>
  </link>""")
    (tmp_path / 'urdf').mkdir()
    path = write(tmp_path / 'urdf', text)
    model = load_urdf(path, primitive_sections=8)
    hull, cylinder, sphere = model.elements
    assert hull.name == 'hull' and cylinder.name == 'a/1' and sphere.name == 'a/2'
    assert hull.source == 'mesh ../meshes/part.stl scale 0.5 2 1'
    np.testing.assert_allclose(hull.vertices.max(axis=0), [0.25, 1.0, 0.5])
    np.testing.assert_allclose(hull.T_link_element[:3, 3], [1, 2, 3])
    np.testing.assert_allclose(hull.T_link_element[:3, 0], [0, 1, 0], atol=1e-12)
    assert cylinder.source == 'cylinder 0.1 0.4' and len(cylinder.vertices) == 18
    assert sphere.source == 'sphere 0.2' and len(sphere.faces) == 2 * 8 * 3
    np.testing.assert_array_equal(cylinder.T_link_element, np.eye(4))


def test_joint_defaults_and_limits(tmp_path):
    text = robot("""
  <link name="base"/> <link name="a"/> <link name="b"/> <link name="c"/>
  <joint name="spin" type="continuous"><parent link="base"/><child link="a"/></joint>
  <joint name="weld" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="slide" type="prismatic">
    <parent link="b"/><child link="c"/><axis xyz="0 0 -3"/>
    <limit lower="-0.5" upper="0.5" effort="10" velocity="0.1"/>
  </joint>""")
    spin, weld, slide = load_urdf(text).joints
    np.testing.assert_array_equal(spin.axis, [1, 0, 0])        # the URDF default
    assert (spin.lower, spin.upper) == (-math.inf, math.inf)
    assert (weld.lower, weld.upper) == (0.0, 0.0) and weld.mimic is None
    np.testing.assert_array_equal(slide.axis, [0, 0, -1])       # normalised
    assert (slide.lower, slide.upper, slide.effort, slide.velocity) == (-0.5, 0.5, 10.0, 0.1)


def test_links_are_ordered_parents_first(tmp_path):
    text = robot("""
  <link name="tip"/> <link name="mid"/> <link name="base"/> <link name="side"/>
  <joint name="j2" type="fixed"><parent link="mid"/><child link="tip"/></joint>
  <joint name="j1" type="fixed"><parent link="base"/><child link="mid"/></joint>
  <joint name="j3" type="fixed"><parent link="base"/><child link="side"/></joint>""")
    model = load_urdf(text)
    assert model.links == ('base', 'mid', 'tip', 'side')
    assert [joint.name for joint in model.joints] == ['j1', 'j2', 'j3']
    assert model.joint_document_order == ('j2', 'j1', 'j3')


# --- bad input: every message names the culprit -----------------------------------------------

def test_missing_mesh_names_link_uri_and_fix(tmp_path):
    text = robot("""
  <link name="forearm"><collision><geometry>
    <mesh filename="package://arm_description/meshes/forearm.stl"/>
  </geometry></collision></link>""")
    with pytest.raises(MeshError) as raised:
        load_urdf(write(tmp_path, text))
    message = str(raised.value)
    assert 'link "forearm"' in message
    assert '"package://arm_description/meshes/forearm.stl"' in message
    assert os.path.join(str(tmp_path), 'meshes/forearm.stl') in message       # a place tried
    assert '--package-path arm_description=DIR' in message


def test_unreadable_mesh_names_link(tmp_path):
    (tmp_path / 'bad.dae').write_text('this is not COLLADA')
    text = robot('<link name="hand"><collision><geometry><mesh filename="bad.dae"/></geometry>'
                 '</collision></link>')
    with pytest.raises(MeshError, match='link "hand".*"bad.dae".*cannot be read'):
        load_urdf(write(tmp_path, text))


def test_broken_xml_names_file_and_line(tmp_path):
    path = write(tmp_path, '<robot name="r">\n<link name="a">\n<link name="b"/>\n</robot>')
    with pytest.raises(RobotDescriptionError, match=r'robot\.urdf.*line \d'):
        load_urdf(path)


def test_entity_expansion_is_refused():
    text = ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
            '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n<robot name="&b;"><link name="l"/>'
            '</robot>')
    with pytest.raises(RobotDescriptionError, match='robot_description text.*declares entities'):
        load_urdf(text)


def test_too_deep_nesting_is_refused():
    text = '<robot name="r"><link name="l">' + '<x>' * 100 + '</x>' * 100 + '</link></robot>'
    with pytest.raises(RobotDescriptionError, match='nested deeper than 64'):
        load_urdf(text)


FLOATING_BASE = """
  <link name="world"/>
  <link name="base"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <link name="arm"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <joint name="root_joint" type="{type}">
    <parent link="world"/> <child link="base"/> <origin xyz="0 0 0.5"/>
  </joint>
  <joint name="j" type="revolute">
    <parent link="base"/> <child link="arm"/> <origin xyz="0 0 2"/>
    <limit lower="-1" upper="1" effort="2" velocity="3"/>
  </joint>
"""


@pytest.mark.parametrize('joint_type, variables', [
    ('floating', ('trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w')),
    ('planar', ('x', 'y', 'theta'))])
def test_floating_base_is_read_and_driven(joint_type, variables):
    from collision_sensor.engine.kinematics import build_kinematic_tree
    with warnings.catch_warnings():
        warnings.simplefilter('error', LoadWarning)   # nothing is held any more
        model = load_urdf(robot(FLOATING_BASE.format(type=joint_type)))
    joint = {j.name: j for j in model.joints}['root_joint']
    assert joint.type == joint_type
    assert joint.variables == tuple(f'root_joint/{v}' for v in variables)
    assert model.held_joints == ()
    tree = build_kinematic_tree(model)
    assert tree.joint_names == joint.variables + ('j',)
    q = tree.neutral()
    q[:2] = 3.0, 4.0   # x (trans_x) and y (trans_y)
    poses = tree.forward_kinematics(q)
    assert np.allclose(poses[tree.link_names.index('base')][:3, 3], [3, 4, 0.5])
    assert np.allclose(poses[tree.link_names.index('arm')][:3, 3], [3, 4, 2.5])


@pytest.mark.parametrize('joint_type', ['floating', 'planar'])
def test_floating_and_planar_joints_inside_the_tree_are_driven(joint_type):
    from collision_sensor.engine.kinematics import build_kinematic_tree
    text = FLOATING_BASE.format(type='fixed').replace('type="revolute"', f'type="{joint_type}"')
    model = load_urdf(robot(text))
    assert model.held_joints == () and model.joints[-1].type == joint_type
    tree = build_kinematic_tree(model)
    assert tree.joint_names == model.joints[-1].variables


def test_unknown_joint_type_is_refused():
    with pytest.raises(RobotDescriptionError, match='joint "j" has type "ball"'):
        load_urdf(two_links('ball'))


def test_package_uri_with_an_empty_package_name_is_read_with_a_warning(erd_package_paths):
    mesh = ('<link name="{0}"><collision><geometry><mesh filename="package:///example-robot-data/'
            'robots/panda_description/meshes/collision/link0.stl"/></geometry></collision></link>')
    text = robot(mesh.format('a') + mesh.format('b') + '<joint name="j" type="fixed">'
                 '<parent link="a"/><child link="b"/></joint>')
    with pytest.warns(LoadWarning, match='1 oddity tolerated') as caught:
        model = load_urdf(text, erd_package_paths)
    assert 'empty package name; read as "package://example-robot-data/robots/' in str(
        caught[0].message)
    assert len(model.elements) == 2 and len(model.elements[0].faces) > 0


def test_mimic_of_unknown_joint_is_tolerated_as_independent():
    # As urdfdom and MoveIt read alex_psyonic_hands.urdf: the joint moves on its own.
    text = two_links().replace('<axis', '<mimic joint="ghost" multiplier="2"/><axis')
    with pytest.warns(LoadWarning, match='joint "j" mimics joint "ghost", which does not exist; '
                                         'it is treated as an independent joint; fix'):
        model = load_urdf(text)
    assert model.joints[0].mimic is None and len(model.warnings) == 1


def test_two_roots_are_named():
    text = robot('<link name="a"/><link name="b"/><link name="c"/>'
                 '<joint name="j" type="fixed"><parent link="a"/><child link="c"/></joint>')
    with pytest.raises(RobotDescriptionError, match=r'several root links \(a, b\)'):
        load_urdf(text)


def test_two_parents_are_named():
    text = robot('<link name="a"/><link name="b"/><link name="c"/>'
                 '<joint name="j1" type="fixed"><parent link="a"/><child link="c"/></joint>'
                 '<joint name="j2" type="fixed"><parent link="b"/><child link="c"/></joint>')
    with pytest.raises(RobotDescriptionError, match='link "c" has two parents.*"j1".*"j2"'):
        load_urdf(text)


def test_cycles_are_refused():
    cycle = robot('<link name="r"/><link name="a"/><link name="b"/>'
                  '<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>'
                  '<joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint>')
    with pytest.raises(RobotDescriptionError, match='links a, b form a cycle'):
        load_urdf(cycle)
    loop = robot('<link name="a"/>'
                 '<joint name="j" type="fixed"><parent link="a"/><child link="a"/></joint>')
    with pytest.raises(RobotDescriptionError, match='cycle'):
        load_urdf(loop)


def test_unknown_link_is_named():
    text = two_links().replace('<child link="arm"/>', '<child link="elbow"/>')
    with pytest.raises(RobotDescriptionError, match='joint "j" names child link "elbow"'):
        load_urdf(text)


@pytest.mark.parametrize('replace, culprit', [
    (('-1', 'nan'), r'joint "j": <limit lower="nan">.*not finite'),
    (('<axis', '<origin xyz="0 inf 0"/><axis'), r'joint "j": <origin xyz="0 inf 0">'),
    (('0 0 1', '0 0'), r'joint "j": <axis xyz="0 0">.*needs 3 numbers'),
    (('0 0 1', '0 0 0'), 'joint "j" has a zero axis'),
    (('<limit lower="-1" upper="1" effort="2" velocity="3"/>', ''), 'joint "j".*has no <limit>'),
    (('lower="-1" upper="1"', 'lower="1" upper="-1"'), 'joint "j": limit lower=1.0 is above'),
])
def test_bad_numbers_are_named(replace, culprit):
    with pytest.raises(RobotDescriptionError, match=culprit):
        load_urdf(two_links().replace(*replace))


def test_bad_collision_geometry_is_named():
    text = robot('<link name="a"><collision><geometry><capsule radius="1" length="2"/>'
                 '</geometry></collision></link>')
    with pytest.raises(RobotDescriptionError, match='link "a" <collision> 0: shape <capsule>'):
        load_urdf(text)
    text = robot('<link name="a"><collision><origin xyz="0 0 0"/></collision></link>')
    with pytest.raises(RobotDescriptionError, match='link "a": <collision> 0.*exactly one shape'):
        load_urdf(text)
    text = robot('<link name="a"><collision><geometry><box size="1 -1 1"/></geometry>'
                 '</collision></link>')
    with pytest.raises(RobotDescriptionError, match='link "a" <collision> 0: box size'):
        load_urdf(text)


def test_not_a_robot_is_refused():
    with pytest.raises(RobotDescriptionError, match='root element is <html>'):
        load_urdf('<html/>')
    with pytest.raises(RobotDescriptionError, match='link "a" is defined twice'):
        load_urdf(robot('<link name="a"/><link name="a"/>'))
