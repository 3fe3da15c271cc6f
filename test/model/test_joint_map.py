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
