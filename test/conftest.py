"""Shared fixtures: the real robots of example-robot-data, and a DDS setup that stays local."""
import os
import random

import pytest

# DDS traffic of the integration tests stays in shared memory on this machine, in a domain of
# this run's own; .ci/run and the Makefile set both, this covers a bare `pytest`.
os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))


@pytest.fixture(scope='session')
def erd_share():
    """Directory ``.../share/example-robot-data`` (holds ``robots/``)."""
    from collision_sensor.example_robots import example_robot_data_dir
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
