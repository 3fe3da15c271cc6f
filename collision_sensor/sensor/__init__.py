"""The collision sensor without ROS: :class:`Sensor` takes joint states (and scene changes,
failures of other sources) and answers each with a :class:`Verdict`; the node puts it on the
ROS graph."""
from collision_sensor.sensor.sensor import (  # noqa: F401
    NEW_MOTION_REASONS, Failure, NearPair, Sensor, Verdict, Zone)
