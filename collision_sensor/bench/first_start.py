"""First-start cost: import, load the Panda, first check, with a cold and then a warm kernel cache.

``python -m collision_sensor.bench.first_start``

Each start runs in a fresh interpreter with ``NUMBA_CACHE_DIR`` pointed at one new temporary
directory: the first start compiles every kernel into it, the second loads them from it.
"""
import os
import subprocess
import sys
import tempfile

_START = '''
import time
t0 = time.perf_counter()
import numpy as np
from collision_sensor import CollisionChecker
from collision_sensor.example_robots import example_robot
robot = example_robot('panda')
checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                     package_paths=robot.package_paths)
t1 = time.perf_counter()
checker.check(np.zeros(len(checker.joint_names)))
t2 = time.perf_counter()
checker.update(np.full(len(checker.joint_names), 0.1))
t3 = time.perf_counter()
print(f'{t1 - t0:.1f} {t2 - t1:.1f} {t3 - t2:.2f} {t3 - t0:.1f}')
'''


def main(argv=None) -> int:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        print('start  import+load s  first check s  first update s  total s')
        for label in ('cold', 'warm'):
            out = subprocess.run([sys.executable, '-c', _START], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            print(f'{label:5}  {out[0]:>13}  {out[1]:>13}  {out[2]:>14}  {out[3]:>7}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
