// The paths the motion checks march along (motion.hpp), each a function q(t) of one
// parameter: a straight motion between two states (StraightPath), straight motions through
// waypoints (PolylinePath) and polynomial segments (SplinePath). Each gives q(t) (at), its end,
// where its speeds jump (clip) and the half-width of the path an interval's bounds hold over
// (room); motion.cpp bounds how far the bodies move along them.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "kinematics.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

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

}  // namespace collision_sensor
