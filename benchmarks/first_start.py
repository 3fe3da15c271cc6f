"""First-start cost: import, load the Panda, first verdict, from cold caches and then warm.

``python -m benchmarks.first_start``

Each start is a fresh interpreter running the same script (import, load the Panda with its
SRDF, one ``check``, one ``update``), in three conditions:

* ``cold``: no bytecode cache for any module (``PYTHONPYCACHEPREFIX`` pointed at a new empty
  directory): numpy, lxml, PyYAML and this package are all compiled from source first;
* ``fresh``: as after a fresh install: this package's modules have no bytecode yet (a copy of
  the package, with its built engine, in a new directory), everything else as installed;
* ``warm``: that copy again, now with the bytecode the ``fresh`` start wrote.

The engine is C++ compiled at install time: no start compiles any of it.
"""
import os
import shutil
import subprocess
import sys
import tempfile

import collision_sensor

_START = '''
import time
t0 = time.perf_counter()
import numpy as np
from collision_sensor import CollisionChecker
from collision_sensor.model.example_robots import example_robot
robot = example_robot('panda')
checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                     package_paths=robot.package_paths)
t1 = time.perf_counter()
checker.check(np.zeros(len(checker.joint_names)))
t2 = time.perf_counter()
checker.update(np.full(len(checker.joint_names), 0.1))
t3 = time.perf_counter()
print(f'{t1 - t0:.2f} {t2 - t1:.4f} {t3 - t2:.4f} {t3 - t0:.2f}')
'''


def _start(env) -> list:
    return subprocess.run([sys.executable, '-c', _START], env=env, check=True,
                          capture_output=True, text=True).stdout.split()


def main(argv=None) -> int:
    """Print the three starts; return 1 if a target is missed (cold >= 3 s, fresh > 2 warm)."""
    base = dict(os.environ)
    base.pop('PYTHONDONTWRITEBYTECODE', None)
    base.pop('PYTHONPYCACHEPREFIX', None)
    rows = {}
    with tempfile.TemporaryDirectory() as work:
        cache = os.path.join(work, 'pycache')
        rows['cold'] = _start(dict(base, PYTHONPYCACHEPREFIX=cache))
        copy = os.path.join(work, 'package')
        shutil.copytree(os.path.dirname(collision_sensor.__file__),
                        os.path.join(copy, 'collision_sensor'),
                        ignore=shutil.ignore_patterns('__pycache__'))
        path = os.pathsep.join([copy] + [p for p in [base.get('PYTHONPATH')] if p])
        for label in ('fresh', 'warm'):
            rows[label] = _start(dict(base, PYTHONPATH=path))
    print('start  import+load s  first check s  first update s  total s')
    for label, out in rows.items():
        print(f'{label:5}  {out[0]:>13}  {out[1]:>13}  {out[2]:>14}  {out[3]:>7}')
    cold, fresh, warm = (float(rows[k][3]) for k in ('cold', 'fresh', 'warm'))
    print(f'targets: cold start < 3 s: {"PASS" if cold < 3 else "MISS"} ({cold:.2f} s); '
          f'fresh install within 2x of warm: {"PASS" if fresh <= 2 * warm else "MISS"} '
          f'({fresh:.2f} vs {warm:.2f} s)')
    return 0 if cold < 3 and fresh <= 2 * warm else 1


if __name__ == '__main__':
    raise SystemExit(main())
