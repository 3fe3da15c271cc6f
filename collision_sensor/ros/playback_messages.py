"""The player's messages: rclpy messages built from what a bag holds (``rosbags`` messages,
or any object with the same fields), and header stamps from recorded times.
"""
import numpy as np
from geometry_msgs.msg import Point
from sensor_msgs.msg import PointCloud2, PointField
from visualization_msgs.msg import Marker


def marker_message(marker) -> Marker:
    """Return an rclpy Marker with the fields the node reads taken from ``marker`` (a rosbags
    message read from a bag, or any object with visualization_msgs/Marker's fields)."""
    msg = Marker(ns=str(marker.ns), id=int(marker.id), type=int(marker.type),
                 action=int(marker.action), text=str(getattr(marker, 'text', '')),
                 mesh_resource=str(getattr(marker, 'mesh_resource', '')))
    msg.header.frame_id = str(marker.header.frame_id)
    position, orientation = marker.pose.position, marker.pose.orientation
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (
        float(position.x), float(position.y), float(position.z))
    msg.pose.orientation.x, msg.pose.orientation.y = float(orientation.x), float(orientation.y)
    msg.pose.orientation.z, msg.pose.orientation.w = float(orientation.z), float(orientation.w)
    msg.scale.x, msg.scale.y, msg.scale.z = (float(marker.scale.x), float(marker.scale.y),
                                             float(marker.scale.z))
    color = getattr(marker, 'color', None)
    if color is not None:
        msg.color.r, msg.color.g, msg.color.b, msg.color.a = (
            float(color.r), float(color.g), float(color.b), float(color.a))
    msg.points = [Point(x=float(p.x), y=float(p.y), z=float(p.z))
                  for p in getattr(marker, 'points', ())]
    return msg


def cloud_message(msg, stamp) -> PointCloud2:
    """Return an rclpy PointCloud2 with the fields of ``msg`` (a rosbags message read from a
    bag), stamped ``stamp``; the data are copied once."""
    out = PointCloud2(height=int(msg.height), width=int(msg.width),
                      fields=[PointField(name=str(f.name), offset=int(f.offset),
                                         datatype=int(f.datatype), count=int(f.count))
                              for f in msg.fields],
                      is_bigendian=bool(msg.is_bigendian), point_step=int(msg.point_step),
                      row_step=int(msg.row_step), is_dense=bool(msg.is_dense))
    out.header.stamp = stamp
    out.header.frame_id = str(msg.header.frame_id)
    out.data = np.asarray(msg.data, dtype=np.uint8).tobytes()
    return out


def stamp_from_seconds(seconds: float):
    """Return ``seconds`` as a ``builtin_interfaces/Time`` (rounded to the nanosecond)."""
    from builtin_interfaces.msg import Time
    nanoseconds = int(round(seconds * 1e9))
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)
