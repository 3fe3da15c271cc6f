"""STL files (binary and ASCII) read with numpy alone.

STL is the mesh format of most robot descriptions' collision geometry. Reading it here, rather
through trimesh, keeps a robot's first verdict from waiting for trimesh's import (with scipy
and networkx behind it, about 3 s with cold bytecode caches on a small machine): trimesh is
imported only for the other formats.

Binary STL: an 80-byte header, a uint32 triangle count, then per triangle 12 float32 (normal,
three vertices) and a uint16; the file size is exactly ``84 + 50 * count``. Anything else is
read as ASCII (``vertex x y z`` lines, three per facet). Vertices that are exactly equal are
merged into one, in the order they first appear, as a mesh loader does; the normals are
ignored (the winding of each facet is kept as written).
"""
import os
import re

import numpy as np

_BINARY_RECORD = np.dtype([('normal', '<f4', (3,)), ('vertices', '<f4', (3, 3)),
                           ('attribute', '<u2')])
_VERTEX = re.compile(rb'^\s*vertex\s+(\S+)\s+(\S+)\s+(\S+)', re.MULTILINE)


class StlError(ValueError):
    """The file is not a readable STL; the message says why."""


def read_stl(path: str):
    """Return ``vertices (n, 3) float64, faces (m, 3) int64`` of the STL file at ``path``.

    :raises StlError: a truncated binary file, or an ASCII file whose vertices are not
        numbers or not a multiple of three.
    """
    size = os.path.getsize(path)
    if size < 84 and not _starts_ascii(path):
        return merge_vertices(np.zeros((0, 3)))  # too short for a single triangle
    with open(path, 'rb') as stream:
        head = stream.read(84)
        count = int.from_bytes(head[80:84], 'little') if len(head) == 84 else -1
        if count >= 0 and size == 84 + 50 * count:
            records = np.fromfile(stream, dtype=_BINARY_RECORD, count=count)
            corners = records['vertices'].astype(np.float64).reshape(-1, 3)
            return merge_vertices(corners)
        stream.seek(0)
        text = stream.read()
    if not text.lstrip().startswith(b'solid'):
        raise StlError(f'{size} bytes: neither a binary STL (84 + 50 per triangle) nor ASCII '
                       '(starting with "solid")')
    try:
        corners = np.array(_VERTEX.findall(text), dtype=np.float64).reshape(-1, 3)
    except ValueError as error:
        raise StlError(f'ASCII STL with a vertex that is not three numbers ({error})') from None
    if len(corners) % 3:
        raise StlError(f'ASCII STL with {len(corners)} vertices, not three per facet')
    return merge_vertices(corners)


def _starts_ascii(path: str) -> bool:
    with open(path, 'rb') as stream:
        return stream.read(84).lstrip().startswith(b'solid')


def merge_vertices(corners: np.ndarray):
    """Return ``vertices, faces`` for triangles given as consecutive corner triples (k, 3):
    exactly equal corners become one vertex, numbered in the order they first appear."""
    if len(corners) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    unique, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind='stable')
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = np.ascontiguousarray(unique[order])
    faces = np.ascontiguousarray(rank[inverse.reshape(-1)].reshape(-1, 3).astype(np.int64))
    return vertices, faces
