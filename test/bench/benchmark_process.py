"""Run a module of ``benchmarks/`` (not installed: it lives in the source tree) as a process.

The benchmarks import the package as installed; the source tree's root goes at the end of
``PYTHONPATH`` so that ``benchmarks`` is found there while ``collision_sensor`` still comes from
wherever this test imports it (the editable install, or colcon's install space).
"""
import os
import subprocess
import sys

SOURCE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def benchmark_env() -> dict:
    """Return this process's environment with the source root last on ``PYTHONPATH``."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [entry for entry in env.get('PYTHONPATH', '').split(os.pathsep) if entry]
        + [SOURCE_ROOT])
    return env


def run_benchmark(module: str, *args, cwd, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run ``python -m <module> <args>`` in ``cwd``; return the finished process (text)."""
    return subprocess.run([sys.executable, '-m', module, *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, cwd=str(cwd), env=benchmark_env())
