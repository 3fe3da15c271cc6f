// Bounds of how the bodies of a pair move along a path, and the test they serve: is a pair
// apart over an interval of the path around one state (motion.hpp's proof, d(m) > D(m, m +- h))?
// SideMotion and MotionMargin bound how far a box moves (zeroth order) and how fast a gap along
// a direction closes (first order); node_pair_apart decides one node pair, trees_within the
// descent of a pair's two trees, as the traversal's collision test decides them at one state.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "box_test.hpp"
#include "distance.hpp"
#include "inlining.hpp"
#include "obb_tree.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"

namespace collision_sensor {

// How the joints between one body of a pair and the pair's common ancestor move its points,
// at one state of the path (motion.cpp fills it), the joints from the body upwards: joint i
// has its origin at origin[i] (world frame; a joint's child frame sits at its origin) and a
// unit axis[i] (world: a revolute or planar joint's axis of rotation, a prismatic joint's
// direction; 0 for a floating joint); per unit of the path parameter it turns its side by at
// most rot[i] rad and translates it by at most trans[i] m; speed[i] is a revolute joint's
// signed turn about axis[i] or a prismatic joint's signed slide along it; above[i] bounds how
// fast the joint's own frame turns (the joints above it on this side, summed). Relative to the
// common ancestor the body turns at omega (world frame); accel[i] bounds how fast speed[i]
// changes (a spline's second derivative; 0 on a straight motion). first_order: every joint is
// revolute, prismatic or fixed, for which the first-order bound below is exact.
struct SideMotion {
    int64_t n;
    const double* origin;  // (n, 3)
    const double* axis;    // (n, 3)
    const double* trans;   // (n,)
    const double* rot;     // (n,)
    const double* speed;   // (n,)
    const double* accel;   // (n,) bound of |speed'| (0 along a straight motion)
    const double* above;   // (n,)
    const double* T;       // (16,) the body's world pose
    bool first_order;
    double omega[3];
};

// What a box of one side does over an interval of the path (MotionMargin::node).
struct BoxMotion {
    double rate;  // its points move at most this fast (m per unit of the parameter)
    double v[3];  // its centre's velocity at the evaluated state (world frame)
    double acc;   // its points accelerate at most this much (m per unit squared)
};

// Bounds of how a box moves over an interval of the path around the evaluated state (the
// file's header, made local). A box of body x with centre c (world) and radius rho, over a
// half-width h <= h2 of the parameter, relative to the pair's common ancestor:
//
// Zeroth order: its points move at most h rate, with, the joints taken from x upwards,
//     lever_i = dist(c, axis line i) + rho + R_i h2,   R_{i+1} = R_i + trans_i + rot_i lever_i,
// rate = R_n: a joint turning by w moves a point by at most w times its distance from the
// joint's axis (from its origin when it has no fixed axis), which the joints below it change
// by at most R_i h2 over the interval (those above move the point and the axis alike). Near a
// joint's axis this is far below the whole body's bound: the two links of an elbow that come
// close do so near the elbow, where its turn moves them least.
//
// First order (Taylor models, as continuous collision checkers for articulated robots use
// them): a point p of the box moves as p(m + s) = p(m) + s p'(m) + e(s), |e(s)| <= s^2 acc / 2,
// with p'(m) = v + omega x (p - c), v = sum_i speed_i axis_i x (c - origin_i) (revolute) +
// speed_i axis_i (prismatic), and
//     |p''| <= sum_i rot_i ((2 above_i + rot_i) L_i + R_i) + accel_i L_i       (revolute)
//            + trans_i above_i + accel_i                                       (prismatic),
// L_i = |c - origin_i| + rho + R_i h2 (differentiating p' = sum_i speed_i axis_i x (p - o_i):
// the axis turns at most above_i, p - o_i at most (above_i + rot_i) L_i + R_i, the speed
// itself at most accel_i). Along a fixed
// unit direction n, the gap between two boxes then closes at most by
//     h (|n . (v_b - v_a)| + rho_a |n x omega_a| + rho_b |n x omega_b|) + h^2 (acc_a + acc_b) / 2
// over the half-width h: the motion towards each other, not all motion. Two links sliding
// past each other, or a link turning about an axis along n, close no gap at all.
struct MotionMargin {
    SideMotion side[2];
    double h2;
    // Per forest node and side, cached while stamp == tag.
    BoxMotion* cache[2];
    int64_t* stamp[2];
    int64_t tag;

    BoxMotion box_motion(const double* box, int s) const {
        const SideMotion& m = side[s];
        BoxMotion out{0.0, {0.0, 0.0, 0.0}, 0.0};
        if (m.n == 0) return out;
        const double* T = m.T;
        double c[3];
        for (int i = 0; i < 3; ++i)
            c[i] = T[4 * i] * box[BOX_CENTER] + T[4 * i + 1] * box[BOX_CENTER + 1] +
                   T[4 * i + 2] * box[BOX_CENTER + 2] + T[4 * i + 3];
        const double rho = box[BOX_RADIUS];
        double R = 0.0, acc = 0.0;
        for (int64_t i = 0; i < m.n; ++i) {
            const double* o = m.origin + 3 * i;
            const double* u = m.axis + 3 * i;
            const double d0 = c[0] - o[0], d1 = c[1] - o[1], d2 = c[2] - o[2];
            const double dd = d0 * d0 + d1 * d1 + d2 * d2;
            // |d x u|^2 = |d|^2 - (d . u)^2 for a unit u; u = 0: |d|.
            const double du = d0 * u[0] + d1 * u[1] + d2 * u[2];
            const double spread = rho + R * h2;
            const double lever = std::sqrt(std::max(dd - du * du, 0.0)) + spread;
            const double w = m.rot[i], tr = m.trans[i];
            if (w > 0.0) {
                const double L = std::sqrt(dd) + spread;
                acc += w * ((2.0 * m.above[i] + w) * L + R) + m.accel[i] * L;
                const double sp = m.speed[i];  // v += speed axis x d
                out.v[0] += sp * (u[1] * d2 - u[2] * d1);
                out.v[1] += sp * (u[2] * d0 - u[0] * d2);
                out.v[2] += sp * (u[0] * d1 - u[1] * d0);
            }
            if (tr > 0.0) {
                acc += tr * m.above[i] + m.accel[i];
                const double sp = m.speed[i];
                out.v[0] += sp * u[0];
                out.v[1] += sp * u[1];
                out.v[2] += sp * u[2];
            }
            R += tr + w * lever;
        }
        out.rate = R * (1.0 + MOTION_BOUND_REL);
        out.acc = acc * (1.0 + MOTION_BOUND_REL);
        return out;
    }

    const BoxMotion& node(const Forest& f, int64_t n, int s) {
        if (stamp[s][n] != tag) {
            stamp[s][n] = tag;
            cache[s][n] = box_motion(f.box(n), s);
        }
        return cache[s][n];
    }

    // How far, over what half-width (<= h2), two boxes (radii rho_a, rho_b; motions ma, mb)
    // whose gap along the unit direction n (world) is g stay more than extra apart, by the
    // first-order bound; 0 when it proves nothing (a side not first_order), or when it does
    // not reach the half-width h the caller needs.
    double first_order_reach(const double* n, double g, double extra, double rho_a,
                             const BoxMotion& ma, double rho_b, const BoxMotion& mb,
                             double h) const {
        if (!side[0].first_order || !side[1].first_order || !(g > extra)) return 0.0;
        auto cross_norm = [n](const double* w) {  // 0 for a side that does not turn
            if (w[0] == 0.0 && w[1] == 0.0 && w[2] == 0.0) return 0.0;
            const double x = n[1] * w[2] - n[2] * w[1], y = n[2] * w[0] - n[0] * w[2],
                         z = n[0] * w[1] - n[1] * w[0];
            return std::sqrt(x * x + y * y + z * z);
        };
        const double closing =
            (std::fabs(n[0] * (mb.v[0] - ma.v[0]) + n[1] * (mb.v[1] - ma.v[1]) +
                       n[2] * (mb.v[2] - ma.v[2])) +
             rho_a * cross_norm(side[0].omega) + rho_b * cross_norm(side[1].omega)) *
            (1.0 + MOTION_BOUND_REL);
        const double a = 0.5 * (ma.acc + mb.acc);
        const double room = g - extra;
        // Below h (the left side grows with x) without a root taken.
        if (a * h * h + closing * h > room) return 0.0;
        // The largest x with a x^2 + closing x <= room.
        double x;
        if (a > 0.0)
            x = 2.0 * room / (closing + std::sqrt(closing * closing + 4.0 * a * room));
        else
            x = closing > 0.0 ? room / closing : INF;
        return std::min(x * (1.0 - MOTION_BOUND_REL), h2);
    }
};

// The result of testing a pair at one state over a half-width h of the path (pair_within).
struct WithinResult {
    bool within;    // some node pair's triangles within padding + their margin (or a solid)
    double margin;  // then: that margin (m): the state is within 2 margin of contact at the
                    // interval's ends
    double reach;   // else: a half-width of the parameter (>= h) over which the pair is apart;
                    // within: the half-width over which the node pair found within would have
                    // been apart (< h), a hint for the next interval
};

// The world direction of a direction d given in box A's frame (body a at world pose Ta).
CS_ALWAYS_INLINE void box_direction_in_world(const double* A, const double* Ta, const double* d,
                                             double* n) {
    double e[3];  // in body a: E_a d
    for (int i = 0; i < 3; ++i)
        e[i] = A[BOX_AXES + 3 * i] * d[0] + A[BOX_AXES + 3 * i + 1] * d[1] +
               A[BOX_AXES + 3 * i + 2] * d[2];
    for (int i = 0; i < 3; ++i) n[i] = Ta[4 * i] * e[0] + Ta[4 * i + 1] * e[1] + Ta[4 * i + 2] * e[2];
}

// What node_pair_apart asks of every node pair of one pair of bodies at one state: body b's
// pose P in body a's frame, body a's world pose Ta (4, 4), the half-width h of the path and the
// distance extra the pair must keep beyond its margin, the motions' bounds (their node rows
// filled on demand: MotionMargin::node), and the box test (BOX_TEST_*).
struct IntervalTest {
    const double* P;
    const double* Ta;
    double h, extra;
    MotionMargin& motion;
    int box_test;
};

// A node pair proven apart: the half-width of the path over which it stays so (>= h), and
// the gap it was proven apart by.
struct NodePairApart {
    double reach, gap;
};

// Is the node pair of boxes A (body a) and B (body b), whose motions are ma and mb, apart over
// the half-width t.h, more than t.extra apart? If so, out says how far and by how much.
// Placed: B's placed row (placed_row: its centre and axes in body a) is given, else B is
// placed by t.P. Cheapest first: the spheres, then the boxes' gap along the direction of their
// nearest points (projected_gap) against the zeroth-order margin, then the same gap against the
// first-order bound, then the box test with both boxes grown by half the zeroth-order margin
// (a box grown by r / 2 along its axes holds every point within r / 2 of it, so grown boxes
// apart are more than r apart: the exact test as the margin goes to 0).
template <bool Placed>
CS_ALWAYS_INLINE bool node_pair_apart_as(const IntervalTest& t, const double* A,
                                         const double* B, const double* placed,
                                         const BoxMotion& ma, const BoxMotion& mb,
                                         NodePairApart& out) {
    const double h = t.h, extra = t.extra;
    const MotionMargin& motion = t.motion;
    const double rate = ma.rate + mb.rate;
    const double r = h * rate + extra;
    auto zeroth = [&](double gap) {
        return rate > 0.0 ? std::min((gap - extra) / rate, motion.h2) : motion.h2;
    };
    double d[3];
    if (Placed) {
        for (int i = 0; i < 3; ++i) d[i] = placed[i] - A[BOX_CENTER + i];
    } else {
        centre_offset(A, B, t.P, d);
    }
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double radii = A[BOX_RADIUS] + B[BOX_RADIUS];
    const double bound = (radii + r) * (1.0 + SPHERE_EPS_REL);
    if (dd > bound * bound) {
        const double g = std::sqrt(dd) - radii * (1.0 + SPHERE_EPS_REL);
        out = {zeroth(g), g};
        return true;
    }
    double T[12], u[3];
    if (Placed)
        placed_in_frame(A, placed, d, T);
    else
        box_in_frame(A, B, t.P, T);
    const double g = projected_gap(A, B, T, u);
    if (g > r) {
        out = {zeroth(g), g};
        return true;
    }
    // No direction: the alternating projection met a point of both boxes, which overlap.
    if (u[0] == 0.0 && u[1] == 0.0 && u[2] == 0.0) return false;
    if (g > extra) {
        double n[3];
        box_direction_in_world(A, t.Ta, u, n);
        const double x = motion.first_order_reach(n, g, extra, A[BOX_RADIUS], ma,
                                                  B[BOX_RADIUS], mb, h);
        if (x >= h) {
            out = {x, g};
            return true;
        }
    }
    const double grow = 0.5 * r;
    const double ha[3] = {A[BOX_HALF] + grow, A[BOX_HALF + 1] + grow, A[BOX_HALF + 2] + grow};
    const double hb[3] = {B[BOX_HALF] + grow, B[BOX_HALF + 1] + grow, B[BOX_HALF + 2] + grow};
    const bool apart = t.box_test == BOX_TEST_PAPER ? boxes_disjoint_paper(ha, hb, T, T + 9)
                                                    : boxes_disjoint_sat(ha, hb, T, T + 9);
    if (apart) {
        const double g = std::max(face_gap_of(ha, hb, T), 0.0) + r;
        out = {std::max(h, zeroth(g)), g};
    }
    return apart;
}

// node_pair_apart_as, B placed by t.P.
CS_ALWAYS_INLINE bool node_pair_apart(const IntervalTest& t, const double* A, const double* B,
                                      const BoxMotion& ma, const BoxMotion& mb,
                                      NodePairApart& out) {
    return node_pair_apart_as<false>(t, A, B, nullptr, ma, mb, out);
}

// node_pair_apart_as, B's placed row given.
CS_ALWAYS_INLINE bool placed_pair_apart(const IntervalTest& t, const double* A, const double* B,
                                        const double* placed, const BoxMotion& ma,
                                        const BoxMotion& mb, NodePairApart& out) {
    return node_pair_apart_as<true>(t, A, B, placed, ma, mb, out);
}

// What trees_within is asked: the tests (TraversalRequest's box_test and expansion), the
// pair's two paddings summed, and the half-width h of the path around the state at hand over
// which the pair must be apart by more than extra (m).
struct WithinRequest {
    int box_test;
    int expansion;
    double pad;
    double h;
    double extra;
};

// The front trees_within records: every node pair where its descent stopped (pruned, or a
// leaf pair tested apart), appended to pairs as (na, nb); with no triangles within, they cover
// every pair of triangles under the seeds once, whatever the pose, so a later test of the pair
// may start from them instead of the roots (motion.cpp: pair_within keeps them per pair). For
// each, reach: a half-width of the parameter over which it stays apart, its own, or further
// by crude (when > 0: a bound of how fast any point of either body moves relative to the other
// over the whole path, per unit of the parameter, the planning's reach rows) against the gap
// it was proven apart by, which holds however far the path goes; and, when with_gaps, gap:
// that gap less extra (-INF when crude proves nothing), the relative motion below which it
// stays apart.
struct WithinFront {
    std::vector<int64_t>& pairs;
    std::vector<double>& reach;
    std::vector<double>& gap;
    double crude;
    bool with_gaps;
};

// A within traversal node (as traversal.hpp's TreePairTraversal): the forest holding both
// trees, body b's pose in body a's frame, what is asked, the two sides' motions over the
// interval, where it works (its stack holds the seeds: rows >= seeds + depth(a) + depth(b) + 2)
// and where tree b's boxes are placed, and the front it records.
struct WithinTraversal {
    const Forest& forest;
    const double* pose;
    const WithinRequest& request;
    MotionMargin& motion;
    TraversalWork work;
    DistanceWork& rows;
    WithinFront& front;
};

// Does any triangle under the node pairs on the node's stack (its first n_seeds rows) come
// within pad + its margin of one of the other tree's, over the half-width h of the path
// (MotionMargin), plus extra? The traversal of trees_collide with each node pair pruned when
// node_pair_apart proves it apart, and the leaves tested by their triangles' distance: apart
// by more than the zeroth-order margin, or along their nearest points' direction by more than
// the first-order one; no witness, the front recorded (WithinFront). When none does, reach is
// the smallest half-width over which a pruned node pair stays apart.
// Defined in motion_within.hpp.
inline WithinResult trees_within(const WithinTraversal& node, int64_t n_seeds);

}  // namespace collision_sensor
