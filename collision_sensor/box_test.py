"""Oriented-box / oriented-box overlap: the paper's three-type test (sec. 5) and the 15-axis SAT.

Arguments shared by every test here (coal's convention: ``[R, T] = [R1'R2, R1'(T2 - T1)]``)::

    ha, hb  : (3,) float64     half extents of box A and box B, >= 0; 0 is allowed
                               (a flat box, a segment, a point).
    R       : (3, 3) float64   proper rotation (det = +1) from F_B to F_A: column j is B's
                               j-th axis in F_A, so R = R_A^T R_B with R_A, R_B box-to-world.
    t       : (3,) float64     B's centre in F_A: t = R_A^T (c_B - c_A).
    scratch : (64,) float64    the caller's work buffer (the paper's test keeps the 8 + 8
                               vertices in it; the SAT does not use it).

Box A is centred at the origin of F_A and axis-aligned there. Each test returns True iff a
separating plane exists with a clear gap, False when the closed boxes meet (touching counts as
overlap). None allocates; all are plain ``@njit`` functions callable from compiled code.

Tolerance rule (``tolerances.BOX_EPS_REL``, ``BOX_EPS_PARALLEL``), the same in both tests: with
``s = ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]`` and ``tol = BOX_EPS_REL * s``, the boxes
are separated along a candidate axis L (unnormalised: a face normal has ``|L| = 1``, an
edge-edge axis ``a_i x b_j`` has ``|L| = sin`` of the angle between the edges) iff::

    |t . L| - r_A(L) - r_B(L)  >  tol * (|L| + BOX_EPS_PARALLEL)

i.e. the gap along the unit axis exceeds ``tol * (1 + BOX_EPS_PARALLEL / |L|)``. The floor
``tol * BOX_EPS_PARALLEL`` is what coal's ``|R| + eps`` does: an axis built from two nearly
parallel edges, whose direction is rounding noise, cannot separate. Both tests consider the same
axes: A's and B's face normals, and ``a_i x b_j`` for every i with ``ha[i] > 0`` (a box with no
extent along ``a_i`` has no edges along it, so the paper's hexagon has no such edge and the
axis is not needed: the test stays exact). With that, the paper's type 1 and type 2 checks are
evaluated in the very same floating-point operations as the SAT's six face axes (bit-identical
decisions); the type 3 and the edge-edge checks compute the same quantity in different ways,
so they can disagree only on an input whose edge-edge gap lies within rounding (~1e-15 s) of
the threshold. Input with a NaN or an infinity anywhere is never separated (both tests answer
False: err toward overlap).
"""
import math

import numba
import numpy as np

from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.tolerances import BOX_EPS_PARALLEL, BOX_EPS_REL

BOX_TEST_PAPER, BOX_TEST_SAT = 0, 1

# Paper Table 1 (sec. 5.1.3), restated in NOTES.md: row i is the silhouette hexagon of a box
# seen along a direction in which vertex i has the smallest coordinate; vertices i and 7 - i
# are hidden. Vertex numbering: bit k of the index selects min (0) or max (1) along box axis k,
# so i and 7 - i are opposite. Consecutive entries differ in exactly one bit (they are box
# edges), and every row runs counter-clockwise seen from the tip of the view direction when A's
# frame is right-handed (test_box_test.py checks both on random rotations). Hence, in the view
# plane coordinates (u, v) with u x v = view axis, the inside of the hexagon is on the left of
# each edge, and the division-free edge function f = alpha * u + beta * v + gamma, with
# alpha = v1 - v0, beta = u0 - u1, gamma = -(alpha * u0 + beta * v0), is > 0 exactly outside.
# The sign is known in advance, so no orientation is computed and a degenerate (zero-area)
# hexagon cannot flip it.
HEXAGON = np.array([
    [1, 3, 2, 6, 4, 5],
    [0, 4, 5, 7, 3, 2],
    [3, 7, 6, 4, 0, 1],
    [2, 0, 1, 5, 7, 6],
    [5, 1, 0, 2, 6, 7],
    [4, 6, 7, 3, 1, 0],
    [7, 5, 4, 0, 2, 3],
    [6, 2, 3, 1, 5, 4],
], dtype=np.int64)

# Orthographic view along B's axis j uses plane coordinates (u, v) = (y, z), (z, x), (x, y)
# (sec. 5.1.4), i.e. u = (j + 1) % 3, v = (j + 2) % 3, so that u x v = +axis j.
_AXIS_OF_BIT = (0, 0, 1, 1, 2, 2, 2, 2)   # index by (p0 ^ p1), which is 1, 2 or 4

# Scratch layout: B's vertices in F_A, coordinate-major (coordinate k of vertex i at 8 k + i),
# then A's vertices in F_B at 24 + 8 k + i.
_B_IN_A = 0
_A_IN_B = 24


@numba.njit(cache=True, inline='always')
def box_tolerance(ha, hb):
    """Return ``BOX_EPS_REL * (sum of the six half extents)``, the box tests' gap tolerance."""
    return BOX_EPS_REL * (ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2])


@numba.njit(cache=True, inline='always')
def _finite(ha, hb, R, t):
    # True iff no input is NaN or infinite: x * 0 is NaN exactly for those. Called only on the
    # way to answering "separated", so the common overlapping path pays nothing for it.
    acc = 0.0
    for k in range(3):
        acc += ha[k] * 0.0 + hb[k] * 0.0 + t[k] * 0.0
        acc += R[k, 0] * 0.0 + R[k, 1] * 0.0 + R[k, 2] * 0.0
    return acc == 0.0


@numba.njit(cache=True)
def _box_vertex_coordinates(c, w0, w1, w2, out, base):
    # Coordinate of the 8 vertices of a box along one axis: c + ((+-w0 +- w1) +- w2), with the
    # sign of w_k chosen by bit k of the vertex index. The association is fixed on purpose: the
    # extreme vertex then equals c -+ ((|w0| + |w1|) + |w2|) to the last bit, which is exactly
    # the radius the SAT computes, so type 1 / type 2 decide exactly as the SAT's face axes.
    for i in range(8):
        s0 = w0 if i & 1 else -w0
        s1 = w1 if i & 2 else -w1
        s2 = w2 if i & 4 else -w2
        out[base + i] = ((s0 + s1) + s2) + c


@numba.njit(cache=True)
def _beyond_face_planes(out, base, h, thr):
    # True iff all 8 coordinates lie beyond the face plane +h (x - h > thr) or all beyond -h
    # (-h - x > thr): sec. 5.1.1, at least 8 and at most 16 inequalities per axis.
    inside = False
    for i in range(8):
        if not (out[base + i] - h > thr):
            inside = True
            break
    if not inside:
        return True
    for i in range(8):
        if not (-h - out[base + i] > thr):
            return False
    return True


@numba.njit(cache=True, inline='always')
def boxes_disjoint_paper(ha, hb, R, t, scratch):
    """Return True iff boxes A and B are separated: the paper's sec. 5 test.

    Type 1: B's 8 vertices in F_A all beyond one of A's six face planes. Type 2: the same with
    A's vertices in F_B (``R^T x - R^T t``). Type 3: with A's vertices in F_B, in the views
    along B's three axes, all 4 corners of B's rectangle strictly outside one edge line of A's
    silhouette hexagon (Table 1). Gaps count only beyond the module's tolerance rule.

    :param ha: (3,) half extents of A.
    :param hb: (3,) half extents of B.
    :param R: (3, 3) rotation, column j = B's axis j in F_A.
    :param t: (3,) B's centre in F_A.
    :param scratch: (64,) float64 work buffer.
    :return: True if separated, False if the closed boxes meet.
    """
    tol = box_tolerance(ha, hb)
    thr_face = tol * (1.0 + BOX_EPS_PARALLEL)

    # Type 1 (sec. 5.1.1). Coordinate k of B's vertex i in F_A is t_k + sum_j +-R[k, j] hb_j;
    # one coordinate at a time, so an early exit skips the rest.
    for k in range(3):
        _box_vertex_coordinates(t[k], R[k, 0] * hb[0], R[k, 1] * hb[1], R[k, 2] * hb[2],
                                scratch, _B_IN_A + 8 * k)
        if _beyond_face_planes(scratch, _B_IN_A + 8 * k, ha[k], thr_face):
            return _finite(ha, hb, R, t)

    # Type 2: A's vertices in F_B, x_B = R^T x_A - R^T t; coordinate j of A's vertex i is
    # -(R^T t)_j + sum_k +-R[k, j] ha_k.
    for j in range(3):
        c = -((R[0, j] * t[0] + R[1, j] * t[1]) + R[2, j] * t[2])
        _box_vertex_coordinates(c, R[0, j] * ha[0], R[1, j] * ha[1], R[2, j] * ha[2],
                                scratch, _A_IN_B + 8 * j)
        if _beyond_face_planes(scratch, _A_IN_B + 8 * j, hb[j], thr_face):
            return _finite(ha, hb, R, t)

    # Type 3 (sec. 5.1.2 - 5.1.4): views along B's axes; B is the rectangle [-hb_u, hb_u] x
    # [-hb_v, hb_v], A the hexagon of Table 1.
    for j in range(3):
        iu = (j + 1) % 3
        iv = (j + 2) % 3
        hu = hb[iu]
        hv = hb[iv]
        # The vertex of A with the smallest coordinate along b_j: bit k is set iff a_k points
        # against b_j (R[k, j] < 0). This is the argmin of the 8 coordinates without ties
        # broken by rounding; on a tie (R[k, j] = 0 or ha_k = 0) both rows are valid.
        imin = 0
        if R[0, j] < 0.0:
            imin += 1
        if R[1, j] < 0.0:
            imin += 2
        if R[2, j] < 0.0:
            imin += 4
        for m in range(6):
            p0 = HEXAGON[imin, m]
            p1 = HEXAGON[imin, (m + 1) % 6]
            bit = p0 ^ p1
            k = _AXIS_OF_BIT[bit]
            # (u1 - u0, v1 - v0) is A's edge along a_k seen in the view: +-2 ha_k times row k
            # of R (a_k in F_B). Formed directly rather than by subtracting two rounded
            # vertices, so a thin box (ha_k << the coordinates) keeps an accurate edge
            # direction; the values are those of the paper's alpha and beta.
            e = 2.0 * ha[k] if p1 & bit else -2.0 * ha[k]
            alpha = e * R[k, iv]              # v1 - v0
            beta = -(e * R[k, iu])            # u0 - u1
            u0 = scratch[_A_IN_B + 8 * iu + p0]
            v0 = scratch[_A_IN_B + 8 * iv + p0]
            gamma = -(alpha * u0 + beta * v0)
            # All 4 corners strictly outside (f > 0); a zero-length edge has f = 0 everywhere.
            fmin = alpha * hu + beta * hv + gamma
            if not (fmin > 0.0):
                continue
            f = alpha * hu - beta * hv + gamma
            if not (f > 0.0):
                continue
            fmin = min(fmin, f)
            f = -alpha * hu + beta * hv + gamma
            if not (f > 0.0):
                continue
            fmin = min(fmin, f)
            f = -alpha * hu - beta * hv + gamma
            if not (f > 0.0):
                continue
            fmin = min(fmin, f)
            # f = |edge| * (distance from the edge line) and |edge| = 2 ha_k |L|: the rule
            # gap > tol (1 + EPS_PARALLEL / |L|) reads fmin > tol (|edge| + 2 ha_k EPS_PARALLEL).
            if fmin > tol * (math.sqrt(alpha * alpha + beta * beta)
                             + 2.0 * ha[k] * BOX_EPS_PARALLEL):
                return _finite(ha, hb, R, t)
    return False


@numba.njit(cache=True, inline='always')
def _edge_axis_separates(ti1, ti2, r_i1j, r_i2j, ha_i1, ha_i2, hb_j1, hb_j2, r_ij1, r_ij2, tol):
    """Edge-edge axis L = e_i x b_j (i1, i2 and j1, j2 the other indices, cyclic)::

        t . L = t[i2] R[i1, j] - t[i1] R[i2, j]
        r_A   = ha[i1] |R[i2, j]| + ha[i2] |R[i1, j]|
        r_B   = hb[j1] |R[i, j2]| + hb[j2] |R[i, j1]|
        |L|   = sqrt(R[i, j1]^2 + R[i, j2]^2)   (a_i in F_B minus its b_j component)
    """
    d = (abs(ti2 * r_i1j - ti1 * r_i2j)
         - (ha_i1 * abs(r_i2j) + ha_i2 * abs(r_i1j))
         - (hb_j1 * abs(r_ij2) + hb_j2 * abs(r_ij1)))
    if d > tol * BOX_EPS_PARALLEL:
        return d > tol * (math.sqrt(r_ij1 * r_ij1 + r_ij2 * r_ij2) + BOX_EPS_PARALLEL)
    return False


@numba.njit(cache=True, inline='always')
def _finite_scalars(a0, a1, a2, b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                    t0, t1, t2):
    # :func:`_finite` over the 18 numbers of a box pair: x * 0 is NaN exactly for NaN or inf.
    acc = (a0 * 0.0 + b0 * 0.0 + t0 * 0.0) + (r00 * 0.0 + r01 * 0.0 + r02 * 0.0)
    acc += (a1 * 0.0 + b1 * 0.0 + t1 * 0.0) + (r10 * 0.0 + r11 * 0.0 + r12 * 0.0)
    acc += (a2 * 0.0 + b2 * 0.0 + t2 * 0.0) + (r20 * 0.0 + r21 * 0.0 + r22 * 0.0)
    return acc == 0.0


@numba.njit(cache=True, inline='always')
def separating_axis(a0, a1, a2, b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                    t0, t1, t2):
    """Return the first axis of the 15-axis test that separates boxes A and B, or -1.

    Axes are numbered in the order they are tried: 0-2 A's face normals e_k, 3-5 B's face
    normals b_j, ``6 + 3 i + j`` the edge-edge axis e_i x b_j. Taking the 18 numbers
    themselves, so that compiled callers (the traversal's inner loop) pass registers, not
    arrays: an array passed to a function, even an inlined one, costs reference-count updates
    that cost more than this whole test. The traversal keeps the axis of a node pair it
    pruned, and an incremental re-check tries that axis alone first
    (:func:`collision_sensor.traversal.axis_gap`, the same arithmetic for one axis).
    """
    tol = BOX_EPS_REL * (a0 + a1 + a2 + b0 + b1 + b2)
    thr_face = tol * (1.0 + BOX_EPS_PARALLEL)
    # L = e_k: r_A = ha_k, r_B = sum_j |R[k, j]| hb_j.
    if (abs(t0) - ((abs(r00 * b0) + abs(r01 * b1)) + abs(r02 * b2))) - a0 > thr_face:
        k = 0
    elif (abs(t1) - ((abs(r10 * b0) + abs(r11 * b1)) + abs(r12 * b2))) - a1 > thr_face:
        k = 1
    elif (abs(t2) - ((abs(r20 * b0) + abs(r21 * b1)) + abs(r22 * b2))) - a2 > thr_face:
        k = 2
    # L = b_j: t . b_j = (R^T t)_j, r_A = sum_k |R[k, j]| ha_k, r_B = hb_j.
    elif (abs((r00 * t0 + r10 * t1) + r20 * t2)
          - ((abs(r00 * a0) + abs(r10 * a1)) + abs(r20 * a2))) - b0 > thr_face:
        k = 3
    elif (abs((r01 * t0 + r11 * t1) + r21 * t2)
          - ((abs(r01 * a0) + abs(r11 * a1)) + abs(r21 * a2))) - b1 > thr_face:
        k = 4
    elif (abs((r02 * t0 + r12 * t1) + r22 * t2)
          - ((abs(r02 * a0) + abs(r12 * a1)) + abs(r22 * a2))) - b2 > thr_face:
        k = 5
    # L = e_i x b_j, only where A has edges along e_i (ha[i] > 0).
    elif a0 > 0.0 and _edge_axis_separates(t1, t2, r10, r20, a1, a2, b1, b2, r01, r02, tol):
        k = 6
    elif a0 > 0.0 and _edge_axis_separates(t1, t2, r11, r21, a1, a2, b2, b0, r02, r00, tol):
        k = 7
    elif a0 > 0.0 and _edge_axis_separates(t1, t2, r12, r22, a1, a2, b0, b1, r00, r01, tol):
        k = 8
    elif a1 > 0.0 and _edge_axis_separates(t2, t0, r20, r00, a2, a0, b1, b2, r11, r12, tol):
        k = 9
    elif a1 > 0.0 and _edge_axis_separates(t2, t0, r21, r01, a2, a0, b2, b0, r12, r10, tol):
        k = 10
    elif a1 > 0.0 and _edge_axis_separates(t2, t0, r22, r02, a2, a0, b0, b1, r10, r11, tol):
        k = 11
    elif a2 > 0.0 and _edge_axis_separates(t0, t1, r00, r10, a0, a1, b1, b2, r21, r22, tol):
        k = 12
    elif a2 > 0.0 and _edge_axis_separates(t0, t1, r01, r11, a0, a1, b2, b0, r22, r20, tol):
        k = 13
    elif a2 > 0.0 and _edge_axis_separates(t0, t1, r02, r12, a0, a1, b0, b1, r20, r21, tol):
        k = 14
    else:
        return -1
    if _finite_scalars(a0, a1, a2, b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                       t0, t1, t2):
        return k
    return -1


@numba.njit(cache=True, inline='always')
def separated_sat(a0, a1, a2, b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                  t0, t1, t2):
    """Return True iff boxes A and B are separated: the 15-axis test on 18 scalars
    (:func:`separating_axis` finds an axis)."""
    return separating_axis(a0, a1, a2, b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21,
                           r22, t0, t1, t2) >= 0


@numba.njit(cache=True, inline='always')
def boxes_disjoint_sat(ha, hb, R, t, scratch):
    """Return True iff boxes A and B are separated: the classical 15-axis separating-axis test.

    Axes, all in F_A: A's face normals e_k, B's face normals b_j (column j of R), and the
    edge-edge axes e_i x b_j for every i with ``ha[i] > 0`` (see the module docstring). Gaps
    count only beyond the module's tolerance rule, the same as the paper's test. The axes are
    unrolled over scalars (:func:`separated_sat`): this runs for every node pair of every
    traversal.

    :param ha: (3,) half extents of A.
    :param hb: (3,) half extents of B.
    :param R: (3, 3) rotation, column j = B's axis j in F_A.
    :param t: (3,) B's centre in F_A.
    :param scratch: (64,) float64 work buffer (unused; kept for a common signature).
    :return: True if separated, False if the closed boxes meet.
    """
    return separated_sat(ha[0], ha[1], ha[2], hb[0], hb[1], hb[2],
                         R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2],
                         R[2, 0], R[2, 1], R[2, 2], t[0], t[1], t[2])


@numba.njit(cache=True, inline='always')
def boxes_disjoint(method, ha, hb, R, t, scratch):
    """Return True iff boxes A and B are separated, by ``method`` (BOX_TEST_PAPER or _SAT).

    :param method: BOX_TEST_PAPER (0) or BOX_TEST_SAT (1); anything else means SAT.
    :return: see :func:`boxes_disjoint_paper`.
    """
    if method == BOX_TEST_PAPER:
        return boxes_disjoint_paper(ha, hb, R, t, scratch)
    return boxes_disjoint_sat(ha, hb, R, t, scratch)


bind_to_kernel_sources(globals())
