"""The exception list's pieces on hand-made trees."""
import pytest

from collision_sensor.errors import ConfigError
from collision_sensor.model.exception_list import adjacent_pairs, parse_pair_strings, sorted_pair


def test_adjacent_pairs_skip_links_without_geometry():
    parents = {'base': None, 'a': 'base', 'mount': 'a', 'b': 'mount', 'c': 'mount',
               'flange': 'b', 'tool': 'flange'}
    pairs = adjacent_pairs(parents, ['base', 'a', 'b', 'c', 'tool'])
    assert pairs == {('a', 'base'), ('a', 'b'), ('a', 'c'), ('b', 'tool')}
    # Siblings hanging off one link are not adjacent to each other.
    assert ('b', 'c') not in pairs


def test_pair_strings_are_sorted_and_checked():
    known = ['a', 'b', 'table']
    assert parse_pair_strings(['b:a', ' table : a ', ''], known) == {('a', 'b'), ('a', 'table')}
    with pytest.raises(ConfigError, match='"x".*"y"'):
        parse_pair_strings(['a:x', 'y:b'], known)
    with pytest.raises(ConfigError, match='with itself'):
        parse_pair_strings(['a:a'], known)
    with pytest.raises(ConfigError, match='"a:b:c"'):
        parse_pair_strings(['a:b:c'], known)
    assert sorted_pair('z', 'a') == ('a', 'z')
