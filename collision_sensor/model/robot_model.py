"""Read a URDF into a plain, validated robot model: links, joints and collision triangles.

Only what the collision sensor needs is kept: the kinematic tree (joints with origin, axis,
limits, mimic) and the ``<collision>`` geometry of every link, each ``<collision>`` element as
its own triangle mesh in its own frame (one sub-group, paper sec. 2.1). ``<visual>``,
``<inertial>``, materials, transmissions and gazebo tags are ignored.

Conventions:

- ``T_<to>_<from>`` is a (4, 4) homogeneous transform taking coordinates in frame ``<from>`` to
  frame ``<to>``; ``T_parent_joint`` is a joint's ``<origin>``, ``T_link_element`` a collision
  element's ``<origin>``.
- ``<origin rpy="r p y">`` is a rotation about the fixed axes x, then y, then z:
  ``R = Rz(y) Ry(p) Rx(r)`` (the URDF convention).
- ``links`` lists the root first, then a depth-first walk where the children of a link follow
  the document order of their joints; ``joints`` follow their child link in that order.

Multi-DOF joints: ``planar`` and ``floating`` joints are read with MoveIt's variable names
(:attr:`Joint.variables`: ``<joint>/x``, ``/y``, ``/theta``; ``<joint>/trans_x``, ``/trans_y``,
``/trans_z``, ``/rot_x``, ``/rot_y``, ``/rot_z``, ``/rot_w``) and driven by
:mod:`collision_sensor.engine.kinematics`. A planar joint moves in its joint frame's x-y plane, as
MoveIt's PlanarJointModel does whatever the URDF says; an explicit ``<axis>`` other than
``(0, 0, +-1)`` (urdfdom's plane normal) is therefore tolerated with a warning. A floating
joint's ``<axis>`` is not used.

Tolerated with a :class:`LoadWarning` naming the file, the joint and the fix (as urdfdom and
MoveIt tolerate them): a ``<mimic>`` naming a joint that does not exist, or a joint with
another number of variables (fixed, planar, floating); the joint is then independent. Also
tolerated, as pinocchio does though ROS's resource_retriever does not: a mesh URI
``package:///NAME/...`` (empty package name) is read as ``package://NAME/...`` (one warning
per URDF; talos_full_v2 of example-robot-data is written so).

Rejected with :class:`RobotDescriptionError` naming the culprit and the fix: a link with two
parents, a cycle, several roots, a joint naming an unknown link, a mimic cycle, non-finite
numbers, a zero axis, a revolute or prismatic joint without ``<limit>``, an unknown joint type,
no ``<link>`` at all. A mesh that cannot be found or read raises :class:`MeshError`; no link
ever silently loses its geometry.
"""
import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from collision_sensor.errors import RobotDescriptionError, listed_lines, warn_load
from collision_sensor.model import mesh_loading
from collision_sensor.model.xacro_expansion import expand_xacro, is_xacro_path
from collision_sensor.model.xml_safety import describe_source, is_xml_text, parse_xml

JOINT_TYPES = ('revolute', 'continuous', 'prismatic', 'fixed', 'planar', 'floating')
#: MoveIt's variable names of a multi-DOF joint, by joint type (``<joint>/<suffix>``).
MULTI_DOF_SUFFIXES = {
    'planar': ('x', 'y', 'theta'),
    'floating': ('trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w'),
}


@dataclass(frozen=True)
class Mimic:
    """A joint that follows another: ``value = multiplier * value(joint) + offset``."""

    joint: str
    multiplier: float
    offset: float


@dataclass(frozen=True, eq=False)
class Joint:
    """One URDF joint.

    ``T_parent_joint : (4, 4) float64`` is the ``<origin>`` (joint frame in the parent link
    frame; the child link frame is the joint frame moved by the joint value). ``axis : (3,)
    float64`` is a unit vector in the joint frame (URDF default ``(1, 0, 0)``). Limits:
    continuous ``-inf, inf``; fixed ``0, 0``.
    """

    name: str
    type: str
    parent: str
    child: str
    T_parent_joint: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    velocity: float
    effort: float
    mimic: Mimic | None

    @property
    def variables(self) -> tuple[str, ...]:
        """MoveIt's variable names: ``()`` fixed, ``(name,)`` 1-DOF, ``name/x`` ... multi-DOF."""
        if self.type == 'fixed':
            return ()
        suffixes = MULTI_DOF_SUFFIXES.get(self.type)
        return (self.name,) if suffixes is None else tuple(f'{self.name}/{s}' for s in suffixes)


@dataclass(frozen=True, eq=False)
class CollisionElement:
    """One ``<collision>`` element of a link, as triangles in its own frame.

    ``vertices : (n, 3) float64`` and ``faces : (m, 3) int64`` are C-contiguous, in the element
    frame, mesh scale applied; ``T_link_element : (4, 4) float64`` is the element's ``<origin>``.
    ``index`` counts the link's ``<collision>`` elements from 0; ``name`` is the element's
    ``name`` attribute, else ``f"{link}/{index}"``.
    """

    link: str
    index: int
    name: str
    source: str
    T_link_element: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    solid: Optional[mesh_loading.Solid] = None  # primitives: what they fill (see Solid)


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot: its tree of links and joints and its collision geometry.

    ``links`` has the root first and every parent before its children; ``joints`` is in the
    order of their child link; ``elements`` is grouped by link in ``links`` order, then by index.
    ``joint_document_order`` names the joints in the order the URDF lists them (the order of the
    configuration vector, see :mod:`collision_sensor.engine.kinematics`); empty means
    ``joints`` order.
    ``held_joints`` is always empty: multi-DOF joints are driven now (kept for callers that
    read it); ``warnings`` what was tolerated, one readable line each.
    """

    name: str
    root_link: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]
    elements: tuple[CollisionElement, ...]
    source: str
    joint_document_order: tuple[str, ...] = ()
    held_joints: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


def load_urdf(urdf, package_paths=None, *, primitive_sections: int = 32,
              xacro_args=None) -> RobotModel:
    """Read a URDF, validate its tree and load its collision geometry.

    :param urdf: a path (``str`` or ``os.PathLike``) or the XML text (a ``str`` whose first
        non-blank character is ``<``, or ``bytes``). A path ending in ``.xacro`` is expanded
        first (:mod:`collision_sensor.model.xacro_expansion`); relative mesh paths then resolve
        against the xacro file's directory.
    :param xacro_args: ``{name: value}`` for the xacro file's ``$(arg name)``.
    :param package_paths: mapping ``{package_name: directory}`` used first to resolve
        ``package://`` mesh URIs (see :mod:`collision_sensor.model.mesh_loading` for the full
        order).
    :param primitive_sections: sections around cylinders and spheres when tessellating them.
    :return: the validated model.
    :raises RobotDescriptionError: unsafe or broken XML, or an invalid or unsupported tree.
    :raises MeshError: a collision mesh that cannot be found or read.
    """
    source = describe_source(urdf, 'URDF')
    base_dir = None if is_xml_text(urdf) else os.path.dirname(os.path.abspath(source))
    if is_xacro_path(urdf):
        root = parse_xml(expand_xacro(urdf, xacro_args, package_paths).encode('utf-8'),
                         'URDF')
    elif xacro_args:
        raise RobotDescriptionError(f'URDF "{source}": xacro_args given, but the description '
                                    'is not a .xacro file; leave xacro_args out')
    else:
        root = parse_xml(urdf, 'URDF')
    context = _Context(source)
    if root.tag != 'robot':
        raise context.error(f'the root element is <{root.tag}>, not <robot>; give a URDF')
    link_elements = {}
    for element in root.findall('link'):
        name = context.name_of(element, 'link')
        if name in link_elements:
            raise context.error(f'link "{name}" is defined twice (lines '
                                f'{link_elements[name].sourceline} and {element.sourceline}); '
                                'rename one')
        link_elements[name] = element
    if not link_elements:
        raise context.error('no <link> element; a robot needs at least one link')
    joints = []
    for element in root.findall('joint'):
        joints.append(_parse_joint(element, context))
    document_order = tuple(joint.name for joint in joints)
    links, joints = _order_tree(list(link_elements), joints, context)
    joints = _tolerate_bad_mimics(joints, context)
    resolve_mimics(joints, source)
    elements = []
    for link in links:
        for index, collision in enumerate(link_elements[link].findall('collision')):
            elements.append(_load_collision(collision, link, index, context, package_paths,
                                            base_dir, primitive_sections))
    if context.warnings:
        warn_load(f'URDF "{source}": {len(context.warnings)} oddit'
                  f'{"y" if len(context.warnings) == 1 else "ies"} tolerated:\n'
                  + listed_lines(context.warnings))
    return RobotModel(name=root.get('name', ''), root_link=links[0], links=tuple(links),
                      joints=tuple(joints), elements=tuple(elements), source=source,
                      joint_document_order=document_order,
                      warnings=tuple(context.warnings))


def _tolerate_bad_mimics(joints, context):
    """Make a joint whose ``<mimic>`` names a missing joint, or one with another number of
    variables, independent, with a warning (urdfdom reads such a URDF, MoveIt ignores the
    mimic)."""
    by_name = {joint.name: joint for joint in joints}
    kept = []
    for joint in joints:
        mimic = joint.mimic
        if mimic is not None and joint.type != 'fixed':
            target = by_name.get(mimic.joint)
            problem = None
            if target is None:
                problem = f'mimics joint "{mimic.joint}", which does not exist'
            elif len(target.variables) != 1 or len(joint.variables) != 1:
                problem = (f'({joint.type}) mimics joint "{mimic.joint}" ({target.type}), '
                           'which has another number of variables')
            if problem is not None:
                context.warnings.append(f'joint "{joint.name}" {problem}; it is treated as an '
                                        'independent joint; fix the <mimic joint=...> name')
                joint = dataclasses.replace(joint, mimic=None)
        kept.append(joint)
    return kept


def resolve_mimics(joints, source: str = '<robot>') -> dict:
    """Resolve every mimic joint to the independent joint that ultimately drives it.

    A chain ``a`` mimics ``b`` mimics ``c`` composes: ``value(a) = m_a (m_b value(c) + o_b) +
    o_a``.

    :param joints: the robot's joints (any order).
    :param source: the URDF, for messages.
    :return: ``{joint_name: (source_joint, multiplier, offset)}`` for every movable mimic joint.
    :raises RobotDescriptionError: a mimic of an unknown or fixed joint, or a mimic cycle.
    """
    by_name = {joint.name: joint for joint in joints}
    resolved = {}
    for joint in joints:
        if joint.mimic is None or joint.type == 'fixed':
            continue
        multiplier, offset = 1.0, 0.0
        chain = [joint.name]
        current = joint
        while current.mimic is not None:
            target = by_name.get(current.mimic.joint)
            if target is None:
                raise RobotDescriptionError(
                    f'URDF "{source}": joint "{current.name}" mimics joint '
                    f'"{current.mimic.joint}", which does not exist; fix the <mimic joint=...> '
                    'name')
            if target.type == 'fixed':
                raise RobotDescriptionError(
                    f'URDF "{source}": joint "{current.name}" mimics joint "{target.name}", '
                    'which is fixed; mimic a movable joint or remove <mimic>')
            # value(current) = m * value(target) + o, and value(joint) = M * value(current) + O.
            offset += multiplier * current.mimic.offset
            multiplier *= current.mimic.multiplier
            if target.name in chain:
                cycle = ' -> '.join(chain[chain.index(target.name):] + [target.name])
                raise RobotDescriptionError(
                    f'URDF "{source}": joint "{joint.name}" is in a mimic cycle ({cycle}); '
                    'one joint of the cycle must be independent, remove its <mimic>')
            chain.append(target.name)
            current = target
        resolved[joint.name] = (current.name, multiplier, offset)
    return resolved


def transform_from_xyz_rpy(xyz, rpy) -> np.ndarray:
    """Return the (4, 4) transform of a URDF ``<origin xyz rpy>``: ``R = Rz(y) Ry(p) Rx(r)``.

    :param xyz: ``(3,)`` translation.
    :param rpy: ``(3,)`` roll, pitch, yaw in radians.
    :return: ``(4, 4) float64``.
    """
    roll, pitch, yaw = (float(v) for v in rpy)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    T[:3, 3] = [float(v) for v in xyz]
    return T


class _Context:
    """Messages of one URDF: every error names the file."""

    def __init__(self, source):
        self.source = source
        self.warnings = []
        self._warned = set()

    def warn_once(self, key, message):
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(message)

    def error(self, message):
        return RobotDescriptionError(f'URDF "{self.source}": {message}')

    def name_of(self, element, kind):
        name = element.get('name')
        if not name:
            raise self.error(f'<{kind}> at line {element.sourceline} has no name; add name="..."')
        return name

    def floats(self, element, attribute, count, owner, default=None):
        text = element.get(attribute) if element is not None else None
        if text is None:
            if default is None:
                tag = element.tag if element is not None else '?'
                raise self.error(f'{owner}: <{tag}> lacks {attribute}="..."; add it')
            return np.array(default, dtype=np.float64)
        parts = text.split()
        try:
            values = np.array([float(part) for part in parts], dtype=np.float64)
        except ValueError:
            values = None
        if values is None or len(values) != count:
            raise self.error(f'{owner}: <{element.tag} {attribute}="{text}"> (line '
                             f'{element.sourceline}) needs {count} numbers; fix it')
        if not np.all(np.isfinite(values)):
            raise self.error(f'{owner}: <{element.tag} {attribute}="{text}"> (line '
                             f'{element.sourceline}) is not finite; give finite numbers')
        return values

    def number(self, element, attribute, owner, default=None):
        return float(self.floats(element, attribute, 1, owner,
                                 None if default is None else [default])[0])

    def origin(self, parent, owner):
        origin = parent.find('origin')
        if origin is None:
            return np.eye(4)
        xyz = self.floats(origin, 'xyz', 3, owner, default=(0.0, 0.0, 0.0))
        rpy = self.floats(origin, 'rpy', 3, owner, default=(0.0, 0.0, 0.0))
        return transform_from_xyz_rpy(xyz, rpy)


def _parse_joint(element, context) -> Joint:
    name = context.name_of(element, 'joint')
    owner = f'joint "{name}"'
    kind = element.get('type')
    if kind not in JOINT_TYPES:
        raise context.error(f'{owner} has type "{kind}"; use one of {", ".join(JOINT_TYPES)}')
    ends = {}
    for end in ('parent', 'child'):
        tag = element.find(end)
        if tag is None or not tag.get('link'):
            raise context.error(f'{owner} lacks <{end} link="..."/>; add it')
        ends[end] = tag.get('link')
    axis_tag = element.find('axis')
    axis = context.floats(axis_tag, 'xyz', 3, owner, default=(1.0, 0.0, 0.0))
    norm = float(np.linalg.norm(axis))
    if norm < 1e-12:
        if kind not in ('fixed', 'floating'):   # neither uses its axis
            raise context.error(f'{owner} has a zero axis; give <axis xyz="..."/> a direction')
        axis = np.array([1.0, 0.0, 0.0])
    else:
        axis = axis / norm
        if kind == 'planar' and axis_tag is not None and abs(abs(axis[2]) - 1.0) > 1e-9:
            context.warnings.append(
                f'{owner} (planar) has <axis xyz="{axis_tag.get("xyz")}"> (line '
                f'{axis_tag.sourceline}); the joint moves in its frame\'s x-y plane (normal z), '
                'as MoveIt drives it; rotate the joint <origin> so that z is the normal')
    limit = element.find('limit')
    velocity = effort = 0.0
    if limit is not None:
        velocity = context.number(limit, 'velocity', owner, default=0.0)
        effort = context.number(limit, 'effort', owner, default=0.0)
    if kind in ('revolute', 'prismatic'):
        if limit is None:
            raise context.error(
                f'{owner} ({kind}) has no <limit>; add <limit lower=".." upper=".." '
                'effort=".." velocity=".."/>' + (' or make it continuous'
                                                 if kind == 'revolute' else ''))
        lower = context.number(limit, 'lower', owner, default=0.0)
        upper = context.number(limit, 'upper', owner, default=0.0)
        if lower > upper:
            raise context.error(f'{owner}: limit lower={lower} is above upper={upper}; swap them')
    elif kind in ('continuous', 'planar', 'floating'):
        lower, upper = -math.inf, math.inf
    else:
        lower = upper = 0.0
    mimic = None
    mimic_tag = element.find('mimic')
    if mimic_tag is not None:
        if not mimic_tag.get('joint'):
            raise context.error(f'{owner}: <mimic> lacks joint="..."; add it')
        mimic = Mimic(joint=mimic_tag.get('joint'),
                      multiplier=context.number(mimic_tag, 'multiplier', owner, default=1.0),
                      offset=context.number(mimic_tag, 'offset', owner, default=0.0))
    return Joint(name=name, type=kind, parent=ends['parent'], child=ends['child'],
                 T_parent_joint=context.origin(element, owner), axis=axis, lower=lower,
                 upper=upper, velocity=velocity, effort=effort, mimic=mimic)


def _order_tree(link_names, joints, context):
    """Check that the joints form one tree over the links; return links and joints in order."""
    known = set(link_names)
    names = set()
    joint_above = {}
    children = {name: [] for name in link_names}
    for joint in joints:
        if joint.name in names:
            raise context.error(f'joint "{joint.name}" is defined twice; rename one')
        names.add(joint.name)
        for end, link in (('parent', joint.parent), ('child', joint.child)):
            if link not in known:
                raise context.error(f'joint "{joint.name}" names {end} link "{link}", which is '
                                    'not defined; add the <link> or fix the name')
        if joint.child in joint_above:
            raise context.error(
                f'link "{joint.child}" has two parents (joints "{joint_above[joint.child].name}" '
                f'and "{joint.name}"); a URDF is a tree, remove one joint')
        joint_above[joint.child] = joint
        children[joint.parent].append(joint)
    roots = [name for name in link_names if name not in joint_above]
    if len(roots) > 1:
        raise context.error(
            f'several root links ({", ".join(roots)}); connect them with joints so that exactly '
            'one link has no parent')
    if not roots:
        raise context.error('every link has a parent, so the joints form a cycle; '
                            'remove a joint of the cycle')
    links, ordered = [], []
    stack = [roots[0]]
    while stack:
        link = stack.pop()
        links.append(link)
        if link in joint_above:
            ordered.append(joint_above[link])
        stack.extend(joint.child for joint in reversed(children[link]))
    if len(links) != len(link_names):
        cycle = sorted(known - set(links))
        raise context.error(f'links {", ".join(cycle)} form a cycle not connected to root '
                            f'"{roots[0]}"; remove a joint of the cycle')
    return links, ordered


def _load_collision(collision, link, index, context, package_paths, base_dir, sections):
    owner = f'link "{link}"'
    name = collision.get('name') or f'{link}/{index}'
    T_link_element = context.origin(collision, f'{owner} <collision> {index}')
    geometry = collision.find('geometry')
    shapes = [] if geometry is None else list(geometry)
    if len(shapes) != 1:
        raise context.error(f'{owner}: <collision> {index} (line {collision.sourceline}) needs '
                            'exactly one shape inside <geometry>; give one mesh, box, cylinder '
                            'or sphere')
    shape = shapes[0]
    where = f'{owner} <collision> {index}'
    solid = None
    if shape.tag == 'mesh':
        uri = shape.get('filename')
        if not uri:
            raise context.error(f'{where}: <mesh> lacks filename="..."; add it')
        scale = context.floats(shape, 'scale', 3, where, default=(1.0, 1.0, 1.0))
        if uri.startswith('package:///') and uri[len('package:///'):].lstrip('/'):
            fixed = 'package://' + uri[len('package:///'):].lstrip('/')
            context.warn_once('package:///', f'mesh "{uri}" ({owner}, and every other '
                              '"package:///" URI) has an empty package name; read as '
                              f'"{fixed}" (as pinocchio does; ROS resource_retriever refuses '
                              'it); write package://PACKAGE/...')
            uri = fixed
        path = mesh_loading.resolve_mesh_uri(uri, package_paths, base_dir, owner=owner)
        vertices, faces = mesh_loading.load_mesh_file(path, scale, owner=owner, uri=uri)
        source = f'mesh {uri}'
        if not np.all(scale == 1.0):
            source += ' scale ' + ' '.join(f'{v:g}' for v in scale)
    elif shape.tag == 'box':
        size = context.floats(shape, 'size', 3, where)
        _check_non_negative(size, where, 'box size', context)
        vertices, faces = mesh_loading.box_mesh(size)
        solid = mesh_loading.box_solid(size)
        source = 'box ' + ' '.join(f'{v:g}' for v in size)
    elif shape.tag == 'cylinder':
        radius = context.number(shape, 'radius', where)
        length = context.number(shape, 'length', where)
        _check_non_negative([radius, length], where, 'cylinder radius and length', context)
        vertices, faces = mesh_loading.cylinder_mesh(radius, length, sections)
        solid = mesh_loading.cylinder_solid(radius, length)
        source = f'cylinder {radius:g} {length:g}'
    elif shape.tag == 'sphere':
        radius = context.number(shape, 'radius', where)
        _check_non_negative([radius], where, 'sphere radius', context)
        vertices, faces = mesh_loading.sphere_mesh(radius, sections)
        solid = mesh_loading.sphere_solid(radius)
        source = f'sphere {radius:g}'
    else:
        raise context.error(f'{where}: shape <{shape.tag}> is not supported; use mesh, box, '
                            'cylinder or sphere')
    return CollisionElement(link=link, index=index, name=name, source=source,
                            T_link_element=T_link_element, vertices=vertices, faces=faces,
                            solid=solid)


def _check_non_negative(values, where, what, context):
    if np.any(np.asarray(values) < 0):
        raise context.error(f'{where}: {what} must not be negative; fix the geometry')
