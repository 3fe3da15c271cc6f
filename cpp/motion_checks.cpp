// The motion checks' entry points (motion.hpp): a straight motion, a polyline, a spline
// segment and update_motion's step, each one query (motion_query.hpp) over its path.
#include "motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "motion_query.hpp"
#include "planning.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

void MotionWork::size_for(const Model& m) {
    if (sized) return;
    const int64_t J = m.n_joints, L = m.n_links, N = m.n_nodes, P = m.n_pairs;
    delta.assign(J, 0.0);
    var.assign(J, 0.0);
    quat0.assign(J, 0.0);
    q.assign(J, 0.0);
    q_prev.assign(J, 0.0);
    q_next.assign(J, 0.0);
    crude.assign(P, -1.0);
    T.assign(16 * L, 0.0);
    turn.assign(3 * L, NAN);
    stamp.assign(L, 0);
    chain.assign(L, 0);
    trans.assign(L, 0.0);
    rot.assign(L, 0.0);
    speed.assign(L, 0.0);
    accel.assign(L, 0.0);
    moving.assign(L, 0);
    depth.assign(L, 0);
    for (int64_t i = 1; i < L; ++i) depth[i] = depth[m.kin.parent[i]] + 1;
    for (int s = 0; s < 2; ++s) {
        side_link[s].assign(L, 0);
        for (auto* v : {&side_trans[s], &side_rot[s], &side_speed[s], &side_accel[s],
                        &side_above[s]})
            v->assign(L, 0.0);
        side_origin[s].assign(3 * L, 0.0);
        side_axis[s].assign(3 * L, 0.0);
        node_motion[s].assign(N, BoxMotion{});
        node_stamp[s].assign(N, 0);
    }
    heap.reserve(P);
    front.assign(P, {});
    front_until.assign(P, {});
    front_measure.assign(P, {});
    front_cost.assign(P, 0);
    marched.reserve(P);
    prev_gap.assign(P, 0.0);
    swept.reserve(P);
    swept_at.assign(P, NAN);
    swept_span.assign(P, 0.0);
    hulls.assign(m.n_elements, Hull{});
    hull_state.assign(m.n_elements, -1);
    body_hull_state.assign(m.n_bodies, -1);
    start_apart.assign(P, 0);
    prev_sums.assign(2 * P, 0.0);
    // A descent from at most MOTION_FRONT_MAX seeds (or a pair's root pairs) holds at most
    // one node pair per level of each tree on top of them.
    stack.assign(PAIR_ROW * (std::max(MOTION_FRONT_MAX, m.most_seeds) + 2 * m.depth + 2), 0);
    tag = 0;
    margin.tag = 0;
    sized = true;
}


using motion_detail::MotionQuery;
using motion_detail::distance_at;
using motion_detail::variable_reach;

int64_t check_straight_motion(MotionContext& c, const double* q0, const double* q1,
                              const int64_t* list, int64_t n, double* t, uint8_t* pairs) {
    MotionQuery query(c);
    MotionWork& w = c.work;
    StraightPath path{q0, c.view.model.motion_kind, c.view.model.n_joints, w.delta.data(),
                      w.var.data(), w.quat0.data()};
    path.prepare(q1);
    query.straight_speeds(q0);
    return query.check(list, list ? n : c.view.model.n_pairs, path, q0, t, pairs);
}

int64_t check_polyline_motion(MotionContext& c, const double* Q, int64_t n, double* t,
                              uint8_t* pairs) {
    MotionQuery query(c);
    MotionWork& w = c.work;
    const Model& m = c.view.model;
    const int64_t J = m.n_joints, S = n - 1;
    for (auto* v : {&w.poly_delta, &w.poly_var, &w.poly_quat0}) v->assign(S * J, 0.0);
    w.poly_speeds.assign(3 * S * m.n_links, 0.0);
    w.poly_T.resize(16 * (S + 1) * m.n_links);
    w.poly_posed.assign(S + 1, 0);
    w.poly_cum.assign((S + 1) * J, 0.0);
    w.pair_rates.assign(J, 0.0);
    PolylinePath path{Q, m.motion_kind, J, S, w.poly_delta.data(), w.poly_var.data(),
                      w.poly_quat0.data()};
    path.prepare();
    query.polyline_speeds(path);
    return query.check(nullptr, m.n_pairs, path, Q, t, pairs);
}

int64_t check_spline_motion(MotionContext& c, const double* coef, double* t, uint8_t* pairs) {
    MotionQuery query(c);
    const SplinePath path{coef, c.view.model.n_joints};
    path.at(0.0, c.work.q_prev.data());
    query.spline_moving(path);
    return query.check(nullptr, c.view.model.n_pairs, path, c.work.q_prev.data(), t, pairs);
}

int64_t check_step_motion(MotionContext& c, const double* q0, const double* q1,
                          const int64_t* rechecked, int64_t n, double extension_before,
                          double* t, uint8_t* pairs) {
    const Model& m = c.view.model;
    const State& s = c.view.state;
    MotionWork& w = c.work;
    w.size_for(m);
    w.measured.clear();
    w.measured_gap.clear();
    // The query's skipped pairs are apart along the straight motion in q, which is this one
    // unless a continuous joint goes the shorter way round the other way: then all march.
    for (int64_t j = 0; j < m.n_joints; ++j) {
        const double d = q1[j] - q0[j];
        if (m.motion_kind[j] == MOTION_WRAP &&
            std::fabs(std::remainder(d, 2.0 * M_PI)) != std::fabs(d))
            return check_straight_motion(c, q0, q1, nullptr, m.n_pairs, t, pairs);
    }
    if (n == 0) return 0;  // nothing re-checked: every pair is apart all along
    StraightPath path{q0, m.motion_kind, m.n_joints, w.delta.data(), w.var.data(),
                      w.quat0.data()};
    path.prepare(q1);
    const double e_max = std::max(extension_before, s.extension[0]);
    MotionQuery query(c);
    bool speeds = false;  // query.straight_speeds, for step_reach: only once one needs them
    w.marched.clear();
    const int64_t J = m.n_joints;
    // The step's bound for pair p: sum_j |dq_j| (reach[p, j] + E_max reach_ext[p, j]), how
    // far any point of either body can move relative to the other over it (in the units of
    // the pair's travel, planning.hpp).
    const auto step_bound = [&](int64_t p) {
        double r = 0.0;
        for (int64_t j = 0; j < J; ++j)
            if (w.var[j] > 0.0) r += w.var[j] * variable_reach(m, p, j, e_max);
        return r * (1.0 + MOTION_BOUND_REL);
    };
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = rechecked[i];
        if (s.status[p] == 0 && w.prev_gap[p] > -INF) {
            // Apart all along when its gaps at the two ends exceed the step's bound, the
            // planning's or the levers' at q1 (step_reach); or, its clearance at q1 being
            // the query's descent's, when its distance measured there does.
            const double gaps = w.prev_gap[p] + s.clearance[p];
            double r = step_bound(p);
            if (gaps > r) continue;
            if (!speeds) query.straight_speeds(q0);
            speeds = true;
            r = std::min(r, query.step_reach(p, q1));
            if (gaps > r) continue;
            const int64_t a = m.pair_a[p], b = m.pair_b[p];
            const double need = r - w.prev_gap[p];
            const double cap = MOTION_MEASURE_AHEAD * need;
            const bool front = s.fronts.state[2 * p] != 0;
            if (!m.is_cloud(b) && !front &&
                cap <= MOTION_MEASURE_SCALE *
                           (m.body_box(a)[BOX_RADIUS] + m.body_box(b)[BOX_RADIUS])) {
                // At q1, where the incremental query placed the bodies; a test vertex nearer
                // a solid than the triangles are counts (pair_within).
                double pose[POSE_WIDTH];
                write_pair_pose(s.poses.T_world_body, a, b, pose);
                const double d = std::min(distance_at(c, p, pose, need, cap),
                                          query.pair_solid_gap(p, pose));
                ++c.scratch.counters[COUNT_MEASURES];
                if (d > need) {
                    w.measured.push_back(p);
                    w.measured_gap.push_back(d);
                    continue;
                }
            }
        }
        w.marched.push_back(p);
    }
    if (w.marched.empty()) return 0;
    // A marched pair the carried state had apart at q0 (its gap recorded, not -INF) is not
    // checked there again, and its march starts from the node pairs where the query's descent
    // at q1 stopped (its front: they cover every pair of triangles, whatever the poses). Each
    // of them is apart at q1 by at least its until less the pair's travel (traversal.hpp:
    // front_scan), so by more than the step's bound apart all along the step: the march
    // never tests it (its proof reaches the step's end).
    const Fronts& fronts = s.fronts;
    for (const int64_t p : w.marched) {
        w.start_apart[p] = w.prev_gap[p] > -INF ? 1 : 0;
        std::vector<int64_t>& front = w.front[p];
        front.clear();
        w.front_until[p].clear();
        w.front_measure[p].clear();
        const int64_t rows = fronts.state[2 * p];
        if (!w.start_apart[p] || rows == 0 || rows > MOTION_FRONT_MAX || m.is_cloud(m.pair_b[p]))
            continue;
        const int64_t* row = fronts.pairs.data() + 3 * p * fronts.capacity;
        const double* until = fronts.until.data() + p * fronts.capacity;
        const double travel = fronts.travel[p];
        const double r = step_bound(p);
        std::vector<double>& proven = w.front_until[p];
        for (int64_t e = 0; e < rows; ++e) {
            front.push_back(row[3 * e]);
            front.push_back(row[3 * e + 1]);
            const double margin = until[e] - travel - FRONT_GUARD_REL * std::fabs(until[e]);
            proven.push_back(margin > r ? 1.0 : -INF);
        }
        w.front_cost[p] = fronts.state[2 * p + 1];
    }
    w.start_known = true;
    const int64_t hit = check_straight_motion(c, q0, q1, w.marched.data(),
                                              int64_t(w.marched.size()), t, pairs);
    w.start_known = false;
    return hit;
}

}  // namespace collision_sensor
