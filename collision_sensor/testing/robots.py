"""The robot a sensor under test runs on: a URDF path, or an example-robot-data robot by name."""
import os
from typing import Mapping, Union

from collision_sensor.errors import ConfigError
from collision_sensor.model.example_robots import example_robot, example_robot_files


def robot_files(robot: Union[str, os.PathLike], srdf=None, package_paths=None):
    """Return ``(urdf, srdf, package_paths list)`` for ``robot``: a URDF (or xacro) path, or
    the name of an example-robot-data robot (``panda``, ``ur5``, a URDF's stem such as
    ``tiago`` or ``talos_reduced``, or ``package/stem``) with its SRDF (``srdf=False``: none)
    and its package path.

    :raises ConfigError: neither a file nor a known example robot.
    """
    path = os.fspath(robot)
    paths = [f'{name}={directory}' for name, directory in dict(package_paths or {}).items()] \
        if isinstance(package_paths, Mapping) else list(package_paths or [])
    if os.path.isfile(path):
        return os.path.abspath(path), (os.fspath(srdf) if srdf else ''), paths
    if path in ('panda', 'ur5'):
        found = example_robot(path)
    else:
        matches = [r for r in example_robot_files()
                   if r.name == path or r.name.rsplit('/', 1)[-1] == path]
        if len(matches) != 1:
            raise ConfigError(
                f'robot "{path}" is neither a URDF file nor one example-robot-data robot '
                f'({len(matches)} match); give the URDF\'s path, or a name such as "panda", '
                '"ur5", "tiago" or "tiago_description/tiago_no_hand"')
        found = matches[0]
    chosen = '' if srdf is False else os.fspath(srdf) if srdf else (found.srdf or '')
    return found.urdf, chosen, paths + [f'{name}={directory}' for name, directory
                                        in found.package_paths.items()]
