"""Where this package's console scripts are, in whichever layout the package was installed.

- colcon (ament_python) installs them into ``<prefix>/lib/collision_sensor/``, where
  ``ros2 run`` looks, with the package in ``<prefix>/lib/pythonX.Y/site-packages/``;
- pip (and ``make``, an editable install into ``.venv``) puts them next to the interpreter.

The prefix is the one this very package was imported from, so a tool (or a test) never starts
the node of another install than the code it runs.
"""
import os
import sys
from typing import List, Optional

import collision_sensor

PACKAGE = 'collision_sensor'
#: Console script -> the module whose ``main`` it runs (``python -m`` when no script is found).
MODULES = {'collision_sensor_node': 'collision_sensor.ros.node'}


def _colcon_prefix() -> Optional[str]:
    """Return ``<prefix>`` when this package was imported from a colcon install, else None."""
    site_packages = os.path.dirname(os.path.dirname(os.path.abspath(collision_sensor.__file__)))
    lib_python = os.path.dirname(site_packages)
    if os.path.basename(site_packages) != 'site-packages' or \
            not os.path.basename(lib_python).startswith('python'):
        return None
    prefix = os.path.dirname(os.path.dirname(lib_python))
    return prefix if os.path.isdir(os.path.join(prefix, 'lib', PACKAGE)) else None


def console_script(name: str) -> str:
    """Return the path of console script ``name`` (``collision_sensor_node``, ...)."""
    prefix = _colcon_prefix()
    if prefix is not None:
        return os.path.join(prefix, 'lib', PACKAGE, name)
    return os.path.join(os.path.dirname(sys.executable), name)


def console_command(name: str) -> List[str]:
    """Return the command that runs console script ``name``: the script where it is installed,
    else this interpreter with ``-m`` and the script's module (a plain source checkout)."""
    script = console_script(name)
    return [script] if os.path.exists(script) else [sys.executable, '-m', MODULES[name]]
