"""Read the parts of an SRDF the collision sensor uses, as MoveIt (srdfdom) reads them.

Read: ``<disable_collisions link1 link2 reason>`` (``reason`` is ``''`` when absent),
``<virtual_joint name type parent_frame child_link>`` and ``<group_state name group>`` with its
``<joint name value>`` children. Groups, end effectors, passive joints and sphere
approximations are not used, but the names they give are checked like the rest.

Leniency (as srdfdom): with the robot's ``link_names`` / ``joints`` given, an entry that names
a link or joint the robot lacks, or that is malformed (a missing attribute, a value that is
not a number), is skipped with a warning naming the file, the line, the element and the fix;
the rest of the document is used. The warnings of one document are issued together as one
:class:`~collision_sensor.errors.LoadWarning` (Python prints an identical warning once) and kept
in :attr:`Srdf.warnings` for callers that log them their own way. Fatal
(:class:`~collision_sensor.errors.SrdfError`) only: a file that is not (safe) XML, a root other
than ``<robot>``, and a document that cannot describe this robot at all, i.e. whose robot name
differs from the URDF's and none of whose link or joint names the robot has. A virtual joint
must reach the URDF's root link (else it is skipped, as MoveIt only places the robot through
its root); groups and passive joints may name virtual joints.

Group-state values: one number for a revolute, continuous or prismatic joint; for a
multi-DOF joint (a virtual joint, or a URDF planar/floating joint) the values are expanded into
MoveIt's variable names: planar ``<joint>/x``, ``/y``, ``/theta`` (3 numbers), floating
``<joint>/trans_x``, ``/trans_y``, ``/trans_z``, ``/rot_x``, ``/rot_y``, ``/rot_z``,
``/rot_w`` (7 numbers: position, then the quaternion x y z w).

Pairs are stored once, as two names in sorted order (``link1 <= link2``); a repeated pair keeps
its first reason.
"""
from dataclasses import dataclass, field

from collision_sensor.errors import SrdfError, listed_lines, warn_load
from collision_sensor.model.xml_safety import describe_source, parse_xml

#: MoveIt's variable names of a multi-DOF joint, by joint type (``<joint>/<suffix>``).
VARIABLE_SUFFIXES = {
    'planar': ('x', 'y', 'theta'),
    'floating': ('trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w'),
}
VIRTUAL_JOINT_TYPES = ('fixed', 'planar', 'floating')
_ONE_VALUE_TYPES = ('revolute', 'continuous', 'prismatic')

# (element path, attribute) of every place an SRDF names a link of the robot, outside
# disable_collisions and virtual_joint (read below).
_LINK_REFERENCES = (
    ('group/link', 'name'), ('group/chain', 'base_link'), ('group/chain', 'tip_link'),
    ('end_effector', 'parent_link'), ('link_sphere_approximation', 'link'),
)
_JOINT_REFERENCES = (('group/joint', 'name'), ('passive_joint', 'name'))

_MAX_NAMES_LISTED = 40


@dataclass(frozen=True)
class DisabledPair:
    """Two links whose collisions are never checked; ``link1 <= link2``."""

    link1: str
    link2: str
    reason: str


@dataclass(frozen=True)
class VirtualJoint:
    """An SRDF ``<virtual_joint>``: how the robot's root link moves in ``parent_frame``.

    ``variables`` are MoveIt's names for its values (empty for ``fixed``).
    """

    name: str
    type: str
    parent_frame: str
    child_link: str
    variables: tuple[str, ...]


@dataclass(frozen=True)
class Srdf:
    """What the sensor uses of an SRDF.

    ``group_states`` maps a state name to ``{'group': str, 'joints': {variable: value}}``
    (a multi-DOF joint's values under its MoveIt variable names, see the module docstring).
    ``warnings`` are the skipped entries, one readable line each.
    """

    robot_name: str
    disabled_pairs: tuple[DisabledPair, ...]
    group_states: dict
    source: str
    virtual_joints: tuple[VirtualJoint, ...] = ()
    warnings: tuple[str, ...] = field(default=())


def load_srdf(srdf, link_names=None, joint_names=None, *, robot_name=None,
              joint_types=None, root_link=None) -> Srdf:
    """Read an SRDF and check the names it uses against the robot.

    :param srdf: a path (``str`` or ``os.PathLike``) or the XML text.
    :param link_names: the robot's links; when given, entries naming other links are skipped
        with a warning.
    :param joint_names: the robot's joints; when given, group-state values and group joints
        naming other joints are skipped with a warning.
    :param robot_name: the URDF's robot name; when given and different, the document is still
        used if it names some link of the robot (with a warning), else it is an error.
    :param joint_types: ``{joint: URDF type}``; when given, the number of values of a
        group-state joint is checked against its type (1, planar 3, floating 7).
    :param root_link: the URDF's root link; when given, a virtual joint to another link is
        skipped with a warning (MoveIt places the robot only through the root link).
    :return: the disabled pairs, virtual joints, group states and the warnings issued.
    :raises SrdfError: unsafe or broken XML, a root other than ``<robot>``, or a document for
        another robot (other name, no link in common).
    """
    source = describe_source(srdf, 'SRDF')
    root = parse_xml(srdf, 'SRDF')
    if root.tag != 'robot':
        raise SrdfError(f'SRDF "{source}": the root element is <{root.tag}>, not <robot>; '
                        'give an SRDF')
    reader = _Reader(source, link_names, joint_names, joint_types, root_link)
    document_name = root.get('name', '')
    if link_names is not None:
        reader.check_robot(root, document_name, robot_name)
        for path, attribute in _LINK_REFERENCES:
            for element in root.findall(path):
                reader.known_link(element, attribute)
    virtual_joints = reader.virtual_joints(root)
    if joint_names is not None:
        reader.joints |= {joint.name for joint in virtual_joints}   # groups may name them
        for path, attribute in _JOINT_REFERENCES:
            for element in root.findall(path):
                reader.known_joint(element, attribute)
    pairs = reader.disabled_pairs(root)
    group_states = reader.group_states(root, {joint.name: joint for joint in virtual_joints})
    if reader.warnings:
        count = len(reader.warnings)
        warn_load(f'SRDF "{source}": {count} entr{"y" if count == 1 else "ies"} skipped (as '
                  'MoveIt skips them):\n' + listed_lines(reader.warnings))
    return Srdf(robot_name=document_name, disabled_pairs=pairs, group_states=group_states,
                source=source, virtual_joints=virtual_joints, warnings=tuple(reader.warnings))


def load_srdf_for_model(srdf, model) -> Srdf:
    """Read an SRDF against a robot model: every name, the robot name and joint types checked.

    :param model: a :class:`~collision_sensor.model.robot_model.RobotModel`.
    """
    return load_srdf(srdf, link_names=model.links,
                     joint_names=[joint.name for joint in model.joints],
                     robot_name=model.name,
                     joint_types={joint.name: joint.type for joint in model.joints},
                     root_link=model.root_link)


class _Reader:
    """The checks of one document; every skipped entry becomes one line in ``warnings``."""

    def __init__(self, source, link_names, joint_names, joint_types, root_link):
        self.source = source
        self.root_link = root_link
        self.links = None if link_names is None else set(link_names)
        self.joints = None if joint_names is None else set(joint_names)
        self.joint_types = joint_types or {}
        self.warnings = []

    def skip(self, element, problem, fix):
        self.warnings.append(f'line {element.sourceline}: <{element.tag}'
                             f'{_name_attribute(element)}> skipped: {problem}; {fix}')

    def check_robot(self, root, document_name, robot_name):
        if robot_name is None or not document_name or document_name == robot_name:
            return
        links = {element.get(attribute) for path, attribute in _LINK_REFERENCES + (
            ('disable_collisions', 'link1'), ('disable_collisions', 'link2'),
            ('virtual_joint', 'child_link')) for element in root.findall(path)} - {None, ''}
        joints = {element.get(attribute) for path, attribute in _JOINT_REFERENCES + (
            ('group_state/joint', 'name'),) for element in root.findall(path)} - {None, ''}
        if (links or joints) and not (links & self.links or joints & (self.joints or set())):
            named = sorted(links) + sorted(joints)
            raise SrdfError(
                f'SRDF "{self.source}" is for robot "{document_name}", not "{robot_name}", and '
                f'none of the {len(named)} link and joint names it uses is in this robot '
                f'(e.g. {_listed(named[:5])}); load the SRDF that belongs to "{robot_name}"')
        self.warnings.append(f'line {root.sourceline}: <robot name="{document_name}">: the '
                             f'URDF robot is "{robot_name}"; the entries that match are used; '
                             'fix the name if this is the right SRDF')

    def known_link(self, element, attribute):
        name = element.get(attribute)
        if name is None or self.links is None or name in self.links:
            return True
        self.skip(element, f'{attribute}="{name}" is not a link of the robot',
                  'fix the name or remove the entry')
        return False

    def known_joint(self, element, attribute):
        name = element.get(attribute)
        if name is None or self.joints is None or name in self.joints:
            return True
        self.skip(element, f'{attribute}="{name}" is not a joint of the robot',
                  'fix the name or remove the entry')
        return False

    def virtual_joints(self, root):
        found = []
        for element in root.findall('virtual_joint'):
            name, kind = element.get('name'), element.get('type')
            child, parent = element.get('child_link'), element.get('parent_frame')
            if not name or not child or not parent:
                self.skip(element, 'it needs name, type, parent_frame and child_link',
                          'add the missing attributes')
                continue
            if kind not in VIRTUAL_JOINT_TYPES:
                self.skip(element, f'type="{kind}" is not one of '
                          f'{", ".join(VIRTUAL_JOINT_TYPES)}', 'fix the type')
                continue
            if not self.known_link(element, 'child_link'):
                continue
            if self.root_link is not None and child != self.root_link:
                self.skip(element, f'child_link="{child}" is not the URDF\'s root link '
                          f'"{self.root_link}"', f'attach it to "{self.root_link}"')
                continue
            variables = tuple(f'{name}/{suffix}' for suffix in VARIABLE_SUFFIXES.get(kind, ()))
            found.append(VirtualJoint(name, kind, parent, child, variables))
        return tuple(found)

    def disabled_pairs(self, root):
        pairs = {}
        for element in root.findall('disable_collisions'):
            link1, link2 = element.get('link1'), element.get('link2')
            if not link1 or not link2:
                self.skip(element, 'it needs link1="..." and link2="..."', 'add them')
                continue
            if not (self.known_link(element, 'link1') and self.known_link(element, 'link2')):
                continue
            key = tuple(sorted((link1, link2)))
            if key not in pairs:
                pairs[key] = DisabledPair(key[0], key[1], element.get('reason', ''))
        return tuple(pairs.values())

    def group_states(self, root, virtual_joints):
        states = {}
        for element in root.findall('group_state'):
            name = element.get('name')
            if not name:
                self.skip(element, 'it has no name', 'add name="..."')
                continue
            joints = {}
            for joint in element.findall('joint'):
                joints.update(self._state_values(joint, name, virtual_joints))
            states[name] = {'group': element.get('group', ''), 'joints': joints}
        return states

    def _state_values(self, joint, state, virtual_joints):
        where = f'in group_state "{state}"'
        joint_name, text = joint.get('name'), joint.get('value')
        if not joint_name or text is None:
            self.skip(joint, f'{where}: it needs name="..." and value="..."', 'add them')
            return {}
        try:
            values = [float(part) for part in text.split()]
        except ValueError:
            values = []
        if not values or any(v != v or abs(v) == float('inf') for v in values):
            self.skip(joint, f'{where}: value="{text}" is not finite numbers',
                      'give one number per variable of the joint')
            return {}
        if joint_name in virtual_joints:
            kind = virtual_joints[joint_name].type
        elif self.joints is not None and joint_name not in self.joints:
            self.skip(joint, f'{where}: "{joint_name}" is not a joint of the robot (nor a '
                      'virtual joint)', 'fix the name or remove the entry')
            return {}
        else:
            kind = self.joint_types.get(joint_name)
        if kind == 'fixed':
            self.skip(joint, f'{where}: joint "{joint_name}" is fixed and has no value',
                      'remove the entry')
            return {}
        suffixes = VARIABLE_SUFFIXES.get(kind)
        expected = len(suffixes) if suffixes else (1 if kind in _ONE_VALUE_TYPES else None)
        if expected is None:  # type unknown (no robot given): take one number or the lot
            if len(values) == 1:
                return {joint_name: values[0]}
            suffixes = {3: VARIABLE_SUFFIXES['planar'],
                        7: VARIABLE_SUFFIXES['floating']}.get(len(values))
            expected = len(suffixes) if suffixes else 1
        if len(values) != expected:
            self.skip(joint, f'{where}: value="{text}" has {len(values)} numbers, joint '
                      f'"{joint_name}" ({kind or "1-DOF"}) has {expected} variable(s)',
                      f'give {expected}')
            return {}
        if suffixes is None:
            return {joint_name: values[0]}
        return {f'{joint_name}/{suffix}': value for suffix, value in zip(suffixes, values)}


def _name_attribute(element):
    for attribute in ('name', 'link1', 'link'):
        if element.get(attribute):
            return f' {attribute}="{element.get(attribute)}"'
    return ''


def _listed(names):
    if len(names) <= _MAX_NAMES_LISTED:
        return ', '.join(names)
    return ', '.join(names[:_MAX_NAMES_LISTED]) + f', ... ({len(names)} in all)'
