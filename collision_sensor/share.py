"""Find this package's installed data (``config/``, ``meshes/``).

Three layouts are supported, tried in this order:

1. run from the source tree: ``<repo>/collision_sensor/`` next to ``<repo>/config/``;
2. installed by colcon: the ament index names the prefix, data in ``<prefix>/share/collision_sensor``;
3. installed by pip: ``<sys.prefix>/share/collision_sensor``.
"""
import os
import sys

PACKAGE = 'collision_sensor'


def _candidates():
    here = os.path.dirname(os.path.abspath(__file__))
    yield os.path.dirname(here)
    try:
        from ament_index_python.packages import get_package_share_directory
        yield get_package_share_directory(PACKAGE)
    except Exception:  # ament index missing or package not registered: try the next layout
        pass
    yield os.path.join(sys.prefix, 'share', PACKAGE)


def share_directory() -> str:
    """Return the directory holding this package's ``config/`` and ``meshes/``.

    :raises FileNotFoundError: if no layout has them (a broken install).
    """
    for candidate in _candidates():
        if os.path.isdir(os.path.join(candidate, 'config')):
            return candidate
    raise FileNotFoundError(
        'collision_sensor: config/ not found in the source tree, the ament index or '
        f'{sys.prefix}/share/{PACKAGE}; reinstall the package')


def config_path(*parts: str) -> str:
    """Return the path of a file under the package's ``config/``."""
    return os.path.join(share_directory(), 'config', *parts)


def mesh_directory() -> str:
    """Return the package's ``meshes/`` directory."""
    return os.path.join(share_directory(), 'meshes')
