"""collision_sensor: a virtual collision sensor for robots.

Importing this package never imports rclpy; the ROS node lives in ``collision_sensor.ros.node``.
"""
from collision_sensor.errors import (
    CollisionSensorError, ConfigError, EngineBuildError, EngineInputError, EngineWorkerError,
    JointStateError, LoadWarning, MeshError, PointCloudError, RobotDescriptionError, SceneError,
    SequenceError, SrdfError)

__all__ = [
    'CollisionChecker', 'CheckResult', 'ProximityRecord', 'CollisionSensorError', 'ConfigError',
    'EngineBuildError', 'EngineInputError', 'EngineWorkerError', 'JointStateError',
    'LoadWarning', 'MeshError', 'PointCloudError', 'PointCloudStats', 'RobotDescriptionError',
    'SceneError', 'SequenceError', 'SrdfError',
]


def __getattr__(name):
    # The checker loads meshes and the compiled engine; import it on first use, so that light
    # tools stay light.
    if name in ('CollisionChecker', 'CheckResult', 'ProximityRecord', 'PointCloudStats'):
        from collision_sensor.engine import checker
        return getattr(checker, name)
    raise AttributeError(f'module "collision_sensor" has no attribute "{name}"')
