"""Write the node's parameter reference from its parameter table, the one source.

``python scripts/parameter_reference.py [--check]`` writes

- ``config/collision_sensor.yaml``: a ros2 params file with every parameter at its default,
  each with its description as a comment, grouped in sections;
- ``docs/parameters.md``: the same as tables (type, default, settable at run time, meaning,
  valid values),

both from :data:`collision_sensor.ros.node_parameters.PARAMETERS` (names, typed defaults,
descriptions, valid values, which are dynamic), with the section titles and details of
:mod:`collision_sensor.ros.parameter_notes`. ``--check`` writes nothing and exits 1 when
either file differs from what the table gives (``test/test_parameter_reference.py`` runs it).
"""
import argparse
import math
import os
import re
import sys
from typing import Iterable, List, Mapping, Optional, Sequence, Tuple

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
YAML_PATH = os.path.join('config', 'collision_sensor.yaml')
DOCS_PATH = os.path.join('docs', 'parameters.md')
WIDTH = 99

YAML_HEADER = '''\
# Parameters of collision_sensor_node (ros2 params-file format), with their defaults.
# Generated from the node's parameter table (collision_sensor/ros/node_parameters.py) by
# "python scripts/parameter_reference.py": change the table, then run it.
#
#   collision_sensor_node --ros-args --params-file collision_sensor.yaml -r __ns:=/robot
#
# Parameters are read at start-up; those marked "settable at run time" can also be changed while
# the node runs (collision_sensor_ctl param set /collision_sensor warning_distance 0.05, or
# ros2 param set with the same arguments), validated as here, and
# the change is answered by a verdict; restart the node to change the others. A bad value, or a
# name the node does not have (a typo), stops the node at start-up with a message naming it
# (exit status 1). Types matter: write 1.0, not 1, for a double.
/**:
  ros__parameters:
'''

DOCS_HEADER = '''\
# `collision_sensor_node`: parameters

Generated from the node's parameter table (`collision_sensor/ros/node_parameters.py`) by
`python scripts/parameter_reference.py`, which also writes
[`config/collision_sensor.yaml`](../config/collision_sensor.yaml): every parameter at its
default, with these descriptions as comments, ready for `--params-file`.

Parameters are read at start-up. A bad value stops the node with a message naming the
parameter and the fix; so does a name the node does not have (a typo, from `-p` or a params
file: `unknown parameter(s): "warning_distnace" (did you mean warning_distance?)`; ROS's own,
such as `use_sim_time`, pass, and a params file's section for another node is not read). File
paths come only from these parameters.

Those settable at run time (`collision_sensor_ctl param set /collision_sensor warning_distance
0.05`, or `ros2 param set /collision_sensor warning_distance 0.05` where ROS 2 comes from apt)
are validated as at start-up; a refused request names the reason and changes nothing, and every
change applied is answered by a verdict at the current state (header: now, root frame).
`padding`, `link_padding` and `allowed_collisions` build a new checker on a thread of its own
while the current one answers (`parameters_pending` on `/diagnostics` until it replaces it,
between two checks); the others apply at once, between two checks. The rest answer "can only
be set at start-up".
'''


def type_name(default) -> str:
    """Return the ROS parameter type of a typed default (``()``: a string array)."""
    if isinstance(default, tuple):
        return 'string[]'
    if isinstance(default, bool):
        return 'bool'
    if isinstance(default, int):
        return 'int'
    if isinstance(default, float):
        return 'double'
    return 'string'


def yaml_value(default) -> str:
    """Return ``default`` as the params file writes it (a double keeps its ``.0``)."""
    if isinstance(default, tuple):
        return '[' + ', '.join(f'"{entry}"' for entry in default) + ']'
    if isinstance(default, bool):
        return 'true' if default else 'false'
    if isinstance(default, int):
        return repr(default)
    if isinstance(default, float):
        if math.isinf(default) or math.isnan(default):
            return ('-' if default < 0 else '') + ('.inf' if math.isinf(default) else '.nan')
        text = repr(default)
        mantissa, e, exponent = text.partition('e')
        # YAML 1.1 reads a float only with a dot in it (1e-06 is a string there)
        return f'{mantissa}.0e{exponent}' if e and '.' not in mantissa else text
    if default and yaml.safe_load(default) == default and default.strip() == default:
        return default
    return "'" + default.replace("'", "''") + "'"


def sentence(text: str) -> str:
    """Return ``text`` with a capital first letter and a closing full stop."""
    text = text.strip()
    if not text:
        return text
    text = text[0].upper() + text[1:]
    return text if text.endswith(('.', '!', '?')) else text + '.'


def meaning(spec, details: Mapping[str, str]) -> str:
    """Return a parameter's description followed by its details, as sentences."""
    return ' '.join(part for part in (sentence(spec.description),
                                      sentence(details.get(spec.name, ''))) if part)


def grouped(parameters, sections: Mapping[str, str]) -> List[Tuple[str, list]]:
    """Return ``[(section title, [spec, ...]), ...]`` in the table's order; a parameter before
    the first section goes into an untitled one."""
    groups: List[Tuple[str, list]] = []
    for spec in parameters:
        if spec.name in sections or not groups:
            groups.append((sections.get(spec.name, ''), []))
        groups[-1][1].append(spec)
    return groups


def wrap(text: str, prefix: str, width: int = WIDTH) -> List[str]:
    """Return ``text`` as lines of at most ``width`` characters, each starting with
    ``prefix`` (a word longer than a line stands alone)."""
    lines, line = [], ''
    for word in text.split():
        if line and len(prefix) + len(line) + 1 + len(word) > width:
            lines.append(prefix + line)
            line = word
        else:
            line = f'{line} {word}' if line else word
    if line:
        lines.append(prefix + line)
    return lines


def params_yaml(parameters, sections: Mapping[str, str], details: Mapping[str, str]) -> str:
    """Return ``config/collision_sensor.yaml``'s text."""
    lines = YAML_HEADER.rstrip('\n').split('\n')
    for title, specs in grouped(parameters, sections):
        if title:
            head = f'    # --- {title} '
            lines.append(head + '-' * max(3, 96 - len(head)))
        for spec in specs:
            text = meaning(spec, details)
            if spec.constraints:
                text += f' Valid: {spec.constraints}.'
            if spec.dynamic:
                text += ' Settable at run time.'
            lines += wrap(text, '    # ')
            lines.append(f'    {spec.name}: {yaml_value(spec.default)}')
    return '\n'.join(lines) + '\n'


def _cell(text: str) -> str:
    """Return ``text`` fit for a markdown table cell: pipes escaped, ``docs/X.md`` linked."""
    text = text.replace('|', '\\|')
    return re.sub(r'\bdocs/([\w-]+\.md)\b', r'[\1](\1)', text)


def parameters_markdown(parameters, sections: Mapping[str, str],
                        details: Mapping[str, str]) -> str:
    """Return ``docs/parameters.md``'s text."""
    lines = DOCS_HEADER.rstrip('\n').split('\n')
    for title, specs in grouped(parameters, sections):
        lines += ['', f'## {sentence(title)[:-1] if title else "Other parameters"}', '',
                  '| parameter | type | default | settable at run time | meaning | valid values |',
                  '|---|---|---|---|---|---|']
        for spec in specs:
            lines.append(f'| `{spec.name}` | {type_name(spec.default)} | '
                         f'`{yaml_value(spec.default)}` | {"yes" if spec.dynamic else "no"} | '
                         f'{_cell(meaning(spec, details))} | {_cell(spec.constraints)} |')
    return '\n'.join(lines) + '\n'


def reference(parameters=None, sections: Optional[Mapping[str, str]] = None,
              details: Optional[Mapping[str, str]] = None) -> dict:
    """Return ``{relative path: text}`` of both files, from the node's table unless given."""
    from collision_sensor.ros import node_parameters, parameter_notes
    parameters = node_parameters.PARAMETERS if parameters is None else parameters
    sections = parameter_notes.SECTIONS if sections is None else sections
    details = parameter_notes.DETAILS if details is None else details
    return {YAML_PATH: params_yaml(parameters, sections, details),
            DOCS_PATH: parameters_markdown(parameters, sections, details)}


def stale(root: str = ROOT, texts: Optional[Mapping[str, str]] = None) -> List[str]:
    """Return the files under ``root`` that differ from what the table gives."""
    texts = reference() if texts is None else texts
    out = []
    for path, text in texts.items():
        try:
            with open(os.path.join(root, path), encoding='utf-8') as stream:
                if stream.read() == text:
                    continue
        except FileNotFoundError:
            pass
        out.append(path)
    return out


def unknown_names(parameters=None, names: Iterable[str] = ()) -> List[str]:
    """Return the names of ``names`` that are no parameter of the table (stale notes)."""
    from collision_sensor.ros import node_parameters
    parameters = node_parameters.PARAMETERS if parameters is None else parameters
    known = {spec.name for spec in parameters}
    return sorted(set(names) - known)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Write both files (or, with ``--check``, say which are stale); return the exit status."""
    parser = argparse.ArgumentParser(prog='python scripts/parameter_reference.py',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 if a file differs from the table')
    parser.add_argument('--root', default=ROOT, help='the source tree (default %(default)s)')
    args = parser.parse_args(argv)
    from collision_sensor.ros import parameter_notes
    unknown = unknown_names(names=list(parameter_notes.SECTIONS) + list(parameter_notes.DETAILS))
    if unknown:
        print(f'parameter_notes names no parameter {", ".join(unknown)}: remove or rename them',
              file=sys.stderr)
        return 1
    texts = reference()
    if args.check:
        out = stale(args.root, texts)
        for path in out:
            print(f'{path} is stale: run python scripts/parameter_reference.py', file=sys.stderr)
        return 1 if out else 0
    for path, text in texts.items():
        with open(os.path.join(args.root, path), 'w', encoding='utf-8', newline='\n') as stream:
            stream.write(text)
        print(os.path.join(args.root, path))
    return 0


if __name__ == '__main__':
    sys.exit(main())
