"""Where a tool finds its sibling executables: the script of its own install, else this
interpreter with ``-m`` (the installed layouts are run for real in ``test/test_packaging.py``:
a wheel in a venv, a colcon workspace)."""
import os
import subprocess
import sys

import pytest

from collision_sensor.ros import console_scripts


def test_a_script_beside_the_interpreter_is_run(tmp_path, monkeypatch):
    monkeypatch.setattr(console_scripts, '_colcon_prefix', lambda: None)
    monkeypatch.setattr(console_scripts, '_user_scripts', lambda: None)
    script = tmp_path / 'collision_sensor_node'
    script.write_text('#!/bin/sh\n')
    script.chmod(0o755)
    monkeypatch.setattr(sys, 'executable', str(tmp_path / 'python'))
    assert console_scripts.console_command('collision_sensor_node') == [str(script)]


@pytest.mark.parametrize('name', sorted(console_scripts.MODULES))
def test_without_an_installed_script_the_module_runs_with_this_interpreter(name, tmp_path,
                                                                            monkeypatch):
    monkeypatch.setattr(console_scripts, '_colcon_prefix', lambda: None)
    monkeypatch.setattr(console_scripts, '_user_scripts', lambda: None)
    real = sys.executable
    monkeypatch.setattr(sys, 'executable', str(tmp_path / 'python'))   # nothing beside it
    command = console_scripts.console_command(name)
    assert command == [str(tmp_path / 'python'), '-m', console_scripts.MODULES[name]]
    if name == 'collision_sensor_node':
        return      # it takes ROS arguments only (no --help): it would start a node
    # The command works, as a process (cwd: not the source tree, whose package has no engine
    # under colcon test).
    run = subprocess.run([real] + command[1:] + ['--help'], capture_output=True, text=True,
                         timeout=120, cwd=str(tmp_path), env=dict(os.environ))
    assert run.returncode == 0, run.stderr
    assert f'usage: {name}' in run.stdout, run.stdout
