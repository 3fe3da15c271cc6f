// Triangle / triangle contact for the leaves of the box hierarchies.
//
// Contract (test/engine_kernels.py states it in plain Python):
//     triangles_intersect(P, Q) == (distance(P, Q) <= TRIANGLE_EPS_REL * m)
// P, Q: 3 vertices each (P[k][i]: coordinate i of vertex k), both in the same frame; distance
// is the Euclidean distance between the closed triangles (0 when they cross or touch), m the
// largest absolute coordinate of the six vertices. Touching counts as contact, and so does a
// gap below the tolerance (about 1e-12 of the coordinates, the scale of their own rounding).
// Coplanar triangles are decided by the same rule. A zero-area triangle is the segment or
// point it is; a sliver thinner than half the tolerance is treated as its three edges. Input
// with a NaN or an infinity answers true (err toward contact).
//
// Why a distance rule rather than orientation predicates alone (Moeller, Guigue-Devillers):
// in float64, signs of near-zero determinants are noise, so "touching" has no stable answer; a
// distance against a tolerance is continuous in the input. A plane test rejects most pairs
// with 2 cross products, an edge piercing the other triangle settles most contacts, the nine
// edge-edge axes most near misses; only pairs within rounding of touching pay for up to 6
// point-triangle and 9 segment-segment distances, with an early exit at the first contact.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "inlining.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

using Triangle = double[3][3];

namespace triangle_detail {

constexpr double U = 1.1102230246251565e-16;  // unit roundoff of float64, 2^-53

inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

// Squared distance from point p to segment [a, b] (a point when a == b).
inline double point_segment_dist2(double p0, double p1, double p2, const double* a,
                                  const double* b) {
    const double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
    const double w0 = p0 - a[0], w1 = p1 - a[1], w2 = p2 - a[2];
    const double dd = d0 * d0 + d1 * d1 + d2 * d2;
    double s = 0.0;
    if (dd > 0.0) s = clamp01((w0 * d0 + w1 * d1 + w2 * d2) / dd);
    const double x0 = w0 - s * d0, x1 = w1 - s * d1, x2 = w2 - s * d2;
    return x0 * x0 + x1 * x1 + x2 * x2;
}

// Parameters of the nearest points of segments [p, q] and [a, b] (either may be a point):
// p + s (q - p) and a + t (b - a), s and t in [0, 1]. Ericson, Real-Time Collision Detection,
// 5.1.9: closest point of the lines, clamped to the segments, re-clamped once. Parallel
// segments (denominator 0) start from s = 0, which is exact.
CS_ALWAYS_INLINE void segment_segment_params(const double* p, const double* q, const double* a,
                                             const double* b, double& s, double& t) {
    const double d10 = q[0] - p[0], d11 = q[1] - p[1], d12 = q[2] - p[2];
    const double d20 = b[0] - a[0], d21 = b[1] - a[1], d22 = b[2] - a[2];
    const double r0 = p[0] - a[0], r1 = p[1] - a[1], r2 = p[2] - a[2];
    const double aa = d10 * d10 + d11 * d11 + d12 * d12;
    const double ee = d20 * d20 + d21 * d21 + d22 * d22;
    const double f = d20 * r0 + d21 * r1 + d22 * r2;
    if (aa == 0.0 && ee == 0.0) {
        s = 0.0;
        t = 0.0;
    } else if (aa == 0.0) {
        s = 0.0;
        t = clamp01(f / ee);
    } else {
        const double c = d10 * r0 + d11 * r1 + d12 * r2;
        if (ee == 0.0) {
            s = clamp01(-c / aa);
            t = 0.0;
        } else {
            const double bb = d10 * d20 + d11 * d21 + d12 * d22;
            const double denom = aa * ee - bb * bb;
            s = denom > 0.0 ? clamp01((bb * f - c * ee) / denom) : 0.0;
            t = (bb * s + f) / ee;
            if (t < 0.0) {
                t = 0.0;
                s = clamp01(-c / aa);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp01((bb - c) / aa);
            }
        }
    }
}

// Squared distance between segments [p, q] and [a, b]; either may be a point.
inline double segment_segment_dist2(const double* p, const double* q, const double* a,
                                    const double* b) {
    double s, t;
    segment_segment_params(p, q, a, b, s, t);
    const double x0 = (p[0] - a[0]) + s * (q[0] - p[0]) - t * (b[0] - a[0]);
    const double x1 = (p[1] - a[1]) + s * (q[1] - p[1]) - t * (b[1] - a[1]);
    const double x2 = (p[2] - a[2]) + s * (q[2] - p[2]) - t * (b[2] - a[2]);
    return x0 * x0 + x1 * x1 + x2 * x2;
}

// True iff x projects into triangle T along its normal n: x lies on the inner side (or on)
// each edge's plane through n, ((T[k+1] - T[k]) x (x - T[k])) . n >= 0 for k = 0, 1, 2.
inline bool inside_prism(const Triangle& T, double n0, double n1, double n2, double x0,
                         double x1, double x2) {
    for (int k = 0; k < 3; ++k) {
        const double* a = T[k];
        const double* b = T[(k + 1) % 3];
        const double e0 = b[0] - a[0], e1 = b[1] - a[1], e2 = b[2] - a[2];
        const double w0 = x0 - a[0], w1 = x1 - a[1], w2 = x2 - a[2];
        const double c =
            ((e1 * w2 - e2 * w1) * n0 + (e2 * w0 - e0 * w2) * n1 + (e0 * w1 - e1 * w0) * n2);
        if (c < 0.0) return false;
    }
    return true;
}

// n = (T1 - T0) x (T2 - T0), nn = |n|, flat iff T is thinner than tol / 2 (|n| / longest edge
// = twice its area over its longest edge), and err a bound on the rounding of n per unit
// distance, so |n . (x - T0)| is exact to within err |x - T0|_1.
struct Plane {
    double n0, n1, n2, nn, err;
    bool flat;
};

inline Plane plane_of(const Triangle& T, double tol) {
    const double a0 = T[1][0] - T[0][0], a1 = T[1][1] - T[0][1], a2 = T[1][2] - T[0][2];
    const double b0 = T[2][0] - T[0][0], b1 = T[2][1] - T[0][1], b2 = T[2][2] - T[0][2];
    Plane pl;
    pl.n0 = a1 * b2 - a2 * b1;
    pl.n1 = a2 * b0 - a0 * b2;
    pl.n2 = a0 * b1 - a1 * b0;
    pl.nn = std::sqrt(pl.n0 * pl.n0 + pl.n1 * pl.n1 + pl.n2 * pl.n2);
    const double c0 = T[2][0] - T[1][0], c1 = T[2][1] - T[1][1], c2 = T[2][2] - T[1][2];
    const double longest = std::sqrt(std::max({a0 * a0 + a1 * a1 + a2 * a2,
                                               b0 * b0 + b1 * b1 + b2 * b2,
                                               c0 * c0 + c1 * c1 + c2 * c2}));
    pl.flat = !(pl.nn > 0.5 * tol * longest);
    const double la = std::fabs(a0) + std::fabs(a1) + std::fabs(a2);
    const double lb = std::fabs(b0) + std::fabs(b1) + std::fabs(b2);
    pl.err = 16.0 * U * (la * lb + std::fabs(pl.n0) + std::fabs(pl.n1) + std::fabs(pl.n2));
    return pl;
}

// True iff all three vertices of S are farther than tol from T's plane, on the same side,
// beyond the rounding of the signed distances (so a rejection here is never wrong).
inline bool beyond_plane(const Triangle& T, const Plane& pl, const Triangle& S, double tol) {
    int pos = 0, neg = 0;
    for (int k = 0; k < 3; ++k) {
        const double w0 = S[k][0] - T[0][0], w1 = S[k][1] - T[0][1], w2 = S[k][2] - T[0][2];
        const double d = pl.n0 * w0 + pl.n1 * w1 + pl.n2 * w2;
        const double margin =
            tol * pl.nn + pl.err * (std::fabs(w0) + std::fabs(w1) + std::fabs(w2));
        if (d > margin)
            ++pos;
        else if (d < -margin)
            ++neg;
        else
            return false;
    }
    return pos == 3 || neg == 3;
}

// True iff an edge of S passes strictly through T's plane at a point inside T.
inline bool edge_crosses(const Triangle& T, const Plane& pl, const Triangle& S) {
    double ds[3];
    for (int k = 0; k < 3; ++k)
        ds[k] = pl.n0 * (S[k][0] - T[0][0]) + pl.n1 * (S[k][1] - T[0][1]) +
                pl.n2 * (S[k][2] - T[0][2]);
    for (int k = 0; k < 3; ++k) {
        const double* a = S[k];
        const double* b = S[(k + 1) % 3];
        const double da = ds[k];
        const double db = ds[(k + 1) % 3];
        if ((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            const double s = da / (da - db);
            const double x0 = a[0] + s * (b[0] - a[0]);
            const double x1 = a[1] + s * (b[1] - a[1]);
            const double x2 = a[2] + s * (b[2] - a[2]);
            if (inside_prism(T, pl.n0, pl.n1, pl.n2, x0, x1, x2)) return true;
        }
    }
    return false;
}

// True iff an axis e_i x f_j (e_i an edge of P, f_j one of Q) shows the triangles farther
// apart than tol, beyond the rounding of the projections (so a rejection here is never wrong).
// The projections of a triangle's three vertices on a line span the whole triangle's, so a
// gap g between them along any axis L bounds the distance from below by g / |L|: the
// rounding in forming L only picks another axis. Two disjoint triangles that neither plane
// separates are separated along one of these nine axes (separating axis theorem), so this
// settles most near misses, which the distances below would take 15 computations to settle.
//
// Rounding: with vertices taken relative to P[0] (coordinates of the pair's own size, at
// most M), each projection is within 4 U |L|_1 M of the exact one, so the gap is within
// 8 U |L|_1 M (16 allowed, as plane_of does).
inline bool edge_axes_separate(const Triangle& P, const Triangle& Q, double tol) {
    double p[3][3], q[3][3];
    double M = 0.0;
    for (int k = 0; k < 3; ++k) {
        for (int i = 0; i < 3; ++i) {
            p[k][i] = P[k][i] - P[0][i];
            q[k][i] = Q[k][i] - P[0][i];
            M = std::max({M, std::fabs(p[k][i]), std::fabs(q[k][i])});
        }
    }
    for (int i = 0; i < 3; ++i) {
        const double* a = p[i];
        const double* b = p[(i + 1) % 3];
        const double e0 = b[0] - a[0], e1 = b[1] - a[1], e2 = b[2] - a[2];
        for (int j = 0; j < 3; ++j) {
            const double* c = q[j];
            const double* d = q[(j + 1) % 3];
            const double f0 = d[0] - c[0], f1 = d[1] - c[1], f2 = d[2] - c[2];
            const double L0 = e1 * f2 - e2 * f1, L1 = e2 * f0 - e0 * f2, L2 = e0 * f1 - e1 * f0;
            const double p0 = L0 * p[0][0] + L1 * p[0][1] + L2 * p[0][2];
            const double p1 = L0 * p[1][0] + L1 * p[1][1] + L2 * p[1][2];
            const double p2 = L0 * p[2][0] + L1 * p[2][1] + L2 * p[2][2];
            const double q0 = L0 * q[0][0] + L1 * q[0][1] + L2 * q[0][2];
            const double q1 = L0 * q[1][0] + L1 * q[1][1] + L2 * q[1][2];
            const double q2 = L0 * q[2][0] + L1 * q[2][1] + L2 * q[2][2];
            const double gap = std::max(std::min({q0, q1, q2}) - std::max({p0, p1, p2}),
                                        std::min({p0, p1, p2}) - std::max({q0, q1, q2}));
            const double err =
                16.0 * U * (std::fabs(L0) + std::fabs(L1) + std::fabs(L2)) * M;
            if (gap > err &&
                gap - err > tol * std::sqrt(L0 * L0 + L1 * L1 + L2 * L2) * (1.0 + 1e-12))
                return true;
        }
    }
    return false;
}

// Squared distance from p to the closed triangle T: to its plane if p projects inside, else
// to the nearest edge; a flat T is its three edges.
inline double point_triangle_dist2(const double* p, const Triangle& T, const Plane& pl) {
    if (!pl.flat && inside_prism(T, pl.n0, pl.n1, pl.n2, p[0], p[1], p[2])) {
        const double d = (pl.n0 * (p[0] - T[0][0]) + pl.n1 * (p[1] - T[0][1]) +
                          pl.n2 * (p[2] - T[0][2])) / pl.nn;
        return d * d;
    }
    double best = point_segment_dist2(p[0], p[1], p[2], T[0], T[1]);
    best = std::min(best, point_segment_dist2(p[0], p[1], p[2], T[1], T[2]));
    return std::min(best, point_segment_dist2(p[0], p[1], p[2], T[2], T[0]));
}

}  // namespace triangle_detail

// True iff the closed triangles P and Q touch or cross (see the contract above).
inline bool triangles_intersect(const Triangle& P, const Triangle& Q) {
    using namespace triangle_detail;
    double m = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            const double a = std::fabs(P[i][k]);
            const double b = std::fabs(Q[i][k]);
            constexpr double inf = std::numeric_limits<double>::infinity();
            if (!(a < inf && b < inf)) return true;  // NaN or infinity
            m = std::max({m, a, b});
        }
    }
    const double tol = TRIANGLE_EPS_REL * m;
    const double tol2 = tol * tol;
    const Plane p = plane_of(P, tol);
    const Plane q = plane_of(Q, tol);
    // 1. A plane with all of the other triangle beyond it (most pairs end here).
    if (!q.flat && beyond_plane(Q, q, P, tol)) return false;
    if (!p.flat && beyond_plane(P, p, Q, tol)) return false;
    // 2. An edge of one piercing the other: distance 0.
    if (!q.flat && edge_crosses(Q, q, P)) return true;
    if (!p.flat && edge_crosses(P, p, Q)) return true;
    // 3. An axis from an edge of each showing them apart by more than tol (near misses).
    if (edge_axes_separate(P, Q, tol)) return false;
    // 4. Otherwise the closest points are a vertex and a triangle, or two edges.
    for (int i = 0; i < 3; ++i) {
        if (point_triangle_dist2(P[i], Q, q) <= tol2) return true;
        if (point_triangle_dist2(Q[i], P, p) <= tol2) return true;
    }
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (segment_segment_dist2(P[i], P[(i + 1) % 3], Q[j], Q[(j + 1) % 3]) <= tol2)
                return true;
    return false;
}

}  // namespace collision_sensor
