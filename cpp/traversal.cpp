// The collision descent of two trees and the re-check of a front (traversal.hpp).
#include "traversal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "box_pair.hpp"
#include "leaf_pair.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

namespace {

// collide_trees for a request that inflates the boxes or not (Inflated: a constant of each of
// the two copies of the descent: the collision queries do not, and pay nothing for it).
template <bool Inflated>
TreesResult collide_trees_as(const TreePairTraversal& node, int64_t n_seeds) {
    // The request's fields as locals: the loop below writes through pointers that could
    // otherwise alias them.
    const TraversalRequest& request = node.request;
    const Forest& f = node.forest;
    const double* P = node.pose;
    const int box_test = request.box_test, expansion = request.expansion;
    const bool track = request.track;
    const int64_t wa = request.witness_a, wb = request.witness_b;
    const double pad = request.pad + request.inflation, grow = 0.5 * request.inflation;
    const double base = request.travel - request.rounding;
    int64_t* stack = node.work.stack;
    FrontRecord no_front = {{nullptr, nullptr, 0}, -1};
    FrontRecord& front = node.front ? *node.front : no_front;
    double best = track ? INF : 0.0;
    int64_t n_boxes = 0, n_spheres = 0, n_triangles = 0;
    bool hit = false;
    int64_t ia = -1, ib = -1;
    int64_t top = n_seeds;
    double grown_a[BOX_WIDTH], grown_b[BOX_WIDTH];
    while (top > 0) {
        --top;
        int64_t* slot = stack + 3 * top;
        const int64_t na = slot[0], nb = slot[1], level = slot[2];
        const double* A = Inflated ? grown(f.box(na), grow, grown_a) : f.box(na);
        const double* B = Inflated ? grown(f.box(nb), grow, grown_b) : f.box(nb);
        const Spheres s = spheres(A, B, P);
        if (s.apart) {
            ++n_spheres;
            if (front.length >= 0) {
                const double g = std::sqrt(s.dd) - s.radii;
                record(front, na, nb, FRONT_SPHERE, base + g);
                best = std::min(best, g);
            } else if (track && best > 0.0) {
                const double bound = best + s.radii;  // sqrt only when it can lower the bound
                if (s.dd < bound * bound) best = std::sqrt(s.dd) - s.radii;
            }
            continue;
        }
        ++n_boxes;
        double T[12];
        box_in_frame(A, B, P, T);
        int64_t how;
        if (box_test == BOX_TEST_PAPER)
            how = paper_separates(A, B, T) ? FRONT_BOX : FRONT_LEAF;
        else
            how = sat_axis(A, B, T);
        if (how != FRONT_LEAF) {
            if (track) {
                double g = face_gap(A, B, T);
                if (how >= 6) g = std::max(g, axis_gap(how, A, B, P).gap);
                best = std::min(best, g);
                record(front, na, nb, how, base + g);
            }
            continue;
        }
        const int64_t* node_a = f.node(na);
        const int64_t* node_b = f.node(nb);
        const bool leaf_a = node_a[NODE_LEFT] < 0;
        const bool leaf_b = node_b[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            const LeafResult leaf = leaves_collide(f.tris, node_a, node_b, P, pad, track);
            n_triangles += leaf.tested;
            if (leaf.hit) {
                hit = true;
                ia = leaf.ia;
                ib = leaf.ib;
                break;
            }
            record(front, na, nb, FRONT_LEAF, base + leaf.gap);
            best = std::min(best, leaf.gap);
            continue;
        }
        const bool expand_a = expand_first(f, na, nb, A, B, leaf_a, leaf_b, level, expansion);
        // Visit first the child nearer the other box's centre (more likely to meet it: a
        // colliding pair stops at its first meeting triangles), or the one holding the last
        // witness.
        int64_t first, second;
        bool swap;
        if (expand_a) {
            first = node_a[NODE_LEFT];
            second = node_a[NODE_RIGHT];
            if (wa >= 0) {
                swap = wa >= f.node(second)[NODE_FIRST];
            } else {  // B's centre in body a
                swap = closer(f, second, first, A[0] + s.d[0], A[1] + s.d[1], A[2] + s.d[2]);
            }
            if (swap) std::swap(first, second);
            slot[0] = second;
            slot[1] = nb;
            slot[2] = level + 1;
            slot[3] = first;
            slot[4] = nb;
        } else {
            first = node_b[NODE_LEFT];
            second = node_b[NODE_RIGHT];
            if (wb >= 0) {
                swap = wb >= f.node(second)[NODE_FIRST];
            } else {  // A's centre in body b: R_ab' (ca - t_ab)
                const double e0 = A[0] - P[9], e1 = A[1] - P[10], e2 = A[2] - P[11];
                swap = closer(f, second, first, P[0] * e0 + P[3] * e1 + P[6] * e2,
                              P[1] * e0 + P[4] * e1 + P[7] * e2,
                              P[2] * e0 + P[5] * e1 + P[8] * e2);
            }
            if (swap) std::swap(first, second);
            slot[0] = na;
            slot[1] = second;
            slot[2] = level + 1;
            slot[3] = na;
            slot[4] = first;
        }
        slot[5] = level + 1;
        top += 2;
    }
    int64_t* counters = node.work.counters;
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_SPHERE_SKIPS] += n_spheres;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
    return {hit, ia, ib, best};
}

}  // namespace

TreesResult collide_trees(const TreePairTraversal& node, int64_t n_seeds) {
    return node.request.inflation > 0.0 ? collide_trees_as<true>(node, n_seeds)
                                        : collide_trees_as<false>(node, n_seeds);
}

FrontScan front_scan(const TreePairTraversal& node, const FrontRows& old,
                            const FrontRows& kept) {
    const Forest& f = node.forest;
    const double* P = node.pose;
    const double travel = node.request.travel, rounding = node.request.rounding;
    const double grow = 0.5 * node.request.inflation;
    int64_t* stack = node.work.stack;
    double best = INF;
    int64_t n_seeds = 0, n_kept = 0, n_boxes = 0, n_spheres = 0, n_untested = 0;
    double grown_a[BOX_WIDTH], grown_b[BOX_WIDTH];
    for (int64_t e = 0; e < old.rows; ++e) {
        const int64_t na = old.pairs[3 * e], nb = old.pairs[3 * e + 1], how = old.pairs[3 * e + 2];
        double until = old.until[e];
        bool apart = until - travel > FRONT_GUARD_REL * until;
        double g = 0.0;
        if (apart) {
            g = until - travel;
            ++n_untested;
        } else if (how >= 0) {
            ++n_boxes;
            const double* A = grown(f.box(na), grow, grown_a);
            const double* B = grown(f.box(nb), grow, grown_b);
            const AxisGap ag = axis_gap(how, A, B, P);
            apart = ag.separated;
            g = ag.gap;
            if (apart) {
                // One axis can leave a small gap to boxes that moved far apart along another:
                // the spheres' gap may say more.
                double d[3];
                centre_offset(A, B, P, d);
                g = std::max(g, std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) -
                                    A[BOX_RADIUS] - B[BOX_RADIUS]);
                until = travel - rounding + g;
            }
        } else if (how == FRONT_SPHERE) {
            ++n_spheres;
            const Spheres s = spheres(grown(f.box(na), grow, grown_a),
                                      grown(f.box(nb), grow, grown_b), P);
            apart = s.apart;
            if (apart) {
                g = std::sqrt(s.dd) - s.radii;
                until = travel - rounding + g;
            }
        }
        if (apart) {
            int64_t* row = kept.pairs + 3 * n_kept;
            row[0] = na;
            row[1] = nb;
            row[2] = how;
            kept.until[n_kept] = until;
            ++n_kept;
            best = std::min(best, g);
        } else {
            int64_t* row = stack + 3 * n_seeds;
            row[0] = na;
            row[1] = nb;
            row[2] = 0;
            ++n_seeds;
        }
    }
    int64_t* counters = node.work.counters;
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_SPHERE_SKIPS] += n_spheres;
    counters[COUNT_FRONT_STARTS] += 1;
    counters[COUNT_FRONT_UNTESTED] += n_untested;
    return {n_seeds, n_kept, best};
}

}  // namespace collision_sensor
