"""The node's parameters: their declarations, and their conversion into engine settings.

Two halves. :data:`PARAMETERS` and :func:`settings_from_values` are pure Python (no rclpy):
they define every parameter (name, typed default, description) and turn a ``{name: value}``
mapping into validated :class:`NodeSettings`, raising :class:`~collision_sensor.ConfigError`
with a message that names the parameter and the fix. :func:`declare_node_parameters` is the
only part that touches rclpy (imported inside it): it declares each parameter on a node with a
read-only, typed descriptor and reads the values back.

Empty string arrays: rclpy infers the type of a ``[]`` default as BYTE_ARRAY, after which a
string list from a params file is refused. String-array parameters are therefore declared by
type alone (``Parameter.Type.STRING_ARRAY``), and a parameter left unset, or set to ``[]`` in a
params file or on the command line (which rcl reads as "not set"), reads as the empty list.

Every parameter is listed, with comments, in ``config/collision_sensor.yaml``; keep the two in
step (``test_node_parameters`` in ``test/test_node.py`` checks it).
"""
import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Tuple

from collision_sensor.engine.checker_config import BOX_TESTS, OBB_FITS, CheckerConfig
from collision_sensor.engine.scene_markers import SceneLimits
from collision_sensor.engine.traversal import EXPANSION_RULES
from collision_sensor.errors import ConfigError
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.ros.joint_state_merger import (
    DEFAULT_LIMIT_TOLERANCE, LIMIT_POLICIES, MAX_UNKNOWN_NAMES)

#: Default of ``max_joint_state_bytes``: a JointState of 1000 joints, names of 24 characters,
#: positions, velocities and efforts is about 60 KiB serialized.
MAX_JOINT_STATE_BYTES = 64 * 1024
#: Accepted values of ``joint_states_qos``.
JOINT_STATES_QOS = ('sensor_data', 'reliable')
#: The engine's defaults, so that the node and the offline tools agree out of the box.
_ENGINE = CheckerConfig()
#: The scene topic's default caps.
_TOPIC = SceneLimits()


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter: name, typed default (its Python type is the parameter type), meaning."""

    name: str
    default: Any
    description: str
    constraints: str = ''


#: Every parameter of the node, in the order of ``config/collision_sensor.yaml``. A default of
#: ``()`` marks a string array (declared by type, see the module docstring).
PARAMETERS: Tuple[ParameterSpec, ...] = (
    ParameterSpec('urdf_path', '',
                  'URDF file of the robot; empty: take the robot from the robot_description '
                  'topic (std_msgs/String, transient local)'),
    ParameterSpec('xacro_args', (),
                  'arguments of a .xacro urdf_path, as "name:=value"',
                  'each entry "name:=value"'),
    ParameterSpec('srdf_path', '',
                  'SRDF file whose disable_collisions entries are not checked; empty: none'),
    ParameterSpec('package_paths', (),
                  'directories of ROS packages for package:// mesh URIs, as "name=dir"',
                  'each entry "name=dir" with an existing directory'),
    ParameterSpec('scene_path', '',
                  'YAML file of static scene objects checked against the robot; empty: none'),
    ParameterSpec('allowed_collisions', (),
                  'pairs never checked, as "link_a:link_b" (links of the robot or scene objects)',
                  'each entry "link_a:link_b" with two different names'),
    ParameterSpec('ignore_adjacent', True,
                  'skip pairs of links joined by one joint (they usually touch by design)'),
    ParameterSpec('motion_tolerance', _ENGINE.motion_tolerance,
                  'joint motion (rad or m) below which a link counts as not moved by the '
                  'incremental check', '>= 0'),
    ParameterSpec('box_test', _ENGINE.box_test,
                  'box overlap test: "sat" (15 separating axes) or "paper" (paper sec. 5); '
                  'same answers, different speed', ' | '.join(sorted(BOX_TESTS))),
    ParameterSpec('expansion', _ENGINE.expansion,
                  'which box of an overlapping pair is split first (paper sec. 4.1); same '
                  'answers, different speed', ' | '.join(sorted(EXPANSION_RULES))),
    ParameterSpec('obb_fit', _ENGINE.obb_fit,
                  'how boxes are fitted to triangles when the model is built',
                  ' | '.join(sorted(OBB_FITS))),
    ParameterSpec('mesh_containment', _ENGINE.mesh_containment,
                  'treat closed (watertight) meshes as solid: a part wholly inside one '
                  'collides with it (primitives always are solid)'),
    ParameterSpec('padding', _ENGINE.padding,
                  'metres every robot link is grown by (a sphere swept over its geometry, as '
                  'MoveIt\'s link padding): two links, or a link and a scene object, are in '
                  'contact when their surfaces are within the sum of their paddings', '>= 0'),
    ParameterSpec('link_padding', (),
                  'a link\'s own padding instead of padding, as "link=metres"',
                  'each entry "link=metres" with a link of the robot and a number >= 0'),
    ParameterSpec('require_all_joints', True,
                  'publish no verdict until every movable joint has been heard at least once'),
    ParameterSpec('stale_timeout', 1.0,
                  'seconds without an accepted joint state before the state is reported stale '
                  'on /diagnostics; 0 turns the check off', '>= 0'),
    ParameterSpec('joint_limit_policy', 'reject',
                  'a joint state with a value beyond its joint limits (URDF) by more than '
                  'joint_limit_tolerance: "reject" it whole (state unchanged, warning), '
                  '"clamp" the value to the limit, or "accept" it as given (reported); joints '
                  'without limits take any finite value', ' | '.join(LIMIT_POLICIES)),
    ParameterSpec('joint_limit_tolerance', DEFAULT_LIMIT_TOLERANCE,
                  'rad or m a value may lie beyond a joint limit and still be taken as given '
                  '(encoder noise, calibration)', '>= 0'),
    ParameterSpec('max_unknown_joints', MAX_UNKNOWN_NAMES,
                  'unknown joint names remembered (listed on /diagnostics, warned about once); '
                  'more are only counted, so memory stays bounded', '>= 0'),
    ParameterSpec('max_joint_state_bytes', MAX_JOINT_STATE_BYTES,
                  'largest joint_states message taken (bytes, serialized); a larger one is '
                  'rejected before it is decoded (rejected_oversized on /diagnostics). The '
                  'default holds about 1000 joints with names, positions, velocities and '
                  'efforts', '>= 1024'),
    ParameterSpec('joint_states_qos', 'sensor_data',
                  'QoS of the joint_states subscription: "sensor_data" (best effort, depth 5) '
                  'or "reliable" (reliable, keep all: every message is checked)',
                  ' | '.join(JOINT_STATES_QOS)),
    ParameterSpec('overload_policy', 'newest',
                  'when more joint states wait than the node can check at once: "newest" '
                  'checks only the newest and counts the rest (skipped_superseded), staying '
                  'current; "every" checks every one in order however far behind (a recorded '
                  'path replayed as fast as possible, one verdict per frame)',
                  'newest | every'),
    ParameterSpec('warning_distance', 0.0,
                  'metres: pairs nearer than this (padded distance) are reported on near, '
                  'min_distance and near_pairs with every verdict; 0 turns the proximity '
                  'outputs off', '>= 0'),
    ParameterSpec('publish_markers', False,
                  'publish the boxes of colliding links, the scene objects, and the nearest '
                  'points of pairs nearer than warning_distance, on ~/markers '
                  '(visualization_msgs/MarkerArray)'),
    ParameterSpec('scene_max_objects', _TOPIC.max_objects,
                  'objects the scene topic may hold at once; an array that would add more is '
                  'rejected', '>= 0'),
    ParameterSpec('scene_max_triangles', _TOPIC.max_triangles,
                  'triangles of one object from the scene topic, at most', '>= 0'),
    ParameterSpec('scene_max_total_triangles', _TOPIC.max_total_triangles,
                  'triangles of all objects from the scene topic together, at most', '>= 0'),
    ParameterSpec('scene_max_mesh_bytes', _TOPIC.max_mesh_bytes,
                  'size of a MESH_RESOURCE file the scene topic may make the node read, at most',
                  '>= 0'),
    ParameterSpec('scene_mesh_roots', (),
                  'directories under which MESH_RESOURCE files given as file:// or absolute '
                  'paths may lie (package:// URIs need none); empty: package:// only',
                  'each entry an existing directory'),
)

_SPECS = {spec.name: spec for spec in PARAMETERS}


@dataclass(frozen=True)
class NodeSettings:
    """Validated parameters.

    :ivar urdf_path: URDF file, or ``None`` to take the robot from ``robot_description``.
    :ivar srdf_path: SRDF file or ``None``.
    :ivar package_paths: ``{package_name: directory}``.
    :ivar scene_path: scene YAML or ``None``.
    :ivar checker_config: the engine's ``config`` mapping for ``CollisionChecker.from_urdf``.
    :ivar require_all_joints: hold verdicts until every movable joint is known.
    :ivar stale_timeout: seconds; 0 disables the stale check.
    :ivar joint_states_qos: one of :data:`JOINT_STATES_QOS`.
    :ivar publish_markers: publish ``~/markers``.
    :ivar joint_limit_policy: one of
        :data:`~collision_sensor.ros.joint_state_merger.LIMIT_POLICIES`.
    :ivar joint_limit_tolerance: rad or m beyond a limit still taken as given.
    :ivar max_unknown_joints: unknown joint names remembered.
    :ivar max_joint_state_bytes: largest serialized joint_states message taken.
    :ivar xacro_args: ``{name: value}`` for a ``.xacro`` urdf_path.
    :ivar warning_distance: metres; 0: no proximity outputs.
    :ivar scene_limits: the ``scene`` topic's caps and mesh roots.
    """

    urdf_path: Optional[str]
    srdf_path: Optional[str]
    package_paths: Dict[str, str]
    scene_path: Optional[str]
    checker_config: Dict[str, Any] = field(default_factory=dict)
    require_all_joints: bool = True
    stale_timeout: float = 1.0
    joint_states_qos: str = 'sensor_data'
    publish_markers: bool = False
    joint_limit_policy: str = 'reject'
    joint_limit_tolerance: float = DEFAULT_LIMIT_TOLERANCE
    max_unknown_joints: int = MAX_UNKNOWN_NAMES
    max_joint_state_bytes: int = MAX_JOINT_STATE_BYTES
    xacro_args: Dict[str, str] = field(default_factory=dict)
    overload_policy: str = 'newest'
    warning_distance: float = 0.0
    scene_limits: SceneLimits = field(default_factory=SceneLimits)


def default_values() -> Dict[str, Any]:
    """Return ``{name: default}`` for every parameter (string arrays as lists)."""
    return {spec.name: list(spec.default) if isinstance(spec.default, tuple) else spec.default
            for spec in PARAMETERS}


def _existing_file(values, name) -> Optional[str]:
    path = values[name]
    if not path:
        return None
    path = os.path.expanduser(path)
    if not os.path.isfile(path):
        raise ConfigError(f'parameter {name}: file "{path}" not found; give an existing file '
                          'or an empty string')
    return path


def _directories(values, name) -> Tuple[str, ...]:
    roots = []
    for entry in values[name]:
        directory = os.path.abspath(os.path.expanduser(entry))
        if not os.path.isdir(directory):
            raise ConfigError(f'parameter {name}: directory "{entry}" not found; give existing '
                              'directories')
        roots.append(directory)
    return tuple(roots)


def _parse_xacro_args(entries: List[str]) -> Dict[str, str]:
    args = {}
    for entry in entries:
        name, separator, value = entry.partition(':=')
        if not separator or not name.strip():
            raise ConfigError(f'parameter xacro_args: entry "{entry}" is not "name:=value"; '
                              'write e.g. "arm_id:=panda"')
        args[name.strip()] = value
    return args


def _parse_allowed_collisions(entries: List[str]) -> List[str]:
    pairs = []
    for entry in entries:
        first, separator, second = entry.partition(':')
        first, second = first.strip(), second.strip()
        if not separator or not first or not second or ':' in second:
            raise ConfigError(f'parameter allowed_collisions: entry "{entry}" is not '
                              '"link_a:link_b"; write e.g. "panda_link0:panda_link2"')
        if first == second:
            raise ConfigError(f'parameter allowed_collisions: entry "{entry}" names one link '
                              'twice; a pair needs two different links')
        pairs.append(f'{first}:{second}')
    return pairs


def _parse_link_padding(entries: List[str]) -> Dict[str, float]:
    padding = {}
    for entry in entries:
        link, separator, metres = entry.partition('=')
        link = link.strip()
        try:
            value = float(metres)
        except ValueError:
            value = math.nan
        if not separator or not link or not (math.isfinite(value) and value >= 0.0):
            raise ConfigError(f'parameter link_padding: entry "{entry}" is not "link=metres" '
                              'with a number >= 0; write e.g. "panda_hand=0.02"')
        padding[link] = value
    return padding


def _choice(values, name, choices) -> str:
    value = values[name]
    if value not in choices:
        raise ConfigError(f'parameter {name}: "{value}" is not one of '
                          f'{", ".join(map(repr, choices))}')
    return value


def _non_negative(values, name) -> float:
    value = float(values[name])
    if not (math.isfinite(value) and value >= 0.0):
        raise ConfigError(f'parameter {name}: {value} is not a finite number >= 0')
    return value


def _non_negative_int(values, name) -> int:
    return _at_least(values, name, 0)


def _at_least(values, name, smallest: int) -> int:
    value = values[name]
    if isinstance(value, bool) or not isinstance(value, int) or value < smallest:
        raise ConfigError(f'parameter {name}: {value!r} is not an integer >= {smallest}')
    return value


def settings_from_values(values: Mapping[str, Any]) -> NodeSettings:
    """Validate parameter values and convert them into :class:`NodeSettings`.

    :param values: ``{name: value}``; missing names take their default, string arrays may be
        ``None`` (unset) and are then empty.
    :return: the settings; ``checker_config`` is ready for ``CollisionChecker.from_urdf``.
    :raises ConfigError: a value that is malformed, out of range, or names a missing file; the
        message names the parameter and the fix. Whether links named in ``allowed_collisions``
        exist is only known once the robot is loaded (the engine checks it then).
    """
    unknown = set(values) - set(_SPECS)
    if unknown:
        raise ConfigError(f'unknown parameters {sorted(unknown)}; known: {sorted(_SPECS)}')
    merged = default_values()
    for name, value in values.items():
        if isinstance(_SPECS[name].default, tuple):
            value = [] if value is None else list(value)
        merged[name] = value
    checker_config = {
        'allowed_collisions': _parse_allowed_collisions(merged['allowed_collisions']),
        'ignore_adjacent': bool(merged['ignore_adjacent']),
        'motion_tolerance': _non_negative(merged, 'motion_tolerance'),
        'box_test': merged['box_test'],
        'expansion': merged['expansion'],
        'obb_fit': merged['obb_fit'],
        'mesh_containment': bool(merged['mesh_containment']),
        'padding': _non_negative(merged, 'padding'),
        'link_padding': _parse_link_padding(merged['link_padding']),
    }
    try:
        # The engine validates its own settings; doing it now makes a typo fail configuration
        # at start-up even when the robot only arrives later on robot_description.
        CheckerConfig.from_mapping(checker_config)
    except ConfigError as error:
        raise ConfigError(f'parameter {error}'.replace('parameter setting ', 'parameter ')
                          ) from None
    return NodeSettings(
        urdf_path=_existing_file(merged, 'urdf_path'),
        srdf_path=_existing_file(merged, 'srdf_path'),
        package_paths=parse_package_paths(merged['package_paths'], 'parameter package_paths'),
        scene_path=_existing_file(merged, 'scene_path'),
        xacro_args=_parse_xacro_args(merged['xacro_args']),
        overload_policy=_choice(merged, 'overload_policy', ('newest', 'every')),
        checker_config=checker_config,
        require_all_joints=bool(merged['require_all_joints']),
        stale_timeout=_non_negative(merged, 'stale_timeout'),
        joint_states_qos=_choice(merged, 'joint_states_qos', JOINT_STATES_QOS),
        publish_markers=bool(merged['publish_markers']),
        joint_limit_policy=_choice(merged, 'joint_limit_policy', LIMIT_POLICIES),
        joint_limit_tolerance=_non_negative(merged, 'joint_limit_tolerance'),
        max_unknown_joints=_non_negative_int(merged, 'max_unknown_joints'),
        max_joint_state_bytes=_at_least(merged, 'max_joint_state_bytes', 1024),
        warning_distance=_non_negative(merged, 'warning_distance'),
        scene_limits=SceneLimits(
            max_objects=_non_negative_int(merged, 'scene_max_objects'),
            max_triangles=_non_negative_int(merged, 'scene_max_triangles'),
            max_total_triangles=_non_negative_int(merged, 'scene_max_total_triangles'),
            max_mesh_bytes=_non_negative_int(merged, 'scene_max_mesh_bytes'),
            mesh_roots=_directories(merged, 'scene_mesh_roots')),
    )


def declare_node_parameters(node) -> NodeSettings:
    """Declare every parameter on ``node`` (typed, read-only descriptors) and validate them.

    :param node: an ``rclpy.node.Node``.
    :return: the validated settings.
    :raises ConfigError: a value of the wrong type (e.g. ``1`` for a double: write ``1.0``) or
        one that :func:`settings_from_values` refuses.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.exceptions import (
        InvalidParameterTypeException, InvalidParameterValueException,
        ParameterUninitializedException)
    from rclpy.parameter import Parameter

    values = {}
    for spec in PARAMETERS:
        string_array = isinstance(spec.default, tuple)
        type_ = (Parameter.Type.STRING_ARRAY if string_array
                 else Parameter.Type.from_parameter_value(spec.default))
        descriptor = ParameterDescriptor(
            name=spec.name, type=type_.value, description=spec.description,
            additional_constraints=spec.constraints, read_only=True)
        try:
            node.declare_parameter(spec.name, type_ if string_array else spec.default,
                                   descriptor)
        except (InvalidParameterTypeException, InvalidParameterValueException) as error:
            raise ConfigError(f'parameter {spec.name}: {error}; expected a '
                              f'{type_.name.lower()} (e.g. write 1.0, not 1, for a double)'
                              ) from None
        try:
            values[spec.name] = node.get_parameter(spec.name).value
        except ParameterUninitializedException:
            values[spec.name] = None    # a string array left unset or set to []
    return settings_from_values(values)
