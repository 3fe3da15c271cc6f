// The tests of one leaf pair of two trees at a pose (traversal.hpp): the triangles of leaf a
// against those of leaf b (body b at pose P in body a), by the contact rule with padding.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>

#include "inlining.hpp"
#include "obb_tree.hpp"
#include "triangle_distance.hpp"
#include "triangle_test.hpp"

namespace collision_sensor {

// Triangle row ib (body b), taken to body a's frame by the pose.
CS_ALWAYS_INLINE void triangle_in_a(const double* tris, int64_t ib, const double* pose,
                                    Triangle& Q) {
    const double* t = tris + 9 * ib;
    for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i)
            Q[k][i] = pose[3 * i] * t[3 * k] + pose[3 * i + 1] * t[3 * k + 1] +
                      pose[3 * i + 2] * t[3 * k + 2] + pose[9 + i];
}

CS_ALWAYS_INLINE const Triangle&  triangle_at(const double* tris, int64_t i) {
    return *reinterpret_cast<const Triangle*>(tris + 9 * i);
}

// visit(P, Q, ia, ib) for each triangle ia of leaf a (P) and ib of leaf b (Q: in body a's frame
// by the pose, placed once for all of leaf a), until a visit returns true (then true).
template <class Visit>
CS_ALWAYS_INLINE bool each_triangle_pair(const double* tris, const int64_t* leaf_a,
                                         const int64_t* leaf_b, const double* pose,
                                         Visit&& visit) {
    Triangle Q;
    const int64_t first_a = leaf_a[NODE_FIRST], end_a = first_a + leaf_a[NODE_COUNT];
    const int64_t first_b = leaf_b[NODE_FIRST], end_b = first_b + leaf_b[NODE_COUNT];
    for (int64_t ib = first_b; ib < end_b; ++ib) {
        triangle_in_a(tris, ib, pose, Q);
        for (int64_t ia = first_a; ia < end_a; ++ia)
            if (visit(triangle_at(tris, ia), Q, ia, ib)) return true;
    }
    return false;
}

// True iff triangle P is within pad of triangle Q (pad > 0: the padded contact rule, the
// triangles' distance against the pair's padding, distance <= pad), or (pad 0) meets it.
CS_ALWAYS_INLINE bool triangles_within(const Triangle& P, const Triangle& Q, double pad,
                                       double& distance) {
    if (pad > 0.0) {
        double x[3], y[3];
        distance = triangle_distance(P, Q, x, y);
        return distance <= pad;
    }
    distance = 0.0;
    return triangles_intersect(P, Q);
}

// True iff triangle ia (body a) meets triangle ib (body b, at pose), or comes within pad.
inline bool triangle_pair_collides(const double* tris, int64_t ia, int64_t ib,
                                   const double* pose, double pad) {
    Triangle Q;
    triangle_in_a(tris, ib, pose, Q);
    double distance;
    return triangles_within(triangle_at(tris, ia), Q, pad, distance);
}

// Every triangle of leaf a against every triangle of leaf b (body b at pose), by the padded
// rule (triangles_within): the first pair in contact (-1, -1 if none), the number of triangle
// pairs tested, and, with pad > 0 or measure and none in contact, the smallest distance minus
// pad (the leaf pair's clearance; 0 otherwise, where no distance is measured). Without padding
// the intersection test decides and the distance only bounds: an incremental query measures
// it (measure), since a leaf pair's clearance of 0 would have its pair re-checked at every
// state, and its motion swept at every step (update_motion), while it stays that near.
struct LeafResult {
    bool hit;
    int64_t ia, ib, tested;
    double gap;
};

inline LeafResult leaves_collide(const double* tris, const int64_t* leaf_a,
                                 const int64_t* leaf_b, const double* pose, double pad,
                                 bool measure = false) {
    int64_t tested = 0, hit_a = -1, hit_b = -1;
    double nearest = std::numeric_limits<double>::infinity();
    const bool hit = each_triangle_pair(
        tris, leaf_a, leaf_b, pose,
        [&](const Triangle& P, const Triangle& Q, int64_t ia, int64_t ib) {
            ++tested;
            double distance;
            if (triangles_within(P, Q, pad, distance)) {
                hit_a = ia;
                hit_b = ib;
                return true;
            }
            if (measure && !(pad > 0.0)) {
                double x[3], y[3];
                distance = triangle_distance(P, Q, x, y);
            }
            nearest = std::min(nearest, distance);
            return false;
        });
    if (hit) return {true, hit_a, hit_b, tested, 0.0};
    return {false, -1, -1, tested, (pad > 0.0 || measure) ? nearest - pad : 0.0};
}

}  // namespace collision_sensor
