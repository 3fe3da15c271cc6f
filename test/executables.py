"""Where the package's console scripts are, in whichever layout the tested package came from.

- colcon (ament_python) installs them into ``<prefix>/lib/collision_sensor/``, where
  ``ros2 run`` looks, with the package in ``<prefix>/lib/pythonX.Y/site-packages/``;
- pip (and ``make``, an editable install into ``.venv``) puts them next to the interpreter.

The prefix is the one the imported ``collision_sensor`` belongs to, so a test never runs the
scripts of another install than the package it imports.
"""
import os
import sys

import collision_sensor

PACKAGE = 'collision_sensor'


def _colcon_prefix():
    """Return ``<prefix>`` when collision_sensor was imported from a colcon install, else None."""
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
