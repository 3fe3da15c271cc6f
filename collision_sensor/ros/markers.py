"""``~/markers`` (``publish_markers``): the boxes of colliding bodies, the scene objects and the
near pairs' nearest points, as ``visualization_msgs/MarkerArray`` in the robot's root link frame;
and the boxes of the links in contact at the last planned trajectory's first contact
(namespace ``trajectory_contact``, :mod:`.trajectory_source`) until the next trajectory.
"""
import math
import time
from typing import Dict, NamedTuple, Optional

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_CYLINDER, SOLID_SPHERE

MARKER_PERIOD = 0.1         # s between marker updates while the colliding set stays the same
MARKER_COLOR = ColorRGBA(r=1.0, g=0.0, b=0.0, a=0.6)
NEAR_COLOR = ColorRGBA(r=1.0, g=0.55, b=0.0, a=0.9)   # nearest-point segments
TEXT_COLOR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=0.9)
SEGMENT_WIDTH = 0.004       # m, line width of the nearest-point segments
CONTACT_DIAMETER = 0.02     # m, the contact points' spheres
TEXT_HEIGHT = 0.02          # m
#: Scene objects on ~/markers: fixed in the world, attached to a link, colliding.
WORLD_OBJECT_COLOR = ColorRGBA(r=0.6, g=0.6, b=0.65, a=0.8)
ATTACHED_OBJECT_COLOR = ColorRGBA(r=0.2, g=0.8, b=0.3, a=0.8)
COLLIDING_OBJECT_COLOR = ColorRGBA(r=1.0, g=0.1, b=0.1, a=0.9)
#: A planned trajectory's first contact.
TRAJECTORY_COLOR = ColorRGBA(r=1.0, g=0.0, b=1.0, a=0.6)
TRAJECTORY_NS = 'trajectory_contact'
#: A mesh object with more triangles is drawn as its box on ~/markers.
MARKER_MAX_TRIANGLES = 20_000
#: A point cloud's voxels drawn: those within this (m) of a link's boxes, at most
#: MARKER_MAX_VOXELS of them (the nearest first).
VOXEL_MARKER_RANGE = 0.15
MARKER_MAX_VOXELS = 5000
CLOUD_COLOR = ColorRGBA(r=0.2, g=0.6, b=1.0, a=0.6)


def quaternion_from_matrix(R) -> tuple:
    """Return the unit quaternion ``(x, y, z, w)`` of a rotation matrix (Shepperd's method).

    :param R: (3, 3) float, a rotation matrix.
    """
    trace = R[0][0] + R[1][1] + R[2][2]
    # Branch on the largest of w, x, y, z so the square root is of a value >= 1/4 (stable).
    if trace > max(R[0][0], R[1][1], R[2][2]):
        s = 2.0 * math.sqrt(1.0 + trace)
        return ((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s,
                0.25 * s)
    if R[0][0] >= R[1][1] and R[0][0] >= R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[0][0] - R[1][1] - R[2][2])
        return (0.25 * s, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s,
                (R[2][1] - R[1][2]) / s)
    if R[1][1] >= R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[1][1] - R[0][0] - R[2][2])
        return ((R[0][1] + R[1][0]) / s, 0.25 * s, (R[1][2] + R[2][1]) / s,
                (R[0][2] - R[2][0]) / s)
    s = 2.0 * math.sqrt(1.0 + R[2][2] - R[0][0] - R[1][1])
    return ((R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, 0.25 * s,
            (R[1][0] - R[0][1]) / s)


class CheckerView:
    """What the markers read of a checker, copied at one moment (the sensor held still): its
    objects, attachments, paddings, clouds' voxels, and the boxes of the bodies drawn.

    :param colliding: the bodies in contact (their boxes are drawn).
    """

    def __init__(self, checker, colliding):
        self.object_names = checker.object_names
        self.attachments = checker.attachments
        self.scene_objects = checker.scene_objects
        self.paddings = checker.paddings
        self.point_cloud_sources = checker.point_cloud_sources
        self.link_names = checker.link_names
        self._voxels = {source: checker.cloud_voxels(source)
                        for source in self.point_cloud_sources}
        # Links (for the clouds' nearby voxels), the bodies in contact, big meshes' boxes.
        names = set(colliding) | set(self.object_names)
        if self.point_cloud_sources:
            names |= set(self.link_names)
        self._boxes = {}
        for box in checker.collision_boxes(sorted(names)):
            self._boxes.setdefault(box[0], []).append(box)

    def collision_boxes(self, names):
        return [box for name in names for box in self._boxes.get(name, ())]

    def cloud_voxels(self, source):
        return self._voxels[source]


class NearRecord(NamedTuple):
    """A near pair as the markers draw it (points as arrays)."""

    link_a: str
    link_b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray


def _point(point) -> Point:
    return Point(x=float(point[0]), y=float(point[1]), z=float(point[2]))


class MarkerPublisher:
    """Publish ``~/markers`` (``publish_markers``): the sensor's verdicts shown, looked at on
    the node's poll timer.

    :param node: the node that owns the publisher.
    :param enabled: ``publish_markers``.
    :ivar scene_changed: set when the scene's objects changed (the markers show them again).
    """

    def __init__(self, node, enabled: bool):
        self._node = node
        self._publisher = None
        self.root_frame = ''
        self._content = ()      # (colliding links, near pairs) the markers show
        self._serial = None     # the held verdict's serial they show
        self._time = 0.0
        self._shapes: Dict[str, tuple] = {}   # object: (its vertices, its marker's shape)
        self.scene_changed = True       # the scene file's objects, on the first verdict
        self._trajectory = []   # the last trajectory's first-contact markers
        self.enable(enabled)

    @property
    def enabled(self) -> bool:
        return self._publisher is not None

    def enable(self, enabled: bool) -> None:
        """Advertise ``~/markers`` (``publish_markers`` true), or clear the markers and withdraw
        it."""
        if enabled and self._publisher is None:
            self._publisher = self._node.create_publisher(MarkerArray, '~/markers', 10)
            self.scene_changed = True
        elif not enabled and self._publisher is not None:
            self.clear(self.root_frame)
            self._node.destroy_publisher(self._publisher)
            self._publisher = None

    def forget(self, root_frame: str) -> None:
        """A new model: clear what the old one showed."""
        if self.enabled:
            self.clear(root_frame)
        self.root_frame = root_frame
        self.scene_changed = True
        self._serial = None

    def refresh(self, sensor) -> None:
        """Show the verdict the sensor holds, when it changed (or at most every MARKER_PERIOD
        while something collides or is near, or an attached object moves with the robot)."""
        if not self.enabled:
            return
        held = sensor.held()
        if held is None or (held['serial'] == self._serial and not self.scene_changed):
            return
        # What the markers show, read with the checker held still (poses, objects, voxels);
        # the messages are built and published after, without holding the sensor.
        pairs = [tuple(pair) for pair in held['now']]
        zone = held['zone']
        records = [] if zone is None else [
            NearRecord(a, b, d, np.array(pa), np.array(pb)) for a, b, d, pa, pb in zone['records']]
        self._serial = held['serial']
        with sensor.changing() as checker:
            if checker is None or not self._due(checker, pairs, records):
                return
            view = CheckerView(checker, {name for pair in pairs for name in pair})
        sec, nanosec = held['stamp']
        self.publish(view, Time(sec=sec, nanosec=nanosec), pairs, records)

    def publish(self, checker, stamp, pairs, records=()) -> None:
        """Publish the boxes of the colliding bodies, the scene objects and, with
        ``warning_distance``, the near pairs' nearest points: when any of them changes, and at
        most every MARKER_PERIOD while something collides or is near, or an attached object
        moves with the robot.

        :param checker: the checker that gave the verdict (at the state it describes).
        :param stamp: the verdict's stamp.
        :param pairs: the colliding pairs.
        :param records: the warning zone's near pairs (``link_a``, ``link_b``, ``distance``,
            ``point_a``, ``point_b``).
        """
        colliding = tuple(sorted({name for pair in pairs for name in pair}))
        if not colliding and not records and not checker.object_names:
            self.clear()
            return
        if not self._due(checker, pairs, records):
            return
        self._content = (colliding, tuple((r.link_a, r.link_b) for r in records))
        self._time, self.scene_changed = time.monotonic(), False
        # DELETEALL first: bodies that stopped colliding lose their boxes in the same message.
        markers = [Marker(action=Marker.DELETEALL)]
        for index, (name, T_world_box, half) in enumerate(checker.collision_boxes(colliding)):
            marker = self._marker(name, index, Marker.CUBE, T_world_box, stamp, MARKER_COLOR)
            marker.scale.x, marker.scale.y, marker.scale.z = (2.0 * float(h) for h in half)
            markers.append(marker)
        attached = checker.attachments
        for index, obj in enumerate(checker.scene_objects):
            color = (COLLIDING_OBJECT_COLOR if obj.name in colliding else
                     ATTACHED_OBJECT_COLOR if obj.name in attached else WORLD_OBJECT_COLOR)
            markers.append(self._object_marker(checker, obj, index, stamp, color))
        markers.extend(self._cloud_markers(checker, stamp, colliding))
        markers.extend(self._proximity_markers(checker, stamp, records))
        markers.extend(self._trajectory)   # DELETEALL took them too
        self._publisher.publish(MarkerArray(markers=markers))

    def _due(self, checker, pairs, records) -> bool:
        """Whether what the markers show changed (or, while something collides or is near, or
        an attached object moves with the robot, MARKER_PERIOD passed)."""
        colliding = tuple(sorted({name for pair in pairs for name in pair}))
        near = tuple((r.link_a, r.link_b) for r in records)
        if not colliding and not near and not checker.object_names:
            return bool(self._content)      # to clear what is shown
        moving = colliding or near or checker.attachments
        return self.scene_changed or (colliding, near) != self._content or (
            bool(moving) and time.monotonic() - self._time >= MARKER_PERIOD)

    def trajectory_contact(self, boxes, stamp, text: str) -> None:
        """Show ``boxes`` (``(name, T_world_box, half)``: the links at a planned trajectory's
        first contact) with ``text`` above the first, instead of the last trajectory's; no
        boxes: clear them."""
        markers = [Marker(ns=TRAJECTORY_NS, id=m.id, action=Marker.DELETE)
                   for m in self._trajectory]
        for marker in markers:
            marker.header.frame_id = self.root_frame
        shown = []
        for index, (name, T_world_box, half) in enumerate(boxes):
            marker = self._marker(TRAJECTORY_NS, index, Marker.CUBE, T_world_box, stamp,
                                  TRAJECTORY_COLOR)
            marker.scale.x, marker.scale.y, marker.scale.z = (2.0 * float(h) for h in half)
            marker.text = name
            shown.append(marker)
        if shown:
            at = np.array(boxes[0][1], dtype=float)
            at[:3, :3] = np.eye(3)
            at[2, 3] += float(np.linalg.norm(boxes[0][2])) + TEXT_HEIGHT
            label = self._marker(TRAJECTORY_NS, len(shown), Marker.TEXT_VIEW_FACING, at, stamp,
                                 TEXT_COLOR)
            label.scale.z = TEXT_HEIGHT
            label.text = text
            shown.append(label)
        self._trajectory = shown
        if markers or shown:
            self._publisher.publish(MarkerArray(markers=markers + shown))

    def _cloud_markers(self, checker, stamp, colliding) -> list:
        """Each point cloud's voxels near the robot (within VOXEL_MARKER_RANGE of a link's
        boxes), as one CUBE_LIST (ns ``cloud/<source>``; red when it is in contact)."""
        sources = checker.point_cloud_sources
        if not sources:
            return []
        boxes = checker.collision_boxes(checker.link_names)
        markers = []
        for index, source in enumerate(sources):
            centres, size = checker.cloud_voxels(source)
            if not len(centres) or not boxes:
                continue
            gap = np.full(len(centres), np.inf)
            for _, T, half in boxes:
                local = np.abs((centres - T[:3, 3]) @ T[:3, :3]) - half
                gap = np.minimum(gap, np.linalg.norm(np.maximum(local, 0.0), axis=1))
            near = np.flatnonzero(gap <= VOXEL_MARKER_RANGE + 0.5 * math.sqrt(3.0) * size)
            near = near[np.argsort(gap[near], kind='stable')[:MARKER_MAX_VOXELS]]
            if not len(near):
                continue
            name = f'cloud/{source}'
            marker = self._marker(name, index, Marker.CUBE_LIST, np.eye(4), stamp,
                                  COLLIDING_OBJECT_COLOR if name in colliding else CLOUD_COLOR)
            marker.scale.x = marker.scale.y = marker.scale.z = float(size)
            marker.points = [Point(x=x, y=y, z=z) for x, y, z in centres[near].tolist()]
            marker.text = name
            markers.append(marker)
        return markers

    def _proximity_markers(self, checker, stamp, records) -> list:
        """The near pairs: nearest points joined (LINE_LIST, apart pairs), the contact points
        (SPHERE_LIST) and each pair's distance as text, with the padding it includes."""
        identity = np.eye(4)
        segments = self._marker('proximity', 0, Marker.LINE_LIST, identity, stamp, NEAR_COLOR)
        segments.scale.x = SEGMENT_WIDTH
        contacts = self._marker('proximity', 1, Marker.SPHERE_LIST, identity, stamp,
                                MARKER_COLOR)
        contacts.scale.x = contacts.scale.y = contacts.scale.z = CONTACT_DIAMETER
        labels = []
        paddings = checker.paddings
        for index, r in enumerate(records):
            a, b = _point(r.point_a), _point(r.point_b)
            if r.distance > 0:
                segments.points.extend((a, b))
            else:
                contacts.points.append(a)
            padding = paddings.get(r.link_a, 0.0) + paddings.get(r.link_b, 0.0)
            at = np.eye(4)
            at[:3, 3] = 0.5 * (r.point_a + r.point_b)
            label = self._marker('proximity/distance', index, Marker.TEXT_VIEW_FACING, at,
                                 stamp, TEXT_COLOR)
            label.scale.z = TEXT_HEIGHT
            label.text = (f'{r.link_a}:{r.link_b} {1e3 * r.distance:.1f} mm'
                          + (f' (padding {1e3 * padding:g} mm)' if padding > 0 else ''))
            labels.append(label)
        return [m for m in (segments, contacts) if m.points] + labels

    def _marker(self, ns: str, index: int, kind: int, T_world, stamp, color) -> Marker:
        x, y, z, w = quaternion_from_matrix(T_world[:3, :3])
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T_world[:3, 3])
        pose.orientation.x, pose.orientation.y = x, y
        pose.orientation.z, pose.orientation.w = z, w
        marker = Marker(ns=ns, id=index, type=kind, action=Marker.ADD, pose=pose, color=color,
                        frame_locked=False)
        marker.header.frame_id = self.root_frame
        marker.header.stamp = stamp
        return marker

    def _object_marker(self, checker, obj, index: int, stamp, color) -> Marker:
        """A scene object's marker (ns ``scene_objects``): its primitive, its triangles, or for
        a mesh of more than MARKER_MAX_TRIANGLES its box."""
        cached = self._shapes.get(obj.name)
        if cached is None or cached[0] is not obj.vertices:
            solid, size = obj.solid, (1.0, 1.0, 1.0)
            kind, points, T_object_shape = Marker.TRIANGLE_LIST, [], np.eye(4)
            if solid is not None and solid.kind in (SOLID_BOX, SOLID_SPHERE, SOLID_CYLINDER):
                h = solid.size
                kind, size = {SOLID_BOX: (Marker.CUBE, (2 * h[0], 2 * h[1], 2 * h[2])),
                              SOLID_SPHERE: (Marker.SPHERE, (2 * h[0],) * 3),
                              SOLID_CYLINDER: (Marker.CYLINDER, (2 * h[0], 2 * h[0], 2 * h[1]))
                              }[solid.kind]
            elif len(obj.faces) <= MARKER_MAX_TRIANGLES:
                points = [Point(x=x, y=y, z=z)
                          for x, y, z in obj.vertices[obj.faces.ravel()].tolist()]
            else:
                _, T_world_box, half = checker.collision_boxes([obj.name])[0]
                kind, size = Marker.CUBE, tuple(2.0 * float(v) for v in half)
                T_object_shape = np.linalg.inv(obj.T_world_object) @ T_world_box
            cached = (obj.vertices, kind, size, points, T_object_shape)
            self._shapes[obj.name] = cached
        _, kind, size, points, T_object_shape = cached
        marker = self._marker('scene_objects', index, kind, obj.T_world_object @ T_object_shape,
                              stamp, color)
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in size)
        marker.points = points
        marker.text = obj.name
        return marker

    def clear(self, root_frame: Optional[str] = None) -> None:
        """Delete every marker shown (a new model, or nothing left to show but the last
        trajectory's first contact, which stays until the next trajectory or a new model)."""
        dropped = root_frame is not None and bool(self._trajectory)
        if root_frame is not None:
            self._trajectory = []
        if self._publisher is not None and (self._content or self._shapes or dropped):
            marker = Marker(action=Marker.DELETEALL)
            marker.header.frame_id = self.root_frame
            self._publisher.publish(MarkerArray(markers=[marker] + self._trajectory))
        if root_frame is not None:
            self.root_frame = root_frame
        self._content = ()
        self._shapes = {}
