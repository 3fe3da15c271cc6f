// trees_within (motion_bounds.hpp): a pair's two trees descended over an interval of a path.
// Inline, in the one file that calls it (motion.cpp: pair_within, at every interval of a
// march), where it is compiled into its caller.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "motion_bounds.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"
#include "triangle_distance.hpp"

namespace collision_sensor {

inline WithinResult trees_within(const WithinTraversal& node, int64_t n_seeds) {
    // The node's fields as locals: the loop writes through pointers that could alias them.
    const Forest& f = node.forest;
    const double* P = node.pose;
    const WithinRequest& request = node.request;
    const int box_method = request.box_test, expansion = request.expansion;
    const double h = request.h, extra = request.extra, pad = request.pad;
    MotionMargin& motion = node.motion;
    int64_t* stack = node.work.stack;
    int64_t* counters = node.work.counters;
    DistanceWork& rows = node.rows;
    WithinFront& front = node.front;
    double reach = motion.h2;
    const double* Ta = motion.side[0].T;
    ++rows.placed_tag;  // tree b's boxes placed at P: each once (placed_row)
    int64_t n_boxes = 0, n_triangles = 0;
    const double crude = front.crude;
    const bool crude_holds = crude > 0.0 && crude < INF;
    auto stopped = [&](int64_t na, int64_t nb, double x, double gap) {
        front.pairs.push_back(na);
        front.pairs.push_back(nb);
        if (crude_holds && gap > extra)
            x = std::max(x, (gap - extra) / crude * (1.0 - MOTION_BOUND_REL));
        front.reach.push_back(x);
        if (front.with_gaps) front.gap.push_back(crude_holds && gap > extra ? gap - extra : -INF);
    };
    int64_t top = n_seeds;
    while (top > 0) {
        --top;
        int64_t* slot = stack + 3 * top;
        const int64_t na = slot[0], nb = slot[1], level = slot[2];
        const double* A = f.box(na);
        const double* B = f.box(nb);
        const BoxMotion& ma = motion.node(f, na, 0);
        const BoxMotion& mb = motion.node(f, nb, 1);
        const double* placed = placed_row(f, nb, P, rows);
        ++n_boxes;
        double x, gap;
        if (node_pair_apart(A, B, P, Ta, ma, mb, h, extra, motion, box_method, &x, &gap,
                            placed)) {
            reach = std::min(reach, x);
            stopped(na, nb, x, gap);
            continue;
        }
        const int64_t* node_a = f.node(na);
        const int64_t* node_b = f.node(nb);
        const bool leaf_a = node_a[NODE_LEFT] < 0;
        const bool leaf_b = node_b[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            const double rate = ma.rate + mb.rate;
            const double r = h * rate + extra;
            double leaf_reach = motion.h2, leaf_gap = INF;
            Triangle Q;
            for (int64_t ib = node_b[NODE_FIRST]; ib < node_b[NODE_FIRST] + node_b[NODE_COUNT];
                 ++ib) {
                triangle_in_a(f.tris, ib, P, Q);
                for (int64_t ia = node_a[NODE_FIRST];
                     ia < node_a[NODE_FIRST] + node_a[NODE_COUNT]; ++ia) {
                    ++n_triangles;
                    double xa[3], yb[3];
                    const double distance =
                        triangle_distance(triangle_at(f.tris, ia), Q, xa, yb) - pad;
                    // Apart over this half-width by the zeroth-order bound (within when
                    // nothing moves and the triangles are within extra).
                    double got = rate > 0.0 ? std::min((distance - extra) / rate, motion.h2)
                                            : (distance > extra ? motion.h2 : -1.0);
                    if (!(distance > r) && distance > extra) {
                        // Along the nearest points' direction the triangles are distance
                        // apart (each lies behind its nearest point's plane).
                        const double w[3] = {(yb[0] - xa[0]) / (distance + pad),
                                             (yb[1] - xa[1]) / (distance + pad),
                                             (yb[2] - xa[2]) / (distance + pad)};
                        double n[3];
                        for (int i = 0; i < 3; ++i)
                            n[i] = Ta[4 * i] * w[0] + Ta[4 * i + 1] * w[1] + Ta[4 * i + 2] * w[2];
                        got = std::max(got, motion.first_order_reach(
                                                n, distance, extra, A[BOX_RADIUS], ma,
                                                B[BOX_RADIUS], mb, h));
                    }
                    if (!(got >= h)) {
                        counters[COUNT_BOX_TESTS] += n_boxes;
                        counters[COUNT_TRIANGLE_TESTS] += n_triangles;
                        return {true, r, std::max(got, 0.0)};
                    }
                    reach = std::min(reach, got);
                    leaf_reach = std::min(leaf_reach, got);
                    leaf_gap = std::min(leaf_gap, distance);
                }
            }
            stopped(na, nb, leaf_reach, leaf_gap);
            continue;
        }
        const bool expand_a = expand_first(f, na, nb, A, B, leaf_a, leaf_b, level, expansion);
        const double dc[3] = {placed[0] - A[BOX_CENTER], placed[1] - A[BOX_CENTER + 1],
                              placed[2] - A[BOX_CENTER + 2]};
        int64_t first, second;
        if (expand_a) {
            first = node_a[NODE_LEFT];
            second = node_a[NODE_RIGHT];
            if (closer(f, second, first, A[0] + dc[0], A[1] + dc[1], A[2] + dc[2]))
                std::swap(first, second);
            slot[0] = second;
            slot[1] = nb;
            slot[3] = first;
            slot[4] = nb;
        } else {
            first = node_b[NODE_LEFT];
            second = node_b[NODE_RIGHT];
            const double e0 = A[0] - P[9], e1 = A[1] - P[10], e2 = A[2] - P[11];
            if (closer(f, second, first, P[0] * e0 + P[3] * e1 + P[6] * e2,
                       P[1] * e0 + P[4] * e1 + P[7] * e2, P[2] * e0 + P[5] * e1 + P[8] * e2))
                std::swap(first, second);
            slot[0] = na;
            slot[1] = second;
            slot[3] = na;
            slot[4] = first;
        }
        slot[2] = slot[5] = level + 1;
        top += 2;
    }
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
    return {false, 0.0, reach};
}

}  // namespace collision_sensor
