// Distance between two triangles, with nearest points: the leaf kernel of both
// the proximity traversal (distance.hpp) and the padded contact test (traversal.hpp).
//
// Contract (test/engine_kernels.py states it in plain Python):
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
#pragma once

#include <cmath>
#include <cstring>
#include <limits>

#include "tolerances.hpp"
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
// projects inside T, its foot y is nearer than best: returns the squared distance, else
// infinity.
// (Outside the prism the nearest point of T is on an edge: the segment tests cover it.)
inline double vertex_face(const Triangle& T, const FacePlane& f, const double* v, double sk,
                          double best, double* y) {
    const double d2 = sk * sk / f.nn2;
    if (!(d2 < best) ||
        !triangle_detail::inside_prism(T, f.n[0], f.n[1], f.n[2], v[0], v[1], v[2]))
        return std::numeric_limits<double>::infinity();
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
    double best = std::numeric_limits<double>::infinity(), u[3], v[3];
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

}  // namespace collision_sensor
