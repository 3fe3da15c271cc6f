"""Find a ROS package's directory, in the order a ROS user expects.

Used for ``package://NAME/rest`` mesh URIs and for xacro's ``$(find NAME)``. The places, in
order (the first that has the package wins):

1. the explicit mapping ``package_paths[NAME]`` (``--package-path NAME=DIR``, the node's
   ``package_paths`` parameter);
2. the ament index: for every prefix of ``AMENT_PREFIX_PATH``, in order, a package is installed
   there iff ``<prefix>/share/ament_index/resource_index/packages/NAME`` exists; its directory
   is ``<prefix>/share/NAME``;
3. ``ROS_PACKAGE_PATH``: every entry, in order, is crawled (as rospack does: depth-first, not
   below a package, skipping ``CATKIN_IGNORE``/``COLCON_IGNORE`` folders and hidden ones) for a
   directory whose ``package.xml`` has ``<name>NAME</name>``;
4. for ``NAME == 'collision_sensor'``, this package's own share directory (running from a
   source tree without an install).

The environment variables are read on every call; the packages found under a
``ROS_PACKAGE_PATH`` entry are remembered for the process. No ROS Python package is needed.
"""
import functools
import os
from typing import List, Mapping, Optional, Tuple

from lxml import etree

_IGNORE_MARKERS = ('CATKIN_IGNORE', 'COLCON_IGNORE', 'AMENT_IGNORE')
_CRAWL_DEPTH = 8


def find_package(name: str, package_paths: Optional[Mapping[str, str]] = None
                 ) -> Tuple[Optional[str], List[str]]:
    """Return the directory of package ``name`` and every place searched.

    :param name: the package name.
    :param package_paths: ``{package: directory}`` searched first, or None.
    :return: ``(directory or None, places)``; ``places`` describes each place looked at, in
        order, for error messages.
    """
    places = []
    if package_paths and name in package_paths:
        return os.fspath(package_paths[name]), places
    places.append(f'package_paths (no entry "{name}")')
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    for prefix in prefixes:
        marker = os.path.join(prefix, 'share', 'ament_index', 'resource_index', 'packages', name)
        if os.path.isfile(marker):
            return os.path.join(prefix, 'share', name), places
        places.append(f'ament index {marker}')
    if not prefixes:
        places.append('ament index (AMENT_PREFIX_PATH is not set)')
    roots = [p for p in os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep) if p]
    for root in roots:
        found = _crawl(os.path.abspath(root)).get(name)
        if found is not None:
            return found, places
        places.append(f'ROS_PACKAGE_PATH entry {root}')
    if not roots:
        places.append('ROS_PACKAGE_PATH (not set)')
    if name == 'collision_sensor':
        from collision_sensor.model.share import share_directory
        try:
            return share_directory(), places
        except FileNotFoundError:
            places.append('the share directory of collision_sensor (not found)')
    return None, places


def package_path_fix(name: str) -> str:
    """Return how to give the directory of package ``name``, in each place that takes it: the
    tools' command line, the node's ``package_paths`` parameter, the Python API (a loader
    cannot know which of them called it)."""
    return (f'give the directory of package "{name}": --package-path {name}=DIR (command '
            f'line), package_paths: ["{name}=DIR"] (node parameter), or package_paths='
            f'{{"{name}": DIR}} (Python); or source the workspace that installs it')


def package_name_of(directory: str) -> Optional[str]:
    """Return the ``<name>`` of ``directory/package.xml``, or None if it has none."""
    manifest = os.path.join(directory, 'package.xml')
    if not os.path.isfile(manifest):
        return None
    try:
        parser = etree.XMLParser(resolve_entities=False, no_network=True)
        name = etree.parse(manifest, parser).getroot().findtext('name')
    except (etree.XMLSyntaxError, OSError):
        return None
    return name.strip() if name else None


@functools.lru_cache(maxsize=64)
def _crawl(root: str) -> dict:
    """``{package name: directory}`` of the packages under ``root`` (first found wins).

    Cached per root for the process: one crawl serves every mesh of a robot.
    """
    found = {}
    for directory, is_package in _walk(root, 0):
        name = package_name_of(directory) if is_package else None
        if name is not None:
            found.setdefault(name, directory)
    return found


def _walk(directory, depth):
    if depth > _CRAWL_DEPTH or not os.path.isdir(directory):
        return
    try:
        entries = sorted(os.listdir(directory))
    except OSError:
        return
    if any(marker in entries for marker in _IGNORE_MARKERS):
        return
    is_package = 'package.xml' in entries
    yield directory, is_package
    if is_package:
        return  # rospack does not look for packages inside a package
    for entry in entries:
        path = os.path.join(directory, entry)
        if not entry.startswith('.') and os.path.isdir(path):
            yield from _walk(path, depth + 1)
