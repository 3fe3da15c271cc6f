"""Reading SRDFs: disabled pairs, group states, and names the robot does not have."""
import pytest

from collision_sensor.errors import LoadWarning, SrdfError
from collision_sensor.model.robot_model import load_urdf
from collision_sensor.model.srdf import DisabledPair, load_srdf, load_srdf_for_model


@pytest.fixture(scope='module')
def panda(panda_urdf, erd_package_paths):
    return load_urdf(panda_urdf, erd_package_paths)


def test_panda(panda, panda_srdf):
    srdf = load_srdf(panda_srdf, panda.links, [joint.name for joint in panda.joints])
    assert srdf.robot_name == 'panda' and srdf.source == panda_srdf
    with open(panda_srdf) as stream:
        assert len(srdf.disabled_pairs) == stream.read().count('<disable_collisions') == 35
    assert DisabledPair('panda_hand', 'panda_leftfinger', 'Adjacent') in srdf.disabled_pairs
    assert DisabledPair('panda_link5', 'panda_link7', 'Default') in srdf.disabled_pairs
    assert all(pair.link1 <= pair.link2 for pair in srdf.disabled_pairs)
    default = srdf.group_states['default']
    assert default['group'] == 'arm_and_hand'
    assert default['joints']['panda_joint4'] == -2.35619
    assert default['joints']['panda_finger_joint1'] == 0.001
    assert len(default['joints']) == 8


def test_ur5_pairs_without_reason(ur5_srdf):
    srdf = load_srdf(ur5_srdf)
    assert srdf.disabled_pairs[0] == DisabledPair('base_link', 'shoulder_link', '')
    assert srdf.group_states == {}


def test_pairs_are_sorted_and_stored_once():
    srdf = load_srdf('<robot name="r"><disable_collisions link1="b" link2="a" reason="x"/>'
                     '<disable_collisions link1="a" link2="b" reason="y"/></robot>')
    assert srdf.disabled_pairs == (DisabledPair('a', 'b', 'x'),)
    assert srdf.source == '<SRDF text>'


def _read(text, model, **names):
    with pytest.warns(LoadWarning) as caught:
        srdf = load_srdf_for_model(text, model, **names) if names else load_srdf_for_model(
            text, model)
    assert len(caught) == 1   # one warning per document, listing every skipped entry
    assert caught[0].filename == __file__   # printed at the caller's line, not inside the package
    return srdf, str(caught[0].message)


def test_unknown_links_are_skipped_with_file_line_and_element(panda, tmp_path):
    path = tmp_path / 'wrong.srdf'
    path.write_text("""<robot name="panda">
  <group name="arm"><chain base_link="panda_link0" tip_link="panda_link99"/></group>
  <disable_collisions link1="panda_link1" link2="panda_linkX" reason="Never"/>
  <end_effector name="ee" parent_link="flange" group="arm"/>
  <disable_collisions link1="panda_link1" link2="panda_link2" reason="Adjacent"/>
  <virtual_joint name="v" type="fixed" parent_frame="world" child_link="nowhere"/>
</robot>""")
    srdf, message = _read(str(path), panda)
    assert str(path) in message and '4 entries skipped' in message
    for culprit in ('line 2: <chain> skipped: tip_link="panda_link99" is not a link',
                    'line 3: <disable_collisions link1="panda_link1"> skipped: '
                    'link2="panda_linkX" is not a link of the robot; fix the name',
                    'line 4: <end_effector name="ee"> skipped: parent_link="flange"',
                    'line 6: <virtual_joint name="v"> skipped: child_link="nowhere"'):
        assert culprit in message
    # The rest of the document is used.
    assert srdf.disabled_pairs == (DisabledPair('panda_link1', 'panda_link2', 'Adjacent'),)
    assert srdf.virtual_joints == ()
    assert srdf.warnings and len(srdf.warnings) == 4


def test_unknown_joints_in_group_states_are_skipped(panda):
    text = ('<robot name="panda"><virtual_joint name="world_joint" type="fixed" '
            'parent_frame="world" child_link="panda_link0"/>'
            '<group_state name="home" group="arm"><joint name="panda_joint1" value="0.5"/>'
            '<joint name="elbow" value="1"/><joint name="panda_joint2" value="1 2"/>'
            '</group_state></robot>')
    srdf, message = _read(text, panda)
    assert 'in group_state "home": "elbow" is not a joint of the robot' in message
    assert 'value="1 2" has 2 numbers, joint "panda_joint2" (revolute) has 1' in message
    assert srdf.group_states['home']['joints'] == {'panda_joint1': 0.5}
    # Without the robot's names nothing is checked.
    with pytest.warns(LoadWarning, match='panda_joint2'):   # its count is still checked
        assert load_srdf(text).group_states['home']['joints']['elbow'] == 1.0


def test_multi_dof_group_state_values_get_moveit_variable_names(panda):
    text = ('<robot name="panda">'
            '<virtual_joint name="root_joint" type="floating" parent_frame="world" '
            'child_link="panda_link0"/>'
            '<virtual_joint name="base" type="planar" parent_frame="odom" '
            'child_link="panda_link0"/>'
            '<group_state name="standing" group="all">'
            '<joint name="root_joint" value="0. 0. 0.26 0. 0. 0. 1."/>'
            '<joint name="base" value="1 2 0.5"/><joint name="panda_joint1" value="0.1"/>'
            '</group_state></robot>')
    srdf = load_srdf_for_model(text.replace('<group_state', '<group name="all"><joint '
                                            'name="root_joint"/></group><group_state'), panda)
    assert srdf.warnings == ()   # a group may name a virtual joint
    joints = srdf.group_states['standing']['joints']
    assert joints == {'root_joint/trans_x': 0.0, 'root_joint/trans_y': 0.0,
                      'root_joint/trans_z': 0.26, 'root_joint/rot_x': 0.0,
                      'root_joint/rot_y': 0.0, 'root_joint/rot_z': 0.0,
                      'root_joint/rot_w': 1.0, 'base/x': 1.0, 'base/y': 2.0,
                      'base/theta': 0.5, 'panda_joint1': 0.1}
    floating, planar = srdf.virtual_joints
    assert floating.variables[0] == 'root_joint/trans_x' and len(floating.variables) == 7
    assert planar.variables == ('base/x', 'base/y', 'base/theta')
    # A floating joint given 3 numbers is skipped, naming the count it needs.
    _, message = _read(text.replace('0. 0. 0.26 0. 0. 0. 1.', '0 0 1'), panda)
    assert 'joint "root_joint" (floating) has 7 variable(s); give 7' in message


def test_virtual_joint_must_reach_the_root_link(panda):
    srdf, message = _read('<robot name="panda"><virtual_joint name="v" type="floating" '
                          'parent_frame="world" child_link="panda_link3"/></robot>', panda)
    assert 'child_link="panda_link3" is not the URDF\'s root link "panda_link0"' in message
    assert srdf.virtual_joints == ()


def test_srdf_of_another_robot(panda):
    # Another name but matching links: used, with a warning.
    srdf, message = _read('<robot name="franka"><disable_collisions link1="panda_link1" '
                          'link2="panda_link3"/></robot>', panda)
    assert 'the URDF robot is "panda"' in message and len(srdf.disabled_pairs) == 1
    # Another name and nothing in common: it cannot describe this robot.
    with pytest.raises(SrdfError, match='is for robot "ur5", not "panda", and none of the 2 link '
                                        'and joint names'):
        load_srdf_for_model('<robot name="ur5"><disable_collisions link1="shoulder_link" '
                            'link2="base_link"/></robot>', panda)
    # Joints count as well as links (alex_psyonic_hands.srdf names only joints).
    srdf, message = _read('<robot name="franka"><group name="arm"><joint name="panda_joint1"/>'
                          '<joint name="elbow"/></group></robot>', panda)
    assert 'line 1: <joint name="elbow"> skipped: name="elbow" is not a joint' in message


def test_a_long_list_of_skipped_entries_is_cut_when_printed(panda):
    text = '<robot name="panda">' + ''.join(
        f'<disable_collisions link1="a{i}" link2="panda_link1"/>' for i in range(30)) + '</robot>'
    srdf, message = _read(text, panda)
    assert len(srdf.warnings) == 30 and message.count('skipped:') == 20
    assert '... and 10 more (all in .warnings)' in message


@pytest.mark.parametrize('text, culprit', [
    ('<robot><disable_collisions link1="a"/></robot>', 'needs link1="..." and link2'),
    ('<robot><group_state name="s"><joint name="j" value="x"/></group_state></robot>',
     'group_state "s": value="x" is not finite numbers'),
    ('<robot><group_state name="s"><joint name="j" value="nan"/></group_state></robot>',
     'is not finite numbers'),
    ('<robot><group_state name="s"><joint name="j"/></group_state></robot>', 'value="..."'),
    ('<robot><virtual_joint name="v" type="revolute" parent_frame="w" child_link="a"/></robot>',
     'type="revolute" is not one of fixed, planar, floating'),
])
def test_malformed_entries_are_skipped_with_a_warning(text, culprit):
    with pytest.warns(LoadWarning, match=culprit):
        load_srdf(text)


@pytest.mark.parametrize('text, culprit', [
    ('<robot', 'broken XML at line 1'),
    ('<srdf/>', 'root element is <srdf>'),
])
def test_malformed_srdf_is_named(text, culprit):
    with pytest.raises(SrdfError, match=culprit):
        load_srdf(text)


def test_entity_expansion_is_refused():
    with pytest.raises(SrdfError, match='declares entities'):
        load_srdf('<!DOCTYPE robot [<!ENTITY a "b">]><robot name="&a;"/>')
