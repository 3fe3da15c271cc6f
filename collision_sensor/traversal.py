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

Data, as the kernels take it (built by :func:`collision_sensor.obb_tree.box_table` and
:func:`~collision_sensor.obb_tree.node_table` from an :class:`ObbForest`)::

    boxes : (N, BOX_WIDTH) float64   one row per box: centre, axes (row-major, column k is
                                     axis k), half extents, sphere radius (obb_tree.BOX_*)
    nodes : (N, 4) int64             left child (-1 for a leaf), right child, first triangle,
                                     triangle count
    pose  : (POSE_WIDTH,) float64    body b in body a's frame: R_ab row-major, then t_ab

Why one row per box and scalars everywhere in the loop: a node pair is ~60 multiplications,
so anything else shows. Passing an array to a function, even one numba inlines, can cost two
atomic reference-count updates per array (``NRT_incref``/``NRT_decref``, not pruned across the
branches of an inlined body), which made them 60% of the traversal's time; the loop therefore
reads a box row into a tuple (:func:`load_box`, straight-line, pruned) and calls only
functions of numbers and tuples. The rare leaf pairs and the optional paper box test go to
separate functions, whose reference counting is paid per call, not per box.
"""
import numba
import numpy as np

from collision_sensor.box_test import (
    BOX_TEST_PAPER, boxes_disjoint_paper, separated_sat, separating_axis)
from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.obb_tree import (
    BOX_AXES, BOX_CENTER, BOX_HALF, BOX_RADIUS, NODE_COUNT, NODE_FIRST, NODE_LEFT, NODE_RIGHT)
from collision_sensor.tolerances import BOX_EPS_PARALLEL, BOX_EPS_REL, SPHERE_EPS_REL
from collision_sensor.triangle_test import triangles_intersect

EXPAND_SAME, EXPAND_ALTERNATE, EXPAND_LARGER, EXPAND_PROMISING = 0, 1, 2, 3
EXPANSION_RULES = {
    'same': EXPAND_SAME, 'alternate': EXPAND_ALTERNATE, 'larger': EXPAND_LARGER,
    'promising': EXPAND_PROMISING,
}

# counters[COUNT_*]: work done, for the benchmarks and tests: box tests, triangle tests, box
# pairs skipped by the sphere pre-test, pair re-checks that started from a front, and front
# node pairs kept untested (see front_scan).
(COUNT_BOX_TESTS, COUNT_TRIANGLE_TESTS, COUNT_SPHERE_SKIPS, COUNT_FRONT_STARTS,
 COUNT_FRONT_UNTESTED) = range(5)
N_COUNTERS = 5

#: Length of a pose vector: R_ab (row-major), then t_ab.
POSE_WIDTH = 12
#: Floats of the ``work`` buffer the functions here need.
TRAVERSAL_WORK = 100

# A front (see trees_collide) is a (n, 3) int64 table of node pairs (na, nb, how): ``how`` is
# the axis of the 15-axis test that separated the pair's boxes (0-14, see
# box_test.separating_axis), or one of these.
FRONT_LEAF = -1     # a leaf pair tested triangle by triangle (apart then)
FRONT_SPHERE = -2   # the spheres around the two boxes were apart
FRONT_BOX = -3      # the paper's box test separated them (it names no axis)
#: A front's node pair is kept untested while its ``until`` exceeds the pair's travel by
#: more than this fraction of itself: the travel is a running sum, and this covers the
#: rounding of a million additions to it.
FRONT_GUARD_REL = 1e-9


@numba.njit(cache=True, inline='always')
def load_box(boxes, n):
    """Row ``n`` of a box table as a 16-tuple (straight-line, so its reference counting is
    pruned; the functions below then take only tuples of numbers)."""
    return (boxes[n, 0], boxes[n, 1], boxes[n, 2], boxes[n, 3], boxes[n, 4], boxes[n, 5],
            boxes[n, 6], boxes[n, 7], boxes[n, 8], boxes[n, 9], boxes[n, 10], boxes[n, 11],
            boxes[n, 12], boxes[n, 13], boxes[n, 14], boxes[n, 15])


@numba.njit(cache=True, inline='always')
def load_pose(pose):
    """A pose vector as a 12-tuple: R_ab row-major, then t_ab."""
    return (pose[0], pose[1], pose[2], pose[3], pose[4], pose[5], pose[6], pose[7], pose[8],
            pose[9], pose[10], pose[11])


@numba.njit(cache=True, inline='always')
def _centre_offset(A, B, P):
    # d = R_ab cb + t_ab - ca: B's centre relative to A's, in body a's frame.
    c = BOX_CENTER
    d0 = P[0] * B[c] + P[1] * B[c + 1] + P[2] * B[c + 2] + P[9] - A[c]
    d1 = P[3] * B[c] + P[4] * B[c + 1] + P[5] * B[c + 2] + P[10] - A[c + 1]
    d2 = P[6] * B[c] + P[7] * B[c + 1] + P[8] * B[c + 2] + P[11] - A[c + 2]
    return d0, d1, d2


@numba.njit(cache=True, inline='always')
def _spheres(A, B, P):
    """Return ``(apart, dd, radii, d)``: :func:`spheres_apart`'s answer, ``|d|^2``, the sum
    of the two radii and ``d`` (:func:`_centre_offset`), which the traversal reuses."""
    d = _centre_offset(A, B, P)
    dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    radii = A[BOX_RADIUS] + B[BOX_RADIUS]
    reach = radii * (1.0 + SPHERE_EPS_REL)
    return dd > reach * reach, dd, radii, d


@numba.njit(cache=True, inline='always')
def spheres_apart(A, B, P):
    """True iff the spheres around boxes A (body a) and B (body b at pose P) are clearly apart.

    A cheap pre-test before the box test: the sphere around a box (centre the box centre,
    radius |half|) contains it, so spheres apart means boxes apart.
    """
    return _spheres(A, B, P)[0]


@numba.njit(cache=True, inline='always')
def box_in_frame(A, B, P):
    """Return box B (body b, at pose P in body a) in box A's frame: 12-tuple R (row-major), t.

    With box frames ``[Ea, ca]``, ``[Eb, cb]`` (rows of a box table)::

        [R, t] = [Ea' R_ab Eb, Ea' (R_ab cb + t_ab - ca)]
    """
    d0, d1, d2 = _centre_offset(A, B, P)
    # M = R_ab Eb: B's axes (columns) in body a's frame; Eb[i, k] = B[BOX_AXES + 3 i + k].
    e = BOX_AXES
    m00 = P[0] * B[e] + P[1] * B[e + 3] + P[2] * B[e + 6]
    m01 = P[0] * B[e + 1] + P[1] * B[e + 4] + P[2] * B[e + 7]
    m02 = P[0] * B[e + 2] + P[1] * B[e + 5] + P[2] * B[e + 8]
    m10 = P[3] * B[e] + P[4] * B[e + 3] + P[5] * B[e + 6]
    m11 = P[3] * B[e + 1] + P[4] * B[e + 4] + P[5] * B[e + 7]
    m12 = P[3] * B[e + 2] + P[4] * B[e + 5] + P[5] * B[e + 8]
    m20 = P[6] * B[e] + P[7] * B[e + 3] + P[8] * B[e + 6]
    m21 = P[6] * B[e + 1] + P[7] * B[e + 4] + P[8] * B[e + 7]
    m22 = P[6] * B[e + 2] + P[7] * B[e + 5] + P[8] * B[e + 8]
    # R = Ea' M, t = Ea' d: row i of both uses A's axis i, column i of Ea.
    return (A[e] * m00 + A[e + 3] * m10 + A[e + 6] * m20,
            A[e] * m01 + A[e + 3] * m11 + A[e + 6] * m21,
            A[e] * m02 + A[e + 3] * m12 + A[e + 6] * m22,
            A[e + 1] * m00 + A[e + 4] * m10 + A[e + 7] * m20,
            A[e + 1] * m01 + A[e + 4] * m11 + A[e + 7] * m21,
            A[e + 1] * m02 + A[e + 4] * m12 + A[e + 7] * m22,
            A[e + 2] * m00 + A[e + 5] * m10 + A[e + 8] * m20,
            A[e + 2] * m01 + A[e + 5] * m11 + A[e + 8] * m21,
            A[e + 2] * m02 + A[e + 5] * m12 + A[e + 8] * m22,
            A[e] * d0 + A[e + 3] * d1 + A[e + 6] * d2,
            A[e + 1] * d0 + A[e + 4] * d1 + A[e + 7] * d2,
            A[e + 2] * d0 + A[e + 5] * d1 + A[e + 8] * d2)


@numba.njit(cache=True, inline='always')
def face_gap(A, B, T):
    """Return a lower bound of the distance between boxes A and B (B in A's frame: ``T``).

    The largest gap between the two boxes' projections on the six face normals (unit axes,
    so each gap is at most the Euclidean distance; <= 0 if no face axis separates them):
    ``|t . u| - r_A(u) - r_B(u)``. Rounding is the caller's to allow for (sec. 4.2 clearance).
    """
    h = BOX_HALF
    a0, a1, a2, b0, b1, b2 = A[h], A[h + 1], A[h + 2], B[h], B[h + 1], B[h + 2]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = T[0], T[1], T[2], T[3], T[4], T[5], T[6], \
        T[7], T[8]
    t0, t1, t2 = T[9], T[10], T[11]
    g = abs(t0) - a0 - (abs(r00) * b0 + abs(r01) * b1 + abs(r02) * b2)
    g = max(g, abs(t1) - a1 - (abs(r10) * b0 + abs(r11) * b1 + abs(r12) * b2))
    g = max(g, abs(t2) - a2 - (abs(r20) * b0 + abs(r21) * b1 + abs(r22) * b2))
    g = max(g, abs(r00 * t0 + r10 * t1 + r20 * t2) - b0
            - (abs(r00) * a0 + abs(r10) * a1 + abs(r20) * a2))
    g = max(g, abs(r01 * t0 + r11 * t1 + r21 * t2) - b1
            - (abs(r01) * a0 + abs(r11) * a1 + abs(r21) * a2))
    g = max(g, abs(r02 * t0 + r12 * t1 + r22 * t2) - b2
            - (abs(r02) * a0 + abs(r12) * a1 + abs(r22) * a2))
    return g


@numba.njit(cache=True, inline='always')
def box_pair_gap(A, B, P):
    """Return a lower bound of the distance between boxes A and B (body b at pose P).

    The larger of the spheres' gap and :func:`face_gap`; <= 0 when neither separates.
    """
    d0, d1, d2 = _centre_offset(A, B, P)
    g = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - (A[BOX_RADIUS] + B[BOX_RADIUS])
    return max(g, face_gap(A, B, box_in_frame(A, B, P)))


@numba.njit(cache=True, inline='always')
def sat_separates(A, B, T):
    """True iff the 15-axis test separates boxes A and B, B in A's frame given by ``T``
    (:func:`box_in_frame`)."""
    h = BOX_HALF
    return separated_sat(A[h], A[h + 1], A[h + 2], B[h], B[h + 1], B[h + 2],
                         T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7], T[8],
                         T[9], T[10], T[11])


@numba.njit(cache=True, inline='always')
def sat_axis(A, B, T):
    """Return the axis that separates boxes A and B (:func:`box_test.separating_axis`), or -1;
    B in A's frame given by ``T`` (:func:`box_in_frame`)."""
    h = BOX_HALF
    return separating_axis(A[h], A[h + 1], A[h + 2], B[h], B[h + 1], B[h + 2],
                           T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7], T[8],
                           T[9], T[10], T[11])


@numba.njit(cache=True, inline='always')
def axis_gap(k, A, B, P):
    """Return ``(separated, gap)`` along axis k of :func:`box_test.separating_axis` alone,
    for boxes A (body a) and B (body b at pose P in body a).

    ``separated`` is that test's decision for this axis (its arithmetic and tolerance rule,
    on only the entries of :func:`box_in_frame` the axis needs: a front re-check tries one
    axis per node pair); ``gap`` is then the boxes' gap along the unit axis, a lower bound
    of their distance (rounding is the caller's to allow for). Inputs are the traversal's
    own, always finite.
    """
    h = BOX_HALF
    e = BOX_AXES
    ha = (A[h], A[h + 1], A[h + 2])
    hb = (B[h], B[h + 1], B[h + 2])
    tol = BOX_EPS_REL * (ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2])
    d0, d1, d2 = _centre_offset(A, B, P)
    if k < 3:  # L = e_k: row k of R is A's axis k, taken to body b, against B's axes
        x0, x1, x2 = A[e + k], A[e + 3 + k], A[e + 6 + k]
        u0 = P[0] * x0 + P[3] * x1 + P[6] * x2
        u1 = P[1] * x0 + P[4] * x1 + P[7] * x2
        u2 = P[2] * x0 + P[5] * x1 + P[8] * x2
        r0 = u0 * B[e] + u1 * B[e + 3] + u2 * B[e + 6]
        r1 = u0 * B[e + 1] + u1 * B[e + 4] + u2 * B[e + 7]
        r2 = u0 * B[e + 2] + u1 * B[e + 5] + u2 * B[e + 8]
        d = (abs(x0 * d0 + x1 * d1 + x2 * d2)
             - ((abs(r0 * hb[0]) + abs(r1 * hb[1])) + abs(r2 * hb[2]))) - ha[k]
        return d > tol * (1.0 + BOX_EPS_PARALLEL), d
    j = (k - 3) % 3  # B's axis j (k < 6), or the b_j of e_i x b_j
    m0 = P[0] * B[e + j] + P[1] * B[e + 3 + j] + P[2] * B[e + 6 + j]
    m1 = P[3] * B[e + j] + P[4] * B[e + 3 + j] + P[5] * B[e + 6 + j]
    m2 = P[6] * B[e + j] + P[7] * B[e + 3 + j] + P[8] * B[e + 6 + j]
    if k < 6:  # L = b_j: column j of R, and all of t
        r0 = A[e] * m0 + A[e + 3] * m1 + A[e + 6] * m2
        r1 = A[e + 1] * m0 + A[e + 4] * m1 + A[e + 7] * m2
        r2 = A[e + 2] * m0 + A[e + 5] * m1 + A[e + 8] * m2
        t0 = A[e] * d0 + A[e + 3] * d1 + A[e + 6] * d2
        t1 = A[e + 1] * d0 + A[e + 4] * d1 + A[e + 7] * d2
        t2 = A[e + 2] * d0 + A[e + 5] * d1 + A[e + 8] * d2
        d = (abs((r0 * t0 + r1 * t1) + r2 * t2)
             - ((abs(r0 * ha[0]) + abs(r1 * ha[1])) + abs(r2 * ha[2]))) - hb[j]
        return d > tol * (1.0 + BOX_EPS_PARALLEL), d
    # L = e_i x b_j (see box_test._edge_axis_separates): R[i1, j], R[i2, j], R[i, j1],
    # R[i, j2], t[i1], t[i2], with i1, i2 and j1, j2 the other indices, cyclic.
    i = (k - 6) // 3
    i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
    r_i1j = A[e + i1] * m0 + A[e + 3 + i1] * m1 + A[e + 6 + i1] * m2
    r_i2j = A[e + i2] * m0 + A[e + 3 + i2] * m1 + A[e + 6 + i2] * m2
    x0, x1, x2 = A[e + i], A[e + 3 + i], A[e + 6 + i]
    u0 = P[0] * x0 + P[3] * x1 + P[6] * x2
    u1 = P[1] * x0 + P[4] * x1 + P[7] * x2
    u2 = P[2] * x0 + P[5] * x1 + P[8] * x2
    r_ij1 = u0 * B[e + j1] + u1 * B[e + 3 + j1] + u2 * B[e + 6 + j1]
    r_ij2 = u0 * B[e + j2] + u1 * B[e + 3 + j2] + u2 * B[e + 6 + j2]
    t_i1 = A[e + i1] * d0 + A[e + 3 + i1] * d1 + A[e + 6 + i1] * d2
    t_i2 = A[e + i2] * d0 + A[e + 3 + i2] * d1 + A[e + 6 + i2] * d2
    d = (abs(t_i2 * r_i1j - t_i1 * r_i2j)
         - (ha[i1] * abs(r_i2j) + ha[i2] * abs(r_i1j))
         - (hb[j1] * abs(r_ij2) + hb[j2] * abs(r_ij1)))
    length = np.sqrt(r_ij1 * r_ij1 + r_ij2 * r_ij2)
    if ha[i] > 0.0 and d > tol * BOX_EPS_PARALLEL and d > tol * (length + BOX_EPS_PARALLEL):
        return True, d / length
    return False, d


@numba.njit(cache=True, _nrt=False)
def paper_separates(A, B, T, work):
    """True iff the paper's test separates boxes A and B (as :func:`sat_separates`).

    The paper's test takes arrays, so the numbers are laid out in ``work`` first. Not
    inlined, and called only in its own branch: an array passed to an inlined function costs
    reference counting on every path through it; besides, inlining this test everywhere made
    compiling slow.
    """
    ha = work[0:3]
    hb = work[3:6]
    R = work[6:15].reshape(3, 3)
    t = work[15:18]
    for k in range(3):
        ha[k] = A[BOX_HALF + k]
        hb[k] = B[BOX_HALF + k]
        t[k] = T[9 + k]
        for j in range(3):
            R[k, j] = T[3 * k + j]
    return boxes_disjoint_paper(ha, hb, R, t, work[32:96])


@numba.njit(cache=True, _nrt=False)
def triangle_pair_collides(tris, ia, ib, pose, tri_work):
    """Return True iff triangle ``tris[ia]`` (body a) meets ``tris[ib]`` (body b, at ``pose``).

    :param tri_work: (2, 3, 3) float64 work buffer.
    """
    P = tri_work[0]
    Q = tri_work[1]
    for k in range(3):
        for i in range(3):
            P[k, i] = tris[ia, k, i]
            Q[k, i] = (pose[3 * i] * tris[ib, k, 0] + pose[3 * i + 1] * tris[ib, k, 1]
                       + pose[3 * i + 2] * tris[ib, k, 2] + pose[9 + i])
    return triangles_intersect(P, Q)


@numba.njit(cache=True, _nrt=False)
def leaves_collide(tris, first_a, count_a, first_b, count_b, pose, tri_work):
    """Test every triangle of leaf a against every triangle of leaf b (body b at ``pose``).

    :param tri_work: (2, 3, 3) float64 work buffer.
    :return: ``(hit, ia, ib, tested)``: the first meeting triangles (-1, -1 if none) and the
        number of triangle pairs tested.
    """
    P = tri_work[0]
    Q = tri_work[1]
    tested = 0
    for ib in range(first_b, first_b + count_b):
        for k in range(3):
            for i in range(3):
                Q[k, i] = (pose[3 * i] * tris[ib, k, 0] + pose[3 * i + 1] * tris[ib, k, 1]
                           + pose[3 * i + 2] * tris[ib, k, 2] + pose[9 + i])
        for ia in range(first_a, first_a + count_a):
            for k in range(3):
                for i in range(3):
                    P[k, i] = tris[ia, k, i]
            tested += 1
            if triangles_intersect(P, Q):
                return True, ia, ib, tested
    return False, -1, -1, tested


@numba.njit(cache=True, inline='always')
def _closer(boxes, m, n, x0, x1, x2):
    """True iff box m's centre is nearer the point x than box n's (same body frame)."""
    a0, a1, a2 = boxes[m, 0] - x0, boxes[m, 1] - x1, boxes[m, 2] - x2
    b0, b1, b2 = boxes[n, 0] - x0, boxes[n, 1] - x1, boxes[n, 2] - x2
    return a0 * a0 + a1 * a1 + a2 * a2 < b0 * b0 + b1 * b1 + b2 * b2


@numba.njit(cache=True, inline='always')
def _record(front, front_until, n_front, na, nb, how, until):
    """Append ``(na, nb, how)`` and ``until`` to the front; return its new length, -1 once
    it overflows (or was not being recorded: ``n_front`` -1)."""
    if n_front < 0 or n_front >= front.shape[0]:
        return -1
    front[n_front, 0] = na
    front[n_front, 1] = nb
    front[n_front, 2] = how
    front_until[n_front] = until
    return n_front + 1


@numba.njit(cache=True, inline='always')
def trees_collide(n_seeds, pose, boxes, nodes, volume, gain, tris, box_method, expansion, stack,
                  work, tri_work, counters, track, wa, wb, front, front_until, n_front,
                  travel):
    """Return ``(hit, ia, ib, gap, n_front)``: does any triangle under the node pairs
    ``stack[:n_seeds]`` (na in tree a, nb in tree b, a level) meet one of the other's, and
    if not, how far apart are they at least?

    Contract in plain Python, for a seed the two roots of a body's sub-group trees::

        hit = any(triangles_intersect(P, R_ab @ Q + t_ab)
                  for P in triangles(na) for Q in triangles(nb) for na, nb in seeds)

    computed by descending both trees and pruning node pairs whose boxes are disjoint;
    ``ia, ib`` are the rows of ``tris`` of the first meeting pair found (-1 if none), a
    witness the caller may test first next time.

    With ``track``, ``gap`` is a lower bound of the distance between the two trees'
    triangles when they do not meet: the smallest gap of the node pairs pruned (sphere gap
    ``|d| - r_a - r_b``, or :func:`face_gap` for a box test, or the gap along the edge axis
    that separated them), 0 once a leaf pair had to be tested triangle by triangle (no
    bound). Not rounded down: the caller allows for that. Without ``track`` (full checks),
    ``gap`` is 0 and costs nothing.

    The front: with ``n_front >= 0``, every node pair where the descent stopped (pruned, or
    a leaf pair found apart) is appended to ``front`` at ``n_front`` with how it was settled
    (the separating axis, or ``FRONT_*``), and ``front_until`` with ``travel`` plus its gap:
    the pair's travel (see :func:`front_scan`) up to which it is still apart. When no
    triangles meet, those pairs cover every
    pair of triangles under the seeds exactly once, whatever the pose: a later re-check may
    start from them instead of the roots (:func:`front_scan`), which skips every node pair
    above them. ``n_front`` comes back -1 when ``front`` is full (the descent goes on, the
    front is then incomplete) or was -1.

    Which child is visited first (only the work depends on it, never the answer): with a
    witness ``wa, wb`` (rows of ``tris``, or -1), the one whose triangles include it (a
    node's triangles are the range starting at its ``first``; the right child's starts
    where the left's ends), so a contact that slid to a neighbouring triangle is found near
    it; without one, the child whose centre is nearer the other box's centre. A colliding
    pair stops at its first meeting triangles, so this finds them sooner (demo arm, random
    configurations: 175 -> 112 box tests per check); a pair apart visits every overlapping
    node pair either way.

    :param n_seeds: node pairs the caller put on ``stack``, all under the same two bodies.
    :param pose: (POSE_WIDTH,) tree b's body pose in tree a's body frame.
    :param boxes, nodes: the node tables (module docstring); ``volume, gain``: (N,) float64,
        read by the 'larger' and 'promising' rules.
    :param tris: (T, 3, 3) float64, triangles in their body frames.
    :param box_method: ``box_test.BOX_TEST_PAPER`` or ``BOX_TEST_SAT``.
    :param expansion: one of the ``EXPAND_*`` rules.
    :param stack: (S, 3) int64 work stack; S >= n_seeds + depth(a) + depth(b) + 2.
    :param work: (TRAVERSAL_WORK,) float64; ``tri_work``: (2, 3, 3) float64.
    :param counters: (N_COUNTERS,) int64, work done is added to it.
    :param front, front_until: (F, 3) int64 and (F,) float64, where the front is recorded.
    :param travel: the pair's travel now, less its rounding margin.
    """
    P = load_pose(pose)
    best = np.inf if track else 0.0
    n_boxes = 0
    n_spheres = 0
    n_triangles = 0
    hit = False
    ia = -1
    ib = -1
    top = n_seeds
    while top > 0:
        top -= 1
        na = stack[top, 0]
        nb = stack[top, 1]
        level = stack[top, 2]
        A = load_box(boxes, na)
        B = load_box(boxes, nb)
        apart, dd, radii, (d0, d1, d2) = _spheres(A, B, P)
        if apart:
            n_spheres += 1
            if n_front >= 0:
                g = np.sqrt(dd) - radii
                n_front = _record(front, front_until, n_front, na, nb, FRONT_SPHERE, travel + g)
                best = min(best, g)
            elif track and best > 0.0:
                bound = best + radii  # sqrt only when it can lower the bound
                if dd < bound * bound:
                    best = np.sqrt(dd) - radii
            continue
        n_boxes += 1
        T = box_in_frame(A, B, P)
        if box_method == BOX_TEST_PAPER:
            how = FRONT_BOX if paper_separates(A, B, T, work) else FRONT_LEAF
        else:
            how = sat_axis(A, B, T)
        if how != FRONT_LEAF:
            if track:
                g = face_gap(A, B, T)
                if how >= 6:
                    g = max(g, axis_gap(how, A, B, P)[1])
                best = min(best, g)
                n_front = _record(front, front_until, n_front, na, nb, how, travel + g)
            continue
        leaf_a = nodes[na, NODE_LEFT] < 0
        leaf_b = nodes[nb, NODE_LEFT] < 0
        if leaf_a and leaf_b:
            hit, ia, ib, tested = leaves_collide(
                tris, nodes[na, NODE_FIRST], nodes[na, NODE_COUNT], nodes[nb, NODE_FIRST],
                nodes[nb, NODE_COUNT], pose, tri_work)
            n_triangles += tested
            if hit:
                break
            n_front = _record(front, front_until, n_front, na, nb, FRONT_LEAF, travel)
            best = min(best, 0.0)
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
        # Visit first the child nearer the other box's centre (more likely to meet it:
        # a colliding pair stops at its first meeting triangles), or the one holding the
        # last witness.
        if expand_a:
            first, second = nodes[na, NODE_LEFT], nodes[na, NODE_RIGHT]
            if wa >= 0:
                swap = wa >= nodes[second, NODE_FIRST]
            else:
                x0, x1, x2 = A[0] + d0, A[1] + d1, A[2] + d2  # B's centre in body a
                swap = _closer(boxes, second, first, x0, x1, x2)
            if swap:
                first, second = second, first
            stack[top, 0], stack[top, 1], stack[top, 2] = second, nb, level + 1
            stack[top + 1, 0], stack[top + 1, 1] = first, nb
        else:
            first, second = nodes[nb, NODE_LEFT], nodes[nb, NODE_RIGHT]
            if wb >= 0:
                swap = wb >= nodes[second, NODE_FIRST]
            else:
                # A's centre in body b: R_ab' (ca - t_ab).
                e0, e1, e2 = A[0] - P[9], A[1] - P[10], A[2] - P[11]
                swap = _closer(boxes, second, first, P[0] * e0 + P[3] * e1 + P[6] * e2,
                               P[1] * e0 + P[4] * e1 + P[7] * e2,
                               P[2] * e0 + P[5] * e1 + P[8] * e2)
            if swap:
                first, second = second, first
            stack[top, 0], stack[top, 1], stack[top, 2] = na, second, level + 1
            stack[top + 1, 0], stack[top + 1, 1] = na, first
        stack[top + 1, 2] = level + 1
        top += 2
    counters[COUNT_BOX_TESTS] += n_boxes
    counters[COUNT_SPHERE_SKIPS] += n_spheres
    counters[COUNT_TRIANGLE_TESTS] += n_triangles
    return hit, ia, ib, best, n_front


@numba.njit(cache=True, _nrt=False)
def front_scan(front, front_until, n_old, pose, boxes, travel, margin, stack, kept,
               kept_until, counters):
    """Re-settle a front (see :func:`trees_collide`) at a new pose, cheaply where it can.

    The pair's travel is a running sum of bounds of how far any point of one body can have
    moved relative to the other (paper sec. 4.2, :func:`query_kernel.plan_update`), so a
    node pair whose gap, when last settled, exceeds the travel since then is still apart
    untested: its ``until`` (the travel then plus the gap) is above ``travel``. Every other
    node pair is tried the way it was settled last time: its one separating axis
    (:func:`axis_gap`), or its spheres. Those still apart are copied to ``kept``; the
    others (leaf pairs among them: a triangle test has no cheaper proof) are put on
    ``stack`` as seeds for :func:`trees_collide`, which then descends from them (and
    records their new front after ``kept``'s). Under coherent motion most node pairs stay
    apart, and no node pair above the front is tested again: a pair of bodies in near
    contact, whose proof from the roots tests hundreds of overlapping boxes, costs a
    comparison for each far node pair of its front and one axis for each near one.

    :param front, front_until: (n_old, 3) int64 and (n_old,) float64, a complete front.
    :param pose: (POSE_WIDTH,) body b's pose in body a's frame.
    :param travel: the pair's travel now; a node pair is kept untested only if its
        ``until`` exceeds it by more than ``FRONT_GUARD_REL`` of itself (rounding).
    :param margin: the pair's rounding margin (a node pair tried gets ``until = travel -
        margin + gap``).
    :param stack: (S, 3) int64, S >= n_old: the seeds are written from row 0.
    :param kept, kept_until: (F, 3) int64 and (F,) float64, F >= n_old: the node pairs
        still apart (``until`` for those tried: ``travel - margin`` plus the gap found).
    :param counters: (N_COUNTERS,) int64; a pair tried counts as a box test (or a sphere skip).
    :return: ``(n_seeds, n_kept, gap)``: ``gap`` a lower bound of the distance between the
        kept node pairs' triangles (``np.inf`` if none).
    """
    P = load_pose(pose)
    best = np.inf
    n_seeds = 0
    n_kept = 0
    n_boxes = 0
    n_spheres = 0
    n_untested = 0
    for e in range(n_old):
        na = front[e, 0]
        nb = front[e, 1]
        how = front[e, 2]
        until = front_until[e]
        apart = until - travel > FRONT_GUARD_REL * until
        if apart:
            g = until - travel
            n_untested += 1
        elif how >= 0:
            n_boxes += 1
            A = load_box(boxes, na)
            B = load_box(boxes, nb)
            apart, g = axis_gap(how, A, B, P)
            if apart:
                # One axis can leave a small gap to boxes that moved far apart along
                # another: the spheres' gap may say more.
                d0, d1, d2 = _centre_offset(A, B, P)
                g = max(g, np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - A[BOX_RADIUS] - B[BOX_RADIUS])
                until = travel - margin + g
        elif how == FRONT_SPHERE:
            n_spheres += 1
            apart, dd, radii, _ = _spheres(load_box(boxes, na), load_box(boxes, nb), P)
            if apart:
                g = np.sqrt(dd) - radii
                until = travel - margin + g
        if apart:
            kept[n_kept, 0], kept[n_kept, 1], kept[n_kept, 2] = na, nb, how
            kept_until[n_kept] = until
            n_kept += 1
            best = min(best, g)
        else:
            stack[n_seeds, 0], stack[n_seeds, 1], stack[n_seeds, 2] = na, nb, 0
            n_seeds += 1
    counters[COUNT_BOX_TESTS] += n_boxes
    counters[COUNT_SPHERE_SKIPS] += n_spheres
    counters[COUNT_FRONT_STARTS] += 1
    counters[COUNT_FRONT_UNTESTED] += n_untested
    return n_seeds, n_kept, best


bind_to_kernel_sources(globals())
