"""Reading SRDFs: disabled pairs, group states, and names the robot does not have."""
import pytest

from collision_sensor.errors import SrdfError
from collision_sensor.robot_model import load_urdf
from collision_sensor.srdf import DisabledPair, load_srdf


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


def test_unknown_links_are_all_listed_with_the_file(panda, tmp_path):
    path = tmp_path / 'wrong.srdf'
    path.write_text("""<robot name="panda">
  <group name="arm"><chain base_link="panda_link0" tip_link="panda_link99"/></group>
  <disable_collisions link1="panda_link1" link2="panda_linkX" reason="Never"/>
  <end_effector name="ee" parent_link="flange" group="arm"/>
</robot>""")
    with pytest.raises(SrdfError) as raised:
        load_srdf(str(path), panda.links)
    message = str(raised.value)
    assert str(path) in message and '3 unknown link(s)' in message
    for culprit in ('panda_link99 (chain tip_link, line 2)',
                    'panda_linkX (disable_collisions link2, line 3)',
                    'flange (end_effector parent_link, line 4)'):
        assert culprit in message
    assert 'panda_link0' in message   # the links the robot does have


def test_unknown_joints_in_group_states_are_listed(panda):
    text = ('<robot name="panda"><virtual_joint name="world_joint" type="fixed" '
            'parent_frame="world" child_link="panda_link0"/>'
            '<group_state name="home" group="arm"><joint name="panda_joint1" value="0"/>'
            '<joint name="world_joint" value="0"/><joint name="elbow" value="1"/></group_state>'
            '</robot>')
    joint_names = [joint.name for joint in panda.joints]
    with pytest.raises(SrdfError, match=r'1 unknown joint\(s\): elbow \(group_state "home"'):
        load_srdf(text, panda.links, joint_names)
    # Without the robot's names nothing is checked.
    assert load_srdf(text).group_states['home']['joints']['elbow'] == 1.0


@pytest.mark.parametrize('text, culprit', [
    ('<robot><disable_collisions link1="a"/></robot>', 'needs link1="..." and link2'),
    ('<robot><group_state name="s"><joint name="j" value="x"/></group_state></robot>',
     'group_state "s": joint "j" value="x"'),
    ('<robot><group_state name="s"><joint name="j" value="nan"/></group_state></robot>',
     'not one finite number'),
    ('<robot><group_state name="s"><joint name="j"/></group_state></robot>', 'value="..."'),
    ('<robot', 'broken XML at line 1'),
    ('<srdf/>', 'root element is <srdf>'),
])
def test_malformed_srdf_is_named(text, culprit):
    with pytest.raises(SrdfError, match=culprit):
        load_srdf(text)


def test_entity_expansion_is_refused():
    with pytest.raises(SrdfError, match='declares entities'):
        load_srdf('<!DOCTYPE robot [<!ENTITY a "b">]><robot name="&a;"/>')
