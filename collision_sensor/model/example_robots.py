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


def example_robot_files() -> list:
    """Return every URDF of example-robot-data with the SRDF that belongs to it, name-sorted.

    A URDF ``<pkg>/{urdf,robots}/<stem>.urdf`` takes ``<pkg>/srdf/<stem>.srdf`` if it exists,
    else the package SRDF whose stem is the longest prefix of ``<stem>`` (``solo12`` takes
    ``solo``, ``talos_reduced`` takes ``talos``, ``ur5_robot`` takes ``ur5``), else none. The
    name is ``<pkg>/<stem>``.

    :return: a list of :class:`ExampleRobot`.
    """
    share = example_robot_data_dir()
    robots_dir = os.path.join(share, 'robots')
    found = []
    for package in sorted(os.listdir(robots_dir)):
        srdf_dir = os.path.join(robots_dir, package, 'srdf')
        srdfs = sorted(name[:-5] for name in os.listdir(srdf_dir)
                       if name.endswith('.srdf')) if os.path.isdir(srdf_dir) else []
        for folder in ('urdf', 'robots'):
            directory = os.path.join(robots_dir, package, folder)
            if not os.path.isdir(directory):
                continue
            for name in sorted(os.listdir(directory)):
                if not name.endswith('.urdf'):
                    continue
                stem = name[:-5]
                prefixes = [s for s in srdfs if stem == s or stem.startswith(s)]
                srdf = (os.path.join(srdf_dir, max(prefixes, key=len) + '.srdf')
                        if prefixes else None)
                found.append(ExampleRobot(f'{package}/{stem}', os.path.join(directory, name),
                                          srdf, {'example-robot-data': share}))
    return found
