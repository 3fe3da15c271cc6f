"""Turn mesh URIs and geometric primitives into plain triangle arrays.

Everything leaves this module as ``vertices : (n, 3) float64`` and ``faces : (m, 3) int64``, both
C-contiguous, in metres; the engine never sees a trimesh object. A COLLADA file's ``<unit
meter="s"/>`` scales its vertices by ``s``, as ROS tools (assimp, RViz) do; its scene graph's node
transforms are applied. Its ``<up_axis>`` is *not* applied, as in MoveIt and RViz: assimp puts the
up-axis rotation into the root node's transform, which geometric_shapes and RViz reset, so the
vertices are used in the file's own axes (87 DAE files of example-robot-data declare ``Y_UP`` yet
are authored in their link's frame). Every triangle of a mesh file is kept as it is, zero-area ones
included (the engine handles them); a mesh without any triangle is an error.

Mesh URIs (:func:`resolve_mesh_uri`) are tried in this order:

1. ``package://NAME/rest``: ``<package directory>/rest``, the package found as
   :func:`collision_sensor.model.package_lookup.find_package` finds it (explicit ``package_paths``,
   then the ament index, then ``ROS_PACKAGE_PATH``); failing that, next to the robot
   description: ``<base_dir>/rest``, then ``<ancestor>/rest`` for every ancestor directory of
   ``base_dir`` (finds the meshes of example-robot-data, whose URIs start with the package
   directory itself).
2. ``file:///abs/path``: that path (percent-escapes decoded).
3. a plain path: absolute as it is; relative against ``base_dir``.

``base_dir`` is the directory of the URDF or scene file. A robot given as XML text has none:
relative paths then resolve against the current directory and ``package://`` URIs through
(a)-(c) only.

Primitives are tessellated so that every vertex lies ON the true surface: the polyhedra are
inscribed, never larger than the shape.

- box: 8 vertices, 12 triangles, centred on the origin;
- cylinder (axis z, centred): two rings of ``sections`` vertices at angles ``2 pi k / sections``
  plus the two cap centres; ``2 sections + 2`` vertices, ``4 sections`` triangles;
- sphere: a UV sphere of ``sections`` meridians and ``stacks = max(2, sections // 2)`` bands:
  the two poles plus ``stacks - 1`` rings of ``sections`` vertices at polar angles
  ``pi i / stacks``; ``sections (stacks - 1) + 2`` vertices, ``2 sections (stacks - 1)``
  triangles. With the default 32 sections: 482 vertices, 960 triangles.
"""
import difflib
import functools
from stat import S_ISREG
from dataclasses import dataclass
import os
import re
import urllib.parse
from typing import Dict, Optional, Sequence

import numpy as np

from collision_sensor.model.stl import read_stl

from collision_sensor.errors import ConfigError, MeshError
from collision_sensor.model.package_lookup import find_package, package_path_fix

#: File types read by :func:`load_mesh_file` (through trimesh; DAE through pycollada).
MESH_EXTENSIONS = ('.stl', '.obj', '.ply', '.dae')


def parse_package_paths(entries: Sequence[str], what: str = '--package-path') -> Dict[str, str]:
    """Turn ``"name=dir"`` strings into the ``{package: directory}`` mapping loaders take.

    :param entries: the strings, as a command line or a node parameter gives them.
    :param what: the option or parameter, for messages.
    :raises ConfigError: on a malformed entry, a package given twice, or a missing directory.
    """
    packages = {}
    for entry in entries:
        name, separator, directory = entry.partition('=')
        name, directory = name.strip(), os.path.expanduser(directory.strip())
        if not separator or not name or not directory:
            raise ConfigError(f'{what} "{entry}": expected NAME=DIR (name=dir), e.g. '
                              '"example-robot-data=/opt/erd/share/example-robot-data"')
        if name in packages:
            raise ConfigError(f'{what}: package "{name}" is given twice; keep one entry per '
                              'package')
        if not os.path.isdir(directory):
            raise ConfigError(f'{what}: directory "{directory}" of package "{name}" not found; '
                              'give an existing directory')
        packages[name] = directory
    return packages


def resolve_mesh_uri(uri: str, package_paths=None, base_dir=None, *, owner: str = 'mesh',
                     error: type = MeshError) -> str:
    """Return the existing file a mesh URI names.

    :param uri: ``package://NAME/rest``, ``file://PATH``, or a plain path.
    :param package_paths: mapping ``{package_name: directory}``, or None.
    :param base_dir: directory of the file that names the URI (URDF, scene), or None when the
        description came as text (then relative paths resolve against the current directory).
    :param owner: who names the mesh, for messages, e.g. ``'link "panda_link1"'``.
    :param error: exception class to raise.
    :return: the path of an existing file.
    :raises MeshError: no candidate exists; the message lists every place tried and the fix.
    """
    tried = []
    if uri.startswith('package://'):
        package, _, rest = uri[len('package://'):].partition('/')
        if not package or not rest:
            raise error(f'{owner}: mesh "{uri}" is not a valid package URI; '
                        'write package://PACKAGE/path/to/mesh')
        directory, places = find_package(package, package_paths)
        if directory is not None:
            candidate = os.path.join(directory, rest)
            if os.path.isfile(candidate):
                return candidate
            tried.append(f'{candidate} (package "{package}" found at {directory})')
        else:
            tried.extend(places)
        for candidate in _beside_description(rest, base_dir):
            if os.path.isfile(candidate):
                return candidate
            tried.append(candidate)
        where = '' if base_dir is not None else (
            ' (robot given as XML text: nothing next to a file is searched)')
        if directory is not None and os.path.isdir(directory):
            # The package is there and the file is not: a misspelt name, or a mesh the
            # package does not install. Giving the package's directory again cannot help.
            close = closest_file(directory, rest)
            fix = (f'did you mean "package://{package}/{close}"? Fix the file name in the '
                   'description' if close is not None else
                   f'check the file name, and that package "{package}" installs its meshes '
                   f'(look in {os.path.dirname(os.path.join(directory, rest))})')
            beside = (f' (nor has {base_dir} or a directory above it)' if base_dir is not None
                      else where)
            raise error(f'{owner}: mesh "{uri}" not found: package "{package}" is at '
                        f'{directory} and has no file {rest}{beside}; {fix}')
        raise error(
            f'{owner}: mesh "{uri}" of package "{package}" not found{where}; searched: '
            f'{"; ".join(tried)}; {package_path_fix(package)}')
    if uri.startswith('file://'):
        path = urllib.parse.unquote(uri[len('file://'):])
    else:
        path = uri
    if not os.path.isabs(path):
        path = os.path.join(base_dir if base_dir is not None else os.getcwd(), path)
    path = os.path.normpath(path)
    if os.path.isfile(path):
        return path
    if base_dir is None and not os.path.isabs(uri.replace('file://', '', 1)):
        hint = ('the robot came as XML text, so relative paths resolve against the current '
                'directory; use an absolute path or package://')
    else:
        hint = 'fix the path, or use package:// with package_paths'
    raise error(f'{owner}: mesh "{uri}" not found; tried: {path}; {hint}')


def closest_file(directory: str, rest: str) -> Optional[str]:
    """Return the existing file under ``directory`` whose relative path is nearest to ``rest``
    (each missing component replaced by the closest name beside it), or None.

    ``closest_file('/pkg', 'meshes/forarm.stl') == 'meshes/forearm.stl'`` when that exists.
    """
    current, found = directory, []
    parts = [part for part in rest.split('/') if part not in ('', '.')]
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        path = os.path.join(current, part)
        if not (os.path.isfile(path) if last else os.path.isdir(path)):
            try:
                names = [name for name in os.listdir(current)
                         if (os.path.isfile if last else os.path.isdir)(
                             os.path.join(current, name))]
            except OSError:
                return None
            part = _closest_name(part, names)
            if part is None:
                return None
            path = os.path.join(current, part)
        found.append(part)
        current = path
    return '/'.join(found) if found and os.path.isfile(current) else None


#: How alike a name must be to one written (difflib's ratio of the names without extension).
CLOSE_NAME_RATIO = 0.75


def _closest_name(written: str, names: Sequence[str]) -> Optional[str]:
    """The name of ``names`` nearest to ``written``: the same but for case (a file system that
    tells case apart), else the most alike stem (extensions alike would make any two mesh
    names look close), or None."""
    same = sorted(name for name in names if name.lower() == written.lower())
    if same:
        return same[0]
    stem = os.path.splitext(written)[0].lower()
    scored = sorted((difflib.SequenceMatcher(None, stem, os.path.splitext(name)[0].lower())
                     .ratio(), name) for name in names)
    return scored[-1][1] if scored and scored[-1][0] >= CLOSE_NAME_RATIO else None


def _beside_description(rest, base_dir):
    if base_dir is None:
        return
    directory = os.path.abspath(base_dir)
    while True:
        yield os.path.join(directory, rest)
        parent = os.path.dirname(directory)
        if parent == directory:
            break
        directory = parent


def load_mesh_file(path: str, scale=(1.0, 1.0, 1.0), *, owner: str = 'mesh', uri: str = None,
                   error: type = MeshError):
    """Read a mesh file into triangle arrays, with its scale applied.

    A file holding a scene (DAE, multi-object OBJ) is flattened: every geometry is placed by its
    scene-graph transform and the triangles concatenated.

    :param path: an existing STL, OBJ, PLY or DAE file.
    :param scale: ``(3,)`` per-axis scale factors applied to the vertices.
    :param owner: who names the mesh, for messages.
    :param uri: the URI as written, for messages (default ``path``).
    :param error: exception class to raise.
    :return: ``vertices : (n, 3) float64`` and ``faces : (m, 3) int64``, C-contiguous, new arrays.
    :raises MeshError: unsupported type, unreadable file, or no triangles.
    """
    uri = uri or path
    extension = os.path.splitext(path)[1].lower()
    if extension not in MESH_EXTENSIONS:
        raise error(f'{owner}: mesh "{uri}" has type "{extension}", not one of '
                    f'{", ".join(MESH_EXTENSIONS)}; convert it to STL')
    try:
        stat = os.stat(path)
        # A description from the ROS graph names its mesh files: only regular files of
        # bounded size are read (never a device such as /dev/zero, a FIFO that blocks, ...).
        if not S_ISREG(stat.st_mode):
            raise error(f'{owner}: mesh "{uri}" ({path}) is not a regular file; give a mesh '
                        'file')
        if stat.st_size > MAX_MESH_BYTES:
            raise error(f'{owner}: mesh "{uri}" ({path}) has {stat.st_size} bytes, more than '
                        f'{MAX_MESH_BYTES}; decimate it for collision checking')
        vertices, faces = _read_mesh(os.path.abspath(path), stat.st_mtime_ns, stat.st_size)
    except error:
        raise
    except Exception as exc:  # trimesh and its loaders raise anything on a bad file
        raise error(f'{owner}: mesh "{uri}" ({path}) cannot be read: '
                    f'{type(exc).__name__}: {exc}; check that it is a valid '
                    f'{extension[1:].upper()} file') from None
    if len(faces) == 0:
        raise error(f'{owner}: mesh "{uri}" ({path}) has no triangles; '
                    'give a surface mesh, not a point cloud or an empty file')
    scale = np.asarray(scale, dtype=np.float64)
    return np.ascontiguousarray(vertices * scale), faces.copy()


@functools.lru_cache(maxsize=256)
def _read_mesh(path, mtime_ns, size):
    # Keyed on mtime and size so that an edited file is read again; the arrays are read-only
    # so that a cached copy cannot be changed by a caller.
    if path.lower().endswith('.stl'):
        vertices, faces = read_stl(path)
        return _frozen(vertices, faces, path)
    import trimesh  # only for the other formats: see collision_sensor.model.stl
    mesh = trimesh.load(path, force='mesh')
    vertices = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    if path.lower().endswith('.dae'):
        # COLLADA <unit meter="0.001"/>: ROS tools (assimp) scale by it; trimesh only records
        # it, as units "0.001 * meters".
        vertices = vertices * _collada_meters_per_unit(mesh, path)
    faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    return _frozen(vertices, faces, path)


def _frozen(vertices, faces, path):
    """Check and freeze a file's arrays (the cache hands the same ones to every caller)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if not np.all(np.isfinite(vertices)):
        raise MeshError(f'mesh "{path}" has non-finite vertex coordinates; repair the file')
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return vertices, faces


def _collada_meters_per_unit(mesh, path) -> float:
    units = (getattr(mesh, 'units', None) or 'meters').strip()
    if units in ('meters', 'meter', 'm'):
        return 1.0
    match = re.fullmatch(r'([-+0-9.eE]+)\s*\*\s*meters?', units)
    if match is None or not float(match.group(1)) > 0:
        raise MeshError(f'mesh "{path}" has COLLADA units "{units}", which are not understood; '
                        'give <unit meter="..."/> a positive number')
    return float(match.group(1))


#: The largest mesh file read (a collision mesh this size holds millions of triangles).
MAX_MESH_BYTES = 256 * 1024 * 1024

#: Solid kinds (``Solid.kind``), by name: the engine's numbers for them are its own
#: (``collision_sensor.engine.dynamic_scene.solid_row`` translates).
SOLID_BOX, SOLID_SPHERE, SOLID_CYLINDER, SOLID_CLOSED_MESH = (
    'box', 'sphere', 'cylinder', 'closed_mesh')


@dataclass(frozen=True)
class Solid:
    """What a collision element fills, beyond its surface triangles: a primitive is solid.

    ``kind`` is one of ``SOLID_*``; ``size`` ``(3,)``: a box's half extents, a sphere's radius
    (then 0, 0), a cylinder's radius and half length along z (then 0), in the element frame
    (centred, axis-aligned, as the tessellators here build them). Something wholly inside a
    solid collides with it (as FCL reports for primitives), although no triangles meet.
    """

    kind: str
    size: tuple = (0.0, 0.0, 0.0)


def box_solid(size) -> Solid:
    """The solid of a box of edge lengths ``size``."""
    return Solid(SOLID_BOX, tuple(0.5 * float(v) for v in size))


def sphere_solid(radius: float) -> Solid:
    """The solid of a sphere."""
    return Solid(SOLID_SPHERE, (float(radius), 0.0, 0.0))


def cylinder_solid(radius: float, length: float) -> Solid:
    """The solid of a cylinder along z."""
    return Solid(SOLID_CYLINDER, (float(radius), 0.5 * float(length), 0.0))


def is_closed_surface(faces: np.ndarray) -> bool:
    """True iff the triangles form closed, consistently oriented surfaces: every directed edge
    appears once and its reverse once (each edge shared by exactly two faces, wound oppositely).
    A mesh that passes has an inside; ``mesh_containment`` treats it as solid."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) < 4:
        return False
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    if np.any(edges[:, 0] == edges[:, 1]):
        return False
    n = int(faces.max()) + 1
    directed = edges[:, 0] * n + edges[:, 1]
    reverse = edges[:, 1] * n + edges[:, 0]
    if len(np.unique(directed)) != len(directed):
        return False
    return bool(np.all(np.isin(reverse, directed)))


def box_mesh(size):
    """Return the triangles of a box centred on the origin.

    :param size: ``(3,)`` edge lengths along x, y, z.
    :return: ``vertices : (8, 3) float64``, ``faces : (12, 3) int64``, outward winding.
    """
    half = 0.5 * np.asarray(size, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                       dtype=np.float64)
    # Corner index = 4 * (x > 0) + 2 * (y > 0) + (z > 0).
    faces = np.array([
        [0, 1, 3], [0, 3, 2],   # -x
        [4, 6, 7], [4, 7, 5],   # +x
        [0, 4, 5], [0, 5, 1],   # -y
        [2, 3, 7], [2, 7, 6],   # +y
        [0, 2, 6], [0, 6, 4],   # -z
        [1, 5, 7], [1, 7, 3],   # +z
    ], dtype=np.int64)
    return np.ascontiguousarray(corners * half), faces


def cylinder_mesh(radius: float, length: float, sections: int = 32):
    """Return the triangles of a cylinder along z, centred on the origin, inscribed.

    :param radius: radius of the cylinder.
    :param length: extent along z.
    :param sections: vertices around each cap circle, at least 3.
    :return: ``vertices : (2 sections + 2, 3) float64``, ``faces : (4 sections, 3) int64``.
    """
    n = _check_sections(sections)
    angle = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    half = 0.5 * length
    vertices = np.concatenate([
        np.column_stack([ring, np.full(n, -half)]),
        np.column_stack([ring, np.full(n, half)]),
        [[0.0, 0.0, -half], [0.0, 0.0, half]],
    ])
    k = np.arange(n)
    k1 = (k + 1) % n
    bottom, top = 2 * n, 2 * n + 1
    faces = np.concatenate([
        np.stack([k, k1, n + k1], axis=1),
        np.stack([k, n + k1, n + k], axis=1),
        np.stack([np.full(n, bottom), k1, k], axis=1),
        np.stack([np.full(n, top), n + k, n + k1], axis=1),
    ]).astype(np.int64)
    return np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces)


def sphere_mesh(radius: float, sections: int = 32):
    """Return the triangles of a UV sphere centred on the origin, inscribed.

    :param radius: radius of the sphere.
    :param sections: meridians, at least 3; ``stacks = max(2, sections // 2)`` bands.
    :return: ``vertices : (sections (stacks - 1) + 2, 3) float64``,
        ``faces : (2 sections (stacks - 1), 3) int64``.
    """
    n = _check_sections(sections)
    stacks = max(2, n // 2)
    polar = np.pi * np.arange(1, stacks) / stacks                    # (stacks - 1,)
    azimuth = 2.0 * np.pi * np.arange(n) / n                          # (n,)
    sin_p, cos_p = np.sin(polar)[:, None], np.cos(polar)[:, None]
    rings = np.stack([sin_p * np.cos(azimuth), sin_p * np.sin(azimuth),
                      np.broadcast_to(cos_p, (stacks - 1, n))], axis=2).reshape(-1, 3)
    vertices = radius * np.concatenate([rings, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    north, south = len(rings), len(rings) + 1
    k = np.arange(n)
    k1 = (k + 1) % n
    faces = [np.stack([np.full(n, north), k, k1], axis=1)]
    for i in range(stacks - 2):
        a, b = i * n, (i + 1) * n
        faces.append(np.stack([a + k, b + k, b + k1], axis=1))
        faces.append(np.stack([a + k, b + k1, a + k1], axis=1))
    last = (stacks - 2) * n
    faces.append(np.stack([np.full(n, south), last + k1, last + k], axis=1))
    return (np.ascontiguousarray(vertices, dtype=np.float64),
            np.ascontiguousarray(np.concatenate(faces).astype(np.int64)))


def _check_sections(sections):
    n = int(sections)
    if n < 3:
        raise ConfigError(f'primitive_sections={sections}: a primitive needs at least 3 sections '
                          'to enclose a volume; give 3 or more (default 32)')
    return n
