// trees_within (motion_bounds.hpp): a pair's two trees descended over an interval of a path,
// the descent (descent.hpp) with the node that decides node pairs by node_pair_apart and leaf
// pairs by their triangles' distance. Inline, in the one file that calls it (motion.cpp:
// pair_within, at every interval of a march), where it is compiled into its caller.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "descent.hpp"
#include "motion_bounds.hpp"
#include "tolerances.hpp"
#include "triangle_distance.hpp"

namespace collision_sensor {

// The within test's node for the descent (descent.hpp): the traversal's fields as locals of
// the query, what it has found, and the hooks.
struct WithinNode {
    static constexpr bool WHOLE_A = false;
    // What apart() saw of a pair it did not settle: the boxes, their motions over the
    // interval, and B placed in body a (placed_row).
    struct Seen {
        const double* A;
        const double* B;
        const BoxMotion* ma;
        const BoxMotion* mb;
        const double* placed;
    };

    const Forest& f;
    const double* P;
    const int expansion;
    const double h, extra, pad;
    MotionMargin& motion;
    const IntervalTest test;
    DistanceWork& rows;
    WithinFront& front;
    const double* Ta;
    const double crude;
    const bool crude_holds;
    double reach;
    int64_t n_boxes = 0, n_triangles = 0;
    WithinResult within = {false, 0.0, 0.0};

    explicit WithinNode(const WithinTraversal& t)
        : f(t.forest),
          P(t.pose),
          expansion(t.request.expansion),
          h(t.request.h),
          extra(t.request.extra),
          pad(t.request.pad),
          motion(t.motion),
          test{t.pose, t.motion.side[0].T, t.request.h, t.request.extra, t.motion,
               t.request.box_test},
          rows(t.rows),
          front(t.front),
          Ta(t.motion.side[0].T),
          crude(t.front.crude),
          crude_holds(crude > 0.0 && crude < INF),
          reach(t.motion.h2) {}

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return f.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const { return f.node(n); }

    // A pair where the descent stopped (apart, or a leaf pair tested apart), into the front
    // (WithinFront: its reach, or further by the crude rate against its gap).
    CS_ALWAYS_INLINE void stopped(int64_t na, int64_t nb, double x, double gap) {
        front.pairs.push_back(na);
        front.pairs.push_back(nb);
        if (crude_holds && gap > extra)
            x = std::max(x, (gap - extra) / crude * (1.0 - MOTION_BOUND_REL));
        front.reach.push_back(x);
        if (front.with_gaps) front.gap.push_back(crude_holds && gap > extra ? gap - extra : -INF);
    }

    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nb, int64_t, Seen& seen) {
        const double* A = f.box(na);
        const double* B = f.box(nb);
        const BoxMotion& ma = motion.node(f, na, 0);
        const BoxMotion& mb = motion.node(f, nb, 1);
        const double* placed = placed_row(f, nb, P, rows);
        ++n_boxes;
        NodePairApart proof;
        if (placed_pair_apart(test, A, B, placed, ma, mb, proof)) {
            reach = std::min(reach, proof.reach);
            stopped(na, nb, proof.reach, proof.gap);
            return true;
        }
        seen = {A, B, &ma, &mb, placed};
        return false;
    }

    // The triangles by their distance: apart by more than the zeroth-order margin, or along
    // their nearest points' direction by more than the first-order one; one within ends the
    // descent.
    CS_ALWAYS_INLINE bool leaves(int64_t na, int64_t nb, const int64_t* node_a,
                                 const int64_t* node_b, const Seen& seen) {
        const BoxMotion& ma = *seen.ma;
        const BoxMotion& mb = *seen.mb;
        const double rate = ma.rate + mb.rate;
        const double r = h * rate + extra;
        double leaf_reach = motion.h2, leaf_gap = INF;
        const bool hit = each_triangle_pair(
            f.tris, node_a, node_b, P,
            [&](const Triangle& A, const Triangle& Q, int64_t, int64_t) {
                ++n_triangles;
                double xa[3], yb[3];
                const double distance = triangle_distance(A, Q, xa, yb) - pad;
                // Apart over this half-width by the zeroth-order bound (within when nothing
                // moves and the triangles are within extra).
                double got = rate > 0.0 ? std::min((distance - extra) / rate, motion.h2)
                                        : (distance > extra ? motion.h2 : -1.0);
                if (!(distance > r) && distance > extra) {
                    // Along the nearest points' direction the triangles are distance apart
                    // (each lies behind its nearest point's plane).
                    const double w[3] = {(yb[0] - xa[0]) / (distance + pad),
                                         (yb[1] - xa[1]) / (distance + pad),
                                         (yb[2] - xa[2]) / (distance + pad)};
                    double n[3];
                    for (int i = 0; i < 3; ++i)
                        n[i] = Ta[4 * i] * w[0] + Ta[4 * i + 1] * w[1] + Ta[4 * i + 2] * w[2];
                    got = std::max(got, motion.first_order_reach(n, distance, extra,
                                                                 seen.A[BOX_RADIUS], ma,
                                                                 seen.B[BOX_RADIUS], mb, h));
                }
                if (!(got >= h)) {
                    within = {true, r, std::max(got, 0.0)};
                    return true;
                }
                reach = std::min(reach, got);
                leaf_reach = std::min(leaf_reach, got);
                leaf_gap = std::min(leaf_gap, distance);
                return false;
            });
        if (hit) return true;
        stopped(na, nb, leaf_reach, leaf_gap);
        return false;
    }

    CS_ALWAYS_INLINE bool split_a(int64_t na, int64_t nb, int64_t level, const Seen& seen) const {
        return expand_first(f, na, nb, seen.A, seen.B, level, expansion);
    }

    // First the child nearer the other box's centre (B's in body a: its placed row; A's in
    // body b: R_ab' (ca - t_ab)).
    CS_ALWAYS_INLINE void order(int64_t, int64_t, int64_t level, bool on_a, ChildPairs& c,
                                const Seen& seen) const {
        const double* A = seen.A;
        bool swap;
        if (on_a) {
            const double* x = seen.placed;
            const double d0 = x[0] - A[0], d1 = x[1] - A[1], d2 = x[2] - A[2];
            swap = nearer(f.box(c.second), f.box(c.first), A[0] + d0, A[1] + d1, A[2] + d2);
        } else {
            const double e0 = A[0] - P[9], e1 = A[1] - P[10], e2 = A[2] - P[11];
            swap = nearer(f.box(c.second), f.box(c.first), P[0] * e0 + P[3] * e1 + P[6] * e2,
                          P[1] * e0 + P[4] * e1 + P[7] * e2, P[2] * e0 + P[5] * e1 + P[8] * e2);
        }
        if (swap) c.swap();
        c.word_first = c.word_second = level + 1;
    }
};

inline WithinResult trees_within(const WithinTraversal& traversal, int64_t n_seeds) {
    ++traversal.rows.placed_tag;  // tree b's boxes placed at P: each once (placed_row)
    WithinNode node(traversal);
    descend(node, traversal.work.stack, n_seeds);
    int64_t* counters = traversal.work.counters;
    counters[COUNT_BOX_TESTS] += node.n_boxes;
    counters[COUNT_TRIANGLE_TESTS] += node.n_triangles;
    return node.within.within ? node.within : WithinResult{false, 0.0, node.reach};
}

}  // namespace collision_sensor
