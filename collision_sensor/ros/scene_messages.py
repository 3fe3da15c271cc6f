"""Scene files as ``scene`` topic markers: what a client sends to put a scene file's objects on a
running node, or to take them away.

Each object of a scene file (:mod:`collision_sensor.model.scene`) becomes one ``ADD`` marker
named by its ``ns`` (id 0), posed in the robot's root frame (or in ``frame``, a link of the
robot, to attach it): ``box`` a ``CUBE`` (scale: the size), ``sphere`` a ``SPHERE`` (scale: the
diameter), ``cylinder`` a ``CYLINDER`` (scale: diameter, diameter, length), a ``package://``
mesh a ``MESH_RESOURCE`` (the node resolves it with its ``package_paths``), any other mesh a
``TRIANGLE_LIST`` of its triangles (read here: the node reads mesh files only under its
``scene_mesh_roots``). The node then checks the objects as it checks those of its
``scene_path``. The file is read and checked here first, so a bad file is refused with the
file, the object and the fix named, before anything is sent.
"""
import os
from typing import List, Sequence

import yaml
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker

from collision_sensor.errors import SceneError
from collision_sensor.model.scene import load_scene
from collision_sensor.ros.markers import quaternion_from_matrix


def _document(scene):
    """Return the scene's parsed document (``scene``: a YAML path or the dict it parses to)."""
    if isinstance(scene, dict):
        return scene
    try:
        with open(scene, encoding='utf-8') as stream:
            return yaml.safe_load(stream)
    except (OSError, yaml.YAMLError):
        return None     # load_scene says what is wrong, naming the file


def scene_markers(scene, package_paths=None, frame: str = '',
                  touch: Sequence[str] = ()) -> List[Marker]:
    """Return the ``ADD`` markers that put the objects of ``scene`` on the ``scene`` topic.

    :param scene: a scene file's path, or the dict it parses to (relative mesh paths then
        relative to the current directory).
    :param package_paths: ``{package: directory}`` for reading ``package://`` meshes here.
    :param frame: '' (the world) or a link of the robot the objects are attached to (their
        poses then in the link's frame).
    :param touch: links of the robot the objects may touch (never checked against them).
    :raises SceneError: the scene cannot be read, naming the file, the object and the fix.
    """
    objects = load_scene(scene, package_paths)
    entries = (_document(scene) or {}).get('objects') or []
    markers = []
    for entry, obj in zip(entries, objects):
        marker = Marker(ns=obj.name, id=0, action=Marker.ADD, text=' '.join(touch))
        marker.header.frame_id = frame
        T = obj.T_world_object
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (
            float(v) for v in T[:3, 3])
        (marker.pose.orientation.x, marker.pose.orientation.y, marker.pose.orientation.z,
         marker.pose.orientation.w) = (float(v) for v in quaternion_from_matrix(T[:3, :3]))
        marker.color.r = marker.color.g = marker.color.b = 0.6
        marker.color.a = 1.0
        scale = (1.0, 1.0, 1.0)
        if 'box' in entry:
            marker.type, scale = Marker.CUBE, entry['box']['size']
        elif 'sphere' in entry:
            marker.type = Marker.SPHERE
            scale = (2.0 * entry['sphere']['radius'],) * 3
        elif 'cylinder' in entry:
            marker.type = Marker.CYLINDER
            diameter = 2.0 * entry['cylinder']['radius']
            scale = (diameter, diameter, entry['cylinder']['length'])
        elif str(entry['mesh']['filename']).startswith('package://'):
            marker.type, marker.mesh_resource = Marker.MESH_RESOURCE, entry['mesh']['filename']
            scale = entry['mesh'].get('scale', 1.0)
            scale = (scale,) * 3 if isinstance(scale, (int, float)) else scale
        else:   # read here, scaled: sent as its triangles
            marker.type = Marker.TRIANGLE_LIST
            marker.points = [Point(x=float(x), y=float(y), z=float(z))
                             for x, y, z in obj.vertices[obj.faces].reshape(-1, 3)]
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in scale)
        markers.append(marker)
    if len(markers) != len(objects):
        raise SceneError(f'scene "{scene if not isinstance(scene, dict) else "<dict>"}": its '
                         'objects could not be read again; check the file')
    return markers


def delete_markers(names: Sequence[str]) -> List[Marker]:
    """Return the ``DELETE`` markers that remove the objects ``names`` (objects that came
    through the topic)."""
    return [Marker(ns=name, id=0, action=Marker.DELETE) for name in names]


def delete_all_marker() -> Marker:
    """Return the ``DELETEALL`` marker: every object that came through the topic is removed
    (the node's scene file's objects stay)."""
    return Marker(action=Marker.DELETEALL)


def absolute_mesh_paths(document: dict, base_dir: str) -> dict:
    """Return a copy of a scene document whose relative mesh file names are made absolute from
    ``base_dir`` (to write it to a file elsewhere)."""
    objects = []
    for entry in document.get('objects') or []:
        mesh = entry.get('mesh') if isinstance(entry, dict) else None
        if isinstance(mesh, dict) and isinstance(mesh.get('filename'), str) and \
                '://' not in mesh['filename'] and not os.path.isabs(mesh['filename']):
            entry = dict(entry, mesh=dict(mesh, filename=os.path.join(base_dir,
                                                                      mesh['filename'])))
        objects.append(entry)
    return dict(document, objects=objects)
