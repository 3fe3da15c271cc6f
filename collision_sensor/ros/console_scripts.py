"""Where this package's console scripts are, in whichever layout the package was installed.

A tool that starts another (``collision_sensor_demo`` starts ``collision_sensor_node``) runs
the sibling of the install it was itself imported from, never one found on ``PATH``, which may
belong to another install (a workspace's venv, the project's ``.venv``):

- colcon (ament_python) installs the scripts into ``<prefix>/lib/collision_sensor/``, where
  ``ros2 run`` looks, with the package in ``<prefix>/lib/pythonX.Y/site-packages/``;
  ``install/setup.sh`` does not put that directory on ``PATH``;
- pip (``make``'s editable install into ``.venv``, a wheel into a venv or the system) puts them
  next to the interpreter;
- ``pip install --user`` puts them in the user scheme's scripts directory (``~/.local/bin``);
- anywhere else (a colcon ``--symlink-install``, whose package is the source tree; scripts
  not installed) the command is this interpreter with ``-m`` and the script's module, which
  imports the package from where this process did.
"""
import os
import site
import sys
import sysconfig
from typing import List, Optional

import collision_sensor

PACKAGE = 'collision_sensor'
#: Console script -> the module whose ``main`` it runs (``python -m`` when no script is found).
#: setup.py's entry points name the same modules (test/test_packaging.py checks it).
MODULES = {
    'collision_sensor_node': 'collision_sensor.ros.main',
    'collision_sensor_play': 'collision_sensor.ros.player',
    'collision_sensor_check': 'collision_sensor.tools.offline_check',
    'collision_sensor_acm': 'collision_sensor.tools.acm',
    'collision_sensor_demo': 'collision_sensor.ros.demo',
    'collision_sensor_ctl': 'collision_sensor.ros.ctl',
}


def _site_packages() -> str:
    """The directory this package was imported from (holds ``collision_sensor/``)."""
    return os.path.dirname(os.path.dirname(os.path.abspath(collision_sensor.__file__)))


def _colcon_prefix() -> Optional[str]:
    """Return ``<prefix>`` when this package was imported from a colcon install, else None."""
    site_packages = _site_packages()
    lib_python = os.path.dirname(site_packages)
    if os.path.basename(site_packages) != 'site-packages' or \
            not os.path.basename(lib_python).startswith('python'):
        return None
    prefix = os.path.dirname(os.path.dirname(lib_python))
    return prefix if os.path.isdir(os.path.join(prefix, 'lib', PACKAGE)) else None


def _user_scripts() -> Optional[str]:
    """Return the user scheme's scripts directory if this package is a ``--user`` install."""
    user_site = site.getusersitepackages() if site.ENABLE_USER_SITE else None
    if not user_site or os.path.realpath(_site_packages()) != os.path.realpath(user_site):
        return None
    scheme = f'{os.name}_user' if os.name != 'posix' else 'posix_user'
    try:
        return sysconfig.get_path('scripts', scheme)
    except KeyError:
        return None


def console_script(name: str) -> str:
    """Return where console script ``name`` (``collision_sensor_node``, ...) is installed in
    this package's layout (the path may not exist: see :func:`console_command`)."""
    prefix = _colcon_prefix()
    if prefix is not None:
        return os.path.join(prefix, 'lib', PACKAGE, name)
    user = _user_scripts()
    if user is not None:
        return os.path.join(user, name)
    return os.path.join(os.path.dirname(sys.executable), name)


def console_command(name: str) -> List[str]:
    """Return the command that runs console script ``name``: the script where it is installed,
    else this interpreter with ``-m`` and the script's module."""
    script = console_script(name)
    if os.path.isfile(script) and os.access(script, os.X_OK):
        return [script]
    return [sys.executable, '-m', MODULES[name]]
