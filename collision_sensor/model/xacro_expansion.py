"""Expand a ``.xacro`` robot description into URDF text with the ``xacro`` package (PyPI).

``$(find NAME)`` resolves through :func:`collision_sensor.model.package_lookup.find_package`, the
same places as ``package://NAME`` mesh URIs (explicit ``package_paths``, the ament index,
``ROS_PACKAGE_PATH``), so a description needs no ROS install to expand. ``$(arg NAME)`` takes
the ``xacro_args`` mapping (the ``name:=value`` pairs of the ``xacro`` command line).

xacro keeps its state in module globals, so expansions are serialised by a lock.
"""
import os
import threading
from typing import Mapping, Optional

from collision_sensor.errors import RobotDescriptionError
from collision_sensor.model.package_lookup import find_package, package_path_fix

_LOCK = threading.Lock()


def parse_xacro_args(entries, what: str = '--xacro-arg') -> dict:
    """Turn ``"name:=value"`` strings (the xacro command line's form) into ``{name: value}``.

    :raises ConfigError: an entry without ``:=`` or without a name, or a name given twice.
    """
    from collision_sensor.errors import ConfigError
    arguments = {}
    for entry in entries:
        name, separator, value = entry.partition(':=')
        name = name.strip()
        if not separator or not name:
            raise ConfigError(f'{what} "{entry}": expected NAME:=VALUE, e.g. "prefix:=left_"')
        if name in arguments:
            raise ConfigError(f'{what}: argument "{name}" is given twice; keep one')
        arguments[name] = value
    return arguments


def is_xacro_path(description) -> bool:
    """Return True iff ``description`` is a path (not XML text) ending in ``.xacro``."""
    if isinstance(description, (str, os.PathLike)) and not isinstance(description, bytes):
        text = os.fspath(description)
        return not text.lstrip().startswith('<') and text.endswith('.xacro')
    return False


def expand_xacro(path, xacro_args: Optional[Mapping[str, str]] = None,
                 package_paths: Optional[Mapping[str, str]] = None) -> str:
    """Return the URDF text a xacro file expands to.

    :param path: the ``.xacro`` file.
    :param xacro_args: ``{name: value}`` for ``$(arg name)`` (values converted with ``str``).
    :param package_paths: ``{package: directory}`` searched first for ``$(find package)``.
    :return: the expanded XML text.
    :raises RobotDescriptionError: xacro is not installed, the file is missing, an argument or
        package cannot be resolved, or the expansion fails; the message names the file.
    """
    path = os.fspath(path)
    try:
        import xacro
        from xacro import substitution_args
    except ImportError:
        raise RobotDescriptionError(
            f'URDF "{path}" is a xacro file, but the xacro package is not installed; '
            '`pip install xacro`, or expand it first: xacro FILE > robot.urdf') from None
    if not os.path.isfile(path):
        raise RobotDescriptionError(f'URDF "{path}" (xacro) not found; give an existing file')
    arguments = {str(name): str(value) for name, value in (xacro_args or {}).items()}

    def find(package):
        directory, places = find_package(package, package_paths)
        if directory is None:
            raise _FindError(f'$(find {package}): package "{package}" not found; searched: '
                             f'{"; ".join(places)}; {package_path_fix(package)}')
        return directory

    with _LOCK:
        saved = substitution_args._eval_find, substitution_args._eval_dict.get('find')
        substitution_args._eval_find = find
        substitution_args._eval_dict['find'] = find
        try:
            document = xacro.process_file(path, mappings=arguments)
            return document.toprettyxml(indent='  ')
        except Exception as exc:  # xacro raises XacroException, NameError, XML errors, ...
            cause = getattr(exc, 'exc', None)
            if isinstance(exc, _FindError) or isinstance(cause, _FindError):
                raise RobotDescriptionError(f'URDF "{path}" (xacro): {cause or exc}') from None
            if (isinstance(exc, substitution_args.ArgException)
                    or 'Undefined substitution argument' in str(exc)):
                given = ', '.join(sorted(arguments)) or 'none'
                raise RobotDescriptionError(
                    f'URDF "{path}" (xacro): {exc}: the argument has no value and no default; '
                    f'give it in xacro_args (given: {given})') from None
            raise RobotDescriptionError(
                f'URDF "{path}" (xacro) cannot be expanded: {type(exc).__name__}: {exc}; run '
                f'`xacro {path}` to see where') from None
        finally:
            substitution_args._eval_find, find_entry = saved
            if find_entry is not None:
                substitution_args._eval_dict['find'] = find_entry


class _FindError(Exception):
    """A ``$(find)`` that no place resolves (carried through xacro, re-raised as ours)."""
