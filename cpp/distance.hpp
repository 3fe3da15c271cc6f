// Distances with nearest points: triangle / triangle and OBB tree / OBB tree (issue 15).
//
// Contract (collision_sensor/distance.py states it in plain Python, with proximity's):
//     triangle_distance(P, Q, x, y) == min |x - y| over x in P, y in Q (closed triangles)
// with x, y written: a nearest pair of points, x on P and y on Q (x == y, a point of both,
// when they touch or cross). P, Q: 3 vertices each, in the same frame.
//
// The nearest points of two disjoint triangles are a vertex of one and its nearest point on
// the other, or the nearest points of an edge of each (Ericson, Real-Time Collision
// Detection, 5.1.9 and 5.2.7); when the triangles cross, an edge of one pierces the other
// (or, coplanar, two edges meet or a vertex lies inside), so 6 point-triangle, 9
// segment-segment and 6 edge-through-face tests settle every case. A triangle thinner than
// the contact tolerance (its sine below TRIANGLE_EPS_REL) is its three edges.
//
// trees_distance: the smallest triangle distance between two OBB trees (traversal.hpp's
// layout), found by descending both with a lower bound per node pair (the boxes' gap along
// an axis aimed at their nearest points: projected_gap) and pruning every node pair whose
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


// Nearest points x on [p, q] and y on [a, b]; returns |x - y|^2 (triangle_test.hpp's
// parameters, with the points kept).
inline double segment_segment_closest(const double* p, const double* q, const double* a,
                                      const double* b, double* x, double* y) {
    double s, t;
    triangle_detail::segment_segment_params(p, q, a, b, s, t);
    for (int k = 0; k < 3; ++k) {
        x[k] = p[k] + s * (q[k] - p[k]);
        y[k] = a[k] + t * (b[k] - a[k]);
    }
    const double w0 = x[0] - y[0], w1 = x[1] - y[1], w2 = x[2] - y[2];
    return w0 * w0 + w1 * w1 + w2 * w2;
}

// A triangle's plane for the distance: n = (T1 - T0) x (T2 - T0), nn2 = |n|^2, s[k] =
// n . (S[k] - T0) for the other triangle S's vertices; flat when T is thinner than the
// contact tolerance (|n| below TRIANGLE_EPS_REL times its two edges' lengths: a sine), and
// then only its edges count.
struct FacePlane {
    double n[3], nn2, s[3];
    bool flat;
};

inline FacePlane face_plane(const Triangle& T, const Triangle& S) {
    const double a0 = T[1][0] - T[0][0], a1 = T[1][1] - T[0][1], a2 = T[1][2] - T[0][2];
    const double b0 = T[2][0] - T[0][0], b1 = T[2][1] - T[0][1], b2 = T[2][2] - T[0][2];
    FacePlane f;
    f.n[0] = a1 * b2 - a2 * b1;
    f.n[1] = a2 * b0 - a0 * b2;
    f.n[2] = a0 * b1 - a1 * b0;
    f.nn2 = f.n[0] * f.n[0] + f.n[1] * f.n[1] + f.n[2] * f.n[2];
    const double scale = (a0 * a0 + a1 * a1 + a2 * a2) * (b0 * b0 + b1 * b1 + b2 * b2);
    f.flat = !(f.nn2 > TRIANGLE_EPS_REL * TRIANGLE_EPS_REL * scale);
    for (int k = 0; k < 3; ++k)
        f.s[k] = f.n[0] * (S[k][0] - T[0][0]) + f.n[1] * (S[k][1] - T[0][1]) +
                 f.n[2] * (S[k][2] - T[0][2]);
    return f;
}

// True iff an edge of S passes strictly through T's plane at a point inside T; x is then
// that point (a point of both triangles).
inline bool edge_piercing(const Triangle& T, const FacePlane& f, const Triangle& S, double* x) {
    for (int k = 0; k < 3; ++k) {
        const double* a = S[k];
        const double* b = S[(k + 1) % 3];
        const double da = f.s[k], db = f.s[(k + 1) % 3];
        if ((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            const double t = da / (da - db);
            for (int i = 0; i < 3; ++i) x[i] = a[i] + t * (b[i] - a[i]);
            if (triangle_detail::inside_prism(T, f.n[0], f.n[1], f.n[2], x[0], x[1], x[2]))
                return true;
        }
    }
    return false;
}

// Vertex k of S against T's face: if its squared distance to T's plane is below best and it
// projects inside T, its foot y is nearer than best: returns the squared distance, else INF.
// (Outside the prism the nearest point of T is on an edge: the segment tests cover it.)
inline double vertex_face(const Triangle& T, const FacePlane& f, const double* v, double sk,
                          double best, double* y) {
    const double d2 = sk * sk / f.nn2;
    if (!(d2 < best) ||
        !triangle_detail::inside_prism(T, f.n[0], f.n[1], f.n[2], v[0], v[1], v[2]))
        return INF;
    const double k = sk / f.nn2;
    for (int i = 0; i < 3; ++i) y[i] = v[i] - k * f.n[i];
    return d2;
}

}  // namespace distance_detail

// The distance between the closed triangles P and Q, and a nearest pair of points: x on P, y
// on Q (see the contract above). Only for finite input.
//
// Order of the work: an edge piercing the other's face (distance 0, stop); the 9 edge pairs;
// then a vertex against the other's face only where its plane distance can beat the best so
// far (a vertex's nearest point on an edge is already an edge pair's).
//
// apart: the caller knows the triangles apart (boxes around them with a positive gap), so no
// edge can pierce the other's face and that test is skipped.
inline double triangle_distance(const Triangle& P, const Triangle& Q, double* x, double* y,
                                bool apart = false) {
    using namespace distance_detail;
    const FacePlane p = face_plane(P, Q);
    const FacePlane q = face_plane(Q, P);
    if (!apart &&
        ((!q.flat && edge_piercing(Q, q, P, x)) || (!p.flat && edge_piercing(P, p, Q, x)))) {
        std::memcpy(y, x, 3 * sizeof(double));
        return 0.0;
    }
    double best = INF, u[3], v[3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            const double d =
                segment_segment_closest(P[i], P[(i + 1) % 3], Q[j], Q[(j + 1) % 3], u, v);
            if (d < best) {
                best = d;
                std::memcpy(x, u, sizeof u);
                std::memcpy(y, v, sizeof v);
                // Gottschalk's early exit (PQP TriDist): w = v - u; each edge lies behind its
                // closest point along w (u on P's edge: (p - u) . w <= 0 for its endpoints, by
                // the points' optimality), so if the third vertices do too, the slab between
                // the planes through u and v normal to w separates the triangles: done.
                const double w0 = v[0] - u[0], w1 = v[1] - u[1], w2 = v[2] - u[2];
                const double* p3 = P[(i + 2) % 3];
                const double* q3 = Q[(j + 2) % 3];
                const double ap = (p3[0] - u[0]) * w0 + (p3[1] - u[1]) * w1 + (p3[2] - u[2]) * w2;
                const double bq = (q3[0] - v[0]) * w0 + (q3[1] - v[1]) * w1 + (q3[2] - v[2]) * w2;
                if (d > 0.0 && ap <= 0.0 && bq >= 0.0) return std::sqrt(d);
            }
        }
    }
    for (int i = 0; i < 3; ++i) {
        if (!q.flat) {
            const double d = vertex_face(Q, q, P[i], q.s[i], best, v);
            if (d < best) {
                best = d;
                std::memcpy(x, P[i], sizeof u);
                std::memcpy(y, v, sizeof v);
            }
        }
        if (!p.flat) {
            const double d = vertex_face(P, p, Q[i], p.s[i], best, u);
            if (d < best) {
                best = d;
                std::memcpy(x, u, sizeof u);
                std::memcpy(y, Q[i], sizeof v);
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

// A lower bound of the distance between boxes A and B, B in A's box frame (T: R, t as
// box_in_frame). The boxes' gap along a unit axis bounds their distance whatever the axis;
// this one aims at the nearest points by alternating projection (x, the point of A nearest
// B's centre; y, the point of B nearest x; x again, the point of A nearest y; u = y - x:
// more rounds converge to a nearest pair, but pruned no more node pairs on the Panda and
// UR5). The gap along u is (min over B of u.p) - (max over A of u.p), with each box's support
// |u . axis_k| h_k. (The face axes' gap, tried on top of it, pruned almost nothing more.)
// Boxes whose projection meets (overlapping, or nearly) get face_gap.
CS_ALWAYS_INLINE double projected_gap(const double* A, const double* B, const double* T) {
    using std::fabs;
    const double* ha = A + BOX_HALF;
    const double* hb = B + BOX_HALF;
    const double* R = T;  // column k: B's axis k in A's box frame
    const double* t = T + 9;
    auto clamp = [](double v, double h) { return v < -h ? -h : (v > h ? h : v); };
    double x[3], y[3], z[3];
    for (int i = 0; i < 3; ++i) x[i] = clamp(t[i], ha[i]);
    // y: x taken to B's box frame (R' (x - t)), clamped, and back (R z + t).
    const double w0 = x[0] - t[0], w1 = x[1] - t[1], w2 = x[2] - t[2];
    for (int k = 0; k < 3; ++k) z[k] = clamp(R[k] * w0 + R[3 + k] * w1 + R[6 + k] * w2, hb[k]);
    for (int i = 0; i < 3; ++i)
        y[i] = R[3 * i] * z[0] + R[3 * i + 1] * z[1] + R[3 * i + 2] * z[2] + t[i];
    for (int i = 0; i < 3; ++i) x[i] = clamp(y[i], ha[i]);
    const double u0 = y[0] - x[0], u1 = y[1] - x[1], u2 = y[2] - x[2];
    const double uu = u0 * u0 + u1 * u1 + u2 * u2;
    if (!(uu > 0.0)) return face_gap(A, B, T);
    // The gap along u / |u|, computed along u and divided once.
    double g = u0 * t[0] + u1 * t[1] + u2 * t[2] -
               (ha[0] * fabs(u0) + ha[1] * fabs(u1) + ha[2] * fabs(u2));
    for (int k = 0; k < 3; ++k) g -= hb[k] * fabs(R[k] * u0 + R[3 + k] * u1 + R[6 + k] * u2);
    g /= std::sqrt(uu);
    return g;
}

// Tree b's boxes placed in body a's frame, each computed once per traversal (a node of tree b
// meets many of tree a's): rows (N, PLACED_WIDTH), the centre R_ab cb + t_ab, then the axes
// R_ab Eb (row-major, column k is axis k); a row is current iff stamp[n] == tag.
constexpr int PLACED_WIDTH = 12;
struct PlacedBoxes {
    double* rows;
    int64_t* stamp;
    int64_t tag;
};

// Lower bound of the distance between node na's box (tree a) and node nb's (tree b at pose
// P): projected_gap, with nb's placement taken from (or put into) placed: box_in_frame's
// [R, t] = [Ea' (R_ab Eb), Ea' ((R_ab cb + t_ab) - ca)] from its cached factors.
CS_ALWAYS_INLINE double placed_node_gap(const Forest& f, int64_t na, int64_t nb,
                                        const double* P, PlacedBoxes& placed) {
    const double* A = f.box(na);
    const double* B = f.box(nb);
    double* row = placed.rows + PLACED_WIDTH * nb;
    const int e = BOX_AXES;
    if (placed.stamp[nb] != placed.tag) {
        placed.stamp[nb] = placed.tag;
        for (int i = 0; i < 3; ++i) {
            row[i] = P[3 * i] * B[0] + P[3 * i + 1] * B[1] + P[3 * i + 2] * B[2] + P[9 + i];
            for (int k = 0; k < 3; ++k)
                row[3 + 3 * i + k] = P[3 * i] * B[e + k] + P[3 * i + 1] * B[e + 3 + k] +
                                     P[3 * i + 2] * B[e + 6 + k];
        }
    }
    const double d0 = row[0] - A[0], d1 = row[1] - A[1], d2 = row[2] - A[2];
    const double* M = row + 3;
    double T[12];
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k)
            T[3 * i + k] = A[e + i] * M[k] + A[e + 3 + i] * M[3 + k] + A[e + 6 + i] * M[6 + k];
        T[9 + i] = A[e + i] * d0 + A[e + 3 + i] * d1 + A[e + 6 + i] * d2;
    }
    return projected_gap(A, B, T);
}

// The smallest distance between the triangles under node ra (body a) and under node rb (body
// b at pose P in body a's frame), if it is below best.distance: then best is replaced (points
// in body a's frame). Stops at the first distance 0 (touching or crossing triangles).
//
// stack: (S, 3) int64 work, S >= depth(a) + depth(b) + 2; rows (na, nb, bits of the node
// pair's lower bound). placed: work rows for every node of the forest (its tag is advanced).
// counters: COUNT_BOX_TESTS (node pairs bounded) and COUNT_TRIANGLE_TESTS (triangle pairs
// measured) grow.
inline void trees_distance(int64_t ra, int64_t rb, const double* P, const Forest& f,
                           int64_t* stack, int64_t* counters, NearestPoints& best,
                           PlacedBoxes& placed) {
    ++placed.tag;
    int64_t n_boxes = 1, n_triangles = 0;
    auto push = [&](int64_t top, int64_t na, int64_t nb, double lb) {
        int64_t* row = stack + 3 * top;
        row[0] = na;
        row[1] = nb;
        std::memcpy(row + 2, &lb, sizeof lb);
    };
    int64_t top = 0;
    const double root_gap = placed_node_gap(f, ra, rb, P, placed);
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
                    const double d =
                        triangle_distance(triangle_at(f.tris, ia), Q, x, y, lb > 0.0);
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
        double g1 = placed_node_gap(f, c1a, c1b, P, placed);
        double g2 = placed_node_gap(f, c2a, c2b, P, placed);
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
