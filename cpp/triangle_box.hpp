// A triangle against a solid axis-aligned box: the leaf kernel of a point cloud's
// voxels (voxel_grid.hpp) against a body's triangles.
//
// Contract (test/engine_kernels.py states it in plain Python):
//     triangle_box_distance(T, lo, hi, x, y) == min |x - y| over x in T, y in [lo, hi]
// (T closed, the box solid: a triangle wholly inside the box is at distance 0), with x on T
// and y in the box a nearest pair (x == y, a point of both, when they meet). The box's gaps of
// at most TRIANGLE_EPS_REL times the largest coordinate count as meeting (touching counts, as
// for two triangles: triangle_test.hpp), erring toward contact.
//
// Meeting is decided by the 13 axes of the separating-axis test (Akenine-Moeller, "Fast 3D
// triangle-box overlap testing", 2001): the box's 3 face normals, the triangle's normal and the
// 9 cross products of a box edge and a triangle edge. Two disjoint convex polytopes have nearest
// points on a vertex of one and a face of the other, or on an edge of each (Ericson, Real-Time
// Collision Detection, 5.1): the triangle's 3 vertices clamped to the box, the box's 8 corners
// against the triangle (5.1.5) and the 3 x 12 edge pairs (5.1.9) cover every case.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "tolerances.hpp"
#include "triangle_distance.hpp"

namespace collision_sensor {

namespace triangle_box_detail {

// The nearest point x of the closed triangle T to p; returns |p - x|^2. Ericson 5.1.5 by the
// Voronoi regions of the vertices and edges; a degenerate triangle (no area) is its edges.
inline double closest_on_triangle(const double* p, const Triangle& T, double* x) {
    const double* a = T[0];
    const double* b = T[1];
    const double* c = T[2];
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    auto dot = [](const double* u, const double* v) {
        return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    };
    auto finish = [&](double u0, double u1, double u2) {
        x[0] = u0;
        x[1] = u1;
        x[2] = u2;
        const double d0 = p[0] - u0, d1 = p[1] - u1, d2 = p[2] - u2;
        return d0 * d0 + d1 * d1 + d2 * d2;
    };
    const double n0 = ab[1] * ac[2] - ab[2] * ac[1], n1 = ab[2] * ac[0] - ab[0] * ac[2],
                 n2 = ab[0] * ac[1] - ab[1] * ac[0];
    const double nn = n0 * n0 + n1 * n1 + n2 * n2;
    if (!(nn > TRIANGLE_EPS_REL * TRIANGLE_EPS_REL * dot(ab, ab) * dot(ac, ac))) {
        // No area: the nearest of its three edges.
        double best = std::numeric_limits<double>::infinity(), u[3] = {0.0, 0.0, 0.0};
        for (int k = 0; k < 3; ++k) {
            const double* s = T[k];
            const double* e = T[(k + 1) % 3];
            const double d[3] = {e[0] - s[0], e[1] - s[1], e[2] - s[2]};
            const double dd = dot(d, d);
            double t = 0.0;
            if (dd > 0.0) {
                const double w[3] = {p[0] - s[0], p[1] - s[1], p[2] - s[2]};
                t = std::clamp(dot(w, d) / dd, 0.0, 1.0);
            }
            const double q[3] = {s[0] + t * d[0], s[1] + t * d[1], s[2] + t * d[2]};
            const double g[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
            const double dist = dot(g, g);
            if (dist < best) {
                best = dist;
                u[0] = q[0];
                u[1] = q[1];
                u[2] = q[2];
            }
        }
        return finish(u[0], u[1], u[2]);
    }
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return finish(a[0], a[1], a[2]);
    const double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return finish(b[0], b[1], b[2]);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        return finish(a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]);
    }
    const double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return finish(c[0], c[1], c[2]);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double w = d2 / (d2 - d6);
        return finish(a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return finish(b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]),
                      b[2] + w * (c[2] - b[2]));
    }
    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, w = vc * denom;
    return finish(a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w,
                  a[2] + ab[2] * v + ac[2] * w);
}

// The largest absolute coordinate of T and the box: the scale of the contact tolerance.
inline double coordinate_scale(const Triangle& T, const double* lo, const double* hi) {
    double m = 0.0;
    for (int k = 0; k < 3; ++k)
        m = std::max({m, std::fabs(T[k][0]), std::fabs(T[k][1]), std::fabs(T[k][2]),
                      std::fabs(lo[k]), std::fabs(hi[k])});
    return m;
}

// Clip the convex polygon poly (n vertices, room for n + 1 more) to the half-space where
// coordinate k is >= bound (side +1) or <= bound (side -1); returns the new count.
inline int clip_polygon(double (*poly)[3], int n, int k, double bound, double side,
                        double (*out)[3]) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const double* a = poly[i];
        const double* b = poly[(i + 1) % n];
        const double da = side * (a[k] - bound), db = side * (b[k] - bound);
        if (da >= 0.0) {
            std::copy(a, a + 3, out[m++]);
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            const double t = da / (da - db);
            for (int c = 0; c < 3; ++c) out[m][c] = a[c] + t * (b[c] - a[c]);
            out[m][k] = bound;
            ++m;
        }
    }
    return m;
}

}  // namespace triangle_box_detail

// True iff no axis of the 13 shows the closed triangle T and the solid box of centre c and
// half extents e apart by more than tol (then they meet, or nearly: see the contract).
inline bool triangle_box_overlap(const Triangle& T, const double* c, const double* e,
                                 double tol) {
    double v[3][3];
    for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i) v[k][i] = T[k][i] - c[i];
    // The box's face normals: the triangle's extent along each axis.
    for (int i = 0; i < 3; ++i) {
        const double lo = std::min({v[0][i], v[1][i], v[2][i]});
        const double hi = std::max({v[0][i], v[1][i], v[2][i]});
        if (lo > e[i] + tol || hi < -e[i] - tol) return false;
    }
    const double f[3][3] = {{v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]},
                            {v[2][0] - v[1][0], v[2][1] - v[1][1], v[2][2] - v[1][2]},
                            {v[0][0] - v[2][0], v[0][1] - v[2][1], v[0][2] - v[2][2]}};
    // The triangle's normal.
    const double n[3] = {f[0][1] * f[1][2] - f[0][2] * f[1][1],
                         f[0][2] * f[1][0] - f[0][0] * f[1][2],
                         f[0][0] * f[1][1] - f[0][1] * f[1][0]};
    const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (nn > 0.0) {
        const double r = e[0] * std::fabs(n[0]) + e[1] * std::fabs(n[1]) + e[2] * std::fabs(n[2]);
        const double s = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
        if (std::fabs(s) > r + tol * nn) return false;
    }
    // Box edge i x triangle edge j: a = unit_i x f_j.
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double a[3] = {0.0, 0.0, 0.0};
            const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
            a[i1] = -f[j][i2];
            a[i2] = f[j][i1];
            const double aa = std::sqrt(a[i1] * a[i1] + a[i2] * a[i2]);
            if (!(aa > 0.0)) continue;  // the edge is parallel to the box axis: no axis
            const double p0 = a[0] * v[0][0] + a[1] * v[0][1] + a[2] * v[0][2];
            const double p1 = a[0] * v[1][0] + a[1] * v[1][1] + a[2] * v[1][2];
            const double p2 = a[0] * v[2][0] + a[1] * v[2][1] + a[2] * v[2][2];
            const double r = e[0] * std::fabs(a[0]) + e[1] * std::fabs(a[1]) +
                             e[2] * std::fabs(a[2]);
            if (std::min({p0, p1, p2}) > r + tol * aa || std::max({p0, p1, p2}) < -r - tol * aa)
                return false;
        }
    }
    return true;
}

// The distance between the closed triangle T and the solid box [lo, hi], and a nearest pair
// of points: x on T, y in the box (see the contract above).
inline double triangle_box_distance(const Triangle& T, const double* lo, const double* hi,
                                    double* x, double* y) {
    using namespace triangle_box_detail;
    const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double e[3] = {0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), 0.5 * (hi[2] - lo[2])};
    const double tol = TRIANGLE_EPS_REL * coordinate_scale(T, lo, hi);
    if (triangle_box_overlap(T, c, e, tol)) {
        // A point of both: the triangle clipped to the box (its centroid; the polygon is
        // convex). Empty when they only touch within the tolerance: the nearest points then.
        double a[10][3], b[10][3];
        for (int k = 0; k < 3; ++k) std::copy(T[k], T[k] + 3, a[k]);
        int n = 3;
        for (int k = 0; k < 3 && n > 0; ++k) {
            n = clip_polygon(a, n, k, lo[k], 1.0, b);
            n = n > 0 ? clip_polygon(b, n, k, hi[k], -1.0, a) : 0;
        }
        if (n > 0) {
            double s[3] = {0.0, 0.0, 0.0};
            for (int i = 0; i < n; ++i)
                for (int k = 0; k < 3; ++k) s[k] += a[i][k];
            for (int k = 0; k < 3; ++k) x[k] = y[k] = std::clamp(s[k] / n, lo[k], hi[k]);
            return 0.0;
        }
    }
    double best = std::numeric_limits<double>::infinity(), u[3], w[3];
    // The triangle's vertices against the box: clamped.
    for (int k = 0; k < 3; ++k) {
        double d = 0.0;
        for (int i = 0; i < 3; ++i) {
            w[i] = std::clamp(T[k][i], lo[i], hi[i]);
            d += (T[k][i] - w[i]) * (T[k][i] - w[i]);
        }
        if (d < best) {
            best = d;
            std::copy(T[k], T[k] + 3, x);
            std::copy(w, w + 3, y);
        }
    }
    // The box's corners against the triangle.
    double corner[8][3];
    for (int m = 0; m < 8; ++m) {
        for (int i = 0; i < 3; ++i) corner[m][i] = (m >> i) & 1 ? hi[i] : lo[i];
        const double d = closest_on_triangle(corner[m], T, u);
        if (d < best) {
            best = d;
            std::copy(u, u + 3, x);
            std::copy(corner[m], corner[m] + 3, y);
        }
    }
    // Each edge of the triangle against each of the box's 12 edges (corner m to m + 2^i, bit
    // i of m clear).
    for (int k = 0; k < 3; ++k) {
        for (int m = 0; m < 8; ++m) {
            for (int i = 0; i < 3; ++i) {
                if ((m >> i) & 1) continue;
                const double d = distance_detail::segment_segment_closest(
                    T[k], T[(k + 1) % 3], corner[m], corner[m | (1 << i)], u, w);
                if (d < best) {
                    best = d;
                    std::copy(u, u + 3, x);
                    std::copy(w, w + 3, y);
                }
            }
        }
    }
    return std::sqrt(best);
}

// True iff the closed triangle T comes within pad of the solid box [lo, hi] (pad 0: meets it,
// up to the touching tolerance); distance: the triangle's distance from the box when it was
// measured (pad > 0 and not rejected by a cheap bound), else a lower bound (0 when unknown).
inline bool triangle_box_within(const Triangle& T, const double* lo, const double* hi,
                                double pad, double* distance) {
    using namespace triangle_box_detail;
    *distance = 0.0;
    // The triangle's own box against the box grown by pad (cheapest first).
    double gap = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double tlo = std::min({T[0][i], T[1][i], T[2][i]});
        const double thi = std::max({T[0][i], T[1][i], T[2][i]});
        gap = std::max({gap, tlo - hi[i], lo[i] - thi});
    }
    const double tol = TRIANGLE_EPS_REL * coordinate_scale(T, lo, hi);
    if (gap > pad + tol) {
        *distance = gap;
        return false;
    }
    const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double e[3] = {0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), 0.5 * (hi[2] - lo[2])};
    if (triangle_box_overlap(T, c, e, tol)) return true;
    if (!(pad > 0.0)) {
        *distance = gap;
        return false;
    }
    double x[3], y[3];
    *distance = triangle_box_distance(T, lo, hi, x, y);
    return *distance <= pad;
}

}  // namespace collision_sensor
