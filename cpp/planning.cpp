// Re-check planning: which pairs a query re-checks (planning.hpp).
#include "planning.hpp"

#include <algorithm>
#include <cmath>

#include "inlining.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

namespace {

// E: the sum of |value| of the prismatic joints at q_ref.
double extension(const Model& m, const double* q_ref) {
    const KinematicTree& kin = m.kin;
    double e = 0.0;
    for (int64_t i = 0; i < m.n_links; ++i)
        if (kin.joint_type[i] == JOINT_PRISMATIC)
            e += std::fabs(kin.multiplier[i] * q_ref[kin.q_index[i]] + kin.offset[i]);
    return e;
}

// Pair p's two travel sums from scratch: over variables j, |q_ref[j] - q_eval[p, j]| times
// reach[p, j] and times reach_ext[p, j] (both 0 off the pair's path).
void resync_travel(const Model& m, State& s, int64_t p) {
    const int64_t J = m.n_joints;
    double fixed = 0.0, ext = 0.0;
    const double* e = s.q_eval + J * p;
    const double* r = m.reach + J * p;
    const double* rx = m.reach_ext + J * p;
    for (int64_t j = 0; j < J; ++j) {
        const double d = std::fabs(s.q_ref[j] - e[j]);
        fixed += d * r[j];
        ext += d * rx[j];
    }
    s.travel[2 * p] = fixed;
    s.travel[2 * p + 1] = ext;
}

// Move pair p's travel sums by variable j's terms going from old_value to new_value.
CS_ALWAYS_INLINE void add_travel(const Model& m, State& s, int64_t p, int64_t j,
                                 double old_value, double new_value) {
    const int64_t J = m.n_joints;
    const double e = s.q_eval[J * p + j];
    const double d = std::fabs(new_value - e) - std::fabs(old_value - e);
    s.travel[2 * p] += d * m.reach[J * p + j];
    s.travel[2 * p + 1] += d * m.reach_ext[J * p + j];
}

// False iff pair p is known to be still apart: its travel is below its clearance. Every
// comparison is written so that a NaN (an infinite joint motion times a zero reach, an
// infinite extension times a zero sum) means "re-check": a NaN must never prove a pair apart.
CS_ALWAYS_INLINE bool needs_recheck(const Model& m, State& s, int64_t p, double extension) {
    if (s.status[p] != 0 || !(s.clearance[p] > 0.0)) return true;
    const double c = s.clearance[p];
    if (s.travel[2 * p] + extension * s.travel[2 * p + 1] < TRAVEL_GUARD * c) {
        // A sum can only be trusted while each of its terms is: one huge joint motion added
        // and later taken away again leaves the rounding of the huge value behind (it
        // absorbed the small terms), so a sum that went past the clearance is recomputed.
        return false;
    }
    resync_travel(m, s, p);  // exact near the edge
    return !(s.travel[2 * p] + extension * s.travel[2 * p + 1] < c);
}

// Pair p's gap at the last state from its travel sums there (r.prev_sums; E there:
// extension) and its status and clearance, which planning leaves as they were: its clearance
// less its travel since, which bounds its distance from below; 0 when it has no clearance
// (known apart, by how much unknown), -INF in contact.
CS_ALWAYS_INLINE void record_gap(const State& s, MotionRecord& r, int64_t p, double extension) {
    double gap = 0.0;
    if (s.status[p] != 0) {
        gap = -INF;
    } else if (s.clearance[p] > 0.0) {
        // The running sums' rounding is a few ulps of the clearance (see above).
        const double travel = r.prev_sums[2 * p] + extension * r.prev_sums[2 * p + 1];
        gap = std::max(s.clearance[p] - travel - BOUND_ROUNDING_REL * s.clearance[p], 0.0);
    }
    r.prev_gap[p] = gap;
}

// True iff pair p, which needs_recheck skips at the new state (its travel below its
// clearance), is below its clearance on the whole straight segment from the last state too,
// E having changed from extension_before to extension: each of its sums is convex in q, so
// on the segment the travel is at most max(f0, f1) + max(E0, E1) max(x0, x1).
CS_ALWAYS_INLINE bool below_all_along(const State& s, const MotionRecord& r, int64_t p,
                                      double extension_before, double extension) {
    const double f = std::max(r.prev_sums[2 * p], s.travel[2 * p]);
    const double x = std::max(r.prev_sums[2 * p + 1], s.travel[2 * p + 1]);
    return f + std::max(extension_before, extension) * x < TRAVEL_GUARD * s.clearance[p];
}

}  // namespace

void plan_full(CheckContext& c, const double* q) {
    const Model& m = c.model;
    State& s = c.state;
    for (int64_t j = 0; j < m.n_joints; ++j) s.q_ref[j] = q[j];
    for (int64_t i = 0; i < m.n_links; ++i) s.poses.stale[i] = 1;
    refresh_all_poses(m, s.q_ref, s.poses);
    s.extension[0] = extension(m, s.q_ref);
}

int64_t plan_update(CheckContext& c, const double* q) {
    const Model& m = c.model;
    State& s = c.state;
    int64_t* moved = c.scratch.moved.data();
    int64_t* todo = c.scratch.todo.data();
    int64_t* pending = c.scratch.pending.data();
    const double tolerance = c.options.motion_tolerance;
    int64_t n_moved = 0;
    bool prismatic = false;
    for (int64_t j = 0; j < m.n_joints; ++j) {
        if (std::fabs(q[j] - s.q_ref[j]) > tolerance) {
            moved[n_moved++] = j;
            prismatic |= m.joint_prismatic[j] != 0;
        }
    }
    if (n_moved == 0) return 0;
    for (int64_t k = 0; k < n_moved; ++k) {
        const int64_t j = moved[k];
        for (int64_t t = m.joint_links_start[j]; t < m.joint_links_start[j + 1]; ++t)
            s.poses.stale[m.joint_links[t]] = 1;
    }
    s.flags[QUERY_CALLS] += 1;
    const bool resync = s.flags[QUERY_CALLS] >= TRAVEL_RESYNC_CALLS;
    double ext = s.extension[0];
    const double ext_before = ext;
    // update_motion: a skipped pair must be apart on the whole segment too, which a moved
    // slider (E changing) can make a stricter question than at the two ends.
    MotionRecord* record = c.record;
    const bool segment_bound = record != nullptr && prismatic;
    // update_motion: every pair's sums at the last state, before they move (one copy is
    // cheaper than one per pair as each is first seen); the gaps there only for the pairs
    // re-checked (the rest are apart all along, below_all_along), at the end.
    if (record) std::copy(s.travel, s.travel + 2 * m.n_pairs, record->prev_sums);
    int64_t n = 0;
    if (n_moved == 1 && !resync) {
        const int64_t j = moved[0];
        const double old_value = s.q_ref[j];
        const double new_value = s.q_ref[j] = q[j];
        if (prismatic) s.extension[0] = ext = extension(m, s.q_ref);
        for (int64_t t = m.joint_pairs_start[j]; t < m.joint_pairs_start[j + 1]; ++t) {
            const int64_t p = m.joint_pairs[t];
            if (s.clearance[p] > 0.0) add_travel(m, s, p, j, old_value, new_value);
            if (needs_recheck(m, s, p, ext) ||
                (segment_bound && !below_all_along(s, *record, p, ext_before, ext))) {
                if (record) record_gap(s, *record, p, ext_before);
                todo[n++] = p;
            }
        }
        return n;
    }
    for (int64_t k = 0; k < n_moved; ++k) {
        const int64_t j = moved[k];
        const double old_value = s.q_ref[j];
        const double new_value = s.q_ref[j] = q[j];
        for (int64_t t = m.joint_pairs_start[j]; t < m.joint_pairs_start[j + 1]; ++t) {
            const int64_t p = m.joint_pairs[t];
            if (!pending[p]) {
                pending[p] = 1;
                todo[n++] = p;
            }
            if (s.clearance[p] > 0.0 && !resync) add_travel(m, s, p, j, old_value, new_value);
        }
    }
    if (prismatic) s.extension[0] = ext = extension(m, s.q_ref);
    if (resync) {
        s.flags[QUERY_CALLS] = 0;
        for (int64_t p = 0; p < m.n_pairs; ++p)
            if (s.clearance[p] > 0.0) resync_travel(m, s, p);
    }
    int64_t kept = 0;
    for (int64_t t = 0; t < n; ++t) {
        const int64_t p = todo[t];
        pending[p] = 0;
        if (needs_recheck(m, s, p, ext) ||
            (segment_bound && !below_all_along(s, *record, p, ext_before, ext))) {
            if (record) record_gap(s, *record, p, ext_before);
            todo[kept++] = p;
        }
    }
    return kept;
}

// pending is all zero on entry and on return (plan_update's contract). With forced_mode
// FORCED_LISTED every forced pair is in forced_list: only those are visited.
int64_t add_forced(CheckContext& c, int64_t n) {
    const Model& m = c.model;
    State& s = c.state;
    int64_t* todo = c.scratch.todo.data();
    int64_t* pending = c.scratch.pending.data();
    for (int64_t t = 0; t < n; ++t) pending[todo[t]] = 1;
    const bool listed = s.forced_mode == FORCED_LISTED;
    const int64_t count = listed ? int64_t(s.forced_list.size()) : m.n_pairs;
    for (int64_t k = 0; k < count; ++k) {
        const int64_t p = listed ? s.forced_list[k] : k;
        if (!s.forced[p]) continue;
        s.forced[p] = 0;
        s.fronts.state[2 * p] = 0;
        if (c.record) c.record->prev_gap[p] = -INF;  // no gap known in the new scene
        if (!pending[p]) {
            pending[p] = 1;
            todo[n++] = p;
        }
    }
    for (int64_t t = 0; t < n; ++t) pending[todo[t]] = 0;
    s.forced_list.clear();
    s.forced_mode = FORCED_NONE;
    return n;
}

void clear_forced(State& s, int64_t n_pairs) {
    for (int64_t p = 0; p < n_pairs; ++p) s.forced[p] = 0;
    s.forced_list.clear();
    s.forced_mode = FORCED_NONE;
}

void account_travel(CheckContext& c, int64_t p) {
    const Model& m = c.model;
    State& s = c.state;
    resync_travel(m, s, p);
    Fronts& fronts = s.fronts;
    if (fronts.state[2 * p] == 0) fronts.travel[p] = 0.0;
    fronts.travel[p] += s.travel[2 * p] + s.extension[0] * s.travel[2 * p + 1];
    for (int64_t j = 0; j < m.n_joints; ++j) s.q_eval[m.n_joints * p + j] = s.q_ref[j];
}

}  // namespace collision_sensor
