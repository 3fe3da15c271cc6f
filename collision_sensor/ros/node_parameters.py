"""The node's parameters on the ROS graph: declared with typed descriptors, read back, checked.

The parameters themselves (names, defaults, meanings, validation) are
:mod:`collision_sensor.sensor.parameters`'s; this module is the only part that touches rclpy
(imported inside :func:`declare_node_parameters`): it declares each parameter on a node with a
typed descriptor, read-only except the ``DYNAMIC`` ones, and reads the values back.

Empty string arrays: rclpy infers the type of a ``[]`` default as BYTE_ARRAY, after which a
string list from a params file is refused. String-array parameters are therefore declared by
type alone (``Parameter.Type.STRING_ARRAY``), and a parameter left unset, or set to ``[]`` in a
params file or on the command line (which rcl reads as "not set"), reads as the empty list.
"""
from typing import List, Mapping

from collision_sensor.errors import ConfigError
from collision_sensor.sensor.parameters import (  # noqa: F401 - the node's names for them
    CONTACT, DYNAMIC, FAIL_SAFE_POLICIES, HOLD, JOINT_STATES_QOS, MAX_JOINT_STATE_BYTES,
    MAX_TRAJECTORY_BYTES, PARAMETERS, ROS_PARAMETER_PREFIXES, NodeSettings, ParameterSpec,
    _SPECS, closest_name, default_values, settings_from_values, unknown_parameters_error)


def unknown_overrides(node) -> List[str]:
    """Return the parameter names given to ``node`` (``-p`` arguments, params files and
    ``parameter_overrides``, as rcl matched them to this node) that are neither this node's nor
    ROS's own (``use_sim_time``, ``qos_overrides.*``, whatever rclpy declared itself).

    rclpy keeps those names in ``Node._parameter_overrides`` and offers no public accessor:
    this is the node's one read of a private rclpy attribute, and without it (another rclpy)
    nothing is found.
    """
    overrides = getattr(node, '_parameter_overrides', None)
    if not isinstance(overrides, Mapping):
        return []
    return sorted(name for name in overrides
                  if name not in _SPECS and not node.has_parameter(name)
                  and not name.startswith(ROS_PARAMETER_PREFIXES))


def declare_node_parameters(node) -> NodeSettings:
    """Declare every parameter on ``node`` (typed descriptors, read-only unless dynamic) and
    validate them.

    :param node: an ``rclpy.node.Node``.
    :return: the validated settings.
    :raises ConfigError: a parameter the node does not have (:func:`unknown_overrides`), a
        value of the wrong type (e.g. ``1`` for a double: write ``1.0``) or one that
        :func:`settings_from_values` refuses.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.exceptions import (
        InvalidParameterTypeException, InvalidParameterValueException,
        ParameterUninitializedException)
    from rclpy.parameter import Parameter

    unknown = unknown_overrides(node)
    if unknown:
        raise unknown_parameters_error(unknown)
    values = {}
    for spec in PARAMETERS:
        string_array = isinstance(spec.default, tuple)
        type_ = (Parameter.Type.STRING_ARRAY if string_array
                 else Parameter.Type.from_parameter_value(spec.default))
        descriptor = ParameterDescriptor(
            name=spec.name, type=type_.value, description=spec.description,
            additional_constraints=spec.constraints, read_only=not spec.dynamic)
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
