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

#include "inlining.hpp"
#include "tolerances.hpp"

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
    static constexpr int next[3][2] = {{1, 2}, {2, 0}, {0, 1}};  // (axis + 1, axis + 2) mod 3
    return (f * HULL_SEED_GRID + cell(d[next[axis][0]])) * HULL_SEED_GRID +
           cell(d[next[axis][1]]);
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
// (adj[adj_start[i] : adj_start[i + 1]], local indices), its furthest vertex along each
// hull_seed_direction (seeds, HULL_SEEDS; unused for hulls of at most HULL_SCAN_MAX), the
// vertices' mean (centre, a point inside it) and a radius about it holding every vertex.
struct HullView {
    const double* v;
    int64_t n;
    const int32_t* adj_start;
    const int32_t* adj;
    const int32_t* seeds;
    const double* centre;
    double radius;
    const double* axes;     // a box's (Hull::axes), or nullptr
    const int32_t* corner;  // a box's vertex per octant (Hull::corner), or nullptr
};

namespace sweep_detail {

inline double dot(const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// A climb on a hull toward the vertex furthest along a direction: where it is, how far along
// the direction, and whether it has arrived. On a convex surface a vertex no neighbour of which
// is further along d is furthest of all.
struct Climb {
    int64_t at;
    double top;
    bool done;
};

// Does h's support climb (not a box's corner, not a scan of a few vertices)?
inline bool climbs(const HullView& h) { return !h.corner && h.n > HULL_SCAN_MAX; }

// The climb starts from the seed of d's cell, or from hint (the last answer, -1: none) if
// that is further along d (GJK's directions settle: the last answer is often the answer).
CS_ALWAYS_INLINE Climb climb_start(const HullView& h, const double* d, int64_t hint) {
    Climb c{h.seeds[hull_seed_cell(d)], 0.0, false};
    c.top = dot(h.v + 3 * c.at, d);
    if (hint >= 0) {
        const double x = dot(h.v + 3 * hint, d);
        if (x > c.top) {
            c.top = x;
            c.at = hint;
        }
    }
    return c;
}

// One step: to the neighbour furthest along d if it is further, else arrived.
CS_ALWAYS_INLINE void climb_step(const HullView& h, const double* d, Climb& c) {
    int64_t next = -1;
    for (int64_t k = h.adj_start[c.at]; k < h.adj_start[c.at + 1]; ++k) {
        const double x = dot(h.v + 3 * h.adj[k], d);
        if (x > c.top) {
            c.top = x;
            next = h.adj[k];
        }
    }
    if (next < 0) c.done = true;
    else c.at = next;
}

// The vertex of h furthest along d (ties: any), climbing from *hint (updated).
inline const double* hull_support(const HullView& h, const double* d, int64_t* hint) {
    if (h.corner) {  // a box: the corner on d's side of each axis
        const double* a = h.axes;
        const int octant = (a[0] * d[0] + a[3] * d[1] + a[6] * d[2] > 0.0 ? 1 : 0) |
                           (a[1] * d[0] + a[4] * d[1] + a[7] * d[2] > 0.0 ? 2 : 0) |
                           (a[2] * d[0] + a[5] * d[1] + a[8] * d[2] > 0.0 ? 4 : 0);
        return h.v + 3 * h.corner[octant];
    }
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
    Climb c = climb_start(h, d, *hint);
    for (int64_t steps = 0; !c.done && steps <= h.n; ++steps) climb_step(h, d, c);
    *hint = c.at;
    return h.v + 3 * c.at;
}

// Both hulls' supports when both climb: the two climbs step in turn, so that the processor
// runs each one's loads while the other's wait (each is a chain of dependent loads).
inline void climb_pair(const HullView& A, const double* da, int64_t* hint_a, const HullView& B,
                       const double* db, int64_t* hint_b) {
    Climb a = climb_start(A, da, *hint_a), b = climb_start(B, db, *hint_b);
    for (int64_t steps = 0; !(a.done && b.done) && steps <= A.n + B.n; ++steps) {
        if (!a.done) climb_step(A, da, a);
        if (!b.done) climb_step(B, db, b);
    }
    *hint_a = a.at;
    *hint_b = b.at;
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

// A point moving along p + s u (in a primitive's frame) against its true sphere or cylinder
// (elem_solid row: kind, size): the parameters at which it is inside, [*enter, *leave] (empty
// when *enter > *leave). A box is never asked: its hull is its solid.
inline void solid_span(const double* row, const double* p, const double* u, double* enter,
                       double* leave) {
    *enter = -INFINITY;
    *leave = INFINITY;
    const auto none = [&] {
        *enter = INFINITY;
        *leave = -INFINITY;
    };
    // |p + s u| <= r over the first n coordinates.
    const auto round = [&](int n, double r) {
        double a = 0.0, b = 0.0, c = -r * r;
        for (int i = 0; i < n; ++i) {
            a += u[i] * u[i];
            b += p[i] * u[i];
            c += p[i] * p[i];
        }
        if (!(a > 0.0)) {
            if (c > 0.0) none();
            return;
        }
        const double disc = b * b - a * c;
        if (disc < 0.0) return none();
        const double root = std::sqrt(disc);
        *enter = std::max(*enter, (-b - root) / a);
        *leave = std::min(*leave, (-b + root) / a);
    };
    if (int(row[0]) == 2) {  // a sphere: radius
        round(3, row[1]);
        return;
    }
    round(2, row[1]);  // a cylinder along z: radius, and half its length
    if (u[2] == 0.0) {
        if (std::fabs(p[2]) > row[2]) none();
        return;
    }
    const double x = (-row[2] - p[2]) / u[2], y = (row[2] - p[2]) / u[2];
    *enter = std::max(*enter, std::min(x, y));
    *leave = std::min(*leave, std::max(x, y));
}

// A test vertex against a sphere's or cylinder's true solid (elem_solid row), where B moves
// as in sweep_first_contact (placed by R and t0 in a's frame at the start, translating by d):
// the solid is A's (solid_in_a; the point B's) or B's (the point A's). Its first contact, in
// closed form: SWEEP_CONTACT with *s no later than the point's entry, by at most eps of its
// travel (every earlier state outside), or SWEEP_FREE up to limit.
inline int probe_first_contact(const double* row, const double* point, bool solid_in_a,
                               const double* R, const double* t0, const double* d, double eps,
                               double limit, double* s) {
    const double* Rs = row + 4;
    const double* ts = row + 13;
    double x[3], v[3];  // the point and its motion in the frame the solid's (Rs, ts) place
    if (solid_in_a) {
        for (int i = 0; i < 3; ++i) {
            x[i] = R[3 * i] * point[0] + R[3 * i + 1] * point[1] + R[3 * i + 2] * point[2] +
                   t0[i] - ts[i];
            v[i] = d[i];
        }
    } else {  // in b's frame: R' (point - t0 - s d)
        const double y[3] = {point[0] - t0[0], point[1] - t0[1], point[2] - t0[2]};
        for (int i = 0; i < 3; ++i) {
            x[i] = R[i] * y[0] + R[3 + i] * y[1] + R[6 + i] * y[2] - ts[i];
            v[i] = -(R[i] * d[0] + R[3 + i] * d[1] + R[6 + i] * d[2]);
        }
    }
    double p[3], u[3];  // in the solid's own frame: Rs' x, Rs' v
    for (int i = 0; i < 3; ++i) {
        p[i] = Rs[i] * x[0] + Rs[3 + i] * x[1] + Rs[6 + i] * x[2];
        u[i] = Rs[i] * v[0] + Rs[3 + i] * v[1] + Rs[6 + i] * v[2];
    }
    double enter, leave;
    solid_span(row, p, u, &enter, &leave);
    const double first = std::max(enter, 0.0);
    if (!(first <= leave) || first > limit) return SWEEP_FREE;
    // Back off half of eps of travel: the root's rounding is far below it.
    const double speed = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    *s = speed > 0.0 ? std::max(0.0, first - 0.5 * eps / speed) : first;
    return SWEEP_CONTACT;
}

// Hull B (in b's frame, placed by R (3, 3 row-major) and t0 in a's frame at the start)
// translating by d over the parameter [0, limit] against hull A (a's frame): SWEEP_CONTACT
// with *s the first parameter at which they are within rho + eps (every earlier one farther
// than rho apart), SWEEP_FREE (none up to limit), or SWEEP_UNKNOWN (no convergence: decide
// otherwise). Adds its GJK iterations to *steps.
inline int sweep_first_contact(const HullView& A, const HullView& B, const double* R,
                               const double* t0, const double* d, double rho, double eps,
                               double limit, double* s, int64_t* steps) {
    using namespace sweep_detail;
    int64_t hint_a = -1, hint_b = -1;
    // C's point furthest along u: A's along u less B's (placed) along -u.
    const bool paired = climbs(A) && climbs(B);
    const auto support = [&](const double* u, double* out) {
        const double ub[3] = {-(R[0] * u[0] + R[3] * u[1] + R[6] * u[2]),
                              -(R[1] * u[0] + R[4] * u[1] + R[7] * u[2]),
                              -(R[2] * u[0] + R[5] * u[1] + R[8] * u[2])};
        const double *pa, *pb;
        if (paired) {
            climb_pair(A, u, &hint_a, B, ub, &hint_b);
            pa = A.v + 3 * hint_a;
            pb = B.v + 3 * hint_b;
        } else {
            pa = hull_support(A, u, &hint_a);
            pb = hull_support(B, ub, &hint_b);
        }
        for (int i = 0; i < 3; ++i)
            out[i] = pa[i] - (R[3 * i] * pb[0] + R[3 * i + 1] * pb[1] + R[3 * i + 2] * pb[2] + t0[i]);
    };
    // C lies in the ball about c, the centres' difference, of the radii's sum: x = lambda d
    // is farther than rho + eps from C until it enters that ball grown by rho + eps, so the
    // ray starts there, and misses C when it misses the ball.
    const double reach = rho + eps;
    double c[3];
    for (int i = 0; i < 3; ++i)
        c[i] = A.centre[i] - (R[3 * i] * B.centre[0] + R[3 * i + 1] * B.centre[1] +
                              R[3 * i + 2] * B.centre[2] + t0[i]);
    double lambda = 0.0;
    {
        const double ball = A.radius + B.radius + reach;
        const double dd = dot(d, d), dc = dot(d, c), cc = dot(c, c) - ball * ball;
        if (cc > 0.0) {  // outside the ball at the start
            const double disc = dc * dc - dd * cc;
            if (dc <= 0.0 || disc < 0.0) return SWEEP_FREE;  // moving away, or passing by
            lambda = cc / (dc + std::sqrt(disc));              // the smaller root
            if (lambda > limit) return SWEEP_FREE;
        }
    }
    double x[3] = {lambda * d[0], lambda * d[1], lambda * d[2]};
    double p[4][3], y[4][3], v[3];
    int n = 0;
    // v = x less a point of C (c): its direction points the first support near the answer.
    for (int i = 0; i < 3; ++i) v[i] = x[i] - c[i];
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
