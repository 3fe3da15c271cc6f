"""The sensor's parameters: every one's name, typed default and meaning, and their conversion
into validated settings.

Pure Python, no rclpy: :data:`PARAMETERS` defines every parameter of the node (the one source
of their names, defaults and descriptions) and :func:`settings_from_values` turns a ``{name:
value}`` mapping into :class:`NodeSettings`, raising :class:`~collision_sensor.ConfigError` with
a message that names the parameter and the fix. The node declares them on the ROS graph
(:func:`collision_sensor.ros.node_parameters.declare_node_parameters`); the sensor core
(:class:`collision_sensor.sensor.Sensor`) takes the same names.

:data:`PARAMETERS` is the one source of ``config/collision_sensor.yaml`` and
``docs/parameters.md``: ``python scripts/parameter_reference.py`` writes both from it (with
:mod:`collision_sensor.ros.parameter_notes`), ``test/test_parameter_reference.py`` fails when
either is stale.
"""
import difflib
import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, FrozenSet, List, Mapping, Optional, Tuple

from collision_sensor.engine.checker_config import BOX_TESTS, OBB_FITS, CheckerConfig
from collision_sensor.engine.scene_markers import SceneLimits
from collision_sensor.engine.traversal import EXPANSION_RULES
from collision_sensor.errors import ConfigError
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.model.exception_list import sorted_pair
from collision_sensor.untrusted_text import printable

#: The values of ``on_rejected_input``, ``on_engine_error`` and ``stale_policy``.
CONTACT, HOLD = 'contact', 'hold'
FAIL_SAFE_POLICIES = (CONTACT, HOLD)
#: What a joint state value beyond its joint's limits does (``joint_limit_policy``).
LIMIT_POLICIES = ('reject', 'clamp', 'accept')
#: Default of ``joint_limit_tolerance``: rad or m a value may lie beyond a limit and still be
#: taken as given. 0.01 rad (0.57 deg) / 10 mm is above encoder noise and calibration offsets of
#: industrial arms, and far below the errors it is meant to catch (degrees sent as radians,
#: joints out of order, uninitialised values).
DEFAULT_LIMIT_TOLERANCE = 0.01
#: Default of ``max_unknown_joints``: unknown joint names remembered (and each reported once).
MAX_UNKNOWN_NAMES = 100

#: Default of ``max_joint_state_bytes``: a JointState of 1000 joints, names of 24 characters,
#: positions, velocities and efforts is about 60 KiB serialized.
MAX_JOINT_STATE_BYTES = 64 * 1024
#: Default of ``max_trajectory_bytes``: a JointTrajectory of 7 joints with positions, velocities
#: and accelerations is about 190 bytes a point serialized, so 1 MiB holds about 5000 points.
MAX_TRAJECTORY_BYTES = 1024 * 1024
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
    dynamic: bool = False   # settable while the node runs (ros2 param set)


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
                  'pairs never checked, as "link_a:link_b" (links of the robot or scene objects, '
                  'also objects still to come on the scene topic)',
                  'each entry "link_a:link_b" with two different names', dynamic=True),
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
                  'contact when their surfaces are within the sum of their paddings', '>= 0',
                  dynamic=True),
    ParameterSpec('link_padding', (),
                  'a link\'s own padding instead of padding, as "link=metres"',
                  'each entry "link=metres" with a link of the robot and a number >= 0',
                  dynamic=True),
    ParameterSpec('require_all_joints', True,
                  'publish no verdict until every movable joint has been heard at least once'),
    ParameterSpec('stale_timeout', 1.0,
                  'seconds without an accepted joint state (after the first) before the state '
                  'is stale: /diagnostics ERROR, and stale_policy says what contact does; 0 '
                  'turns the check off', '>= 0'),
    ParameterSpec('joint_limit_policy', 'reject',
                  'a joint state with a value beyond its joint limits (URDF) by more than '
                  'joint_limit_tolerance: "reject" it whole (state unchanged, warning), '
                  '"clamp" the value to the limit, or "accept" it as given (reported); joints '
                  'without limits take any finite value', ' | '.join(LIMIT_POLICIES),
                  dynamic=True),
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
    ParameterSpec('check_motion', True,
                  'each verdict covers the motion from the previous state checked to this one '
                  '(certified, not sampled): contact is true if any contact happens on the way, '
                  'and colliding_pairs lists the pairs met on the way (key first_contact); a '
                  'gap longer than stale_timeout starts a new motion. false: the instant only',
                  dynamic=True),
    ParameterSpec('on_rejected_input', 'contact',
                  'a joint state the node refuses (malformed, beyond its limits, too large) or '
                  'cannot check yet (joints missing) is answered by a colliding_pairs entry '
                  'naming the reason; "contact": contact true (the node does not know where '
                  'the robot is), "hold": contact repeats the last verdict',
                  ' | '.join(FAIL_SAFE_POLICIES)),
    ParameterSpec('on_engine_error', 'contact',
                  'the engine fails on a joint state (the state stays the last one checked, '
                  '/diagnostics ERROR until a state is checked again): "contact" publishes '
                  'contact true and a colliding_pairs entry naming the error, "hold" repeats the '
                  'last verdict with that entry', ' | '.join(FAIL_SAFE_POLICIES)),
    ParameterSpec('stale_policy', 'contact',
                  'no joint state for stale_timeout (/diagnostics ERROR until one comes): '
                  '"contact" publishes contact true and a colliding_pairs entry saying so, '
                  '"hold" publishes nothing (contact keeps the last verdict)',
                  ' | '.join(FAIL_SAFE_POLICIES)),
    ParameterSpec('warning_distance', 0.0,
                  'metres: pairs nearer than this (padded distance) are reported on near, '
                  'min_distance and near_pairs with every verdict; 0 turns the proximity '
                  'outputs off', '>= 0', dynamic=True),
    ParameterSpec('warning_ignore', (),
                  'pairs left out of the warning zone, as "link_a:link_b" (they are still '
                  'checked for contact); the node names at start-up the pairs that are nearer '
                  'than warning_distance wherever the robot goes',
                  'each entry "link_a:link_b" with two different names', dynamic=True),
    ParameterSpec('publish_markers', False,
                  'publish the boxes of colliding links, the scene objects, and the nearest '
                  'points of pairs nearer than warning_distance, on ~/markers '
                  '(visualization_msgs/MarkerArray)', dynamic=True),
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
    ParameterSpec('max_trajectory_bytes', MAX_TRAJECTORY_BYTES,
                  'largest trajectory message taken (bytes, serialized); a larger one is '
                  'answered invalid before it is decoded and never relayed. The default holds '
                  'about 5000 points of 7 joints with positions, velocities and accelerations',
                  '>= 1024'),
    ParameterSpec('point_cloud_topics', (),
                  'sensor_msgs/PointCloud2 topics (relative names, sensor-data QoS) whose points '
                  'are obstacles cloud/<topic>: the robot\'s own points filtered out, the rest '
                  'voxelised and checked against every link (docs/point_clouds.md); empty: none',
                  'each entry a topic name, no two alike'),
    ParameterSpec('point_cloud_voxel_size', _ENGINE.voxel_size,
                  'edge (m) of the world-aligned cubes a cloud\'s points are grouped into',
                  '0.001 to 1'),
    ParameterSpec('point_cloud_self_filter_padding', _ENGINE.self_filter_padding,
                  'points within this (m) of the robot\'s collision geometry (or inside its '
                  'solids, or an attached object) are its own and removed; an object nearer '
                  'a link than this is not seen', '0 to 1'),
    ParameterSpec('point_cloud_max_points', _ENGINE.max_points,
                  'most points taken from one cloud; a larger cloud is subsampled (every k-th '
                  'point) and counted (points_capped on /diagnostics)', '>= 1'),
    ParameterSpec('point_cloud_max_range', 0.0,
                  'points farther than this (m) from the cloud frame\'s origin are dropped; 0: '
                  'no limit', '>= 0'),
    ParameterSpec('point_cloud_timeout', 1.0,
                  'seconds without an accepted cloud on a topic (from the start on) before it '
                  'times out: /diagnostics ERROR, and point_cloud_on_timeout says what '
                  'happens; 0 turns the check off', '>= 0'),
    ParameterSpec('point_cloud_on_timeout', 'contact',
                  'a topic timed out: "contact" answers every verdict with contact true and a '
                  'point_cloud_timeout entry until a cloud comes (fail safe, as nav2\'s '
                  'collision_monitor stops); "ignore" removes its last voxels and goes on',
                  'contact | ignore'),
    ParameterSpec('point_cloud_state_window', 1.0,
                  'seconds of joint states kept to place a cloud with the robot\'s pose at its '
                  'stamp (interpolated); an older cloud is counted and dropped', '> 0'),
    ParameterSpec('point_cloud_persistence', 0.0,
                  'seconds a voxel seen by an earlier cloud of the topic stays an obstacle '
                  '(unless the robot now covers it); 0: only the latest cloud counts', '>= 0'),
)

_SPECS = {spec.name: spec for spec in PARAMETERS}
#: The parameters settable while the node runs (``collision_sensor.ros.runtime_parameters``).
DYNAMIC = frozenset(spec.name for spec in PARAMETERS if spec.dynamic)


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
        :data:`LIMIT_POLICIES`.
    :ivar joint_limit_tolerance: rad or m beyond a limit still taken as given.
    :ivar max_unknown_joints: unknown joint names remembered.
    :ivar max_joint_state_bytes: largest serialized joint_states message taken.
    :ivar check_motion: verdicts cover the motion from the previous state checked.
    :ivar max_trajectory_bytes: largest serialized trajectory message taken.
    :ivar xacro_args: ``{name: value}`` for a ``.xacro`` urdf_path.
    :ivar warning_distance: metres; 0: no proximity outputs.
    :ivar warning_ignore: pairs left out of the warning zone, each sorted.
    :ivar scene_limits: the ``scene`` topic's caps and mesh roots.
    :ivar on_rejected_input: one of :data:`FAIL_SAFE_POLICIES`.
    :ivar on_engine_error: one of :data:`FAIL_SAFE_POLICIES`.
    :ivar stale_policy: one of :data:`FAIL_SAFE_POLICIES`.
    :ivar point_cloud_topics: the PointCloud2 topics, as given.
    :ivar point_cloud_max_range: metres (``inf``: no limit).
    :ivar point_cloud_timeout: seconds; 0 disables the timeout.
    :ivar point_cloud_on_timeout: ``contact`` or ``ignore``.
    :ivar point_cloud_persistence: seconds.
    :ivar point_cloud_state_window: seconds of joint states kept for clouds' stamps.
    :ivar values: the parameter values these settings were made from, ``{name: value}``.
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
    check_motion: bool = True
    max_trajectory_bytes: int = MAX_TRAJECTORY_BYTES
    xacro_args: Dict[str, str] = field(default_factory=dict)
    overload_policy: str = 'newest'
    warning_distance: float = 0.0
    warning_ignore: FrozenSet[Tuple[str, str]] = frozenset()
    scene_limits: SceneLimits = field(default_factory=SceneLimits)
    on_rejected_input: str = CONTACT
    on_engine_error: str = CONTACT
    stale_policy: str = CONTACT
    point_cloud_topics: Tuple[str, ...] = ()
    point_cloud_max_range: float = math.inf
    point_cloud_timeout: float = 1.0
    point_cloud_on_timeout: str = CONTACT
    point_cloud_persistence: float = 0.0
    point_cloud_state_window: float = 1.0
    values: Mapping[str, Any] = field(default_factory=dict, compare=False)


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


def _parse_pairs(entries: List[str], name: str = 'allowed_collisions') -> List[str]:
    pairs = []
    for entry in entries:
        first, separator, second = entry.partition(':')
        first, second = first.strip(), second.strip()
        if not separator or not first or not second or ':' in second:
            raise ConfigError(f'parameter {name}: entry "{entry}" is not '
                              '"link_a:link_b"; write e.g. "panda_link0:panda_link2"')
        if first == second:
            raise ConfigError(f'parameter {name}: entry "{entry}" names one link '
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


def _topics(entries: List[str], name: str) -> Tuple[str, ...]:
    topics = tuple(entry.strip() for entry in entries)
    for topic in topics:
        if not topic:
            raise ConfigError(f'parameter {name}: an empty entry; give topic names such as '
                              '"camera/depth/points"')
        if topics.count(topic) > 1:
            raise ConfigError(f'parameter {name}: "{printable(topic, 200)}" is listed twice; '
                              'list each topic once')
    return topics


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


def _positive(values, name) -> float:
    value = float(values[name])
    if not (math.isfinite(value) and value > 0.0):
        raise ConfigError(f'parameter {name}: {value} is not a finite number > 0')
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
        raise unknown_parameters_error(unknown)
    merged = default_values()
    for name, value in values.items():
        if isinstance(_SPECS[name].default, tuple):
            value = [] if value is None else list(value)
        merged[name] = value
    checker_config = {
        'allowed_collisions': _parse_pairs(merged['allowed_collisions']),
        'ignore_adjacent': bool(merged['ignore_adjacent']),
        'motion_tolerance': _non_negative(merged, 'motion_tolerance'),
        'box_test': merged['box_test'],
        'expansion': merged['expansion'],
        'obb_fit': merged['obb_fit'],
        'mesh_containment': bool(merged['mesh_containment']),
        'padding': _non_negative(merged, 'padding'),
        'link_padding': _parse_link_padding(merged['link_padding']),
        'voxel_size': merged['point_cloud_voxel_size'],
        'self_filter_padding': merged['point_cloud_self_filter_padding'],
        'max_points': merged['point_cloud_max_points'],
    }
    try:
        # The engine validates its own settings; doing it now makes a typo fail configuration
        # at start-up even when the robot only arrives later on robot_description.
        CheckerConfig.from_mapping(checker_config)
    except ConfigError as error:
        text = str(error)
        for key in ('voxel_size', 'self_filter_padding', 'max_points'):
            text = text.replace(f'setting {key}', f'setting point_cloud_{key}')
        raise ConfigError(f'parameter {text}'.replace('parameter setting ', 'parameter ')
                          ) from None
    max_range = _non_negative(merged, 'point_cloud_max_range')
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
        check_motion=bool(merged['check_motion']),
        max_trajectory_bytes=_at_least(merged, 'max_trajectory_bytes', 1024),
        warning_distance=_non_negative(merged, 'warning_distance'),
        warning_ignore=frozenset(sorted_pair(*entry.split(':'))
                                 for entry in _parse_pairs(merged['warning_ignore'],
                                                           'warning_ignore')),
        on_rejected_input=_choice(merged, 'on_rejected_input', FAIL_SAFE_POLICIES),
        on_engine_error=_choice(merged, 'on_engine_error', FAIL_SAFE_POLICIES),
        stale_policy=_choice(merged, 'stale_policy', FAIL_SAFE_POLICIES),
        point_cloud_topics=_topics(merged['point_cloud_topics'], 'point_cloud_topics'),
        point_cloud_max_range=max_range if max_range > 0.0 else math.inf,
        point_cloud_timeout=_non_negative(merged, 'point_cloud_timeout'),
        point_cloud_on_timeout=_choice(merged, 'point_cloud_on_timeout', (CONTACT, 'ignore')),
        point_cloud_persistence=_non_negative(merged, 'point_cloud_persistence'),
        point_cloud_state_window=_positive(merged, 'point_cloud_state_window'),
        values=merged,
        scene_limits=SceneLimits(
            max_objects=_non_negative_int(merged, 'scene_max_objects'),
            max_triangles=_non_negative_int(merged, 'scene_max_triangles'),
            max_total_triangles=_non_negative_int(merged, 'scene_max_total_triangles'),
            max_mesh_bytes=_non_negative_int(merged, 'scene_max_mesh_bytes'),
            mesh_roots=_directories(merged, 'scene_mesh_roots')),
    )


#: Parameters rclpy itself reads (by prefix): never refused as unknown.
ROS_PARAMETER_PREFIXES = ('qos_overrides.',)


def closest_name(name: str) -> str:
    """Return the known parameter name most like ``name``."""
    return max(_SPECS, key=lambda known: difflib.SequenceMatcher(None, name, known).ratio())


def unknown_parameters_error(names) -> ConfigError:
    """Return the error for parameters the node does not have, each with the closest name."""
    listed = '; '.join(f'"{printable(name, 100)}" (did you mean {closest_name(name)}?)'
                       for name in sorted(names))
    return ConfigError(f'unknown parameter(s): {listed}. The node has no such parameter, so its '
                       'value would be ignored: fix the name where it is set (a -p name:=value '
                       'argument or a --params-file), or remove it; every parameter is listed '
                       'in config/collision_sensor.yaml')
