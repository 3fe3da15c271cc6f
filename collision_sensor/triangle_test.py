"""Triangle / triangle contact for the leaves of the box hierarchies.

Contract in plain Python::

    triangles_intersect(P, Q) == (distance(P, Q) <= TRIANGLE_EPS_REL * m)

``P, Q : (3, 3) float64``, rows the vertices, both in the same frame; ``distance`` is the
Euclidean distance between the closed triangles (0 when they cross or touch), ``m`` the largest
absolute coordinate of the six vertices. So touching counts as contact, and so does a gap below
the tolerance (about 1e-12 of the coordinates, the scale of their own rounding). Coplanar
triangles are decided by the same rule (overlapping, touching at an edge or a vertex, or one
inside the other: distance 0). A zero-area triangle is the segment or point it is; a sliver
thinner than half the tolerance is treated as its three edges, which moves it by less than
half the tolerance. Input with a NaN or an infinity answers True (err toward contact).

Why a distance rule rather than orientation predicates alone (Moeller, Guigue-Devillers): in
float64, signs of near-zero determinants are noise, so "touching" has no stable answer; a
distance against a tolerance is continuous in the input, so touching, coplanar and degenerate
cases all get the same reproducible answer and the branches stay few. Cost: a plane test
rejects most pairs with 2 cross products; pairs that survive pay for up to 6 point-triangle
and 9 segment-segment distances, with an early exit at the first contact.
"""
import math

import numba

from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.tolerances import TRIANGLE_EPS_REL

_U = 2.0 ** -53                 # unit roundoff of float64


@numba.njit(cache=True, inline='always')
def _clamp01(x):
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@numba.njit(cache=True, inline='always')
def _point_segment_dist2(p0, p1, p2, a, b):
    # Squared distance from point p to segment [a, b] (a point when a == b).
    d0, d1, d2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    w0, w1, w2 = p0 - a[0], p1 - a[1], p2 - a[2]
    dd = d0 * d0 + d1 * d1 + d2 * d2
    s = 0.0
    if dd > 0.0:
        s = _clamp01((w0 * d0 + w1 * d1 + w2 * d2) / dd)
    x0, x1, x2 = w0 - s * d0, w1 - s * d1, w2 - s * d2
    return x0 * x0 + x1 * x1 + x2 * x2


@numba.njit(cache=True, inline='always')
def _segment_segment_dist2(p, q, a, b):
    # Squared distance between segments [p, q] and [a, b]; either may be a point. Ericson,
    # Real-Time Collision Detection, 5.1.9: closest point of the lines, clamped to the segments,
    # re-clamped once. Parallel segments (denominator 0) start from s = 0, which is exact.
    d10, d11, d12 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    d20, d21, d22 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    r0, r1, r2 = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    aa = d10 * d10 + d11 * d11 + d12 * d12
    ee = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    if aa == 0.0 and ee == 0.0:
        s, t = 0.0, 0.0
    elif aa == 0.0:
        s, t = 0.0, _clamp01(f / ee)
    else:
        c = d10 * r0 + d11 * r1 + d12 * r2
        if ee == 0.0:
            s, t = _clamp01(-c / aa), 0.0
        else:
            bb = d10 * d20 + d11 * d21 + d12 * d22
            denom = aa * ee - bb * bb
            s = _clamp01((bb * f - c * ee) / denom) if denom > 0.0 else 0.0
            t = (bb * s + f) / ee
            if t < 0.0:
                t = 0.0
                s = _clamp01(-c / aa)
            elif t > 1.0:
                t = 1.0
                s = _clamp01((bb - c) / aa)
    x0 = r0 + s * d10 - t * d20
    x1 = r1 + s * d11 - t * d21
    x2 = r2 + s * d12 - t * d22
    return x0 * x0 + x1 * x1 + x2 * x2


@numba.njit(cache=True, inline='always')
def _inside_prism(T, n0, n1, n2, x0, x1, x2):
    # True iff x projects into triangle T along its normal n: x lies on the inner side (or on)
    # each edge's plane through n, ((T[k+1] - T[k]) x (x - T[k])) . n >= 0 for k = 0, 1, 2.
    for k in range(3):
        a = T[k]
        b = T[(k + 1) % 3]
        e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
        w0, w1, w2 = x0 - a[0], x1 - a[1], x2 - a[2]
        c = ((e1 * w2 - e2 * w1) * n0 + (e2 * w0 - e0 * w2) * n1 + (e0 * w1 - e1 * w0) * n2)
        if c < 0.0:
            return False
    return True


@numba.njit(cache=True, inline='always')
def _plane(T, tol):
    # Return (n0, n1, n2, nn, flat, err): n = (T1 - T0) x (T2 - T0), nn = |n|, flat iff T is
    # thinner than tol / 2 (|n| / longest edge = twice its area over its longest edge), and
    # err a bound on the rounding of n per unit distance, so |n . (x - T0)| is exact to within
    # err * |x - T0|_1 (relative rounding u per difference and product, summed generously).
    a0, a1, a2 = T[1, 0] - T[0, 0], T[1, 1] - T[0, 1], T[1, 2] - T[0, 2]
    b0, b1, b2 = T[2, 0] - T[0, 0], T[2, 1] - T[0, 1], T[2, 2] - T[0, 2]
    n0 = a1 * b2 - a2 * b1
    n1 = a2 * b0 - a0 * b2
    n2 = a0 * b1 - a1 * b0
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    c0, c1, c2 = T[2, 0] - T[1, 0], T[2, 1] - T[1, 1], T[2, 2] - T[1, 2]
    longest = math.sqrt(max(a0 * a0 + a1 * a1 + a2 * a2, b0 * b0 + b1 * b1 + b2 * b2,
                            c0 * c0 + c1 * c1 + c2 * c2))
    flat = not (nn > 0.5 * tol * longest)
    la = abs(a0) + abs(a1) + abs(a2)
    lb = abs(b0) + abs(b1) + abs(b2)
    err = 16.0 * _U * (la * lb + abs(n0) + abs(n1) + abs(n2))
    return n0, n1, n2, nn, flat, err


@numba.njit(cache=True, inline='always')
def _beyond_plane(T, n0, n1, n2, nn, err, S, tol):
    # True iff all three vertices of S are farther than tol from T's plane, on the same side,
    # beyond the rounding of the signed distances (so a rejection here is never wrong).
    pos = 0
    neg = 0
    for k in range(3):
        w0, w1, w2 = S[k, 0] - T[0, 0], S[k, 1] - T[0, 1], S[k, 2] - T[0, 2]
        d = n0 * w0 + n1 * w1 + n2 * w2
        margin = tol * nn + err * (abs(w0) + abs(w1) + abs(w2))
        if d > margin:
            pos += 1
        elif d < -margin:
            neg += 1
        else:
            return False
    return pos == 3 or neg == 3


@numba.njit(cache=True, inline='always')
def _edge_crosses(T, n0, n1, n2, S):
    # True iff an edge of S passes strictly through T's plane at a point inside T.
    ds0 = n0 * (S[0, 0] - T[0, 0]) + n1 * (S[0, 1] - T[0, 1]) + n2 * (S[0, 2] - T[0, 2])
    ds1 = n0 * (S[1, 0] - T[0, 0]) + n1 * (S[1, 1] - T[0, 1]) + n2 * (S[1, 2] - T[0, 2])
    ds2 = n0 * (S[2, 0] - T[0, 0]) + n1 * (S[2, 1] - T[0, 1]) + n2 * (S[2, 2] - T[0, 2])
    for k in range(3):
        a = S[k]
        b = S[(k + 1) % 3]
        da = ds0 if k == 0 else (ds1 if k == 1 else ds2)
        db = ds1 if k == 0 else (ds2 if k == 1 else ds0)
        if (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0):
            s = da / (da - db)
            x0 = a[0] + s * (b[0] - a[0])
            x1 = a[1] + s * (b[1] - a[1])
            x2 = a[2] + s * (b[2] - a[2])
            if _inside_prism(T, n0, n1, n2, x0, x1, x2):
                return True
    return False


@numba.njit(cache=True, inline='always')
def _point_triangle_dist2(p, T, n0, n1, n2, nn, flat):
    # Squared distance from p to the closed triangle T: to its plane if p projects inside,
    # else to the nearest edge; a flat T is its three edges.
    if not flat and _inside_prism(T, n0, n1, n2, p[0], p[1], p[2]):
        d = (n0 * (p[0] - T[0, 0]) + n1 * (p[1] - T[0, 1]) + n2 * (p[2] - T[0, 2])) / nn
        return d * d
    best = _point_segment_dist2(p[0], p[1], p[2], T[0], T[1])
    best = min(best, _point_segment_dist2(p[0], p[1], p[2], T[1], T[2]))
    return min(best, _point_segment_dist2(p[0], p[1], p[2], T[2], T[0]))


@numba.njit(cache=True, inline='always')
def triangles_intersect(P, Q):
    """Return True iff the closed triangles P and Q touch or cross (see the module contract).

    :param P: (3, 3) float64, rows the vertices of the first triangle.
    :param Q: (3, 3) float64, rows the vertices of the second, in the same frame.
    :return: True iff their distance is at most ``TRIANGLE_EPS_REL`` times the largest
        absolute coordinate (touching counts as contact).
    """
    m = 0.0
    for i in range(3):
        for k in range(3):
            a = abs(P[i, k])
            b = abs(Q[i, k])
            if not (a < math.inf and b < math.inf):       # NaN or infinity
                return True
            m = max(m, a, b)
    tol = TRIANGLE_EPS_REL * m
    tol2 = tol * tol

    p0, p1, p2, pn, p_flat, p_err = _plane(P, tol)
    q0, q1, q2, qn, q_flat, q_err = _plane(Q, tol)
    # 1. A plane with all of the other triangle beyond it (most pairs end here).
    if not q_flat and _beyond_plane(Q, q0, q1, q2, qn, q_err, P, tol):
        return False
    if not p_flat and _beyond_plane(P, p0, p1, p2, pn, p_err, Q, tol):
        return False
    # 2. An edge of one piercing the other: distance 0.
    if not q_flat and _edge_crosses(Q, q0, q1, q2, P):
        return True
    if not p_flat and _edge_crosses(P, p0, p1, p2, Q):
        return True
    # 3. Otherwise the closest points are a vertex and a triangle, or two edges.
    for i in range(3):
        if _point_triangle_dist2(P[i], Q, q0, q1, q2, qn, q_flat) <= tol2:
            return True
        if _point_triangle_dist2(Q[i], P, p0, p1, p2, pn, p_flat) <= tol2:
            return True
    for i in range(3):
        for j in range(3):
            if _segment_segment_dist2(P[i], P[(i + 1) % 3], Q[j], Q[(j + 1) % 3]) <= tol2:
                return True
    return False


bind_to_kernel_sources(globals())
