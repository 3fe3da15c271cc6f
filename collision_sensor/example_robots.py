"""Locate the robots of the ``example-robot-data`` wheel (used by benchmarks, demos, tests).

The wheel ships no Python module; its files sit under ``<site-packages>/cmeel.prefix``.
"""
import os
import sysconfig
from dataclasses import dataclass
from typing import Dict, Optional

from collision_sensor.errors import CollisionSensorError


@dataclass(frozen=True)
class ExampleRobot:
    """Paths of one example robot: URDF, SRDF and the package mapping for its meshes."""

    name: str
    urdf: str
    srdf: Optional[str]
    package_paths: Dict[str, str]


_ROBOTS = {
    'panda': ('panda_description/urdf/panda.urdf', 'panda_description/srdf/panda.srdf'),
    'ur5': ('ur_description/urdf/ur5_robot.urdf', 'ur_description/srdf/ur5.srdf'),
}


def example_robot_data_dir() -> str:
    """Return ``.../share/example-robot-data``.

    :raises CollisionSensorError: if the wheel is not installed.
    """
    share = os.path.join(sysconfig.get_paths()['purelib'], 'cmeel.prefix', 'share',
                         'example-robot-data')
    if not os.path.isdir(os.path.join(share, 'robots')):
        raise CollisionSensorError(
            f'example-robot-data not found at {share}; install it with '
            '`pip install example-robot-data` (part of the "test" extra)')
    return share


def example_robot(name: str) -> ExampleRobot:
    """Return the paths of example robot ``name`` ('panda' or 'ur5')."""
    if name not in _ROBOTS:
        raise CollisionSensorError(f'unknown example robot "{name}"; choose one of '
                                   f'{", ".join(sorted(_ROBOTS))}')
    share = example_robot_data_dir()
    urdf, srdf = _ROBOTS[name]
    return ExampleRobot(name, os.path.join(share, 'robots', urdf),
                        os.path.join(share, 'robots', srdf),
                        {'example-robot-data': share})
