"""Hierarchy-versus-hierarchy traversal of two OBB trees (paper sec. 4.1), compiled.

Two trees, each in its own body frame, are tested from their roots down. When two boxes
overlap, one of them is expanded (its two children are tested against the other box); when
both are leaves, their triangles are tested exactly. Which side is expanded is the paper's
"node expansion consideration"; four rules are offered:

* ``EXPAND_SAME``: always expand the first tree until it reaches a leaf, then the second;
* ``EXPAND_ALTERNATE``: alternate sides with the depth of the descent;
* ``EXPAND_LARGER``: expand the node with the larger box volume;
* ``EXPAND_PROMISING``: expand the node whose volume most exceeds the sum of its children's
  volumes (the paper's "most promising node").

The answer never depends on the rule, only the work done; ``collision_sensor.bench`` measures
which rule is fastest on real robots and the checker's default follows that measurement.
"""
import numba

from collision_sensor.box_test import boxes_disjoint
from collision_sensor.tolerances import SPHERE_EPS_REL
from collision_sensor.triangle_test import triangles_intersect

EXPAND_SAME, EXPAND_ALTERNATE, EXPAND_LARGER, EXPAND_PROMISING = 0, 1, 2, 3
EXPANSION_RULES = {
    'same': EXPAND_SAME, 'alternate': EXPAND_ALTERNATE, 'larger': EXPAND_LARGER,
    'promising': EXPAND_PROMISING,
}

# counters[COUNT_*]: work done, for the benchmarks: box tests, triangle tests, and box pairs
# skipped by the sphere pre-test.
COUNT_BOX_TESTS, COUNT_TRIANGLE_TESTS, COUNT_SPHERE_SKIPS = 0, 1, 2
N_COUNTERS = 3
TRAVERSAL_WORK = 100


@numba.njit(cache=True, inline='always')
def relative_box(center, axes, na, nb, R_ab, t_ab, R, t):
    """Express box ``nb`` in box ``na``'s frame, writing ``R`` (3, 3) and ``t`` (3,).

    Boxes live in their bodies' frames; ``R_ab, t_ab`` is body b's pose in body a's frame.
    With ``T_a = [Ea, ca]`` and ``T_b = [Eb, cb]`` (``center``, ``axes`` rows ``na``, ``nb``)::

        [R, t] = T_a^-1 [R_ab, t_ab] T_b = [Ea' R_ab Eb, Ea' (R_ab cb + t_ab - ca)]

    Indices rather than row views: a view costs two atomic reference-count updates, which
    in the traversal's inner loop cost more than the arithmetic.
    """
    for j in range(3):
        # Column j of R_ab Eb, then its coordinates on Ea's axes.
        w0 = R_ab[0, 0] * axes[nb, 0, j] + R_ab[0, 1] * axes[nb, 1, j] + R_ab[0, 2] * axes[nb, 2, j]
        w1 = R_ab[1, 0] * axes[nb, 0, j] + R_ab[1, 1] * axes[nb, 1, j] + R_ab[1, 2] * axes[nb, 2, j]
        w2 = R_ab[2, 0] * axes[nb, 0, j] + R_ab[2, 1] * axes[nb, 1, j] + R_ab[2, 2] * axes[nb, 2, j]
        for i in range(3):
            R[i, j] = axes[na, 0, i] * w0 + axes[na, 1, i] * w1 + axes[na, 2, i] * w2
    d0 = (R_ab[0, 0] * center[nb, 0] + R_ab[0, 1] * center[nb, 1] + R_ab[0, 2] * center[nb, 2]
          + t_ab[0] - center[na, 0])
    d1 = (R_ab[1, 0] * center[nb, 0] + R_ab[1, 1] * center[nb, 1] + R_ab[1, 2] * center[nb, 2]
          + t_ab[1] - center[na, 1])
    d2 = (R_ab[2, 0] * center[nb, 0] + R_ab[2, 1] * center[nb, 1] + R_ab[2, 2] * center[nb, 2]
          + t_ab[2] - center[na, 2])
    for i in range(3):
        t[i] = axes[na, 0, i] * d0 + axes[na, 1, i] * d1 + axes[na, 2, i] * d2


@numba.njit(cache=True, inline='always')
def spheres_apart(center, radius, na, nb, R_ab, t_ab):
    """True iff the spheres around boxes ``na`` and ``nb`` are clearly apart.

    A cheap pre-test before the box test: the sphere around a box (centre the box centre,
    radius |half|) contains it, so spheres apart means boxes apart.
    """
    d0 = (R_ab[0, 0] * center[nb, 0] + R_ab[0, 1] * center[nb, 1] + R_ab[0, 2] * center[nb, 2]
          + t_ab[0] - center[na, 0])
    d1 = (R_ab[1, 0] * center[nb, 0] + R_ab[1, 1] * center[nb, 1] + R_ab[1, 2] * center[nb, 2]
          + t_ab[1] - center[na, 1])
    d2 = (R_ab[2, 0] * center[nb, 0] + R_ab[2, 1] * center[nb, 1] + R_ab[2, 2] * center[nb, 2]
          + t_ab[2] - center[na, 2])
    reach = (radius[na] + radius[nb]) * (1.0 + SPHERE_EPS_REL)
    return d0 * d0 + d1 * d1 + d2 * d2 > reach * reach


@numba.njit(cache=True, inline='always')
def copy_row(source, n, out):
    """``out[:] = source[n]`` for (3,) rows, without making a view of ``source``."""
    out[0] = source[n, 0]
    out[1] = source[n, 1]
    out[2] = source[n, 2]


@numba.njit(cache=True, inline='always')
def transform_triangle(tris, n, R_ab, t_ab, out):
    """Write ``R_ab v + t_ab`` for each row ``v`` of ``tris[n]`` (3, 3) into ``out`` (3, 3)."""
    for k in range(3):
        for i in range(3):
            out[k, i] = (R_ab[i, 0] * tris[n, k, 0] + R_ab[i, 1] * tris[n, k, 1]
                         + R_ab[i, 2] * tris[n, k, 2] + t_ab[i])


@numba.njit(cache=True, inline='always')
def copy_triangle(tris, n, out):
    """``out[:, :] = tris[n]`` without making a view of ``tris``."""
    for k in range(3):
        for i in range(3):
            out[k, i] = tris[n, k, i]


@numba.njit(cache=True, inline='always')
def trees_collide(root_a, root_b, R_ab, t_ab, center, axes, half, radius, volume, gain, left,
                  right, first, count, tris, box_method, expansion, stack, work, counters):
    """Return True iff any triangle of tree ``root_a`` meets any triangle of tree ``root_b``.

    Contract in plain Python::

        any(triangles_intersect(P, R_ab @ Q + t_ab)
            for P in triangles(root_a) for Q in triangles(root_b))

    computed by descending both trees and pruning node pairs whose boxes are disjoint.

    :param R_ab, t_ab: (3, 3), (3,): tree b's body pose in tree a's body frame.
    :param center, axes, half, radius, volume, gain, left, right, first, count, tris: the
        :class:`~collision_sensor.obb_tree.ObbForest` arrays.
    :param box_method: ``box_test.BOX_TEST_PAPER`` or ``BOX_TEST_SAT``.
    :param expansion: one of the ``EXPAND_*`` rules.
    :param stack: (S, 3) int64 work stack; S >= depth(a) + depth(b) + 2.
    :param work: (TRAVERSAL_WORK,) float64 work buffer.
    :param counters: (N_COUNTERS,) int64, work done is added to it.
    """
    # Views made once: making one in the loop costs more than a box test.
    R = work[0:9].reshape(3, 3)
    t = work[9:12]
    ha = work[12:15]
    hb = work[15:18]
    P = work[18:27].reshape(3, 3)
    Q = work[27:36].reshape(3, 3)
    scratch = work[36:100]
    stack[0, 0] = root_a
    stack[0, 1] = root_b
    stack[0, 2] = 0
    top = 1
    while top > 0:
        top -= 1
        na = stack[top, 0]
        nb = stack[top, 1]
        level = stack[top, 2]
        if spheres_apart(center, radius, na, nb, R_ab, t_ab):
            counters[COUNT_SPHERE_SKIPS] += 1
            continue
        relative_box(center, axes, na, nb, R_ab, t_ab, R, t)
        copy_row(half, na, ha)
        copy_row(half, nb, hb)
        counters[COUNT_BOX_TESTS] += 1
        if boxes_disjoint(box_method, ha, hb, R, t, scratch):
            continue
        leaf_a = left[na] < 0
        leaf_b = left[nb] < 0
        if leaf_a and leaf_b:
            for ib in range(first[nb], first[nb] + count[nb]):
                transform_triangle(tris, ib, R_ab, t_ab, Q)
                for ia in range(first[na], first[na] + count[na]):
                    counters[COUNT_TRIANGLE_TESTS] += 1
                    copy_triangle(tris, ia, P)
                    if triangles_intersect(P, Q):
                        return True
            continue
        if leaf_a:
            expand_a = False
        elif leaf_b:
            expand_a = True
        elif expansion == EXPAND_SAME:
            expand_a = True
        elif expansion == EXPAND_ALTERNATE:
            expand_a = level % 2 == 0
        elif expansion == EXPAND_LARGER:
            expand_a = volume[na] >= volume[nb]
        else:
            expand_a = gain[na] >= gain[nb]
        if expand_a:
            stack[top, 0], stack[top, 1], stack[top, 2] = right[na], nb, level + 1
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = left[na], nb, level + 1
        else:
            stack[top, 0], stack[top, 1], stack[top, 2] = na, right[nb], level + 1
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = na, left[nb], level + 1
        top += 2
    return False
