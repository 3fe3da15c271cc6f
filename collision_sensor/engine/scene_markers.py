"""The ``scene`` topic: ``visualization_msgs/MarkerArray`` messages turned into scene changes.

Pure Python, no rclpy: a marker is read through its fields (``ns``, ``id``, ``type``,
``action``, ``header.frame_id``, ``pose``, ``scale``, ``points``, ``mesh_resource``, ``text``),
so an rclpy message, a rosbags one or a test double all work. The node's scene source
(:mod:`collision_sensor.ros.scene_source`) applies the changes with
:meth:`CollisionChecker.prepare_scene_changes` and the sensor's ``apply_scene_changes``.

Rules (docs/dynamic_scene.md):

- a marker's ``(ns, id)`` names the object: ``ns`` when ``id`` is 0, else ``ns/id``; printable
  characters only, no ``:`` (pairs are written ``a:b``), at most :data:`MAX_NAME_CHARS`;
- ``ADD`` (= ``MODIFY``) adds the object, or replaces the one of that name; with the same type,
  scale, geometry source, frame and touch links as when it came through the topic last, it only
  moves it (no file read, no tree built). ``DELETE`` removes it (a name not in the scene:
  nothing happens). ``DELETEALL`` removes every object that came through the topic (objects of
  the scene file stay; one that the topic replaced came through the topic);
- shapes: ``CUBE`` (scale = edge lengths), ``SPHERE`` (scale x = y = z = diameter),
  ``CYLINDER`` (scale.x = scale.y = diameter, scale.z = length, along z), ``MESH_RESOURCE``
  (``package://`` or a file under the configured mesh roots, scaled by ``scale``),
  ``TRIANGLE_LIST`` (``points`` three at a time, scaled); primitives are solid;
- ``header.frame_id`` empty, the robot's root link or the world frame
  (:attr:`CollisionChecker.world_frames`): the pose is in the world and the object stays
  there; any other link of the robot: the object is attached to it (pose in the link's
  frame), never checked against it;
- ``text``: the links of the robot the object may touch, separated by spaces, never checked
  against it (a world object too: a table under the robot's base); a name that is not a link of
  the robot rejects the array;
- an array applies all or nothing: the first bad marker raises :class:`MarkerError` naming
  it, the reason and the fix, and nothing changes;
- caps (:class:`SceneLimits`): objects that came through the topic, triangles per object and
  in all, bytes of a mesh file; mesh files only from ``package://`` URIs (inside the package's
  directory) or under a mesh root: a publisher cannot make the node read any other file.

The lifetime, color and ``frame_locked`` of a marker are not used: an object stays until it is
deleted.
"""
import hashlib
import math
import os
import urllib.parse
from dataclasses import dataclass, field
from stat import S_ISREG
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.dynamic_scene import (
    AddObject, MoveObject, RemoveObject, SceneChange, SceneChangeError,
    transform_from_xyz_quaternion)
from collision_sensor.errors import CollisionSensorError, SceneError
from collision_sensor.model import mesh_loading
from collision_sensor.model.package_lookup import find_package
from collision_sensor.model.scene import SceneObject
from collision_sensor.untrusted_text import printable, quoted

#: visualization_msgs/Marker type and action codes.
CUBE, SPHERE, CYLINDER, MESH_RESOURCE, TRIANGLE_LIST = 1, 2, 3, 10, 11
ADD, DELETE, DELETEALL = 0, 2, 3
TYPE_NAMES = {CUBE: 'CUBE', SPHERE: 'SPHERE', CYLINDER: 'CYLINDER',
              MESH_RESOURCE: 'MESH_RESOURCE', TRIANGLE_LIST: 'TRIANGLE_LIST'}
#: Longest object name taken from a marker.
MAX_NAME_CHARS = 256
#: Relative tolerance of the equal scales a sphere and a cylinder need.
SCALE_EQUAL_REL = 1e-9


class MarkerError(SceneError):
    """A marker of a scene array that cannot apply; the array changes nothing.

    :ivar index: the marker's position in the array.
    :ivar reason: what is wrong and the fix.
    """

    def __init__(self, index: int, marker, reason: str):
        self.index, self.reason = index, reason
        name = _marker_label(marker)
        super().__init__(f'marker {index} ({name}): {reason}')


@dataclass(frozen=True)
class SceneLimits:
    """Caps on what the ``scene`` topic may make the node hold and read.

    :ivar max_objects: objects that came through the topic, at most.
    :ivar max_triangles: triangles of one object, at most.
    :ivar max_total_triangles: triangles of all objects from the topic, at most.
    :ivar max_mesh_bytes: size of a mesh file read, at most.
    :ivar mesh_roots: directories under which plain paths and ``file://`` URIs may lie.
    """

    max_objects: int = 256
    max_triangles: int = 200_000
    max_total_triangles: int = 1_000_000
    max_mesh_bytes: int = 64 * 1024 * 1024
    mesh_roots: Tuple[str, ...] = ()


@dataclass(frozen=True)
class TopicObject:
    """An object that came through the topic: what it was built from, and how to build it
    again (:meth:`SceneTopic.readd_changes`).

    :ivar key: type, scale, geometry source, frame and touch links: an ADD with the same key
        only moves the object.
    """

    key: tuple
    triangles: int
    change: AddObject


@dataclass(frozen=True)
class TopicUpdate:
    """The changes one array makes (``sources[k]``: the marker change k comes from), and the
    topic's objects after them."""

    changes: Tuple[SceneChange, ...]
    sources: Tuple[int, ...]
    objects: Dict[str, TopicObject]
    summary: str


@dataclass
class SceneTopic:
    """Turns ``scene`` arrays into scene changes, under :class:`SceneLimits`; remembers what
    came through the topic.

    :param limits: the caps.
    :param package_paths: ``{package: directory}`` for ``package://`` mesh URIs (then the
        ament index and ``ROS_PACKAGE_PATH``, as :func:`find_package` looks).
    """

    limits: SceneLimits = field(default_factory=SceneLimits)
    package_paths: Optional[Mapping[str, str]] = None
    objects: Dict[str, TopicObject] = field(default_factory=dict)

    def update(self, markers: Sequence, checker) -> TopicUpdate:
        """Return the changes ``markers`` make to ``checker``'s scene (nothing is applied;
        what only the checker can judge, a name taken by a link for one, it judges when the
        changes are prepared: :func:`marker_error` names the marker then).

        :param markers: the array's markers, in order.
        :param checker: the :class:`CollisionChecker` they apply to (its frames, links,
            objects and tessellation).
        :raises MarkerError: the first marker that cannot apply, with the fix.
        """
        objects = dict(self.objects)
        present = set(checker.object_names)
        changes: List[SceneChange] = []
        sources: List[int] = []     # the marker each change comes from
        links = set(checker.kinematics.link_names)
        added = moved = removed = 0
        for index, marker in enumerate(markers):
            action = _integer(marker, 'action')
            if action == DELETEALL:
                for name in objects:
                    if name in present:
                        sources.append(index)
                        changes.append(RemoveObject(name))
                        present.discard(name)
                        removed += 1
                objects = {}
                continue
            name = _object_name(index, marker)
            if action == DELETE:
                if name in present:
                    sources.append(index)
                    changes.append(RemoveObject(name))
                    present.discard(name)
                    removed += 1
                objects.pop(name, None)
                continue
            if action != ADD:
                raise MarkerError(index, marker, f'action {action} is not ADD (0), DELETE (2) '
                                  'or DELETEALL (3); send one of those')
            attach_to, touch_links = self._frame(index, marker, checker, links)
            pose = _pose(index, marker)
            kind = _integer(marker, 'type')
            points = _points(index, marker, self.limits) if kind == TRIANGLE_LIST else None
            key = self._key(index, marker, attach_to, touch_links, points)
            old = objects.get(name)
            sources.append(index)
            if old is not None and old.key == key and name in present:
                changes.append(MoveObject(name, pose))
                objects[name] = TopicObject(key, old.triangles, AddObject(
                    old.change.obj, attach_to, touch_links, pose))
                moved += 1
                continue
            obj = self._object(index, marker, name, checker.config.primitive_sections, points)
            change = AddObject(obj, attach_to, touch_links, pose)
            changes.append(change)
            objects[name] = TopicObject(key, len(obj.faces), change)
            present.add(name)
            added += 1
        limits = self.limits
        if len(objects) > limits.max_objects:
            raise MarkerError(len(markers) - 1, markers[-1], f'the topic would hold '
                              f'{len(objects)} objects, more than scene_max_objects '
                              f'{limits.max_objects}; delete some first, or raise the cap')
        total = sum(item.triangles for item in objects.values())
        if total > limits.max_total_triangles:
            raise MarkerError(len(markers) - 1, markers[-1], f'the topic\'s objects would have '
                              f'{total} triangles, more than scene_max_total_triangles '
                              f'{limits.max_total_triangles}; delete some or decimate them')
        summary = (f'{added} added or replaced, {moved} moved, {removed} removed; '
                   f'{len(objects)} objects from the topic ({total} triangles)')
        return TopicUpdate(tuple(changes), tuple(sources), objects, summary)

    def accept(self, update: TopicUpdate) -> None:
        """Take ``update``'s objects as the topic's (once its changes are committed)."""
        self.objects = update.objects

    def readd_changes(self) -> List[AddObject]:
        """The changes that add every object of the topic again (to a new checker)."""
        return [item.change for item in self.objects.values()]

    # -- one marker ---------------------------------------------------------------------------

    def _frame(self, index, marker, checker, links) -> Tuple[Optional[str], Tuple[str, ...]]:
        frame = getattr(getattr(marker, 'header', None), 'frame_id', '') or ''
        in_world = frame == '' or frame in checker.world_frames
        if not in_world and frame not in links:
            world = ' or '.join(repr(name) for name in sorted(checker.world_frames))
            raise MarkerError(index, marker, f'frame {quoted(frame)} is neither the world nor a '
                              f'link of the robot; use "" or {world} for an object fixed in the '
                              'world, or a link name to attach it')
        # Touch links, for an object in the world as for an attached one (a table under the
        # robot's base, a part in the gripper).
        touch = tuple(dict.fromkeys(str(getattr(marker, 'text', '') or '').split()))
        unknown = [name for name in touch if name not in links]
        if unknown:
            raise MarkerError(index, marker, f'touch link {quoted(unknown[0])} (in text) is not '
                              'a link of the robot; list link names separated by spaces, or '
                              'leave text empty')
        return (None if in_world else frame), touch

    def _key(self, index, marker, attach_to, touch_links, points) -> tuple:
        kind = _integer(marker, 'type')
        if kind not in TYPE_NAMES:
            raise MarkerError(index, marker, f'type {kind} is not a shape the sensor checks; '
                              'send CUBE (1), SPHERE (2), CYLINDER (3), MESH_RESOURCE (10) or '
                              'TRIANGLE_LIST (11)')
        scale = _scale(index, marker)
        if kind == MESH_RESOURCE:
            source = str(getattr(marker, 'mesh_resource', '') or '')
        elif kind == TRIANGLE_LIST:
            source = hashlib.sha1(points.tobytes()).hexdigest()
        else:
            source = ''
        return (kind, scale, source, attach_to, touch_links)

    def _object(self, index, marker, name, sections, points) -> SceneObject:
        kind = _integer(marker, 'type')
        scale = np.array(_scale(index, marker))
        solid = None
        if kind == CUBE:
            (vertices, faces), solid = mesh_loading.box_mesh(scale), mesh_loading.box_solid(scale)
            source = 'CUBE ' + ' '.join(f'{v:g}' for v in scale)
        elif kind == SPHERE:
            _equal(index, marker, scale, (0, 1, 2), 'a SPHERE needs scale.x = scale.y = '
                   'scale.z (the diameter); send a MESH_RESOURCE for an ellipsoid')
            radius = 0.5 * scale[0]
            vertices, faces = mesh_loading.sphere_mesh(radius, sections)
            solid, source = mesh_loading.sphere_solid(radius), f'SPHERE {scale[0]:g}'
        elif kind == CYLINDER:
            _equal(index, marker, scale, (0, 1), 'a CYLINDER needs scale.x = scale.y (the '
                   'diameter; scale.z is the length)')
            radius, length = 0.5 * scale[0], scale[2]
            vertices, faces = mesh_loading.cylinder_mesh(radius, length, sections)
            solid = mesh_loading.cylinder_solid(radius, length)
            source = f'CYLINDER {scale[0]:g} {scale[2]:g}'
        elif kind == TRIANGLE_LIST:
            vertices = points * scale
            faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
            source = f'TRIANGLE_LIST of {len(faces)}'
        else:
            uri = str(getattr(marker, 'mesh_resource', '') or '')
            path = self._mesh_path(index, marker, uri)
            try:
                vertices, faces = mesh_loading.load_mesh_file(
                    path, scale, owner=f'marker {index}', uri=uri, error=SceneError)
            except CollisionSensorError as error:
                raise MarkerError(index, marker, f'mesh cannot be read ({error}); send a valid '
                                  'STL, OBJ, PLY or DAE file') from None
            source = f'MESH_RESOURCE {uri}'
        if len(faces) > self.limits.max_triangles:
            raise MarkerError(index, marker, f'{len(faces)} triangles, more than '
                              f'scene_max_triangles {self.limits.max_triangles}; decimate it '
                              'or raise the cap')
        return SceneObject(name=name, source=source, T_world_object=np.eye(4),
                           vertices=np.ascontiguousarray(vertices, dtype=np.float64),
                           faces=np.ascontiguousarray(faces, dtype=np.int64), solid=solid)

    def _mesh_path(self, index, marker, uri: str) -> str:
        """The file ``uri`` names, if it may be read: in its package's directory, or under a
        mesh root; a regular file of at most max_mesh_bytes."""
        if uri.startswith('package://'):
            package, _, rest = uri[len('package://'):].partition('/')
            directory = find_package(package, self.package_paths)[0] if package and rest else None
            if directory is None:
                raise MarkerError(index, marker, f'mesh {quoted(uri)}: package not found; give '
                                  'package://PACKAGE/path of an installed package (or add it to '
                                  'package_paths)')
            roots, path = [directory], os.path.join(directory, rest)
        elif uri.startswith('file://') or uri.startswith('/'):
            path = urllib.parse.unquote(uri[len('file://'):]) if uri.startswith('file://') else uri
            roots = list(self.limits.mesh_roots)
        else:
            raise MarkerError(index, marker, f'mesh {quoted(uri)} is not package://, file:// or '
                              'an absolute path; send one of those')
        real = os.path.realpath(path)
        if not any(os.path.commonpath([real, os.path.realpath(root)]) == os.path.realpath(root)
                   for root in roots):
            where = ('its package\'s directory' if uri.startswith('package://')
                     else 'a directory of scene_mesh_roots (none configured)' if not roots
                     else 'a directory of scene_mesh_roots')
            raise MarkerError(index, marker, f'mesh {quoted(uri)} lies outside {where}; the '
                              'sensor reads no other file')
        try:
            stat = os.stat(real)
        except OSError:
            raise MarkerError(index, marker, f'mesh {quoted(uri)} not found; send an existing '
                              'file') from None
        if not S_ISREG(stat.st_mode) or stat.st_size > self.limits.max_mesh_bytes:
            raise MarkerError(index, marker, f'mesh {quoted(uri)} is not a regular file of at '
                              f'most scene_max_mesh_bytes {self.limits.max_mesh_bytes}; send a '
                              'smaller mesh file')
        return real


# -- fields -----------------------------------------------------------------------------------

def _marker_label(marker) -> str:
    ns = printable(getattr(marker, 'ns', ''), 60)
    try:
        return f'ns "{ns}", id {int(getattr(marker, "id", 0))}'
    except (TypeError, ValueError):
        return f'ns "{ns}"'


def _integer(marker, name: str) -> int:
    value = getattr(marker, name, None)
    try:
        return int(value)
    except (TypeError, ValueError):
        return -1


def _object_name(index, marker) -> str:
    ns = getattr(marker, 'ns', '')
    ident = _integer(marker, 'id')
    if not isinstance(ns, str):
        raise MarkerError(index, marker, 'ns is not text; name the object with ns (and id)')
    name = ns if ident == 0 else f'{ns}/{ident}'
    if not ns or len(name) > MAX_NAME_CHARS or ':' in name or not name.isprintable():
        raise MarkerError(index, marker, f'object name {quoted(name)} (ns, or ns/id) must be '
                          f'1 to {MAX_NAME_CHARS} printable characters without ":"; fix ns')
    return name


def _pose(index, marker) -> np.ndarray:
    pose = getattr(marker, 'pose', None)
    try:
        position, orientation = pose.position, pose.orientation
        xyz = (position.x, position.y, position.z)
        quaternion = (orientation.x, orientation.y, orientation.z, orientation.w)
        T = transform_from_xyz_quaternion(xyz, quaternion, 'pose')
    except AttributeError:
        raise MarkerError(index, marker, 'no pose; send pose.position and pose.orientation'
                          ) from None
    except SceneError as error:
        raise MarkerError(index, marker, str(error)) from None
    return T


def _scale(index, marker) -> Tuple[float, float, float]:
    scale = getattr(marker, 'scale', None)
    try:
        values = (float(scale.x), float(scale.y), float(scale.z))
    except (AttributeError, TypeError, ValueError):
        values = (math.nan,) * 3
    if not all(math.isfinite(v) and 0.0 < v <= 1e6 for v in values):
        raise MarkerError(index, marker, f'scale {values} must be three positive finite numbers '
                          '(edge lengths, diameters, or mesh scale factors); a zero scale has no '
                          'volume')
    return values


def _equal(index, marker, scale, axes, fix) -> None:
    first = scale[axes[0]]
    if any(abs(scale[k] - first) > SCALE_EQUAL_REL * first for k in axes[1:]):
        raise MarkerError(index, marker, f'scale {tuple(scale.tolist())}: {fix}')


def _points(index, marker, limits: SceneLimits) -> np.ndarray:
    points = getattr(marker, 'points', None) or []
    count = len(points)
    if count == 0 or count % 3:
        raise MarkerError(index, marker, f'TRIANGLE_LIST has {count} points; send three per '
                          'triangle, at least one triangle')
    if count // 3 > limits.max_triangles:
        raise MarkerError(index, marker, f'{count // 3} triangles, more than scene_max_triangles '
                          f'{limits.max_triangles}; decimate it or raise the cap')
    try:
        array = np.array([(p.x, p.y, p.z) for p in points], dtype=np.float64)
    except (AttributeError, TypeError, ValueError):
        raise MarkerError(index, marker, 'points must be geometry_msgs/Point') from None
    if not np.isfinite(array).all():
        raise MarkerError(index, marker, 'points are not all finite; send finite coordinates')
    return array


def marker_error(error: SceneError, update: TopicUpdate, markers: Sequence) -> MarkerError:
    """The :class:`MarkerError` for ``error``, raised by the checker on change
    ``error.index`` of ``update`` (a
    :class:`~collision_sensor.engine.dynamic_scene.SceneChangeError`)."""
    index = update.sources[error.index]
    return MarkerError(index, markers[index], error.reason)


def apply_array(topic: SceneTopic, checker, markers: Sequence) -> TopicUpdate:
    """Apply one array to ``checker`` at once (prepare and commit), as the node does in two
    steps; the offline tools replay recorded arrays so.

    :raises MarkerError: the array changes nothing then.
    """
    update = topic.update(markers, checker)
    try:
        checker.commit_scene_changes(checker.prepare_scene_changes(update.changes))
    except SceneChangeError as error:
        raise marker_error(error, update, markers) from None
    topic.accept(update)
    return update
