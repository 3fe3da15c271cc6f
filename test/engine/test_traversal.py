"""The traversal of two OBB trees (``cpp/traversal.hpp``: collide_trees) against brute force
over every triangle pair: the pair meets exactly when some triangles are within pad +
inflation, a meeting pair named is one, and the gap is a lower bound of the distance minus
pad + inflation; for every box test and expansion rule."""
import numpy as np
import pytest
import trimesh

from collision_sensor.engine.compiled import engine
from collision_sensor.engine.obb_tree import box_table, build_forest, node_table
from collision_sensor.engine.traversal import EXPANSION_RULES
from engine_kernels import triangle_distance

#: Pairs within this of the threshold are not judged (the triangle test's tolerance, rounding).
MARGIN = 1e-9


def _posed(tris, R, t):
    return tris @ R.T + t


def _meshes(rng):
    """Two bodies: an icosphere, and a soup of loose triangles, in their own frames."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    soup = rng.uniform(-0.08, 0.08, (60, 3)) + rng.uniform(-0.02, 0.02, 3)
    return [(sphere.vertices, sphere.faces), (soup, np.arange(60).reshape(-1, 3))]


def _rotation(rng):
    q = rng.normal(size=4)
    return trimesh.transformations.quaternion_matrix(q / np.linalg.norm(q))[:3, :3]


@pytest.mark.parametrize('box_test', ['sat', 'paper'])
def test_inflated_traversal_meets_exactly_within_pad_plus_inflation(box_test):
    rng = np.random.default_rng(41)
    forest = build_forest(_meshes(rng), leaf_size=1)
    tables = (box_table(forest.center, forest.axes, forest.half), node_table(forest),
              forest.volume, forest.gain, forest.tris)
    ra, rb = forest.roots
    n_a = _count(forest, ra)   # the first mesh's triangles come first
    tris_a, tris_b = forest.tris[:n_a], forest.tris[n_a:]
    code = engine.BOX_TEST_PAPER if box_test == 'paper' else engine.BOX_TEST_SAT
    judged = {True: 0, False: 0}
    for trial in range(120):
        R, t = _rotation(rng), rng.normal(size=3) * rng.choice([0.1, 0.2, 0.4])
        posed_b = _posed(tris_b, R, t)
        d = triangle_distance(np.repeat(tris_a, len(tris_b), axis=0),
                              np.tile(posed_b, (len(tris_a), 1, 1)))[0].min()
        pose = np.concatenate([R.ravel(), t])
        for pad, inflation in ((0.0, 0.0), (0.0, 0.03), (0.01, 0.0), (0.01, 0.05)):
            rule = list(EXPANSION_RULES.values())[trial % len(EXPANSION_RULES)]
            hit, ia, ib, gap = engine.collide_trees(*tables, ra, rb, pose, code, rule, pad,
                                                    inflation)
            within = pad + inflation
            if hit:
                pair = triangle_distance(forest.tris[ia], _posed(forest.tris[ib], R, t))[0]
                assert pair[0] <= within + MARGIN, (trial, pad, inflation)
            if abs(d - within) <= MARGIN:
                continue
            assert hit == (d < within), (trial, pad, inflation, d)
            judged[hit] += 1
            if not hit:
                assert gap <= d - within + MARGIN, (trial, pad, inflation, d, gap)
    assert judged[True] > 50 and judged[False] > 50


def _count(forest, root):
    """How many triangles the tree at root holds."""
    stack, count = [root], 0
    while stack:
        n = stack.pop()
        if forest.left[n] < 0:
            count += forest.count[n]
        else:
            stack += [forest.left[n], forest.right[n]]
    return count
