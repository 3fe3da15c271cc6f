// How fast the joints move along a path at an interval of it (motion_query.hpp): a
// spline's and a polyline's speeds, and a polyline's leap over waypoints.
#include <algorithm>
#include <cmath>

#include "motion_query.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {
namespace motion_detail {

// A spline's speeds around t (SplinePath::rates over [t - h2, t + h2]).
void MotionQuery::path_speeds(const SplinePath& path, double t, double h2) {
    for (int64_t k = 0; k < m_.n_links; ++k) {
        w_.trans[k] = w_.rot[k] = w_.speed[k] = w_.accel[k] = 0.0;
        if (!w_.moving[k]) continue;
        double speed, speed_max, accel_max;
        path.rates(m_.kin.q_index[k], t, h2, &speed, &speed_max, &accel_max);
        const double mult = m_.kin.multiplier[k];
        const double scale = std::fabs(mult) * (1.0 + MOTION_BOUND_REL);
        if (m_.kin.joint_type[k] == JOINT_REVOLUTE)
            w_.rot[k] = scale * speed_max;
        else
            w_.trans[k] = scale * speed_max;
        w_.speed[k] = mult * speed;
        w_.accel[k] = scale * accel_max;
    }
}

// A polyline's speeds over [t - h2, t + h2]: per link the largest of the segments it meets;
// within one segment its straight motion's (signed speeds, first-order bounds), else speeds
// 0 and the zeroth order only (the direction changes at a waypoint).
void MotionQuery::path_speeds(const PolylinePath& path, double t, double h2) {
    const int64_t L = m_.n_links;
    const int64_t k0 = path.segment_of(t - h2);
    // The segment holding the window's end (an end at waypoint k: segment k - 1).
    const int64_t k1 = std::max(k0, std::min(int64_t(std::ceil(t + h2)) - 1, path.segments - 1));
    w_.first_order = k0 == k1;
    for (int64_t k = 0; k < L; ++k) {
        double trans = 0.0, rot = 0.0;
        for (int64_t s = k0; s <= k1; ++s) {
            const double* speeds = w_.poly_speeds.data() + 3 * (L * s + k);
            trans = std::max(trans, speeds[0]);
            rot = std::max(rot, speeds[1]);
        }
        w_.trans[k] = trans;
        w_.rot[k] = rot;
        w_.speed[k] = k0 == k1 ? w_.poly_speeds[3 * (L * k0 + k) + 2] : 0.0;
        w_.accel[k] = 0.0;
    }
}

// A polyline's crude bound at the waypoints around s.t (their poses shared by every pair and
// computed once): a pair whose spheres are g apart at waypoint k stays apart wherever its
// measure is within g of the measure at k (measure_pair). Takes s.t as far as such a stretch
// around waypoint floor(s.t) or the next one goes, if it holds s.t; false when none takes it
// further.
bool MotionQuery::waypoint_leap(const PolylinePath& path, MotionWork::March& s) {
    if (!measure_pair(s.p)) return false;
    const int64_t L = m_.n_links, S = path.segments;
    const int64_t a = m_.pair_a[s.p], b = m_.pair_b[s.p];
    const double u_end = measure_at(S);
    const double guard = measure_guard();
    const double u_t = measure(s.t);
    const int64_t lo = path.segment_of(s.t);
    double best = s.t;
    for (int64_t k = lo; k <= std::min(lo + 1, S); ++k) {
        double* T = w_.poly_T.data() + 16 * L * k;
        if (!w_.poly_posed[k]) {
            forward_kinematics(m_.kin, path.Q + path.n * k, T);
            w_.poly_posed[k] = 1;
        }
        const double* Tb = m_.is_world_object(b) ? c_.view.state.poses.T_world_body + 16 * b
                                                 : T + 16 * b;
        double pose[POSE_WIDTH];
        relative_pose(T + 16 * a, Tb, pose);
        // The bodies' boxes' gap where their spheres meet (a link's sphere is loose).
        const double u_k = measure_at(k);
        double gap = sphere_gap(s.p, pose);
        if (!(gap * (1.0 - MOTION_BOUND_REL) - guard > std::fabs(u_k - u_t))) {
            double F[12];
            const double* A = m_.body_box(a);
            const double* B = m_.body_box(b);
            box_in_frame(A, B, pose, F);
            gap = std::max(gap, projected_gap(A, B, F, nullptr));
        }
        const double g = gap * (1.0 - MOTION_BOUND_REL) - guard;
        if (!(g > 0.0)) continue;
        if (!(std::fabs(u_k - u_t) < g)) continue;  // waypoint k's stretch must hold s.t
        // The largest t >= k with U(t) - U(k) <= g: the last waypoint i within, then the
        // fraction of its segment (U is linear there).
        if (u_end - u_k <= g) {
            best = path.end();
            break;
        }
        // Galloping from k (a leap is mostly a few segments), then halving.
        int64_t i = k, j = S, stride = 1;  // U(i) - u_k <= g < U(j) - u_k
        while (i + stride < S) {
            if (measure_at(i + stride) - u_k > g) {
                j = i + stride;
                break;
            }
            i += stride;
            stride *= 2;
        }
        while (j - i > 1) {
            const int64_t mid = (i + j) / 2;
            if (measure_at(mid) - u_k <= g) i = mid;
            else j = mid;
        }
        const double u_i = measure_at(i), u_next = measure_at(i + 1);
        const double x = u_next > u_i ? (u_k + g - u_i) / (u_next - u_i) : 1.0;
        best = std::max(best, double(i) + std::min(std::max(x, 0.0), 1.0) *
                                              (1.0 - MOTION_BOUND_REL));
    }
    if (!(best > s.t)) return false;
    s.t = best;
    return true;
}

}  // namespace motion_detail
}  // namespace collision_sensor
