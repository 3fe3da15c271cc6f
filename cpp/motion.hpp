// Certified motion checks (issue 25): is any configuration along a joint-space path in contact?
//
// The paper's verdicts are about one instant. A motion between two clear states can pass
// through an object; sampling it at a fixed resolution can miss a thin one. Here a path is
// proven free, never sampled: with d(t) a lower bound of a pair's padded distance at the
// state q(t) and D(s, t) a bound of how far any point of either body can move relative to the
// other between q(s) and q(t), the pair stays apart on [m - h, m + h] as long as
//     d(m) > D(m, m - h)  and  d(m) > D(m, m + h)
// (Schwarzer, Saha & Latombe 2005, "Adaptive dynamic collision checking for single and
// multiple articulated robots in complex environments", with the engine's traversal as the
// distance bound). d(m) > r is decided by the traversal itself: both bodies' boxes grown by
// r / 2 (a box grown by r / 2 along its axes holds every point within r / 2 of it, so grown
// boxes apart mean the boxes are more than r apart) and leaves tested "triangles within
// padding + r". Nothing is approximated; the answer is exact up to the touching tolerance.
//
// Bounds of the motion (motion_coefficients): a joint k on the tree path between the pair's
// two bodies moves the body on its side. Per unit of its value a revolute joint moves a point
// of body x below it by at most its lever: the joint offsets |t_parent_joint| from k down to
// x, plus the largest extension of the prismatic joints (and the translation of planar and
// floating joints) between them along the path, plus x's reach (|box centre| + radius); a
// prismatic joint, or a planar or floating joint's translation, by 1; a floating joint's
// rotation by its angle (slerp: constant angular speed about a fixed axis) times the lever.
// Summed over the joints each variable drives (|multiplier|: mimic joints follow), this is
// c[p, j], and D(s, t) = sum_j c[p, j] var_j(s, t) with var_j the variable's total variation
// between s and t. Joints above the two bodies' common ancestor move both alike: skipped.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "context.hpp"
#include "distance.hpp"
#include "inlining.hpp"
#include "kinematics.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"

namespace collision_sensor {

// A pair's march (motion.cpp: march_step) sizes its next interval from the half-width over which
// it was last proven apart, times a factor that grows by MARCH_GROW after each interval
// proven (up to MARCH_FACTOR_MAX) and shrinks by MARCH_SHRINK after each that was not (down
// to MARCH_FACTOR_MIN). Only the work depends on them, never the answer; measured on the
// Panda and the UR5 in a cluttered cell (node pairs visited: 7,800 per segment with 1.25, 2,
// 0.7, 0.25; 6,240 with 1.25, 2, 0.5, 0.75). Once a front's node pairs are kept while proven
// (pair_within), larger intervals cost less: scenario 10's box tests per Panda segment, per
// UR5 segment and for the 1,000-waypoint Panda path 2,635 / 5,217 / 89,025 with 1.25, 2;
// 2,658 / 5,189 / 71,913 with these; 2,699 / 5,465 / 72,713 with 2, 4.
constexpr double MARCH_GROW = 1.5, MARCH_FACTOR_MAX = 3.0, MARCH_SHRINK = 0.5,
                 MARCH_FACTOR_MIN = 0.75;
// A pair's test starts from the node pairs where its last descent stopped (its front) while
// that front has at most this many node pairs and starting there costs no more node pairs
// than its last descent from the roots did (motion.cpp: pair_within). Work only, never answers:
// node pairs visited on the Panda in a cluttered cell 6,240 -> 5,240 per segment.
constexpr int64_t MOTION_FRONT_MAX = 1024;
// A pair whose bodies only translate relative to each other along a straight motion, both
// made of convex elements (a primitive, or a convex closed mesh), is swept by ray casts
// (convex_sweep.hpp) instead of marched, up to this many element pairs; the cast stops within
// SWEEP_EPS (tolerances.hpp) of contact.
constexpr int64_t SWEEP_MAX_ELEMENT_PAIRS = 16;
// update_motion: a pair apart at both ends of a step whose gaps there do not exceed the step's
// bound has its distance at q1 measured before it marches (check_step_motion): the
// incremental query's clearance is where its descent stopped, often a tenth of a millimetre
// for a link hovering centimetres from an obstacle, so that the pair would march at every
// step. The search is capped at MOTION_MEASURE_AHEAD times what the proof needs: above what it
// needs, the pair is apart all along, and the distance, carried as its clearance, lets the
// planning skip the pair for the steps to come. A search near a cap that is a sizeable part of
// the bodies descends most of both trees (a slow stream's long steps), so a pair is measured
// only while the cap is at most MOTION_MEASURE_SCALE times its two body radii summed; and only
// a pair that keeps no front: its march starts from the front, whose node pairs the step's
// bound mostly proves already, for less than a search costs (a Panda's self-collision walk,
// node_latency --per-call --walk 0.002: 2.7 us per step marching from fronts, 4.3 measuring).
// Work only, never answers: on scenario 10's 1 kHz walk of the Panda in its cluttered cell,
// update_motion / update went from 1.9x to 1.1x.
constexpr double MOTION_MEASURE_AHEAD = 4.0, MOTION_MEASURE_SCALE = 0.05;

// The straight motion from q0 to q1, t in [0, 1]: each variable as its motion kind says
// (kinematics.hpp: MOTION_*, the interpolation MoveIt uses).
//   var[j]: its total variation over the whole motion (|q1 - q0|, the shorter way for
//           MOTION_WRAP); a floating joint's rotation angle (rad) in its rot_x slot, 0 in
//           rot_y..rot_w.
struct StraightPath {
    const double* q0;
    const int64_t* kind;
    int64_t n;
    double* delta;  // (n,) per variable: q1 - q0 (wrapped); quaternions: see below
    double* var;    // (n,)
    // Floating joints: q0's and q1's unit quaternion (q1's sign taken for the shorter arc) in
    // delta[j..j+3] (q1) and quat0 (per joint, 4 values, in the same slot of this array).
    double* quat0;  // (n,)

    // Prepare from q0, q1 (validated). Returns nothing; fills delta, var, quat0.
    void prepare(const double* q1) {
        for (int64_t j = 0; j < n; ++j) {
            if (kind[j] == MOTION_LINEAR) {
                delta[j] = q1[j] - q0[j];
                var[j] = std::fabs(delta[j]);
            } else if (kind[j] == MOTION_WRAP) {
                // remainder: in [-pi, pi]; at exactly pi either way is as short.
                delta[j] = std::remainder(q1[j] - q0[j], 2.0 * M_PI);
                var[j] = std::fabs(delta[j]);
            } else if (kind[j] == MOTION_QUATERNION) {
                double a[4], b[4];
                unit_quaternion(q0 + j, a);
                unit_quaternion(q1 + j, b);
                double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
                if (dot < 0.0) {  // -b is the same rotation, the shorter arc from a
                    for (double& c : b) c = -c;
                    dot = -dot;
                }
                for (int i = 0; i < 4; ++i) {
                    quat0[j + i] = a[i];
                    delta[j + i] = b[i];
                }
                // The rotation from a to b turns by 2 acos(dot) about a fixed axis; slerp
                // turns at constant speed.
                var[j] = 2.0 * std::acos(std::min(dot, 1.0));
                var[j + 1] = var[j + 2] = var[j + 3] = 0.0;
                j += 3;
            }
        }
    }

    double end() const { return 1.0; }
    // The interval [lo, hi] (march_step) cut where the path's speeds jump: nowhere.
    double clip(double, double hi) const { return hi; }
    // The half-width of the path around m over which an interval [m - h, m + h] is bounded.
    double room(double, double h) const { return 2.0 * h; }

    // q(t) into q.
    void at(double t, double* q) const {
        for (int64_t j = 0; j < n; ++j) {
            if (kind[j] == MOTION_QUATERNION) {
                slerp(quat0 + j, delta + j, 0.5 * var[j], t, q + j);
                j += 3;
            } else {
                q[j] = q0[j] + t * delta[j];
            }
        }
    }

    static void unit_quaternion(const double* v, double* u) {
        double x = 0.0, y = 0.0, z = 0.0, w = 1.0, n2 = 1.0;
        scaled_quaternion(v, &x, &y, &z, &w, &n2);  // usable: validated first
        const double s = 1.0 / std::sqrt(n2);
        u[0] = x * s;
        u[1] = y * s;
        u[2] = z * s;
        u[3] = w * s;
    }

    // Unit quaternions a, b with a . b = cos(half) >= 0: the one a fraction t of the way.
    static void slerp(const double* a, const double* b, double half, double t, double* out) {
        double ka = 1.0 - t, kb = t;
        if (half > SLERP_HALF_ANGLE_MIN) {  // below, the chord (tolerances.hpp)
            const double s = std::sin(half);
            ka = std::sin((1.0 - t) * half) / s;
            kb = std::sin(t * half) / s;
        }
        for (int i = 0; i < 4; ++i) out[i] = ka * a[i] + kb * b[i];
    }
};

// Straight motions through waypoints Q (segments + 1 rows of n), t in [0, segments]: segment k
// (StraightPath from row k to row k + 1) at t in [k, k + 1]. A pair marches along the whole
// polyline at once: where it is far from everything its intervals span many segments (the
// speeds over an interval are the largest of its segments'), so a path of short segments costs
// about what one motion of its length does, not one start per segment.
struct PolylinePath {
    const double* Q;
    const int64_t* kind;
    int64_t n;
    int64_t segments;
    double* delta;  // (segments, n): each segment's StraightPath arrays
    double* var;
    double* quat0;

    void prepare() {
        for (int64_t k = 0; k < segments; ++k) segment(k).prepare(Q + n * (k + 1));
    }
    StraightPath segment(int64_t k) const {
        return {Q + n * k, kind, n, delta + n * k, var + n * k, quat0 + n * k};
    }
    // The segment holding t (a waypoint's t = k: the segment it starts, the last at the end).
    int64_t segment_of(double t) const {
        const double k = std::floor(t);
        return k <= 0.0 ? 0 : std::min(int64_t(k), segments - 1);
    }
    double end() const { return double(segments); }
    // At the waypoint after lo: beyond it the speeds change.
    double clip(double lo, double hi) const {
        return std::min(hi, double(segment_of(lo)) + 1.0);
    }
    // An interval inside one segment is bounded over as much of the segment around it as
    // 2 h allows (first-order bounds hold within a segment only; path_speeds); one that spans
    // waypoints over 2 h.
    double room(double m, double h) const {
        const int64_t k = segment_of(m - h);
        if (m + h > double(k + 1)) return 2.0 * h;
        return std::max(h, std::min({2.0 * h, double(k + 1) - m, m - double(k)}));
    }
    void at(double t, double* q) const {
        const int64_t k = segment_of(t);
        segment(k).at(std::min(std::max(t - double(k), 0.0), 1.0), q);
    }
};

// A path of polynomials, t in [0, 1]: q_j(t) = sum_k coef[6 j + k] t^k, degree at most 5 (a
// segment of joint_trajectory_controller's spline, linear, cubic or quintic in time, with time
// rescaled to [0, 1]); the variables of planar and floating joints stay constant.
struct SplinePath {
    const double* coef;  // (n, 6)
    int64_t n;

    double end() const { return 1.0; }
    double clip(double, double hi) const { return hi; }
    double room(double, double h) const { return 2.0 * h; }

    void at(double t, double* q) const {
        for (int64_t j = 0; j < n; ++j) {
            const double* c = coef + 6 * j;
            q[j] = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
        }
    }

    // Variable j around t: its speed q'(t), and bounds of |q'| and |q''| on [t - h, t + h]
    // (a polynomial is its own Taylor series: |f(t + s)| <= sum_k |f^(k)(t) / k!| |s|^k).
    void rates(int64_t j, double t, double h, double* speed, double* speed_max,
               double* accel_max) const {
        const double* c = coef + 6 * j;
        // D[k] = q^(k)(t) / k! = sum_{i >= k} C(i, k) c_i t^(i - k).
        static constexpr double BINOMIAL[6][6] = {{1, 1, 1, 1, 1, 1},  {0, 1, 2, 3, 4, 5},
                                                  {0, 0, 1, 3, 6, 10}, {0, 0, 0, 1, 4, 10},
                                                  {0, 0, 0, 0, 1, 5},  {0, 0, 0, 0, 0, 1}};
        double D[6];
        for (int k = 0; k < 6; ++k) {
            double d = 0.0, power = 1.0;
            for (int i = k; i < 6; ++i) {
                d += BINOMIAL[k][i] * c[i] * power;
                power *= t;
            }
            D[k] = d;
        }
        *speed = D[1];
        double vmax = 0.0, amax = 0.0, power = 1.0;
        for (int k = 1; k < 6; ++k) {  // power = h^(k - 1)
            vmax += k * std::fabs(D[k]) * power;
            power *= h;
        }
        power = 1.0;
        for (int k = 2; k < 6; ++k) {  // power = h^(k - 2)
            amax += k * (k - 1) * std::fabs(D[k]) * power;
            power *= h;
        }
        *speed_max = vmax;
        *accel_max = amax;
    }

    bool moves(int64_t j) const {
        const double* c = coef + 6 * j;
        return c[1] != 0.0 || c[2] != 0.0 || c[3] != 0.0 || c[4] != 0.0 || c[5] != 0.0;
    }
};

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

// Is the node pair of boxes A (body a at world pose Ta) and B (body b at pose P in body a),
// whose motions are ma and mb, apart over the half-width h, more than extra apart? If so, the
// half-width (>= h) over which it stays so goes to reach. Cheapest first: the spheres, then
// the boxes' gap along the direction of their nearest points (projected_gap) against the
// zeroth-order margin, then the same gap against the first-order bound, then the box test with
// both boxes grown by half the zeroth-order margin (a box grown by r / 2 along its axes holds
// every point within r / 2 of it, so grown boxes apart are more than r apart: the exact test
// as the margin goes to 0).
CS_ALWAYS_INLINE bool node_pair_apart(const double* A, const double* B, const double* P,
                                      const double* Ta, const BoxMotion& ma,
                                      const BoxMotion& mb, double h, double extra,
                                      const MotionMargin& motion, int box_method,
                                      double* reach, double* gap = nullptr,
                                      const double* placed = nullptr) {
    const double rate = ma.rate + mb.rate;
    const double r = h * rate + extra;
    auto zeroth = [&](double gap) {
        return rate > 0.0 ? std::min((gap - extra) / rate, motion.h2) : motion.h2;
    };
    double d[3];
    if (placed) {
        for (int i = 0; i < 3; ++i) d[i] = placed[i] - A[BOX_CENTER + i];
    } else {
        centre_offset(A, B, P, d);
    }
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double radii = A[BOX_RADIUS] + B[BOX_RADIUS];
    const double bound = (radii + r) * (1.0 + SPHERE_EPS_REL);
    if (dd > bound * bound) {
        const double g = std::sqrt(dd) - radii * (1.0 + SPHERE_EPS_REL);
        *reach = zeroth(g);
        if (gap) *gap = g;
        return true;
    }
    double T[12], u[3];
    if (placed)
        placed_in_frame(A, placed, d, T);
    else
        box_in_frame(A, B, P, T);
    const double g = projected_gap(A, B, T, u);
    if (g > r) {
        *reach = zeroth(g);
        if (gap) *gap = g;
        return true;
    }
    // No direction: the alternating projection met a point of both boxes, which overlap.
    if (u[0] == 0.0 && u[1] == 0.0 && u[2] == 0.0) return false;
    if (g > extra) {
        double n[3];
        box_direction_in_world(A, Ta, u, n);
        const double x = motion.first_order_reach(n, g, extra, A[BOX_RADIUS], ma,
                                                  B[BOX_RADIUS], mb, h);
        if (x >= h) {
            *reach = x;
            if (gap) *gap = g;
            return true;
        }
    }
    const double grow = 0.5 * r;
    const double ha[3] = {A[BOX_HALF] + grow, A[BOX_HALF + 1] + grow, A[BOX_HALF + 2] + grow};
    const double hb[3] = {B[BOX_HALF] + grow, B[BOX_HALF + 1] + grow, B[BOX_HALF + 2] + grow};
    const bool apart = box_method == BOX_TEST_PAPER ? boxes_disjoint_paper(ha, hb, T, T + 9)
                                                    : boxes_disjoint_sat(ha, hb, T, T + 9);
    if (apart) {
        const double g = std::max(face_gap_of(ha, hb, T), 0.0) + r;
        *reach = std::max(h, zeroth(g));
        if (gap) *gap = g;
    }
    return apart;
}

// Does any triangle under the node pairs stack[:n_seeds] come within pad + its margin of one
// of the other tree's (body b at pose P in body a), over the half-width h of the path
// (MotionMargin), plus extra? The traversal of trees_collide with each node pair pruned when
// node_pair_apart proves it apart, and the leaves tested by their triangles' distance: apart
// by more than the zeroth-order margin, or along their nearest points' direction by more than
// the first-order one. No front, no witness. When none does, reach is the smallest half-width
// over which a pruned node pair stays apart.
//
// front: when not null, every node pair where the descent stopped (pruned, or a leaf pair
// tested apart) is appended to it, (na, nb) each: with no triangles within, they cover every
// pair of triangles under the seeds once, whatever the pose, so a later test of the pair may
// start from them instead of the roots (motion.cpp: pair_within keeps them per pair).
// front_reach: then, for each, a half-width of the parameter over which it stays apart: its
// own reach, or further by crude (when > 0: a bound of how fast any point of either body
// moves relative to the other over the whole path, per unit of the parameter, the planning's
// reach rows) against the gap it was proven apart by, which holds however far the path goes.
// front_gap: then, for each, that gap less extra (-INF when crude proves nothing): it stays
// apart while its bodies move relative to each other by less.
inline WithinResult trees_within(int64_t n_seeds, const double* P, const Forest& f,
                                 int box_method, int expansion, int64_t* stack,
                                 int64_t* counters, double h, double extra,
                                 MotionMargin& motion, DistanceWork& rows, double pad,
                                 std::vector<int64_t>* front = nullptr,
                                 std::vector<double>* front_reach = nullptr,
                                 double crude = 0.0,
                                 std::vector<double>* front_gap = nullptr) {
    double reach = motion.h2;
    const double* Ta = motion.side[0].T;
    ++rows.placed_tag;  // tree b's boxes placed at P: each once (placed_row)
    int64_t n_boxes = 0, n_triangles = 0;
    const bool crude_holds = crude > 0.0 && crude < INF;
    auto stopped = [&](int64_t na, int64_t nb, double x, double gap) {
        if (front) {
            front->push_back(na);
            front->push_back(nb);
            if (front_reach) {
                if (crude_holds && gap > extra)
                    x = std::max(x, (gap - extra) / crude * (1.0 - MOTION_BOUND_REL));
                front_reach->push_back(x);
            }
            if (front_gap) front_gap->push_back(crude_holds && gap > extra ? gap - extra : -INF);
        }
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

// The distance from point x (in element e's body frame) to the solid of element e, 0 inside:
// the true box, sphere or cylinder (elem_solid row s: kind, size, R, t). INF for a closed mesh
// or none: a body cannot enter a closed mesh without its surface meeting the mesh's, which the
// triangles see; a primitive's tessellation is inscribed, so a vertex can enter the true solid
// (which check() counts) without any triangle meeting.
inline double solid_distance(const double* s, const double* x) {
    const int kind = int(s[0]);
    const double* R = s + 4;
    const double* t = s + 13;
    const double d0 = x[0] - t[0], d1 = x[1] - t[1], d2 = x[2] - t[2];
    const double p0 = R[0] * d0 + R[3] * d1 + R[6] * d2;
    const double p1 = R[1] * d0 + R[4] * d1 + R[7] * d2;
    const double p2 = R[2] * d0 + R[5] * d1 + R[8] * d2;
    switch (kind) {
        case 1: {  // SOLID_BOX: half extents
            const double e0 = std::max(std::fabs(p0) - s[1], 0.0);
            const double e1 = std::max(std::fabs(p1) - s[2], 0.0);
            const double e2 = std::max(std::fabs(p2) - s[3], 0.0);
            return std::sqrt(e0 * e0 + e1 * e1 + e2 * e2);
        }
        case 2:  // SOLID_SPHERE: radius
            return std::max(std::sqrt(p0 * p0 + p1 * p1 + p2 * p2) - s[1], 0.0);
        case 3: {  // SOLID_CYLINDER along z: radius, half length
            const double er = std::max(std::sqrt(p0 * p0 + p1 * p1) - s[1], 0.0);
            const double ez = std::max(std::fabs(p2) - s[2], 0.0);
            return std::sqrt(er * er + ez * ez);
        }
        default:
            return INF;
    }
}

// The motion queries' own work areas (a Scratch's counterparts), sized from the model on
// first use (size_for). Per link: its pose at the evaluated state (T, valid where stamp ==
// tag) and its joint's speeds along the path; per side of the pair at hand, its moving
// joints; per pair, its march and its front; per node and side, MotionMargin's cache.
struct MotionWork {
    // A pair's march along a path (march_step): proven apart on [0, t).
    struct March {
        int64_t p;
        double t, length, factor;
    };
    std::vector<double> delta, var, quat0;  // (J,) StraightPath's
    // PolylinePath's: its segments' arrays (S, J), and per segment and link the joint's
    // trans, rot and signed speed (S, L, 3) as straight_speeds gives them.
    std::vector<double> poly_delta, poly_var, poly_quat0, poly_speeds;
    // Each variable's variation summed over the segments before each waypoint (S + 1, J):
    // how far a pair's bodies can move between two parameters is their difference, weighed
    // by its reach rows (MotionQuery::measure).
    std::vector<double> poly_cum;
    std::vector<double> pair_rates;  // (J,) measure_pair's pair's reach rows, weighed by E
    int64_t rates_pair = -1;
    // Every link's pose at each waypoint, computed on first use (poly_posed): the crude bound
    // at a waypoint (MotionQuery::waypoint_leap) then costs no kinematics.
    std::vector<double> poly_T;        // (S + 1, L, 16)
    std::vector<uint8_t> poly_posed;   // (S + 1,)
    // The speeds in trans, rot, speed hold along the whole interval at hand as one straight
    // motion's (first-order bounds valid); false when it spans segments of a polyline.
    bool first_order = true;
    std::vector<double> q, q_prev, q_next;  // (J,) the state evaluated; update_motion's start
    bool evaluated = false;                 // q holds a state (T follows it where stamped)
    std::vector<double> crude;              // (P,) each pair's crude rate (-1: not yet)
    double extension_max = 0.0;             // E's bound along a straight path
    std::vector<double> T;                  // (L, 16)
    std::vector<double> turn;               // (L, 3) set_link_pose's cosines (kinematics.hpp)
    std::vector<int64_t> stamp, chain;      // (L,)
    int64_t tag = 0;
    std::vector<double> trans, rot, speed, accel;  // (L,) each link's joint's speeds
    std::vector<uint8_t> moving;                   // (L,) its joint moves on the path
    std::vector<int64_t> depth;                    // (L,) links above each
    int64_t side_n[2] = {0, 0};
    std::vector<int64_t> side_link[2];
    std::vector<double> side_trans[2], side_rot[2], side_speed[2], side_accel[2],
        side_above[2], side_origin[2], side_axis[2];
    std::vector<BoxMotion> node_motion[2];  // (N,)
    std::vector<int64_t> node_stamp[2];     // (N,)
    MotionMargin margin{};
    std::vector<March> heap;
    // The pairs swept (MotionQuery::sweep) by the query at hand, each one's first contact
    // (INF: none) and how far its bodies translate relative to each other; NaN for the others.
    std::vector<int64_t> swept;
    std::vector<double> swept_at, swept_span;
    // The pairs the query at hand sweeps, and each one's pose at the start and translation
    // (POSE_WIDTH + 3 each).
    std::vector<int64_t> sweeping;
    std::vector<double> sweep_poses;
    // Each element's hull (model.hpp: element_hull), built on first need: hull_state[e] -1
    // not asked yet, 0 none, 1 hulls[e]; body_hull_state[b] likewise, 1 when every element
    // of body b has one.
    std::vector<Hull> hulls;
    std::vector<int8_t> hull_state, body_hull_state;
    std::vector<std::vector<int64_t>> front;  // (P,) each pair's front (pair_within)
    // (P,) per node pair of the front, the parameter up to which it is proven apart in the
    // query at hand (-INF: not known; empty while the front was set from elsewhere, but for
    // update_motion's, which check_step_motion sets from the carried front's untils).
    std::vector<std::vector<double>> front_until;
    // (P,) along a polyline, the same in the pair's measure (MotionQuery::measure): each node
    // pair is apart while the measure stays below this (-INF: not known).
    std::vector<std::vector<double>> front_measure;
    std::vector<double> recorded_reach, kept_until, recorded_gap, kept_measure;
    std::vector<int64_t> front_cost;          // (P,) its last descent's node pairs
    std::vector<int64_t> recorded, stack, marched;
    std::vector<double> prev_gap, prev_sums;  // (P,), (P, 2): update_motion's MotionRecord
    // update_motion's march (check_step_motion): start_apart[p] = 1 for a pair the carried
    // state has apart at the start, whose front it set from the carried state's; read while
    // start_known.
    std::vector<uint8_t> start_apart;
    bool start_known = false;
    // update_motion: pairs check_step_motion measured at q1 (MOTION_MEASURE_AHEAD), each with
    // its distance there (a clearance, rounding taken off), for the engine to carry.
    std::vector<int64_t> measured;
    std::vector<double> measured_gap;
    bool sized = false;

    void size_for(const Model& m);
    MotionRecord record() { return {prev_gap.data(), prev_sums.data()}; }
};

// What a motion query runs in: the engine's model and carried state (read only: the world
// objects' poses), its options, a Scratch (its counters) and the motion's own areas.
struct MotionContext {
    EngineView view;
    Scratch& scratch;
    MotionWork& work;
};

// Is any state of the straight motion q0 -> q1 (both usable) in contact? 0: none (proven); 1:
// yes, *t its first contact's fraction of the motion (the state there in contact or within
// MOTION_TOUCH_TOLERANCE of it, no earlier state in contact), pairs[p] = 1 for the pairs in
// contact (or within the tolerance) there, 0 for the others. Only the pairs list[:n] are
// looked at (list null: every pair).
int64_t check_straight_motion(MotionContext& c, const double* q0, const double* q1,
                              const int64_t* list, int64_t n, double* t, uint8_t* pairs);

// The same for the straight motions through the waypoints Q (n rows, n >= 2) in turn, as one
// path (PolylinePath): *t in [0, n - 1], segment floor(t) (a contact at waypoint k > 0 is the
// end of segment k - 1: t = k), every pair.
int64_t check_polyline_motion(MotionContext& c, const double* Q, int64_t n, double* t,
                              uint8_t* pairs);

// The same for one spline segment (coef: (J, 6), SplinePath; its ends usable, its planar and
// floating variables constant), every pair.
int64_t check_spline_motion(MotionContext& c, const double* coef, double* t, uint8_t* pairs);

// update_motion's certificate for the step q0 -> q1 once the incremental query took the state
// to q1 (engine.cpp: Engine::update_motion, which states the proof): of the pairs it
// re-checked (rechecked[:n]), those apart at q1 whose gaps at the two ends (the record's, and
// their new clearance) exceed the step's bound are apart all along; the others march
// (check_straight_motion). extension_before: E at q0.
int64_t check_step_motion(MotionContext& c, const double* q0, const double* q1,
                          const int64_t* rechecked, int64_t n, double extension_before,
                          double* t, uint8_t* pairs);

}  // namespace collision_sensor
