"""Oriented-bounding-box trees over triangle meshes, stored flat (paper sec. 2 and 3).

Every collision element (one ``<collision>`` of a link, or one scene object) gets its own
binary OBB tree, built top-down over its triangles: a node's box is fitted to the vertices of
the triangles beneath it, split at the mean of the triangle centroids along the one of the
box's three axes whose halves' boxes have the least surface, down to leaves of at most
``leaf_size`` triangles. All trees of a checker
live in one :class:`ObbForest`, structure of arrays, so that the compiled traversal indexes
nodes by integers and never sees a Python object.

Conventions, shared with :mod:`collision_sensor.engine.bounding_volumes`:

* boxes live in their body's frame (the link frame, or the scene object's frame) and are never
  refitted when the body moves (paper sec. 2.1: "the link and its bounding volume move
  together");
* ``axes[n][:, k]`` is box ``n``'s k-th axis in the body frame, a right-handed orthonormal frame;
  ``half[n]`` its half extents; ``center[n]`` its centre in the body frame;
* ``left[n] == -1`` marks a leaf, whose triangles are ``tris[first[n]:first[n] + count[n]]``;
* ``gain[n] = volume(n) - volume(left) - volume(right)`` is the paper's "most promising node"
  score (sec. 4.1), 0 for leaves.
"""
import concurrent.futures
from dataclasses import dataclass

import numpy as np

from collision_sensor.engine.bounding_volumes import (
    OBB_HULL_PCA, OBB_MIN_VOLUME, OBB_PCA, OBB_REFINED, fit_obb)
from collision_sensor.engine.compiled import engine
from collision_sensor.errors import EngineInputError


# Columns of a box table (:func:`box_table`), one row per box, what the compiled traversal
# reads (``cpp/obb_tree.hpp``): a box's numbers side by side in memory (128 bytes), rather than
# spread over four arrays, and indexable without making array views. BOX_CENTER: 3, centre in
# the body frame; BOX_AXES: 9, axes row-major (element 3 * i + k is row i of axis k); BOX_HALF:
# 3, half extents; BOX_RADIUS: 1, radius of the sphere around the box, |half|.
BOX_CENTER, BOX_AXES, BOX_HALF, BOX_RADIUS = (engine.BOX_CENTER, engine.BOX_AXES,
                                              engine.BOX_HALF, engine.BOX_RADIUS)
BOX_WIDTH = engine.BOX_WIDTH
# Columns of a node table (:func:`node_table`).
NODE_LEFT, NODE_RIGHT, NODE_FIRST, NODE_COUNT = (engine.NODE_LEFT, engine.NODE_RIGHT,
                                                 engine.NODE_FIRST, engine.NODE_COUNT)
NODE_WIDTH = engine.NODE_WIDTH


@dataclass(frozen=True)
class ObbForest:
    """All OBB trees of one checker, concatenated.

    :ivar center: (N, 3) float64, box centres in the owning body's frame.
    :ivar axes: (N, 3, 3) float64, box axes as columns.
    :ivar half: (N, 3) float64, half extents.
    :ivar radius: (N,) float64, radius of the sphere around the box (|half|), a pre-test.
    :ivar volume: (N,) float64, box volumes.
    :ivar gain: (N,) float64, parent volume minus the children's volumes (0 for leaves).
    :ivar left: (N,) int64, left child or -1 for a leaf.
    :ivar right: (N,) int64, right child or -1 for a leaf.
    :ivar first: (N,) int64, first triangle of a leaf.
    :ivar count: (N,) int64, triangle count of a leaf (0 for inner nodes).
    :ivar tris: (T, 3, 3) float64, triangles in the body frame, rows are vertices.
    :ivar roots: (E,) int64, root node of each tree.
    :ivar depth: (E,) int64, depth of each tree (a lone leaf has depth 1).
    """

    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    radius: np.ndarray
    volume: np.ndarray
    gain: np.ndarray
    left: np.ndarray
    right: np.ndarray
    first: np.ndarray
    count: np.ndarray
    tris: np.ndarray
    roots: np.ndarray
    depth: np.ndarray

    @property
    def node_count(self) -> int:
        return len(self.left)

    def nbytes(self) -> int:
        """Return the memory held by the forest's arrays, in bytes."""
        return sum(getattr(self, name).nbytes for name in self.__dataclass_fields__)


def build_tree_kernel(tris, leaf_size, center, axes, half, left, right, first, count, order,
                      refine=False):
    """Build one OBB tree over ``tris`` into preallocated node arrays; return (nodes, depth).

    C++ (cpp/obb_tree.cpp, ``engine.build_obb_tree``; runs without the GIL). Contract in plain
    Python::

        root covers all triangles; a node with more than leaf_size triangles is split in two
        at the mean centroid projection on one of its box's axes: of the axes leaving no side
        empty, the first minimising surface(left) + surface(right), surface(side) = h0 h1 +
        h1 h2 + h2 h0 of the half extents of the side's vertices along the node's axes (the
        halves of the list if every axis leaves a side empty); each node's box is fit_obb_pca
        of its vertices (with refine, fit_obb_refined for nodes of more than m / 64
        triangles); nodes are numbered in creation order, children after their parent.

    :param tris: (m, 3, 3) float64 triangles, m >= 1.
    :param leaf_size: most triangles in a leaf (>= 1).
    :param center, axes, half: (cap, 3), (cap, 3, 3), (cap, 3) float64, written in place.
    :param left, right, first, count: (cap,) int64, written in place.
    :param order: (m,) int64 work array; on return, leaf ``n`` holds
        ``tris[order[first[n]:first[n] + count[n]]]``.
    Node arrays must hold ``cap >= 2 * m - 1`` nodes and be C-contiguous of exactly these
    dtypes (they are written in place, never copied).
    """
    return engine.build_obb_tree(tris, leaf_size, center, axes, half, left, right, first, count,
                                 order, refine)


def triangles_of(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Return (m, 3, 3) float64 triangles from (n, 3) vertices and (m, 3) faces."""
    return np.ascontiguousarray(np.asarray(vertices, dtype=np.float64)[np.asarray(faces)])


def _refit(tris_sorted, center, axes, half, left, right, first, count, n_nodes, method):
    """Refit every node's box with a slower fit (hull PCA, minimum volume), same topology."""
    # A node's triangles are a contiguous range of the sorted list; children have larger
    # indices than their parent, so one backward sweep gives every node's range.
    span_start = np.empty(n_nodes, dtype=np.int64)
    span_end = np.empty(n_nodes, dtype=np.int64)
    for node in range(n_nodes - 1, -1, -1):
        if left[node] < 0:
            span_start[node] = first[node]
            span_end[node] = first[node] + count[node]
        else:
            span_start[node] = span_start[left[node]]
            span_end[node] = span_end[right[node]]
    for node in range(n_nodes):
        tri = tris_sorted[span_start[node]:span_end[node]]
        points = tri.reshape(-1, 3)
        faces = np.arange(len(points)).reshape(-1, 3)
        center[node], axes[node], half[node] = fit_obb(points, method, faces=faces)


def _build_tree(mesh, leaf_size: int, fit: int) -> dict:
    """One mesh's tree, numbered from 0: its node arrays, sorted triangles and depth."""
    vertices, faces = mesh
    tris = triangles_of(vertices, faces)
    m = len(tris)
    cap = 2 * m - 1
    center = np.empty((cap, 3))
    axes = np.empty((cap, 3, 3))
    half = np.empty((cap, 3))
    left = np.empty(cap, dtype=np.int64)
    right = np.empty(cap, dtype=np.int64)
    first = np.empty(cap, dtype=np.int64)
    count = np.empty(cap, dtype=np.int64)
    order = np.empty(m, dtype=np.int64)
    n_nodes, depth = build_tree_kernel(
        tris, leaf_size, center, axes, half, left, right, first, count, order,
        refine=fit == OBB_REFINED)
    tris_sorted = tris[order]
    if fit in (OBB_HULL_PCA, OBB_MIN_VOLUME):
        _refit(tris_sorted, center, axes, half, left, right, first, count, n_nodes, fit)
    return dict(center=center[:n_nodes], axes=axes[:n_nodes], half=half[:n_nodes],
                left=left[:n_nodes], right=right[:n_nodes], first=first[:n_nodes],
                count=count[:n_nodes], tris=tris_sorted, depth=depth)


def build_forest(meshes, leaf_size: int = 2, fit: int = OBB_PCA,
                 threads: int = 1) -> ObbForest:
    """Build one OBB tree per mesh and concatenate them.

    :param meshes: sequence of ((n, 3) float vertices, (m, 3) int faces), in body frames.
    :param leaf_size: most triangles per leaf.
    :param fit: OBB_PCA (default, the paper's Wu method), OBB_REFINED (the same, the top of
        each tree tightened around each principal axis, in the same build), OBB_HULL_PCA or
        OBB_MIN_VOLUME (boxes refitted after the build, in Python: slow).
    :param threads: trees built at once (the kernel runs without the GIL); the forest is the
        same whatever the number.
    :return: the forest; ``roots[i]`` is mesh ``i``'s root node.
    """
    if leaf_size < 1:
        raise EngineInputError(f'leaf_size must be at least 1, got {leaf_size}')
    meshes = list(meshes)
    if threads > 1 and len(meshes) > 1:
        # the largest first, so that no thread is left with a large one at the end
        largest_first = sorted(range(len(meshes)), key=lambda i: -len(meshes[i][1]))
        with concurrent.futures.ThreadPoolExecutor(min(threads, len(meshes))) as pool:
            built = dict(zip(largest_first, pool.map(
                lambda i: _build_tree(meshes[i], leaf_size, fit), largest_first)))
        trees = [built[i] for i in range(len(meshes))]
    else:
        trees = [_build_tree(mesh, leaf_size, fit) for mesh in meshes]
    parts = []
    node_offset = 0
    tri_offset = 0
    for tree in trees:
        n_nodes, m = len(tree['left']), len(tree['tris'])
        inner = tree['left'] >= 0
        left = tree['left'].copy()
        right = tree['right'].copy()
        left[inner] += node_offset
        right[inner] += node_offset
        parts.append(dict(tree, left=left, right=right, first=tree['first'] + tri_offset,
                          root=node_offset))
        node_offset += n_nodes
        tri_offset += m

    def cat(key, shape, dtype):
        if not parts:
            return np.zeros(shape, dtype=dtype)
        return np.ascontiguousarray(np.concatenate([p[key] for p in parts]), dtype=dtype)

    center = cat('center', (0, 3), np.float64)
    axes = cat('axes', (0, 3, 3), np.float64)
    half = cat('half', (0, 3), np.float64)
    left = cat('left', (0,), np.int64)
    right = cat('right', (0,), np.int64)
    volume = 8.0 * np.prod(half, axis=1)
    gain = np.zeros(len(left))
    inner = left >= 0
    gain[inner] = volume[inner] - volume[left[inner]] - volume[right[inner]]
    return ObbForest(
        center=center, axes=axes, half=half, radius=np.sqrt((half * half).sum(axis=1)),
        volume=volume, gain=gain, left=left, right=right,
        first=cat('first', (0,), np.int64), count=cat('count', (0,), np.int64),
        tris=cat('tris', (0, 3, 3), np.float64),
        roots=np.array([p['root'] for p in parts], dtype=np.int64),
        depth=np.array([p['depth'] for p in parts], dtype=np.int64))


def box_table(center: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Return the (N, BOX_WIDTH) float64 box table of boxes given as (N, 3), (N, 3, 3), (N, 3)."""
    center = np.asarray(center, dtype=np.float64).reshape(-1, 3)
    table = np.zeros((len(center), BOX_WIDTH))
    table[:, BOX_CENTER:BOX_CENTER + 3] = center
    table[:, BOX_AXES:BOX_AXES + 9] = np.asarray(axes, dtype=np.float64).reshape(-1, 9)
    table[:, BOX_HALF:BOX_HALF + 3] = half
    table[:, BOX_RADIUS] = np.sqrt((np.asarray(half) ** 2).sum(axis=1))
    return table


def forest_view(boxes: np.ndarray, nodes: np.ndarray, volume: np.ndarray, gain: np.ndarray,
                tris: np.ndarray, roots: np.ndarray, depth: np.ndarray) -> ObbForest:
    """Return an :class:`ObbForest` whose arrays are views of a box and a node table.

    The checker keeps the tables its kernel reads (:func:`box_table`, :func:`node_table`);
    the forest it shows is these views, so no number is held twice. ``center``, ``half``,
    ``left`` ... are then strided views (columns of the tables), not contiguous arrays.

    :param boxes: (N, BOX_WIDTH) float64; ``nodes``: (N, NODE_WIDTH) int64;
        ``volume, gain``: (N,) float64; ``tris``: (T, 3, 3) float64; ``roots, depth``: (E,).
    """
    forest = ObbForest(
        center=boxes[:, BOX_CENTER:BOX_CENTER + 3],
        axes=boxes[:, BOX_AXES:BOX_AXES + 9].reshape(-1, 3, 3),
        half=boxes[:, BOX_HALF:BOX_HALF + 3], radius=boxes[:, BOX_RADIUS],
        volume=volume, gain=gain, left=nodes[:, NODE_LEFT], right=nodes[:, NODE_RIGHT],
        first=nodes[:, NODE_FIRST], count=nodes[:, NODE_COUNT], tris=tris, roots=roots,
        depth=depth)
    # reshape copies silently when it cannot make a view; a copy here would double memory.
    assert len(boxes) == 0 or np.shares_memory(forest.axes, boxes)
    return forest


def node_table(forest: ObbForest) -> np.ndarray:
    """Return the (N, NODE_WIDTH) int64 node table: left, right, first, count per node."""
    return np.ascontiguousarray(
        np.stack([forest.left, forest.right, forest.first, forest.count], axis=1),
        dtype=np.int64).reshape(-1, NODE_WIDTH)

