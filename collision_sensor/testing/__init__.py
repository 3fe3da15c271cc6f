"""``collision_sensor.testing``: the sensor in your own tests, without launch.

A planner's or an application's test starts the sensor in its process on a robot, a scene and
parameters, sends it joint states, scene arrays, clouds and trajectories over its topics and
gets the answer that belongs to each (docs/testing.md)::

    from collision_sensor.testing import running_sensor

    with running_sensor('panda', scene='table.yaml') as sensor:
        sensor.send_joint_state(dict(zip(sensor.joint_names, q)))
        answer = sensor.send_trajectory([(2.0, goal)], arm_joints)
        assert not answer.valid and answer.kind == 'contact'

With pytest, the ``collision_sensor`` fixture (registered by the package: nothing to import)
starts them and stops each at the end of its test. Importing this package imports no ROS;
:mod:`collision_sensor.testing.sensor` (the implementation) does.
"""

#: Public names: the module each comes from.
_EXPORTED = {
    'SensorUnderTest': 'sensor', 'running_sensor': 'sensor', 'own_domain': 'sensor',
    'joint_trajectory': 'messages', 'robot_files': 'robots',
    'NoAnswer': 'outcomes', 'SceneAnswer': 'outcomes', 'CloudAnswer': 'outcomes',
    'TrajectoryOutcome': 'outcomes', 'PendingVerdict': 'outcomes',
    'PendingTrajectory': 'outcomes', 'TIMEOUT': 'outcomes',
}

__all__ = sorted(_EXPORTED)


def __getattr__(name):
    if name in _EXPORTED:
        import importlib
        return getattr(importlib.import_module(f'collision_sensor.testing.{_EXPORTED[name]}'),
                       name)
    raise AttributeError(f'module "collision_sensor.testing" has no attribute "{name}"')
