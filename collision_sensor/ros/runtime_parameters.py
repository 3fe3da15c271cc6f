"""Parameters changed while the node runs (``ros2 param set``), validated as at start-up and
applied between two checks, all at once.

The dynamic parameters (:data:`~collision_sensor.ros.node_parameters.DYNAMIC`):
``warning_distance``, ``warning_ignore``, ``publish_markers``, ``joint_limit_policy`` and
``check_motion`` are applied under the node's lock before the request is answered; ``padding``,
``link_padding`` and ``allowed_collisions`` change the checker itself: the request is answered
once the values are validated (names against the robot in use), and a new checker is built on
the loader thread with them, carrying the joint state and the scene over, while the current one
keeps answering; it replaces the current one between two checks (``parameters_pending`` on
/diagnostics until then, ``parameter_changes_applied_total`` counts the changes applied).
Either way the change is answered by a verdict at the current state (header: the time and the
root frame), as a scene change is, and logged. A refused request changes nothing and names the
reason (``ros2 param set`` prints it).
"""
from typing import List

from rcl_interfaces.msg import SetParametersResult

from collision_sensor.errors import ConfigError
from collision_sensor.ros.node_parameters import DYNAMIC, PARAMETERS, settings_from_values
from collision_sensor.untrusted_text import printable

PARAMETER_NAMES = frozenset(spec.name for spec in PARAMETERS)
#: The parameters whose change needs a new checker.
CHECKER_PARAMETERS = ('padding', 'link_padding', 'allowed_collisions')


def check_names(settings, checker) -> None:
    """Check the links ``link_padding`` names against ``checker``'s robot, as its build would
    (``allowed_collisions`` and ``warning_ignore`` may name scene objects still to come).

    :raises ConfigError: naming the parameter, the unknown link and the links.
    """
    links = set(checker.kinematics.link_names)
    for link, _ in settings.checker_config['link_padding'].items():
        if link not in links:
            raise ConfigError(f'parameter link_padding: "{link}" is not a link of the robot; '
                              f'links: {", ".join(sorted(links))}')


class RuntimeParameters:
    """The node's ``on_set_parameters`` callback (the executor's thread).

    :param node: the :class:`~collision_sensor.ros.node.CollisionSensorNode`.
    """

    def __init__(self, node):
        self._node = node

    def on_set(self, parameters: List) -> SetParametersResult:
        node = self._node
        ours = [p for p in parameters if p.name in PARAMETER_NAMES]
        if not ours:
            return SetParametersResult(successful=True)    # ROS's own (use_sim_time)
        read_only = [p.name for p in ours if p.name not in DYNAMIC]
        if read_only:
            return _refused(f'{", ".join(read_only)} can only be set at start-up; the '
                            f'parameters settable at run time are {", ".join(sorted(DYNAMIC))}')
        requested = node.requested_settings
        values = dict(requested.values)
        for parameter in ours:
            values[parameter.name] = parameter.value
        try:
            settings = settings_from_values(values)
            with node.lock:
                checker = node.checker
            if checker is not None:
                check_names(settings, checker)
        except ConfigError as error:
            return _refused(printable(error, 1000))
        changed = ', '.join(f'{p.name} = {printable(repr(p.value), 200)}' for p in ours)
        node.change_settings(settings, changed)
        return SetParametersResult(successful=True)


def _refused(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)
