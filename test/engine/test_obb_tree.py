"""OBB trees: every box contains the geometry beneath it; the tree partitions the triangles."""
import numpy as np
import pytest
import trimesh

from collision_sensor.engine.bounding_volumes import OBB_HULL_PCA, OBB_MIN_VOLUME, OBB_PCA
from collision_sensor.engine.obb_tree import build_forest, build_tree_kernel


def _leaves_below(forest, node):
    stack, leaves = [node], []
    while stack:
        n = stack.pop()
        if forest.left[n] < 0:
            leaves.append(n)
        else:
            stack += [forest.left[n], forest.right[n]]
    return leaves


def _check_forest(forest, meshes, leaf_size):
    seen = np.zeros(len(forest.tris), dtype=int)
    for root, (vertices, faces) in zip(forest.roots, meshes):
        leaves = _leaves_below(forest, root)
        tris = np.concatenate([forest.tris[forest.first[n]:forest.first[n] + forest.count[n]]
                               for n in leaves])
        # The tree holds exactly the mesh's triangles, each once.
        expected = np.sort(vertices[faces].reshape(len(faces), -1), axis=0)
        np.testing.assert_array_equal(np.sort(tris.reshape(len(tris), -1), axis=0), expected)
        for n in leaves:
            assert 1 <= forest.count[n] <= leaf_size
            seen[forest.first[n]:forest.first[n] + forest.count[n]] += 1
        stack = [root]
        while stack:
            n = stack.pop()
            axes = forest.axes[n]
            np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-9)
            assert np.linalg.det(axes) > 0
            points = np.concatenate([forest.tris[forest.first[m]:forest.first[m] + forest.count[m]]
                                     for m in _leaves_below(forest, n)]).reshape(-1, 3)
            local = (points - forest.center[n]) @ axes
            scale = max(1.0, np.abs(points).max())
            assert np.all(np.abs(local) <= forest.half[n] + 1e-9 * scale)
            if forest.left[n] >= 0:
                stack += [forest.left[n], forest.right[n]]
                assert forest.gain[n] == pytest.approx(
                    forest.volume[n] - forest.volume[forest.left[n]]
                    - forest.volume[forest.right[n]])
    assert np.all(seen == 1)


@pytest.mark.parametrize('leaf_size', [1, 2, 5])
def test_boxes_contain_geometry_and_leaves_partition_triangles(leaf_size):
    rng = np.random.default_rng(0)
    meshes = [
        (trimesh.creation.icosphere(subdivisions=2).vertices,
         trimesh.creation.icosphere(subdivisions=2).faces),
        (trimesh.creation.cylinder(0.1, 2.0, sections=12).vertices,
         trimesh.creation.cylinder(0.1, 2.0, sections=12).faces),
        (rng.normal(size=(40, 3)) * [3.0, 0.2, 0.01], rng.integers(0, 40, size=(60, 3))),
    ]
    forest = build_forest(meshes, leaf_size=leaf_size)
    _check_forest(forest, meshes, leaf_size)
    # Trees built side by side on threads make the same forest, mesh for mesh.
    threaded = build_forest(meshes, leaf_size=leaf_size, threads=3)
    for name in forest.__dataclass_fields__:
        ours, theirs = getattr(forest, name), getattr(threaded, name)
        assert np.array_equal(ours, theirs), name


def test_degenerate_meshes_build():
    one = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    # Identical triangles: centroids coincide, the builder must still split them.
    same = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.zeros((9, 3), dtype=int)
            + np.array([0, 1, 2]))
    # Zero-area (collinear) triangles on a line.
    line = (np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]),
            np.array([[0, 1, 2], [1, 2, 3], [0, 0, 3]]))
    meshes = [one, same, line]
    forest = build_forest(meshes, leaf_size=1)
    _check_forest(forest, meshes, 1)
    assert forest.depth[1] <= 6  # nine identical triangles: halves, not a chain


@pytest.mark.slow
@pytest.mark.parametrize('fit', [OBB_HULL_PCA, OBB_MIN_VOLUME])
def test_slower_fits_keep_containment(fit):
    mesh = trimesh.creation.capsule(height=0.5, radius=0.1, count=[8, 8])
    meshes = [(mesh.vertices, mesh.faces)]
    _check_forest(build_forest(meshes, leaf_size=4, fit=fit), meshes, 4)
    pca = build_forest(meshes, leaf_size=4, fit=OBB_PCA)
    if fit == OBB_MIN_VOLUME:
        assert build_forest(meshes, 4, fit).volume[0] <= pca.volume[0] * (1 + 1e-9)


def test_tree_kernel_refuses_bad_buffers():
    # The node arrays are written in place: a wrong dtype or layout is refused (never copied,
    # which would lose the writes), a wrong shape names the argument.
    tris = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 2)
    cap = 3

    def buffers(**changes):
        arrays = dict(center=np.empty((cap, 3)), axes=np.empty((cap, 3, 3)),
                      half=np.empty((cap, 3)), left=np.empty(cap, dtype=np.int64),
                      right=np.empty(cap, dtype=np.int64), first=np.empty(cap, dtype=np.int64),
                      count=np.empty(cap, dtype=np.int64), order=np.empty(2, dtype=np.int64))
        arrays.update(changes)
        return arrays

    assert build_tree_kernel(tris, 1, **buffers()) == (3, 2)
    with pytest.raises(TypeError):
        build_tree_kernel(tris, 1, **buffers(left=np.empty(cap, dtype=np.int32)))
    with pytest.raises(TypeError):
        build_tree_kernel(tris, 1, **buffers(half=np.empty((3, cap)).T))
    with pytest.raises(ValueError, match='center'):
        build_tree_kernel(tris, 1, **buffers(center=np.empty((2, 3))))
    with pytest.raises(ValueError, match='order'):
        build_tree_kernel(tris, 1, **buffers(order=np.empty(3, dtype=np.int64)))
    with pytest.raises(ValueError, match='leaf_size'):
        build_tree_kernel(tris, 0, **buffers())
    with pytest.raises(ValueError, match='NaN'):
        build_tree_kernel(np.full((2, 3, 3), np.nan), 1, **buffers())
