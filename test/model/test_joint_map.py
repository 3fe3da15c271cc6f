"""Joint maps: the YAML forms, scale words, and the errors that name the key and the fix."""
import math

import numpy as np
import pytest

from collision_sensor.errors import ConfigError, SequenceError
from collision_sensor.model.joint_map import JointMap, joint_map_from_mapping, load_joint_map


def test_forms_scales_offsets_fixed_joints_and_indices(tmp_path):
    path = tmp_path / 'map.yaml'
    path.write_text('feature: observation.state\n'
                    'joints:\n'
                    '  a.pos: {joint: a, scale: degrees}\n'
                    '  b.pos: b\n'
                    '  3: {joint: c, scale: 2.0, offset: -1.0}\n'
                    'fixed: {d: 0.04}\n')
    joint_map = load_joint_map(path)
    joint_map.check_robot(('a', 'b', 'c', 'd'))
    state = np.array([[90.0, 0.5, 7.0, 1.0], [-180.0, -0.5, 0.0, 2.0]])
    q = joint_map.positions(state, ('a.pos', 'b.pos', 'x', 'y'), ('d', 'c', 'b', 'a'), 'ds#0')
    np.testing.assert_array_equal(q, [[0.04, 1.0, 0.5, math.pi / 2],
                                      [0.04, 3.0, -0.5, -math.pi]])


@pytest.mark.parametrize('document, pattern', [
    ({}, r'expected a mapping with "joints:"'),
    ({'joints': {'a': {'joint': 'a', 'scale': 'inches'}}}, r'scale .inches. is not a finite'),
    ({'joints': {'a': {'joint': 'a', 'scale': 0}}}, r'scale 0 would hold the joint'),
    ({'joints': {'a': {'joint': 'a', 'gain': 2}}}, r"unknown key\(s\) \['gain'\]"),
    ({'joints': {'a': 'a'}, 'frame': 1}, r"unknown key\(s\) \['frame'\]"),
    ({'joints': {-1: 'a'}}, r'must be a state entry'),
    ({'joints': {'a': {'scale': 2}}}, r'expected a joint name, or a mapping with "joint"'),
])
def test_malformed_maps_name_the_key(document, pattern):
    with pytest.raises(ConfigError, match=pattern):
        joint_map_from_mapping(document, 'map.yaml')


def test_the_map_must_name_the_robots_joints_each_once_and_all():
    def check(document, joints=('a', 'b')):
        joint_map_from_mapping(document, 'map.yaml').check_robot(joints)
    with pytest.raises(ConfigError, match=r"\['z'\] are not joints of the robot"):
        check({'joints': {'x': 'a', 'y': 'z'}})
    with pytest.raises(ConfigError, match=r"\['a'\] are mapped more than once"):
        check({'joints': {'x': 'a', 'y': 'b'}, 'fixed': {'a': 0.0}})
    with pytest.raises(ConfigError, match=r'robot joint\(s\) \[.b.\] are not in the joint map.*'
                                          r'fixed: \{b: 0.0\}'):
        check({'joints': {'x': 'a'}})


def test_entries_the_state_lacks_name_what_it_has():
    joint_map = joint_map_from_mapping({'joints': {'x': 'a', 5: 'b'}}, 'map.yaml')
    with pytest.raises(SequenceError, match=r'ds#2: "observation.state" has no entry "x".*'
                                            r"its entries: \['p', 'q'\]"):
        joint_map.positions(np.zeros((2, 2)), ('p', 'q'), ('a', 'b'), 'ds#2')
    with pytest.raises(SequenceError, match=r'state entry 5 \(for joint "b"\) is out of range'):
        joint_map.positions(np.zeros((2, 2)), ('x', 'q'), ('a', 'b'), 'ds#2')
    identity = JointMap.identity(('a',))
    identity.check_robot(('a', 'b'))        # no file: the reader says what is missing


#: The SO-101's URDF limits (example-robot-data ``so101.urdf``), rad.
SO101_LIMITS = {'shoulder_pan': (-1.91986, 1.91986), 'elbow_flex': (-1.69, 1.69),
                'gripper': (-0.174533, 1.74533), 'wrist_roll': (-2.74385, 2.84121)}


def test_a_range_maps_onto_the_joints_urdf_limits():
    """LeRobot's SO-101 body joints run -100..100 over the calibrated range, its gripper
    0..100; each value lands where the hand-computed fraction of the limits puts it."""
    joint_map = joint_map_from_mapping({'joints': {
        'shoulder_pan.pos': {'joint': 'shoulder_pan', 'range': [-100, 100]},
        'elbow_flex.pos': {'joint': 'elbow_flex', 'range': [100, -100]},   # counts the other way
        'gripper.pos': {'joint': 'gripper', 'range': [0, 100]},
        'wrist_roll.pos': {'joint': 'wrist_roll', 'scale': 'degrees'}}}, 'so101.yaml')
    ready = joint_map.for_robot(tuple(SO101_LIMITS), SO101_LIMITS)
    names = ('shoulder_pan.pos', 'elbow_flex.pos', 'gripper.pos', 'wrist_roll.pos')
    state = np.array([[-100.0, -100.0, 0.0, 90.0],
                      [100.0, 100.0, 100.0, 0.0],
                      [50.0, 50.0, 25.0, -45.0],
                      [0.0, 0.0, 50.0, 0.0]])
    q = ready.positions(state, names, tuple(SO101_LIMITS), 'so101#0')
    # shoulder_pan: -1.91986 + (v + 100) / 200 * 3.83972; elbow_flex: 1.69 - (v + 100) / 200
    # * 3.38; gripper: -0.174533 + v / 100 * 1.919863
    np.testing.assert_allclose(q, [[-1.91986, 1.69, -0.174533, math.pi / 2],
                                   [1.91986, -1.69, 1.74533, 0.0],
                                   [0.95993, -0.845, 0.30543275, -math.pi / 4],
                                   [0.0, 0.0, 0.7853985, 0.0]], rtol=0, atol=1e-12)
    with pytest.raises(ConfigError, match=r'map a range: call JointMap.for_robot first'):
        joint_map.positions(state, names, tuple(SO101_LIMITS), 'so101#0')


def test_a_range_pickles_and_an_entry_without_one_pickles_as_four_fields():
    import pickle
    entry = joint_map_from_mapping({'joints': {'a': {'joint': 'a', 'range': [0, 100]}}},
                                   'm').entries[0].on_limits(-1.0, 1.0)
    assert pickle.loads(pickle.dumps(entry)) == entry and entry.range == (0.0, 100.0)
    plain = JointMap.identity(('a',)).entries[0]
    assert pickle.loads(pickle.dumps(plain)) == plain
    assert set(plain.__getstate__()) == {'key', 'joint', 'scale', 'offset'}


@pytest.mark.parametrize('entry, pattern', [
    ({'joint': 'a', 'range': [-100, 100], 'scale': 2}, r'range: and scale: both given'),
    ({'joint': 'a', 'range': [-100, 100], 'offset': 1}, r'range: and offset: both given'),
    ({'joint': 'a', 'range': [0, 100, 200]}, r'expected two numbers \[a, b\]'),
    ({'joint': 'a', 'range': '0..100'}, r'expected two numbers \[a, b\]'),
    ({'joint': 'a', 'range': [0, 'max']}, r"range bound 'max' is not a finite number"),
    ({'joint': 'a', 'range': [5, 5]}, r'range \[5, 5\] is empty'),
])
def test_malformed_ranges_name_the_key(entry, pattern):
    with pytest.raises(ConfigError, match=r'map.yaml: joints: x: .*' + pattern):
        joint_map_from_mapping({'joints': {'x': entry}}, 'map.yaml')


def test_a_joint_without_finite_limits_cannot_take_a_range():
    joint_map = joint_map_from_mapping(
        {'joints': {'roll.pos': {'joint': 'roll', 'range': [-100, 100]}}}, 'map.yaml')
    with pytest.raises(ConfigError, match=r'map.yaml: joints: roll.pos: joint "roll" has no '
                                          r'finite limits.*continuous.*give scale: and '
                                          r'offset: instead'):
        joint_map.for_robot(('roll',), {'roll': (-math.inf, math.inf)})
