"""Shared fixtures: the real robots of example-robot-data, and a DDS setup that stays local."""
import glob
import importlib.machinery
import os
import random
import sys

import pytest

SOURCE_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _test_the_installed_package():
    """Under ``colcon test``, import collision_sensor from the install space, not the source.

    colcon runs ``python -m pytest`` in the package's source directory, which puts that
    directory first on ``sys.path``; its ``collision_sensor`` has no compiled engine (colcon
    builds the extension into ``build/`` and installs it), while the installed copy, on
    ``PYTHONPATH`` from the workspace's setup files, has. Drop the source directory then. With
    ``make test`` (an editable install, the engine built in the source tree) nothing changes.
    """
    if glob.glob(os.path.join(SOURCE_ROOT, 'collision_sensor', 'engine', '_engine*')):
        return
    elsewhere = [entry for entry in sys.path
                 if os.path.abspath(entry or os.curdir) != SOURCE_ROOT]
    if importlib.machinery.PathFinder.find_spec('collision_sensor', elsewhere) is not None:
        # The source directory last: its benchmarks/ (never installed) stay importable.
        sys.path[:] = elsewhere + [SOURCE_ROOT]
    # else: not installed anywhere; importing the source tree says how to build the engine


def _benchmarks_importable():
    """Put the source directory on ``sys.path`` (last) if it is missing: ``benchmarks/`` is
    not installed, and a bare ``pytest`` (not ``python -m pytest``) does not add it."""
    if not any(os.path.abspath(entry or os.curdir) == SOURCE_ROOT for entry in sys.path):
        sys.path.append(SOURCE_ROOT)


_test_the_installed_package()
_benchmarks_importable()

# DDS traffic of the integration tests stays in shared memory on this machine, in a domain of
# this run's own; .ci/run and the Makefile set both, this covers a bare `pytest`.
os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))
#: Fast DDS maps a domain to UDP ports 7400 + 250 * domain + ...: 232 is the last that fits.
LAST_DOMAIN = 232


def worker_domain(base: int, worker: str) -> int:
    """Return the DDS domain of pytest-xdist worker ``worker`` (``gw0``, ``gw1``, ...) in a run
    whose domain is ``base``: ``base`` for the first, 100 further on for each next (wrapping
    within 1..232), so that parallel workers never see each other's nodes, not even on
    the global ``/diagnostics``."""
    index = int(worker[2:]) if worker.startswith('gw') and worker[2:].isdigit() else 0
    return 1 + (base - 1 + 100 * index) % LAST_DOMAIN


if os.environ.get('PYTEST_XDIST_WORKER'):
    os.environ['ROS_DOMAIN_ID'] = str(worker_domain(int(os.environ['ROS_DOMAIN_ID']),
                                                    os.environ['PYTEST_XDIST_WORKER']))
    # (the controller's value, inherited, is the first worker's domain, not this one's)
    os.environ['COLLISION_SENSOR_TEST_DOMAIN'] = os.environ['ROS_DOMAIN_ID']
# The collision_sensor fixture's sensors too (collision_sensor.testing picks a domain of its
# own otherwise): set, not defaulted, since an xdist worker inherits the controller's value
# and must follow its own domain.
os.environ['COLLISION_SENSOR_TEST_DOMAIN'] = os.environ['ROS_DOMAIN_ID']


@pytest.fixture(scope='session')
def erd_share():
    """Directory ``.../share/example-robot-data`` (holds ``robots/``)."""
    from collision_sensor.model.example_robots import example_robot_data_dir
    return example_robot_data_dir()


@pytest.fixture(scope='session')
def erd_package_paths(erd_share):
    """Package mapping that resolves ``package://example-robot-data/...`` mesh URIs."""
    return {'example-robot-data': erd_share}


@pytest.fixture(scope='session')
def panda_urdf(erd_share):
    return os.path.join(erd_share, 'robots', 'panda_description', 'urdf', 'panda.urdf')


@pytest.fixture(scope='session')
def panda_srdf(erd_share):
    return os.path.join(erd_share, 'robots', 'panda_description', 'srdf', 'panda.srdf')


@pytest.fixture(scope='session')
def ur5_urdf(erd_share):
    return os.path.join(erd_share, 'robots', 'ur_description', 'urdf', 'ur5_robot.urdf')


@pytest.fixture(scope='session')
def ur5_srdf(erd_share):
    return os.path.join(erd_share, 'robots', 'ur_description', 'srdf', 'ur5.srdf')
