"""Messages a test sends, built from plain values."""
from typing import Mapping, Optional, Sequence, Tuple

from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint


def joint_trajectory(points, joint_names: Optional[Sequence[str]] = None,
                     stamp: Tuple[int, int] = (0, 0), frame: str = '') -> JointTrajectory:
    """Return a ``JointTrajectory`` of ``points``: ``(time_from_start, positions[, velocities[,
    accelerations]])``, positions a sequence in the order of ``joint_names`` or a dict (then
    ``joint_names`` defaults to its keys). Stamp 0 (start at once), as planners send."""
    points = list(points)
    if joint_names is None:
        if not points or not isinstance(points[0][1], Mapping):
            raise ValueError('give joint_names, or each point\'s positions as a dict')
        joint_names = list(points[0][1])
    msg = JointTrajectory(joint_names=list(joint_names))
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    msg.header.frame_id = frame
    for point in points:
        t, positions = float(point[0]), point[1]
        if isinstance(positions, Mapping):
            positions = [positions[name] for name in msg.joint_names]
        sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
        msg.points.append(JointTrajectoryPoint(
            positions=[float(v) for v in positions],
            velocities=[float(v) for v in (point[2] if len(point) > 2 else ())],
            accelerations=[float(v) for v in (point[3] if len(point) > 3 else ())],
            time_from_start=Duration(sec=sec, nanosec=nanosec)))
    return msg
