"""The pytest plugin (entry point ``pytest11``: loaded by pytest wherever the package is
installed): the ``collision_sensor`` fixture.

Loading it imports nothing of ROS; the fixture does, when a test asks for it.
"""
import pytest

#: Warnings the ROS 2 wheels raise on import, whoever uses them (rosidl's parser imports lark,
#: which imports modules Python 3.11 deprecates): not the test's business.
ROS_IMPORT_WARNINGS = (
    "ignore:module 'sre_parse' is deprecated:DeprecationWarning",
    "ignore:module 'sre_constants' is deprecated:DeprecationWarning",
)


def pytest_configure(config):
    for line in ROS_IMPORT_WARNINGS:
        config.addinivalue_line('filterwarnings', line)


@pytest.fixture
def collision_sensor():
    """Start the sensor in this process: ``collision_sensor(robot, scene=, parameters=, ...)``
    returns a started :class:`~collision_sensor.testing.sensor.SensorUnderTest` (its options);
    every sensor started is stopped at the end of the test."""
    from collision_sensor.testing.sensor import SensorUnderTest
    started = []

    def start(robot='panda', **options):
        sensor = SensorUnderTest(robot, **options)
        started.append(sensor)
        return sensor.start()

    yield start
    for sensor in reversed(started):
        sensor.close()
