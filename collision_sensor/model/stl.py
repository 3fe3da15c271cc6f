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


#: Odd 64-bit multipliers of :func:`merge_vertices`' hash, one per coordinate word.
_HASH_WORDS = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9],
                       dtype=np.uint64)


def merge_vertices(corners: np.ndarray):
    """Return ``vertices, faces`` for triangles given as consecutive corner triples (k, 3):
    exactly equal corners become one vertex, numbered in the order they first appear.

    Corners are grouped by a 64-bit hash of their coordinates (one sort of integers, not a sort
    of rows) and each group is then checked to hold one corner only; a hash shared by unequal
    corners (or a NaN) falls back to sorting the rows.
    """
    if len(corners) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    corners = np.ascontiguousarray(corners, dtype=np.float64) + 0.0   # -0.0 as 0.0
    words = corners.view(np.uint64)
    keys = np.zeros(len(words), dtype=np.uint64)
    for k in range(3):      # multiply and xor-shift each word in (modulo 2**64)
        keys ^= words[:, k]
        keys *= _HASH_WORDS[k]
        keys ^= keys >> np.uint64(31)
    order = np.argsort(keys)
    sorted_keys = keys[order]
    change = sorted_keys[1:] != sorted_keys[:-1]
    starts = np.flatnonzero(np.concatenate(([True], change)))
    group = np.cumsum(np.concatenate(([0], change)))
    first = np.minimum.reduceat(order, starts)      # each group's first corner in the file
    if not np.array_equal(corners[order], corners[first[group]]):
        return _merge_vertices_by_rows(corners)
    inverse = np.empty(len(corners), dtype=np.int64)
    inverse[order] = group
    return _numbered_by_first(corners, first, inverse)


def _merge_vertices_by_rows(corners: np.ndarray):
    """:func:`merge_vertices` by sorting the rows (slow, and exact whatever the hash does)."""
    _, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    return _numbered_by_first(corners, first, inverse.reshape(-1))


def _numbered_by_first(corners: np.ndarray, first: np.ndarray, inverse: np.ndarray):
    """Vertices and faces from groups of equal corners (``first``: each group's first corner,
    ``inverse``: each corner's group), the groups numbered in the order they first appear."""
    order = np.argsort(first, kind='stable')
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = np.ascontiguousarray(corners[first[order]])
    faces = np.ascontiguousarray(rank[inverse].reshape(-1, 3).astype(np.int64))
    return vertices, faces
