"""The parameter reference (``config/collision_sensor.yaml``, ``docs/parameters.md``) is what
``scripts/parameter_reference.py`` writes from the node's parameter table; no ROS is started.

When a test here fails after a parameter was added or changed: run
``python scripts/parameter_reference.py`` and commit both files.
"""
import dataclasses
import os

import yaml

from collision_sensor.ros import node_parameters, parameter_notes
from scripts import parameter_reference

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_both_files_are_what_the_table_gives():
    assert parameter_reference.stale(ROOT) == [], \
        'stale: run python scripts/parameter_reference.py and commit the files'


def test_the_notes_name_only_parameters_and_sections_follow_the_table():
    names = [spec.name for spec in node_parameters.PARAMETERS]
    assert parameter_reference.unknown_names(
        names=list(parameter_notes.SECTIONS) + list(parameter_notes.DETAILS)) == []
    order = [name for name in names if name in parameter_notes.SECTIONS]
    assert order == list(parameter_notes.SECTIONS)       # sections in the table's order
    assert names[0] in parameter_notes.SECTIONS          # the first parameter opens one


def test_the_params_file_sets_every_parameter_to_its_typed_default():
    with open(os.path.join(ROOT, 'config', 'collision_sensor.yaml')) as stream:
        values = yaml.safe_load(stream)['/**']['ros__parameters']
    defaults = node_parameters.default_values()
    assert list(values) == list(defaults)
    for name, value in values.items():
        assert value == defaults[name] and type(value) is type(defaults[name]), name


def test_the_generator_reads_the_table_it_is_given():
    """A parameter added to the table appears in both files, in its section, with its type,
    default, description, details and valid values; a change of a default shows."""
    table = list(node_parameters.PARAMETERS)
    added = node_parameters.ParameterSpec('probe_limit', 2.5, 'a limit the test adds',
                                          '> 0', dynamic=True)
    table.insert(1, added)
    table[0] = dataclasses.replace(table[0], default='robot.urdf')
    texts = parameter_reference.reference(
        table, {table[0].name: 'first', 'probe_limit': 'the added one'},
        {'probe_limit': 'its details'})
    params = texts[parameter_reference.YAML_PATH]
    assert yaml.safe_load(params)['/**']['ros__parameters']['probe_limit'] == 2.5
    assert f'    {table[0].name}: robot.urdf\n' in params
    assert ('    # --- the added one ---' in params
            and '    # A limit the test adds. Its details. Valid: > 0. Settable at run time.\n'
                '    probe_limit: 2.5\n' in params)
    docs = texts[parameter_reference.DOCS_PATH]
    assert '## The added one' in docs
    assert ('| `probe_limit` | double | `2.5` | yes | A limit the test adds. Its details. | '
            '> 0 |') in docs
    assert parameter_reference.stale(ROOT, texts) == [parameter_reference.YAML_PATH,
                                                       parameter_reference.DOCS_PATH]


def test_values_are_written_as_yaml_reads_them_back():
    for value in ('', 'sat', 'a b', 'true', '1.0', "it's", (), ('a', 'b=c'), True, False, 0,
                  65536, 0.0, 0.01, 1e-06, 2.5e+20, float('inf')):
        text = parameter_reference.yaml_value(value)
        back = yaml.safe_load(f'x: {text}')['x']
        assert back == (list(value) if isinstance(value, tuple) else value), (value, text)
        assert type(back) is (list if isinstance(value, tuple) else type(value)), (value, text)
