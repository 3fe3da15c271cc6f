"""The pytest plugin (entry point ``pytest11``: loaded by pytest wherever the package is
installed): the ``collision_sensor`` fixture.

Loading it imports nothing of ROS; the fixture does, when a test asks for it.
"""
import pytest


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
