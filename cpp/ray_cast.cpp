// Rays against OBB trees (ray_cast.hpp).
#include "ray_cast.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace collision_sensor {

namespace {

constexpr double NO_HIT = std::numeric_limits<double>::infinity();

// The ray's parameter interval inside box row B (body frame: o, d), clipped to [0, far]:
// false when empty.
inline bool slab(const double* B, const double* o, const double* d, double far) {
    double lo = 0.0, hi = far;
    for (int k = 0; k < 3; ++k) {
        // Along box axis k (column k of the axes).
        const double* e = B + BOX_AXES;
        const double oc = e[k] * (o[0] - B[0]) + e[3 + k] * (o[1] - B[1]) + e[6 + k] * (o[2] - B[2]);
        const double dc = e[k] * d[0] + e[3 + k] * d[1] + e[6 + k] * d[2];
        const double h = B[BOX_HALF + k];
        if (std::fabs(dc) < 1e-300) {
            if (std::fabs(oc) > h) return false;
            continue;
        }
        double t0 = (-h - oc) / dc, t1 = (h - oc) / dc;
        if (t0 > t1) std::swap(t0, t1);
        lo = std::max(lo, t0);
        hi = std::min(hi, t1);
        if (lo > hi) return false;
    }
    return true;
}

// Moeller-Trumbore: the ray's parameter at triangle tri, or NO_HIT.
inline double hit_triangle(const double* tri, const double* o, const double* d) {
    const double e1[3] = {tri[3] - tri[0], tri[4] - tri[1], tri[5] - tri[2]};
    const double e2[3] = {tri[6] - tri[0], tri[7] - tri[1], tri[8] - tri[2]};
    const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                         d[0] * e2[1] - d[1] * e2[0]};
    const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (std::fabs(det) < 1e-300) return NO_HIT;
    const double inv = 1.0 / det;
    const double s[3] = {o[0] - tri[0], o[1] - tri[1], o[2] - tri[2]};
    const double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) * inv;
    if (u < 0.0 || u > 1.0) return NO_HIT;
    const double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                         s[0] * e1[1] - s[1] * e1[0]};
    const double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
    if (v < 0.0 || u + v > 1.0) return NO_HIT;
    const double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
    return t > 0.0 ? t : NO_HIT;
}

}  // namespace

void cast_rays(const Forest& f, const int64_t* roots, const double* T, int64_t n_trees,
               const double* origin, const double* dirs, int64_t n, double max_range,
               double* t) {
    std::vector<int64_t> stack;
    // The origin in each tree's body frame: R' (o - t).
    std::vector<double> o_body(3 * n_trees);
    for (int64_t e = 0; e < n_trees; ++e) {
        const double* P = T + 16 * e;
        const double w[3] = {origin[0] - P[3], origin[1] - P[7], origin[2] - P[11]};
        for (int i = 0; i < 3; ++i)
            o_body[3 * e + i] = P[i] * w[0] + P[4 + i] * w[1] + P[8 + i] * w[2];
    }
    for (int64_t r = 0; r < n; ++r) {
        const double* dw = dirs + 3 * r;
        double best = max_range;
        bool found = false;
        for (int64_t e = 0; e < n_trees; ++e) {
            const double* P = T + 16 * e;
            const double d[3] = {P[0] * dw[0] + P[4] * dw[1] + P[8] * dw[2],
                                 P[1] * dw[0] + P[5] * dw[1] + P[9] * dw[2],
                                 P[2] * dw[0] + P[6] * dw[1] + P[10] * dw[2]};
            const double* o = o_body.data() + 3 * e;
            stack.assign(1, roots[e]);
            while (!stack.empty()) {
                const int64_t node = stack.back();
                stack.pop_back();
                if (!slab(f.box(node), o, d, best)) continue;
                const int64_t* row = f.node(node);
                if (row[NODE_LEFT] >= 0) {
                    stack.push_back(row[NODE_LEFT]);
                    stack.push_back(row[NODE_RIGHT]);
                    continue;
                }
                for (int64_t k = row[NODE_FIRST]; k < row[NODE_FIRST] + row[NODE_COUNT]; ++k) {
                    const double hit = hit_triangle(f.tris + 9 * k, o, d);
                    if (hit <= best) {
                        best = hit;
                        found = true;
                    }
                }
            }
        }
        t[r] = found ? best : NO_HIT;
    }
}

}  // namespace collision_sensor
