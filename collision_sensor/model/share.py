"""Find this package's installed data (``package.xml``, ``config/``, ``meshes/``).

Three layouts are supported, tried in this order:

1. run from the source tree: ``<repo>/collision_sensor/`` next to ``<repo>/config/``;
2. installed by colcon: the ament index names the prefix, data in
   ``<prefix>/share/collision_sensor``;
3. installed by pip: ``<sys.prefix>/share/collision_sensor``.

A directory counts only if it holds both ``package.xml`` and ``config/``: an installed package's
parent directory is ``site-packages``, where another distribution may have left a ``config/``.
"""
import os
import sys
from typing import Iterator, List, Optional

PACKAGE = 'collision_sensor'

# <repo> when this file is <repo>/collision_sensor/model/share.py; <site-packages> when installed.
SOURCE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The ament resource index is a directory convention, not an API: a prefix registers package
# NAME with the (empty) marker file <prefix>/share/ament_index/resource_index/packages/NAME, and
# the first prefix on AMENT_PREFIX_PATH that has it wins (ament_index_python's
# get_package_prefix does the same walk). Reading it here keeps the pip layout free of ROS
# packages and lets a test pass the search path instead of editing the environment.
AMENT_MARKER = ('share', 'ament_index', 'resource_index', 'packages', PACKAGE)


def ament_share_directory(ament_prefix_path: Optional[str] = None) -> Optional[str]:
    """Return ``<prefix>/share/collision_sensor`` of the first prefix that registers it.

    :param ament_prefix_path: ``os.pathsep``-separated prefixes; default ``$AMENT_PREFIX_PATH``.
    :return: the share directory, or None when no prefix registers the package.
    """
    if ament_prefix_path is None:
        ament_prefix_path = os.environ.get('AMENT_PREFIX_PATH', '')
    for prefix in ament_prefix_path.split(os.pathsep):
        if prefix and os.path.isfile(os.path.join(prefix, *AMENT_MARKER)):
            return os.path.join(prefix, 'share', PACKAGE)
    return None


def _candidates(source_root: Optional[str] = None, ament_prefix_path: Optional[str] = None,
                prefix: Optional[str] = None) -> Iterator[str]:
    """Yield the directories that may hold the data, in the order of the module docstring."""
    # Defaults are read at call time, so a test can patch SOURCE_ROOT, sys.prefix or the
    # environment and go through the public functions.
    yield SOURCE_ROOT if source_root is None else source_root
    ament = ament_share_directory(ament_prefix_path)
    if ament is not None:
        yield ament
    yield os.path.join(sys.prefix if prefix is None else prefix, 'share', PACKAGE)


def _holds_data(directory: str) -> bool:
    return (os.path.isfile(os.path.join(directory, 'package.xml'))
            and os.path.isdir(os.path.join(directory, 'config')))


def find_share_directory(source_root: Optional[str] = None,
                         ament_prefix_path: Optional[str] = None,
                         prefix: Optional[str] = None) -> str:
    """Return the first candidate directory that holds ``package.xml`` and ``config/``.

    :param source_root: the source tree's root (default: ``SOURCE_ROOT``).
    :param ament_prefix_path: colcon prefixes (default: ``$AMENT_PREFIX_PATH``).
    :param prefix: the pip install prefix (default: ``sys.prefix``).
    :raises FileNotFoundError: if no layout has them (a broken install); the message lists
        every directory looked in.
    """
    tried: List[str] = []
    for candidate in _candidates(source_root, ament_prefix_path, prefix):
        if _holds_data(candidate):
            return candidate
        tried.append(candidate)
    raise FileNotFoundError(
        f'{PACKAGE}: package.xml and config/ not found in any of: {", ".join(tried)} '
        '(source tree, ament index from AMENT_PREFIX_PATH, pip prefix); reinstall the package '
        '(pip install . or colcon build) and, for colcon, source install/setup.bash')


def share_directory() -> str:
    """Return the directory holding this package's ``config/`` and ``meshes/``.

    :raises FileNotFoundError: if no layout has them (a broken install).
    """
    return find_share_directory()


def config_path(*parts: str) -> str:
    """Return the path of a file under the package's ``config/``."""
    return os.path.join(share_directory(), 'config', *parts)


def mesh_directory() -> str:
    """Return the package's ``meshes/`` directory."""
    return os.path.join(share_directory(), 'meshes')
