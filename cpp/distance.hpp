// Distances with nearest points: triangle / triangle and OBB tree / OBB tree (issue 15).
//
// Contract (collision_sensor/distance.py states it in plain Python):
//     triangle_distance(P, Q, x, y) == min |x - y| over x in P, y in Q (closed triangles)
// with x, y written: a nearest pair of points, x on P and y on Q (x == y, a point of both,
// when they touch or cross). P, Q: 3 vertices each, in the same frame.
//
// The nearest points of two disjoint triangles are a vertex of one and its nearest point on
// the other, or the nearest points of an edge of each (Ericson, Real-Time Collision
// Detection, 5.1.9 and 5.2.7); when the triangles cross, an edge of one pierces the other
// (or, coplanar, two edges meet or a vertex lies inside), so 6 point-triangle, 9
// segment-segment and 6 edge-through-face tests settle every case. A triangle thinner than
// the contact tolerance (triangle_test.hpp) is its three edges.
//
// trees_distance: the smallest triangle distance between two OBB trees (traversal.hpp's
// layout), found by descending both with a lower bound per node pair (the larger of the
// spheres' gap and the six face axes' gap, box_pair_gap) and pruning every node pair whose
// bound is not below the best distance found so far, which starts at the caller's cutoff
// (max_distance, or the best over the pair's other trees): a pair with nothing nearer than
// the cutoff costs only the node pairs that prove it. The nearer child pair is visited first.
#pragma once

#include <cstdint>
#include <cstring>

#include "traversal.hpp"
#include "triangle_test.hpp"

namespace collision_sensor {

namespace distance_detail {

using triangle_detail::clamp01;

// Nearest point y on segment [a, b] to p (a point when a == b); returns |p - y|^2.
inline double point_segment_closest(const double* p, const double* a, const double* b,
                                    double* y) {
    const double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
    const double dd = d0 * d0 + d1 * d1 + d2 * d2;
    double s = 0.0;
    if (dd > 0.0)
        s = clamp01(((p[0] - a[0]) * d0 + (p[1] - a[1]) * d1 + (p[2] - a[2]) * d2) / dd);
    y[0] = a[0] + s * d0;
    y[1] = a[1] + s * d1;
    y[2] = a[2] + s * d2;
    const double x0 = p[0] - y[0], x1 = p[1] - y[1], x2 = p[2] - y[2];
    return x0 * x0 + x1 * x1 + x2 * x2;
}

// Nearest points x on [p, q] and y on [a, b]; returns |x - y|^2. The same parameters as
// triangle_test.hpp's segment_segment_dist2 (Ericson 5.1.9), with the points kept.
inline double segment_segment_closest(const double* p, const double* q, const double* a,
                                      const double* b, double* x, double* y) {
    const double d10 = q[0] - p[0], d11 = q[1] - p[1], d12 = q[2] - p[2];
    const double d20 = b[0] - a[0], d21 = b[1] - a[1], d22 = b[2] - a[2];
    const double r0 = p[0] - a[0], r1 = p[1] - a[1], r2 = p[2] - a[2];
    const double aa = d10 * d10 + d11 * d11 + d12 * d12;
    const double ee = d20 * d20 + d21 * d21 + d22 * d22;
    const double f = d20 * r0 + d21 * r1 + d22 * r2;
    double s, t;
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
    x[0] = p[0] + s * d10;
    x[1] = p[1] + s * d11;
    x[2] = p[2] + s * d12;
    y[0] = a[0] + t * d20;
    y[1] = a[1] + t * d21;
    y[2] = a[2] + t * d22;
    const double w0 = x[0] - y[0], w1 = x[1] - y[1], w2 = x[2] - y[2];
    return w0 * w0 + w1 * w1 + w2 * w2;
}

// Nearest point y of the closed triangle T (plane pl, triangle_test.hpp) to p; returns
// |p - y|^2. Its foot on the plane when p projects inside T, else the nearest edge point
// (the nearest point of a convex set outside its prism lies on its boundary).
inline double point_triangle_closest(const double* p, const Triangle& T,
                                     const triangle_detail::Plane& pl, double* y) {
    if (!pl.flat && triangle_detail::inside_prism(T, pl.n0, pl.n1, pl.n2, p[0], p[1], p[2])) {
        const double k = (pl.n0 * (p[0] - T[0][0]) + pl.n1 * (p[1] - T[0][1]) +
                          pl.n2 * (p[2] - T[0][2])) / (pl.nn * pl.nn);
        y[0] = p[0] - k * pl.n0;
        y[1] = p[1] - k * pl.n1;
        y[2] = p[2] - k * pl.n2;
        const double d0 = p[0] - y[0], d1 = p[1] - y[1], d2 = p[2] - y[2];
        return d0 * d0 + d1 * d1 + d2 * d2;
    }
    double z[3];
    double best = point_segment_closest(p, T[0], T[1], y);
    for (int k = 1; k < 3; ++k) {
        const double d = point_segment_closest(p, T[k], T[(k + 1) % 3], z);
        if (d < best) {
            best = d;
            std::memcpy(y, z, sizeof z);
        }
    }
    return best;
}

// True iff an edge of S passes strictly through T's plane at a point inside T; x is then
// that point (a point of both triangles).
inline bool edge_piercing(const Triangle& T, const triangle_detail::Plane& pl, const Triangle& S,
                          double* x) {
    double ds[3];
    for (int k = 0; k < 3; ++k)
        ds[k] = pl.n0 * (S[k][0] - T[0][0]) + pl.n1 * (S[k][1] - T[0][1]) +
                pl.n2 * (S[k][2] - T[0][2]);
    for (int k = 0; k < 3; ++k) {
        const double* a = S[k];
        const double* b = S[(k + 1) % 3];
        const double da = ds[k], db = ds[(k + 1) % 3];
        if ((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            const double s = da / (da - db);
            for (int i = 0; i < 3; ++i) x[i] = a[i] + s * (b[i] - a[i]);
            if (triangle_detail::inside_prism(T, pl.n0, pl.n1, pl.n2, x[0], x[1], x[2]))
                return true;
        }
    }
    return false;
}

}  // namespace distance_detail

// The distance between the closed triangles P and Q, and a nearest pair of points: x on P, y
// on Q (see the contract above). Only for finite input.
inline double triangle_distance(const Triangle& P, const Triangle& Q, double* x, double* y) {
    using namespace distance_detail;
    using triangle_detail::plane_of;
    using triangle_detail::Plane;
    double m = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) m = std::max({m, std::fabs(P[i][k]), std::fabs(Q[i][k])});
    const double tol = TRIANGLE_EPS_REL * m;
    const Plane p = plane_of(P, tol);
    const Plane q = plane_of(Q, tol);
    if ((!q.flat && edge_piercing(Q, q, P, x)) || (!p.flat && edge_piercing(P, p, Q, x))) {
        std::memcpy(y, x, 3 * sizeof(double));
        return 0.0;
    }
    double best = INF, u[3], v[3];
    for (int i = 0; i < 3; ++i) {
        double d = point_triangle_closest(P[i], Q, q, v);
        if (d < best) {
            best = d;
            std::memcpy(x, P[i], sizeof u);
            std::memcpy(y, v, sizeof v);
        }
        d = point_triangle_closest(Q[i], P, p, u);
        if (d < best) {
            best = d;
            std::memcpy(x, u, sizeof u);
            std::memcpy(y, Q[i], sizeof v);
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            const double d =
                segment_segment_closest(P[i], P[(i + 1) % 3], Q[j], Q[(j + 1) % 3], u, v);
            if (d < best) {
                best = d;
                std::memcpy(x, u, sizeof u);
                std::memcpy(y, v, sizeof v);
            }
        }
    }
    return std::sqrt(best);
}

// The nearest triangles found by trees_distance: distance, and the points on each (x in
// body a's frame on tree a's triangle, y on tree b's, also in body a's frame).
struct NearestPoints {
    double distance;
    double x[3], y[3];
    bool found;  // false: nothing nearer than the cutoff
};

// Lower bound of the distance between node na's box (tree a) and node nb's (tree b at pose P).
CS_ALWAYS_INLINE double node_gap(const Forest& f, int64_t na, int64_t nb, const double* P) {
    return box_pair_gap(f.box(na), f.box(nb), P);
}

// The smallest distance between the triangles under node ra (body a) and under node rb (body
// b at pose P in body a's frame), if it is below best.distance: then best is replaced (points
// in body a's frame). Stops at the first distance 0 (touching or crossing triangles).
//
// stack: (S, 3) int64 work, S >= depth(a) + depth(b) + 2; rows (na, nb, bits of the node
// pair's lower bound). counters: COUNT_BOX_TESTS (node pairs bounded) and
// COUNT_TRIANGLE_TESTS (triangle pairs measured) grow.
inline void trees_distance(int64_t ra, int64_t rb, const double* P, const Forest& f,
                           int64_t* stack, int64_t* counters, NearestPoints& best) {
    int64_t n_boxes = 1, n_triangles = 0;
    auto push = [&](int64_t top, int64_t na, int64_t nb, double lb) {
        int64_t* row = stack + 3 * top;
        row[0] = na;
        row[1] = nb;
        std::memcpy(row + 2, &lb, sizeof lb);
    };
    int64_t top = 0;
    const double root_gap = node_gap(f, ra, rb, P);
    if (root_gap < best.distance) push(top++, ra, rb, root_gap);
    Triangle Q;
    double x[3], y[3];
    while (top > 0 && best.distance > 0.0) {
        --top;
        const int64_t* row = stack + 3 * top;
        const int64_t na = row[0], nb = row[1];
        double lb;
        std::memcpy(&lb, row + 2, sizeof lb);
        if (lb >= best.distance) continue;  // the best improved since it was pushed
        const int64_t* node_a = f.node(na);
        const int64_t* node_b = f.node(nb);
        const bool leaf_a = node_a[NODE_LEFT] < 0;
        const bool leaf_b = node_b[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            for (int64_t ib = node_b[NODE_FIRST]; ib < node_b[NODE_FIRST] + node_b[NODE_COUNT];
                 ++ib) {
                triangle_in_a(f.tris, ib, P, Q);
                for (int64_t ia = node_a[NODE_FIRST];
                     ia < node_a[NODE_FIRST] + node_a[NODE_COUNT]; ++ia) {
                    ++n_triangles;
                    const double d = triangle_distance(triangle_at(f.tris, ia), Q, x, y);
                    if (d < best.distance) {
                        best.distance = d;
                        best.found = true;
                        std::memcpy(best.x, x, sizeof x);
                        std::memcpy(best.y, y, sizeof y);
                    }
                }
            }
            continue;
        }
        // Expand the larger box (EXPAND_LARGER by radius), or the one that is not a leaf.
        const bool expand_a =
            !leaf_a && (leaf_b || f.box(na)[BOX_RADIUS] >= f.box(nb)[BOX_RADIUS]);
        int64_t c1a = na, c1b = nb, c2a = na, c2b = nb;
        if (expand_a) {
            c1a = node_a[NODE_LEFT];
            c2a = node_a[NODE_RIGHT];
        } else {
            c1b = node_b[NODE_LEFT];
            c2b = node_b[NODE_RIGHT];
        }
        double g1 = node_gap(f, c1a, c1b, P);
        double g2 = node_gap(f, c2a, c2b, P);
        n_boxes += 2;
        if (g1 < g2) {  // the nearer child pair on top: popped first
            std::swap(g1, g2);
            std::swap(c1a, c2a);
            std::swap(c1b, c2b);
        }
        if (g1 < best.distance) push(top++, c1a, c1b, g1);
        if (g2 < best.distance) push(top++, c2a, c2b, g2);
    }
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
}

}  // namespace collision_sensor
