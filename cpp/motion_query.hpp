// The motion checks' query (motion.cpp, motion_pairs.cpp, motion_sweeps.cpp,
// motion_speeds.cpp): one check over one context, its path's states, and its pairs' marches.
// Private to those files: motion.hpp is the checks' interface.
#pragma once

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <type_traits>

#include "model.hpp"
#include "motion.hpp"

namespace collision_sensor {
namespace motion_detail {

// How far pair p's bodies can move relative to each other per unit of variable j, with E
// (planning.hpp) at most e: the planning's reach rows, reach[p, j] + e reach_ext[p, j].
inline double variable_reach(const Model& m, int64_t p, int64_t j, double e) {
    const int64_t k = m.n_joints * p + j;
    return m.reach[k] + e * m.reach_ext[k];
}

// [R_ab, t_ab] = T_world_a^-1 T_world_b = [Ra' Rb, Ra' (tb - ta)] (POSE_WIDTH numbers).
inline void relative_pose(const double* Ta, const double* Tb, double* pose) {
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            pose[3 * i + j] = Ta[i] * Tb[j] + Ta[4 + i] * Tb[4 + j] + Ta[8 + i] * Tb[8 + j];
        pose[9 + i] = Ta[i] * (Tb[3] - Ta[3]) + Ta[4 + i] * (Tb[7] - Ta[7]) +
                      Ta[8 + i] * (Tb[11] - Ta[11]);
    }
}

// A motion query over one context: the model, the path's states and the pairs' marches.
class MotionQuery {
   public:
    explicit MotionQuery(MotionContext& c)
        : c_(c), m_(c.view.model), w_(c.work), counters_(c.scratch.counters) {
        w_.size_for(m_);
        w_.evaluated = false;   // the model's joint origins may have changed since
        w_.first_order = true;  // until a polyline's interval spans segments
        std::fill(w_.crude.begin(), w_.crude.end(), -1.0);
    }

    // The straight path q0 -> q1 prepared: each link's joint's speed per unit of the
    // parameter (constant along it).
    void straight_speeds(const double* q0) {
        w_.extension_max = extension_bound(q0, w_.delta.data());
        for (int64_t k = 0; k < m_.n_links; ++k) {
            double speeds[3];
            link_speeds(k, w_.delta.data(), w_.var.data(), speeds);
            w_.trans[k] = speeds[0];
            w_.rot[k] = speeds[1];
            w_.speed[k] = speeds[2];
            w_.accel[k] = 0.0;
            w_.moving[k] = (speeds[0] > 0.0 || speeds[1] > 0.0) ? 1 : 0;
        }
    }

    // The polyline prepared: its segments' speeds per link (path_speeds picks an interval's
    // largest), var[j] the largest of its segments' (the crude bound's rate, per unit of the
    // parameter everywhere) and E's bound the largest of its straight segments'.
    void polyline_speeds(const PolylinePath& path) {
        poly_ = &path;
        w_.rates_pair = -1;
        const int64_t J = m_.n_joints, L = m_.n_links;
        std::fill(w_.var.begin(), w_.var.end(), 0.0);
        std::fill(w_.moving.begin(), w_.moving.end(), uint8_t(0));
        w_.extension_max = 0.0;
        for (int64_t s = 0; s < path.segments; ++s) {
            const double* delta = path.delta + J * s;
            const double* var = path.var + J * s;
            w_.extension_max =
                std::max(w_.extension_max, extension_bound(path.Q + J * s, delta));
            for (int64_t j = 0; j < J; ++j) w_.var[j] = std::max(w_.var[j], var[j]);
            const double* before = w_.poly_cum.data() + J * s;
            double* after = w_.poly_cum.data() + J * (s + 1);
            for (int64_t j = 0; j < J; ++j) after[j] = before[j] + var[j];
            for (int64_t k = 0; k < L; ++k) {
                double* speeds = w_.poly_speeds.data() + 3 * (L * s + k);
                link_speeds(k, delta, var, speeds);
                if (speeds[0] > 0.0 || speeds[1] > 0.0) w_.moving[k] = 1;
            }
        }
    }

    // The links a spline moves (revolute and prismatic joints whose variable is not
    // constant).
    void spline_moving(const SplinePath& path) {
        for (int64_t k = 0; k < m_.n_links; ++k) {
            const int64_t kind = m_.kin.joint_type[k];
            w_.moving[k] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC) &&
                           path.moves(m_.kin.q_index[k]);
        }
    }

    // update_motion's second bound for pair p along the straight step prepared
    // (straight_speeds): how far its bodies' points can move relative to each other over the
    // step, bounded at its end q1 (MotionMargin's zeroth order over the whole step: the levers
    // of this configuration, not the planning's configuration-free reach).
    double step_reach(int64_t p, const double* q1) {
        const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
        double pose[POSE_WIDTH];
        evaluate(q1);
        pair_pose(a, b, pose);
        sides(p);
        margin(p, 1.0);
        const BoxMotion ma = w_.margin.box_motion(m_.body_box(a), 0);
        const BoxMotion mb = w_.margin.box_motion(m_.body_box(b), 1);
        return (ma.rate + mb.rate) * (1.0 + MOTION_BOUND_REL);
    }

    // Pair p's solid_gap with body b at pose in body a (INF without a solid element).
    double pair_solid_gap(int64_t p, const double* pose) const {
        const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
        return m_.body_solid[a] || m_.body_solid[b] ? solid_gap(a, b, pose) : INF;
    }

    // Pairs list[:n] (null: all) marched along path; returns the pair of the first contact
    // (-1: none), its parameter in *best.
    template <class Path>
    int64_t march_pairs(const int64_t* list, int64_t n, const Path& path, const double* q0,
                        double* best);

    // pairs[p] = 1 for the pairs list[:n] in contact at path(t), or within the touching
    // tolerance: a margin of MOTION_TOUCH_TOLERANCE everywhere; 0 for every other pair.
    template <class Path>
    void contacts(const int64_t* list, int64_t n, const Path& path, double t, double extra,
                  uint8_t* pairs);

    template <class Path>
    int64_t check(const int64_t* list, int64_t n, const Path& path, const double* q0, double* t,
                  uint8_t* pairs) {
        double best;
        const int64_t best_pair = march_pairs(list, n, path, q0, &best);
        if (best_pair < 0) return 0;
        // In contact at the start: the pairs in contact there, as a check of the start gives
        // them; else the pairs within the touching tolerance of contact.
        contacts(list, n, path, best, best == 0.0 ? 0.0 : MOTION_TOUCH_TOLERANCE, pairs);
        // A sweep may meet its pair at the start within SWEEP_EPS of contact, not in it: that
        // pair is named only if the start has no pair in contact.
        if (best > 0.0 || std::find(pairs, pairs + m_.n_pairs, uint8_t(1)) == pairs + m_.n_pairs)
            pairs[best_pair] = 1;
        *t = best;
        return 1;
    }

   private:
    static constexpr int MARCH_ON = 0, MARCH_FREE = 1, MARCH_CONTACT = 2;

    // E (planning.hpp: the prismatic joints' |value|, summed) along the straight motion from
    // q0 by delta: at most its larger end's.
    double extension_bound(const double* q0, const double* delta) const {
        double e0 = 0.0, e1 = 0.0;
        for (int64_t k = 0; k < m_.n_links; ++k) {
            if (m_.kin.joint_type[k] != JOINT_PRISMATIC) continue;
            const int64_t j = m_.kin.q_index[k];
            const double mult = m_.kin.multiplier[k], off = m_.kin.offset[k];
            e0 += std::fabs(mult * q0[j] + off);
            e1 += std::fabs(mult * (q0[j] + delta[j]) + off);
        }
        return std::max(e0, e1) * (1.0 + MOTION_BOUND_REL);
    }

    // Link k's joint along a straight motion (StraightPath's delta, var): {trans, rot, signed
    // speed} per unit of the parameter.
    void link_speeds(int64_t k, const double* delta, const double* var, double* out) const {
        const int64_t kind = m_.kin.joint_type[k];
        const int64_t j = m_.kin.q_index[k];
        double trans = 0.0, rot = 0.0;
        if (kind == JOINT_REVOLUTE) {
            rot = std::fabs(m_.kin.multiplier[k]) * var[j];
        } else if (kind == JOINT_PRISMATIC) {
            trans = std::fabs(m_.kin.multiplier[k]) * var[j];
        } else if (kind == JOINT_PLANAR) {
            trans = std::hypot(delta[j], delta[j + 1]);
            rot = var[j + 2];
        } else if (kind == JOINT_FLOATING) {
            trans = std::sqrt(delta[j] * delta[j] + delta[j + 1] * delta[j + 1] +
                              delta[j + 2] * delta[j + 2]);
            rot = var[j + 3];
        }
        out[0] = trans * (1.0 + MOTION_BOUND_REL);
        out[1] = rot * (1.0 + MOTION_BOUND_REL);
        out[2] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC)
                     ? m_.kin.multiplier[k] * delta[j]
                     : 0.0;
    }

    // Whether pair p can be swept along a straight path: no joint between its bodies turns
    // (sides(p) has just listed them), so they only translate relative to each other, and
    // each body's elements are convex hulls. A pair that can joins w_.sweeping, with its
    // pose at the evaluated state (the path's start) and its translation to the end
    // (pair_shift) in w_.sweep_poses. Asked of every pair that moves: the turns here, the
    // bodies in motion_sweeps.cpp (sweepable_bodies).
    bool sweepable(const StraightPath&, int64_t p) {
        for (int s = 0; s < 2; ++s)
            for (int64_t i = 0; i < w_.side_n[s]; ++i)
                if (w_.side_rot[s][i] != 0.0) return false;
        return sweepable_bodies(p);
    }
    bool sweepable_bodies(int64_t p);
    // The pairs in w_.sweeping: their first contacts by ray casts (convex_sweep.hpp) instead
    // of marches; the first contact lowers *best (its pair in *best_pair), and a pair a sweep
    // cannot decide joins the marches (heap).
    void sweep_pairs(double* best, int64_t* best_pair);
    // Sweepable pair p's translation d (3,) of body b relative to body a along the straight
    // path, in a's frame, from its sides (sides(p) has just listed them) and the poses at the
    // evaluated state (its start, which pair_pose has just placed).
    void pair_shift(int64_t p, double* d);
    // Pair p's sweep from the pose of b in a at the start along the translation d:
    // SWEEP_CONTACT (*t), SWEEP_FREE, or SWEEP_UNKNOWN (march it).
    int sweep(int64_t p, const double* pose0, const double* d, double* t);
    // Whether every element of body b has a hull (built now if not yet asked).
    bool body_hulls(int64_t b) {
        int8_t& state = w_.body_hull_state[b];
        if (state < 0) {
            bool all = m_.elements(b) > 0;
            for (int64_t e = m_.elem_start[b]; all && e < m_.elem_end[b]; ++e) {
                if (w_.hull_state[e] < 0) w_.hull_state[e] = element_hull(m_, e, w_.hulls[e]);
                all = w_.hull_state[e] == 1;
            }
            state = all ? 1 : 0;
        }
        return state == 1;
    }

    void evaluate(const double* q);
    void link_pose(int64_t i);
    void pair_pose(int64_t a, int64_t b, double* pose);
    bool sides(int64_t p);
    void margin(int64_t p, double h2);
    WithinResult pair_within(int64_t p, const double* pose, double m, double h, double crude,
                             double extra = 0.0);
    // The crude rate (crude_rate) where the path has one, else 0.
    double crude_or_none(const SplinePath&, int64_t) { return 0.0; }
    template <class Path>
    double crude_or_none(const Path&, int64_t p) { return crude_rate(p); }
    double solid_gap(int64_t a, int64_t b, const double* pose) const;
    bool crude_apart(const SplinePath&, int64_t, const double*, double, double*) {
        return false;
    }
    bool crude_apart(const PolylinePath&, int64_t p, const double* pose, double h,
                     double* reach) {
        return crude_apart(p, pose, h, reach);
    }
    bool crude_apart(const StraightPath&, int64_t p, const double* pose, double h,
                     double* reach) {
        return crude_apart(p, pose, h, reach);
    }
    bool crude_apart(int64_t p, const double* pose, double h, double* reach);
    double crude_rate(int64_t p);
    double sphere_gap(int64_t p, const double* pose) const;
    bool waypoint_leap(const StraightPath&, MotionWork::March&) { return false; }
    bool waypoint_leap(const SplinePath&, MotionWork::March&) { return false; }
    bool waypoint_leap(const PolylinePath& path, MotionWork::March& s);
    void path_speeds(const StraightPath&, double, double) {}  // constant (straight_speeds)
    void path_speeds(const SplinePath& path, double t, double h2);
    void path_speeds(const PolylinePath& path, double t, double h2);
    template <class Path>
    int march_step(MotionWork::March& s, const Path& path, double t_end);

    // Along a polyline, pair p's measure: U(t) = sum_j rate_j var_j(t), var_j(t) variable
    // j's variation along the path up to t (MotionWork::poly_cum, linear within a segment)
    // and rate_j its reach rows (the crude bound's), so that between parameters u < v the
    // pair's bodies move relative to each other by at most U(v) - U(u). measure_pair readies
    // p's (false: it bounds nothing, a floating joint's INF rows); measure_guard is the
    // rounding of its prefix sums, to take off any gap it is compared with.
    bool measure_pair(int64_t p);
    double measure_at(int64_t k) const;  // at waypoint k
    double measure(double t) const;
    double measure_guard() const;

    const PolylinePath* poly_ = nullptr;  // the polyline at hand (polyline_speeds)
    MotionContext& c_;
    const Model& m_;
    MotionWork& w_;
    int64_t* counters_;
};

// Small functions of every march step, inline here for the templates in motion.cpp.
inline double MotionQuery::measure_at(int64_t k) const {
    const int64_t J = m_.n_joints;
    const double* c = w_.poly_cum.data() + J * k;
    const double* rates = w_.pair_rates.data();
    double u = 0.0;
    for (int64_t j = 0; j < J; ++j) u += rates[j] * c[j];
    return u;
}

inline double MotionQuery::measure(double t) const {
    const int64_t k = poly_->segment_of(t);
    const int64_t J = m_.n_joints;
    const double* v = poly_->var + J * k;
    const double* rates = w_.pair_rates.data();
    double du = 0.0;
    for (int64_t j = 0; j < J; ++j) du += rates[j] * v[j];
    const double x = std::min(std::max(t - double(k), 0.0), 1.0);
    return measure_at(k) + x * du;
}

inline double MotionQuery::measure_guard() const {
    // At most a few ulps of the total per term summed.
    return 4.0 * double(poly_->segments + m_.n_joints) * DBL_EPSILON *
           measure_at(poly_->segments);
}

// The cheapest proof first, before the pair's joints are even looked at: the planning's
// configuration-free bound of how far each variable moves the pair (model.hpp: reach,
// reach_ext, E at most its largest along the path), against the gap of the spheres around
// the two bodies. Pairs far apart pass whole motions so. INF reach rows (a floating joint's
// quaternion) prove nothing here.
inline double MotionQuery::crude_rate(int64_t p) {
    double& rate = w_.crude[p];
    if (rate < 0.0) {
        double sum = 0.0;
        for (int64_t j = 0; j < m_.n_joints; ++j)
            if (w_.var[j] > 0.0) sum += w_.var[j] * variable_reach(m_, p, j, w_.extension_max);
        rate = sum * (1.0 + MOTION_BOUND_REL);
    }
    return rate;
}

// The gap between the spheres around pair p's two bodies (body b at pose in body a).
inline double MotionQuery::sphere_gap(int64_t p, const double* pose) const {
    const double* A = m_.body_box(m_.pair_a[p]);
    const double* B = m_.body_box(m_.pair_b[p]);
    double d[3];
    centre_offset(A, B, pose, d);
    return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) -
           (A[BOX_RADIUS] + B[BOX_RADIUS]) * (1.0 + SPHERE_EPS_REL);
}

// Body b's pose in body a's frame at the evaluated state (a is a link; b a link, or a world
// object, which no joint moves: its pose is the carried state's).
inline void MotionQuery::pair_pose(int64_t a, int64_t b, double* pose) {
    link_pose(a);
    const double* Tb = c_.view.state.poses.T_world_body + 16 * b;
    if (!m_.is_world_object(b)) {
        link_pose(b);
        Tb = w_.T.data() + 16 * b;
    }
    relative_pose(w_.T.data() + 16 * a, Tb, pose);
}

inline bool MotionQuery::crude_apart(int64_t p, const double* pose, double h, double* reach) {
    const double rate = crude_rate(p);
    if (!(rate < INF)) return false;
    const double gap = sphere_gap(p, pose);
    if (!(gap > rate * h)) return false;
    *reach = rate > 0.0 ? gap / rate : INF;
    return true;
}

// Pair p's padded distance with body b at pose in body a, less the rounding allowed for a
// clearance (poses.hpp: clearance_margin), when below cap; else cap less that. The search
// stops once the distance is known to be at most floor.
double distance_at(MotionContext& c, int64_t p, const double* pose, double floor, double cap);

}  // namespace motion_detail
}  // namespace collision_sensor
