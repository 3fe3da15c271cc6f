// Convex sweeps: when two convex bodies move relative to each other by a translation alone,
// their first contact along it is a ray cast against their Minkowski difference (van den
// Bergen, "Ray casting against general convex objects with application to continuous
// collision detection", 2004: GJK that advances along the ray to each separating plane it
// finds). Exact up to eps, and conservative: every state before the answer is apart.
//
// Body b translates in body a's frame: its points x_b map to R x_b + t0 + s d at the motion's
// parameter s in [0, 1]. Shape A (in a's frame) and shape B (in b's frame) meet at s iff s d
// lies in C = A - (R B + t0), within rho of it with padding rho. The ray from the origin along
// d is advanced to C's supporting planes, never into C, until it is within rho + eps of C
// (the state there is within eps of contact) or it leaves C behind (apart all along).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace collision_sensor {

// The ray cast's answers.
constexpr int SWEEP_FREE = 0, SWEEP_CONTACT = 1, SWEEP_UNKNOWN = 2;
// GJK iterations before a sweep gives up (SWEEP_UNKNOWN: the caller marches instead).
constexpr int SWEEP_ITERATIONS = 96;
// A hull of at most this many vertices is scanned; larger ones are climbed along edges.
constexpr int64_t HULL_SCAN_MAX = 24;

// Directions whose furthest vertices a hull keeps, to start its climbs near the answer: the
// centres of a cube map's cells, HULL_SEED_GRID x HULL_SEED_GRID on each of the cube's six
// faces (unnormalised: only the largest dot product counts). A direction's cell is
// hull_seed_cell's: its largest component picks the face, the other two the cell.
constexpr int HULL_SEED_GRID = 6;
constexpr int HULL_SEEDS = 6 * HULL_SEED_GRID * HULL_SEED_GRID;

inline int hull_seed_cell(const double* d) {
    const double a[3] = {std::fabs(d[0]), std::fabs(d[1]), std::fabs(d[2])};
    const int axis = a[0] >= a[1] ? (a[0] >= a[2] ? 0 : 2) : (a[1] >= a[2] ? 1 : 2);
    const int f = 2 * axis + (d[axis] >= 0.0 ? 0 : 1);
    if (!(a[axis] > 0.0)) return 0;  // no direction (or NaN): any seed will do
    const double scale = 0.5 * HULL_SEED_GRID / a[axis];
    const auto cell = [scale](double x) {
        return std::min(HULL_SEED_GRID - 1, std::max(0, int((x * scale) + 0.5 * HULL_SEED_GRID)));
    };
    return (f * HULL_SEED_GRID + cell(d[(axis + 1) % 3])) * HULL_SEED_GRID +
           cell(d[(axis + 2) % 3]);
}

inline const double* hull_seed_direction(int k) {
    static const auto table = [] {
        std::array<double, 3 * HULL_SEEDS> t{};
        for (int f = 0; f < 6; ++f)
            for (int i = 0; i < HULL_SEED_GRID; ++i)
                for (int j = 0; j < HULL_SEED_GRID; ++j) {
                    // Face f: axis f / 2, positive for even f; cells along the next two.
                    const int axis = f / 2, u = (axis + 1) % 3, v = (axis + 2) % 3;
                    double* x = t.data() + 3 * ((f * HULL_SEED_GRID + i) * HULL_SEED_GRID + j);
                    x[axis] = f % 2 == 0 ? 1.0 : -1.0;
                    x[u] = (2.0 * i + 1.0) / HULL_SEED_GRID - 1.0;
                    x[v] = (2.0 * j + 1.0) / HULL_SEED_GRID - 1.0;
                }
        return t;
    }();
    return table.data() + 3 * k;
}

// The distinct vertices (n, 3) of a convex hull, each one's neighbours along its edges
// (adj[adj_start[i] : adj_start[i + 1]], local indices) and its furthest vertex along each
// hull_seed_direction (seeds, HULL_SEEDS; unused for hulls of at most HULL_SCAN_MAX).
struct HullView {
    const double* v;
    int64_t n;
    const int64_t* adj_start;
    const int64_t* adj;
    const int64_t* seeds;
};

// What a sweep moves: a hull, one point, or a primitive's true solid (layout.hpp's elem_solid
// row: kind, size (3), R (3, 3), t (3)), each in its body's frame.
struct SweepShape {
    enum Kind { HULL, POINT, SOLID } kind;
    HullView hull;
    const double* x;  // POINT: the point; SOLID: the elem_solid row
};

namespace sweep_detail {

inline double dot(const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// The vertex of h furthest along d (ties: any), climbing from *hint (updated). On a convex
// surface a vertex no neighbour of which is further along d is furthest of all.
inline const double* hull_support(const HullView& h, const double* d, int64_t* hint) {
    if (h.n <= HULL_SCAN_MAX) {
        int64_t best = 0;
        double top = dot(h.v, d);
        for (int64_t i = 1; i < h.n; ++i) {
            const double x = dot(h.v + 3 * i, d);
            if (x > top) {
                top = x;
                best = i;
            }
        }
        return h.v + 3 * best;
    }
    // The climb starts from the seed of d's cell, or from the last answer if that is further
    // along d (GJK's directions settle: the last answer is often the answer).
    int64_t at = h.seeds[hull_seed_cell(d)];
    double top = dot(h.v + 3 * at, d);
    if (*hint >= 0) {
        const double x = dot(h.v + 3 * *hint, d);
        if (x > top) {
            top = x;
            at = *hint;
        }
    }
    for (int64_t steps = 0; steps <= h.n; ++steps) {
        int64_t next = -1;
        for (int64_t k = h.adj_start[at]; k < h.adj_start[at + 1]; ++k) {
            const double x = dot(h.v + 3 * h.adj[k], d);
            if (x > top) {
                top = x;
                next = h.adj[k];
            }
        }
        if (next < 0) break;
        at = next;
    }
    *hint = at;
    return h.v + 3 * at;
}

// A primitive's true solid, furthest along d (body frame), into out.
inline void solid_support(const double* s, const double* d, double* out) {
    const double* R = s + 4;
    const double* t = s + 13;
    // d in the solid's own frame: R' d (x_body = R x_solid + t).
    const double e[3] = {R[0] * d[0] + R[3] * d[1] + R[6] * d[2],
                         R[1] * d[0] + R[4] * d[1] + R[7] * d[2],
                         R[2] * d[0] + R[5] * d[1] + R[8] * d[2]};
    double p[3] = {0.0, 0.0, 0.0};
    switch (int(s[0])) {
        case 1:  // box: half extents
            for (int i = 0; i < 3; ++i) p[i] = e[i] >= 0.0 ? s[1 + i] : -s[1 + i];
            break;
        case 2: {  // sphere: radius
            const double n = std::sqrt(dot(e, e));
            if (n > 0.0)
                for (int i = 0; i < 3; ++i) p[i] = s[1] * e[i] / n;
            break;
        }
        default: {  // cylinder along z: radius, half length
            const double n = std::hypot(e[0], e[1]);
            if (n > 0.0) {
                p[0] = s[1] * e[0] / n;
                p[1] = s[1] * e[1] / n;
            }
            p[2] = e[2] >= 0.0 ? s[2] : -s[2];
            break;
        }
    }
    for (int i = 0; i < 3; ++i) out[i] = R[3 * i] * p[0] + R[3 * i + 1] * p[1] + R[3 * i + 2] * p[2] + t[i];
}

inline void shape_support(const SweepShape& s, const double* d, int64_t* hint, double* out) {
    if (s.kind == SweepShape::HULL) {
        const double* v = hull_support(s.hull, d, hint);
        out[0] = v[0];
        out[1] = v[1];
        out[2] = v[2];
    } else if (s.kind == SweepShape::POINT) {
        out[0] = s.x[0];
        out[1] = s.x[1];
        out[2] = s.x[2];
    } else {
        solid_support(s.x, d, out);
    }
}

// The closest point to the origin of the simplex y[0 .. n) (n <= 4) into v; returns the
// vertices (bits) whose hull holds it, 0xF for a tetrahedron holding the origin (v = 0).
// Ericson, Real-Time Collision Detection, 5.1.2-5.1.6.
inline int closest_segment(const double* a, const double* b, double* v) {
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double t = -dot(a, ab);
    if (t <= 0.0) {
        std::copy(a, a + 3, v);
        return 1;
    }
    const double l = dot(ab, ab);
    if (t >= l) {
        std::copy(b, b + 3, v);
        return 2;
    }
    const double f = t / l;
    for (int i = 0; i < 3; ++i) v[i] = a[i] + f * ab[i];
    return 3;
}

inline int closest_triangle(const double* a, const double* b, const double* c, double* v) {
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double d1 = -dot(ab, a), d2 = -dot(ac, a);
    if (d1 <= 0.0 && d2 <= 0.0) {
        std::copy(a, a + 3, v);
        return 1;
    }
    const double d3 = -dot(ab, b), d4 = -dot(ac, b);
    if (d3 >= 0.0 && d4 <= d3) {
        std::copy(b, b + 3, v);
        return 2;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double f = d1 / (d1 - d3);
        for (int i = 0; i < 3; ++i) v[i] = a[i] + f * ab[i];
        return 3;
    }
    const double d5 = -dot(ab, c), d6 = -dot(ac, c);
    if (d6 >= 0.0 && d5 <= d6) {
        std::copy(c, c + 3, v);
        return 4;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double f = d2 / (d2 - d6);
        for (int i = 0; i < 3; ++i) v[i] = a[i] + f * ac[i];
        return 5;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        const double f = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int i = 0; i < 3; ++i) v[i] = b[i] + f * (c[i] - b[i]);
        return 6;
    }
    const double sum = va + vb + vc;
    if (!(sum > 0.0)) {  // flat to rounding: the nearest of its edges
        static const int edge[3][2] = {{0, 1}, {1, 2}, {0, 2}};
        const double* corner[3] = {a, b, c};
        int mask = 0;
        double best = INFINITY;
        for (const auto& e : edge) {
            double w[3];
            const int m = closest_segment(corner[e[0]], corner[e[1]], w);
            if (dot(w, w) < best) {
                best = dot(w, w);
                std::copy(w, w + 3, v);
                mask = ((m & 1) ? 1 << e[0] : 0) | ((m & 2) ? 1 << e[1] : 0);
            }
        }
        return mask;
    }
    const double fb = vb / sum, fc = vc / sum;
    for (int i = 0; i < 3; ++i) v[i] = a[i] + fb * ab[i] + fc * ac[i];
    return 7;
}

// Is the origin on the other side of plane (a, b, c) than d (or on it)?
inline bool outside(const double* a, const double* b, const double* c, const double* d) {
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2],
                         ab[0] * ac[1] - ab[1] * ac[0]};
    const double ad[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    return -dot(a, n) * dot(ad, n) <= 0.0;
}

inline int closest_simplex(const double (*y)[3], int n, double* v) {
    if (n == 1) {
        std::copy(y[0], y[0] + 3, v);
        return 1;
    }
    if (n == 2) return closest_segment(y[0], y[1], v);
    if (n == 3) return closest_triangle(y[0], y[1], y[2], v);
    // A tetrahedron: its faces the origin lies outside of (all four where it is flat).
    static const int face[4][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 3, 2, 0}};
    int mask = 0xF;
    double best = INFINITY;
    for (const auto& f : face) {
        if (!outside(y[f[0]], y[f[1]], y[f[2]], y[f[3]])) continue;
        double w[3];
        const int m = closest_triangle(y[f[0]], y[f[1]], y[f[2]], w);
        const double d = dot(w, w);
        if (d < best) {
            best = d;
            std::copy(w, w + 3, v);
            mask = 0;
            for (int k = 0; k < 3; ++k)
                if (m & (1 << k)) mask |= 1 << f[k];
        }
    }
    if (mask == 0xF) v[0] = v[1] = v[2] = 0.0;
    return mask;
}

}  // namespace sweep_detail

// Shape B (in b's frame, placed by R (3, 3 row-major) and t0 in a's frame at the start)
// translating by d over the parameter [0, limit] against shape A (a's frame): SWEEP_CONTACT
// with *s the first parameter at which they are within rho + eps (every earlier one farther
// than rho apart), SWEEP_FREE (none up to limit), or SWEEP_UNKNOWN (no convergence: decide
// otherwise). Adds its GJK iterations to *steps.
inline int sweep_first_contact(const SweepShape& A, const SweepShape& B, const double* R,
                               const double* t0, const double* d, double rho, double eps,
                               double limit, double* s, int64_t* steps) {
    using namespace sweep_detail;
    int64_t hint_a = -1, hint_b = -1;
    // C's point furthest along u: A's along u less B's (placed) along -u.
    const auto support = [&](const double* u, double* out) {
        double pa[3], pb[3];
        shape_support(A, u, &hint_a, pa);
        const double ub[3] = {-(R[0] * u[0] + R[3] * u[1] + R[6] * u[2]),
                              -(R[1] * u[0] + R[4] * u[1] + R[7] * u[2]),
                              -(R[2] * u[0] + R[5] * u[1] + R[8] * u[2])};
        shape_support(B, ub, &hint_b, pb);
        for (int i = 0; i < 3; ++i)
            out[i] = pa[i] - (R[3 * i] * pb[0] + R[3 * i + 1] * pb[1] + R[3 * i + 2] * pb[2] + t0[i]);
    };
    double lambda = 0.0, x[3] = {0.0, 0.0, 0.0};
    double p[4][3], y[4][3], v[3];
    int n = 0;
    support(d, v);  // any point of C: v = x - it
    for (int i = 0; i < 3; ++i) v[i] = -v[i];
    const double reach = rho + eps;
    for (int iteration = 0; iteration < SWEEP_ITERATIONS; ++iteration) {
        ++*steps;
        const double vv = dot(v, v);
        if (vv <= reach * reach) {
            *s = lambda;
            return SWEEP_CONTACT;
        }
        const double length = std::sqrt(vv);
        double q[3], w[3];
        support(v, q);
        for (int i = 0; i < 3; ++i) w[i] = x[i] - q[i];
        const double vw = dot(v, w);
        if (vw > rho * length) {  // the plane through q, normal v, rho out, separates x from C
            const double vd = dot(v, d);
            if (vd >= 0.0) return SWEEP_FREE;  // the ray moves away from it
            lambda -= (vw - rho * length) / vd;
            if (lambda > limit) return SWEEP_FREE;
            for (int i = 0; i < 3; ++i) x[i] = lambda * d[i];
        } else if (vv - vw <= 1e-12 * vv) {
            // GJK converged here: x is |v| from C, more than rho + eps, yet no plane shows it;
            // only rounding does that.
            return SWEEP_UNKNOWN;
        }
        bool known = false;
        for (int k = 0; k < n; ++k)
            known |= p[k][0] == q[0] && p[k][1] == q[1] && p[k][2] == q[2];
        if (!known) {
            if (n == 4) return SWEEP_UNKNOWN;
            std::copy(q, q + 3, p[n++]);
        }
        for (int k = 0; k < n; ++k)
            for (int i = 0; i < 3; ++i) y[k][i] = x[i] - p[k][i];
        const int mask = closest_simplex(y, n, v);
        if (mask == 0xF) {  // x inside C: reached (only where C is flat to rounding)
            *s = lambda;
            return SWEEP_CONTACT;
        }
        int kept = 0;
        for (int k = 0; k < n; ++k)
            if (mask & (1 << k)) {
                if (kept != k) std::copy(p[k], p[k] + 3, p[kept]);
                ++kept;
            }
        n = kept;
    }
    return SWEEP_UNKNOWN;
}

}  // namespace collision_sensor
