"""Read the parts of an SRDF the collision sensor uses: disabled pairs and named states.

Read: ``<disable_collisions link1 link2 reason>`` (``reason`` is ``''`` when absent) and
``<group_state name group>`` with its ``<joint name value>`` children. Every other element is
ignored, but the links it names are checked: with ``link_names`` given, a link named by
``disable_collisions``, ``group/link``, ``chain``, ``end_effector parent_link``,
``virtual_joint child_link`` or ``link_sphere_approximation`` that the robot lacks is an error
listing all of them; with ``joint_names`` given, unknown joints in ``group_state`` likewise.

Pairs are stored once, as two names in sorted order (``link1 <= link2``); a repeated pair keeps
its first reason.
"""
from dataclasses import dataclass

from collision_sensor.errors import SrdfError
from collision_sensor.xml_safety import describe_source, parse_xml

# (element path, attribute) of every place an SRDF names a link of the robot.
_LINK_REFERENCES = (
    ('disable_collisions', 'link1'), ('disable_collisions', 'link2'),
    ('group/link', 'name'), ('group/chain', 'base_link'), ('group/chain', 'tip_link'),
    ('end_effector', 'parent_link'), ('virtual_joint', 'child_link'),
    ('link_sphere_approximation', 'link'),
)

_MAX_NAMES_LISTED = 40


@dataclass(frozen=True)
class DisabledPair:
    """Two links whose collisions are never checked; ``link1 <= link2``."""

    link1: str
    link2: str
    reason: str


@dataclass(frozen=True)
class Srdf:
    """What the sensor uses of an SRDF.

    ``group_states`` maps a state name to ``{'group': str, 'joints': {joint: value}}``.
    """

    robot_name: str
    disabled_pairs: tuple[DisabledPair, ...]
    group_states: dict
    source: str


def load_srdf(srdf, link_names=None, joint_names=None) -> Srdf:
    """Read an SRDF and check the names it uses against the robot.

    :param srdf: a path (``str`` or ``os.PathLike``) or the XML text.
    :param link_names: the robot's links; when given, unknown links named anywhere are an error.
    :param joint_names: the robot's joints; when given, unknown joints in a ``group_state`` are
        an error.
    :return: the disabled pairs and group states.
    :raises SrdfError: unsafe or broken XML, a malformed element, or unknown names (all listed,
        with the SRDF file).
    """
    source = describe_source(srdf, 'SRDF')
    root = parse_xml(srdf, 'SRDF')
    if root.tag != 'robot':
        raise SrdfError(f'SRDF "{source}": the root element is <{root.tag}>, not <robot>; '
                        'give an SRDF')
    if link_names is not None:
        _check_links(root, set(link_names), source, root.get('name', ''))
    pairs = {}
    for element in root.findall('disable_collisions'):
        link1, link2 = element.get('link1'), element.get('link2')
        if not link1 or not link2:
            raise SrdfError(f'SRDF "{source}": <disable_collisions> at line '
                            f'{element.sourceline} needs link1="..." and link2="..."; add them')
        key = tuple(sorted((link1, link2)))
        if key not in pairs:
            pairs[key] = DisabledPair(key[0], key[1], element.get('reason', ''))
    virtual_joints = {element.get('name') for element in root.findall('virtual_joint')}
    group_states = {}
    unknown_joints = []
    for element in root.findall('group_state'):
        name = element.get('name')
        if not name:
            raise SrdfError(f'SRDF "{source}": <group_state> at line {element.sourceline} has '
                            'no name; add name="..."')
        joints = {}
        for joint in element.findall('joint'):
            joint_name = joint.get('name')
            if not joint_name or joint.get('value') is None:
                raise SrdfError(f'SRDF "{source}": group_state "{name}": <joint> at line '
                                f'{joint.sourceline} needs name="..." and value="..."; add them')
            joints[joint_name] = _joint_value(joint, name, source)
            if (joint_names is not None and joint_name not in joint_names
                    and joint_name not in virtual_joints):
                unknown_joints.append(f'{joint_name} (group_state "{name}", line '
                                      f'{joint.sourceline})')
        group_states[name] = {'group': element.get('group', ''), 'joints': joints}
    if unknown_joints:
        raise SrdfError(
            f'SRDF "{source}": {len(unknown_joints)} unknown joint(s): '
            f'{_listed(unknown_joints)}; the robot has joints {_listed(sorted(joint_names))}; '
            'fix the names or load the SRDF that belongs to this robot')
    return Srdf(robot_name=root.get('name', ''), disabled_pairs=tuple(pairs.values()),
                group_states=group_states, source=source)


def _check_links(root, known, source, robot_name):
    unknown = []
    for path, attribute in _LINK_REFERENCES:
        for element in root.findall(path):
            name = element.get(attribute)
            if name is not None and name not in known:
                unknown.append(f'{name} ({element.tag} {attribute}, line {element.sourceline})')
    if unknown:
        raise SrdfError(
            f'SRDF "{source}" (robot "{robot_name}"): {len(unknown)} unknown link(s): '
            f'{_listed(unknown)}; the robot has links {_listed(sorted(known))}; fix the names '
            'or load the SRDF that belongs to this robot')


def _joint_value(joint, state, source) -> float:
    text = joint.get('value')
    try:
        values = [float(part) for part in text.split()]
    except ValueError:
        values = []
    if len(values) != 1 or values[0] != values[0] or abs(values[0]) == float('inf'):
        raise SrdfError(f'SRDF "{source}": group_state "{state}": joint "{joint.get("name")}" '
                        f'value="{text}" (line {joint.sourceline}) is not one finite number; '
                        'fix it')
    return values[0]


def _listed(names):
    if len(names) <= _MAX_NAMES_LISTED:
        return ', '.join(names)
    return ', '.join(names[:_MAX_NAMES_LISTED]) + f', ... ({len(names)} in all)'
