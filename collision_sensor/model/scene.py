"""Read the static scene: named objects with a shape and a pose in the robot's root frame.

The scene is a YAML file (or the dict it parses to)::

    objects:
      - name: table                       # unique; used as the pair name in results
        box: {size: [1.0, 0.8, 0.05]}     # edge lengths x, y, z, all > 0
        pose: {xyz: [0.5, 0.0, -0.025], rpy: [0.0, 0.0, 0.0]}   # optional, identity
      - name: post
        cylinder: {radius: 0.05, length: 0.5}   # axis z, centred on the pose
      - name: ball
        sphere: {radius: 0.1}
      - name: washer
        mesh: {filename: ../meshes/demo_cell/washer.stl, scale: [1, 1, 1]}   # scale optional

Rules:

- ``objects`` is the only top-level key; it holds a list (possibly empty).
- Each object has ``name``, exactly one shape key (``box``, ``cylinder``, ``sphere``, ``mesh``)
  and optionally ``pose``; any other key is an error.
- ``pose``: ``xyz`` (metres) and ``rpy`` (radians, ``R = Rz(y) Ry(p) Rx(r)`` as in URDF), both
  optional; the pose is ``T_world_object`` with world the robot's root link frame.
- ``mesh.filename``: relative to the YAML file's directory (to the current directory for a
  dict), ``package://NAME/...`` or ``file://...``; resolved as in
  :mod:`collision_sensor.model.mesh_loading`. ``scale`` is three numbers or one.
- Primitives are tessellated as in :mod:`collision_sensor.model.mesh_loading` (inscribed).

Every error is a :class:`SceneError` naming the file, the object and the fix.
"""
import math
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np
import yaml

from collision_sensor.errors import SceneError
from collision_sensor.model import mesh_loading
from collision_sensor.model.robot_model import transform_from_xyz_rpy
from collision_sensor.model.xml_safety import MAX_DOCUMENT_BYTES

SHAPES = ('box', 'cylinder', 'sphere', 'mesh')
_OBJECT_KEYS = ('name', 'pose') + SHAPES
_SHAPE_KEYS = {'box': ('size',), 'cylinder': ('radius', 'length'), 'sphere': ('radius',),
               'mesh': ('filename', 'scale')}


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One static object: ``T_world_object : (4, 4) float64``; ``vertices : (n, 3) float64``
    and ``faces : (m, 3) int64`` in the object frame, C-contiguous.
    """

    name: str
    source: str
    T_world_object: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    solid: Optional[mesh_loading.Solid] = None  # primitives: what they fill


def load_scene(scene, package_paths=None, *,
               primitive_sections: int = 32) -> tuple[SceneObject, ...]:
    """Read a scene and tessellate its objects.

    :param scene: path of a YAML file (``str`` or ``os.PathLike``), or an already parsed dict.
    :param package_paths: mapping ``{package_name: directory}`` for ``package://`` meshes.
    :param primitive_sections: sections around cylinders and spheres.
    :return: the objects in file order.
    :raises SceneError: unreadable file, or an object described badly.
    """
    if isinstance(scene, dict):
        source, base_dir, document = '<scene dict>', None, scene
    else:
        source = os.fspath(scene)
        base_dir = os.path.dirname(os.path.abspath(source))
        document = _read_yaml(source)
    where = f'scene "{source}"'
    if not isinstance(document, dict) or 'objects' not in document:
        raise SceneError(f'{where}: no top-level "objects" key; write "objects:" followed by a '
                         'list of objects (or "objects: []")')
    extra = sorted(set(document) - {'objects'})
    if extra:
        raise SceneError(f'{where}: unknown top-level key(s) {", ".join(map(str, extra))}; '
                         'only "objects" is read')
    entries = document['objects'] or []
    if not isinstance(entries, list):
        raise SceneError(f'{where}: "objects" must be a list ("- name: ..." entries)')
    objects, seen = [], set()
    for position, entry in enumerate(entries):
        item = _parse_object(entry, position, where, package_paths, base_dir,
                             primitive_sections)
        if item.name in seen:
            raise SceneError(f'{where}: object name "{item.name}" is used twice; names must be '
                             'unique, rename one')
        seen.add(item.name)
        objects.append(item)
    return tuple(objects)


def _read_yaml(path):
    try:
        if os.stat(path).st_size > MAX_DOCUMENT_BYTES:
            raise SceneError(f'scene "{path}": larger than {MAX_DOCUMENT_BYTES} bytes; '
                             'this is not a plausible scene file')
        with open(path, encoding='utf-8') as stream:
            return yaml.safe_load(stream)
    except OSError as exc:
        raise SceneError(f'scene "{path}": cannot read the file ({exc.strerror or exc}); '
                         'check the path') from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        line = f' at line {mark.line + 1}' if mark is not None else ''
        raise SceneError(f'scene "{path}": broken YAML{line}: '
                         f'{getattr(exc, "problem", None) or exc}; fix the file') from None


def _parse_object(entry, position, where, package_paths, base_dir, sections) -> SceneObject:
    if not isinstance(entry, dict):
        raise SceneError(f'{where}: object #{position} is not a mapping; write '
                         '"- name: ...", a shape and an optional pose')
    name = entry.get('name')
    if not isinstance(name, str) or not name:
        raise SceneError(f'{where}: object #{position} has no name; add "name: ..." (unique)')
    owner = f'{where}, object "{name}"'
    unknown = sorted(set(map(str, entry)) - set(_OBJECT_KEYS))
    if unknown:
        raise SceneError(f'{owner}: unknown key(s) {", ".join(unknown)}; use name, pose and '
                         f'one of {", ".join(SHAPES)}')
    shapes = [key for key in SHAPES if key in entry]
    if len(shapes) != 1:
        found = ', '.join(shapes) if shapes else 'none'
        raise SceneError(f'{owner}: needs exactly one shape key of {", ".join(SHAPES)} '
                         f'(found {found}); split it into several objects or add a shape')
    shape = shapes[0]
    spec = entry[shape]
    if not isinstance(spec, dict):
        raise SceneError(f'{owner}: "{shape}" must be a mapping, e.g. '
                         f'{_EXAMPLES[shape]}')
    extra = sorted(set(map(str, spec)) - set(_SHAPE_KEYS[shape]))
    if extra:
        raise SceneError(f'{owner}: {shape} has unknown key(s) {", ".join(extra)}; write '
                         f'{_EXAMPLES[shape]}')
    T_world_object = _pose(entry.get('pose'), owner)
    solid = None
    if shape == 'box':
        size = _numbers(spec.get('size'), 3, f'{owner}: box size', _EXAMPLES['box'])
        if np.any(size <= 0):
            raise SceneError(f'{owner}: box size {size.tolist()} must be three positive '
                             f'numbers; write {_EXAMPLES["box"]}')
        vertices, faces = mesh_loading.box_mesh(size)
        solid = mesh_loading.box_solid(size)
        source = 'box ' + ' '.join(f'{v:g}' for v in size)
    elif shape == 'cylinder':
        radius = _positive(spec.get('radius'), f'{owner}: cylinder radius', _EXAMPLES[shape])
        length = _positive(spec.get('length'), f'{owner}: cylinder length', _EXAMPLES[shape])
        vertices, faces = mesh_loading.cylinder_mesh(radius, length, sections)
        solid = mesh_loading.cylinder_solid(radius, length)
        source = f'cylinder {radius:g} {length:g}'
    elif shape == 'sphere':
        radius = _positive(spec.get('radius'), f'{owner}: sphere radius', _EXAMPLES[shape])
        vertices, faces = mesh_loading.sphere_mesh(radius, sections)
        solid = mesh_loading.sphere_solid(radius)
        source = f'sphere {radius:g}'
    else:
        uri = spec.get('filename')
        if not isinstance(uri, str) or not uri:
            raise SceneError(f'{owner}: mesh has no filename; write {_EXAMPLES["mesh"]}')
        scale = spec.get('scale', 1.0)
        if isinstance(scale, (int, float)) and not isinstance(scale, bool):
            scale = [scale] * 3
        scale = _numbers(scale, 3, f'{owner}: mesh scale', _EXAMPLES['mesh'])
        path = mesh_loading.resolve_mesh_uri(uri, package_paths, base_dir, owner=owner,
                                             error=SceneError)
        vertices, faces = mesh_loading.load_mesh_file(path, scale, owner=owner, uri=uri,
                                                      error=SceneError)
        source = f'mesh {uri}'
    return SceneObject(name=name, source=source, T_world_object=T_world_object,
                       vertices=vertices, faces=faces, solid=solid)


_EXAMPLES = {
    'box': 'box: {size: [1.0, 0.8, 0.05]}',
    'cylinder': 'cylinder: {radius: 0.05, length: 0.5}',
    'sphere': 'sphere: {radius: 0.1}',
    'mesh': 'mesh: {filename: meshes/part.stl, scale: [1, 1, 1]}',
    'pose': 'pose: {xyz: [0.5, 0.0, 0.0], rpy: [0.0, 0.0, 0.0]}',
}


def _pose(pose, owner) -> np.ndarray:
    if pose is None:
        return np.eye(4)
    if not isinstance(pose, dict):
        raise SceneError(f'{owner}: pose must be a mapping; write {_EXAMPLES["pose"]}')
    extra = sorted(set(map(str, pose)) - {'xyz', 'rpy'})
    if extra:
        raise SceneError(f'{owner}: pose has unknown key(s) {", ".join(extra)}; write '
                         f'{_EXAMPLES["pose"]}')
    xyz = _numbers(pose.get('xyz', [0.0, 0.0, 0.0]), 3, f'{owner}: pose xyz', _EXAMPLES['pose'])
    rpy = _numbers(pose.get('rpy', [0.0, 0.0, 0.0]), 3, f'{owner}: pose rpy', _EXAMPLES['pose'])
    return transform_from_xyz_rpy(xyz, rpy)


def _numbers(value, count, what, example) -> np.ndarray:
    if (not isinstance(value, (list, tuple)) or len(value) != count
            or not all(_is_finite_number(v) for v in value)):
        raise SceneError(f'{what} is {value!r}, not {count} finite numbers; write {example}')
    return np.array(value, dtype=np.float64)


def _positive(value, what, example) -> float:
    if not _is_finite_number(value) or value <= 0:
        raise SceneError(f'{what} is {value!r}, not a positive number; write {example}')
    return float(value)


def _is_finite_number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))
