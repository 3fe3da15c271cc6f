// The engine's motion checks (engine.hpp: motion, update_motion, path, spline), each on the
// motion queries of motion.hpp, and the segments of a spline on the engine's threads.
#include "engine.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <vector>

#include "kinematics.hpp"
#include "motion.hpp"
#include "workers.hpp"

namespace collision_sensor {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

void Engine::clear(MotionResult& result) const {
    result.contact = false;
    result.t = 0.0;
    result.segment = -1;
    result.bad = BadValue();
    result.pairs.assign(model_.n_pairs, 0);
}

void Engine::motion(const double* q0, const double* q1, MotionResult& result) {
    const int64_t J = model_.n_joints;
    clear(result);
    const int64_t bad0 = unusable_variable(model_.kin, q0, J);
    const int64_t bad1 = bad0 >= 0 ? -1 : unusable_variable(model_.kin, q1, J);
    if (bad0 >= 0 || bad1 >= 0) {
        result.bad.row = bad0 >= 0 ? 0 : 1;
        result.bad.variable = bad0 >= 0 ? bad0 : bad1;
        return;
    }
    MotionContext c = motion_context();
    result.contact = check_straight_motion(c, q0, q1, nullptr, model_.n_pairs, &result.t,
                                           result.pairs.data()) != 0;
}

// The motion from the last state q0 to q, on the incremental query:
//   - a pair in contact at q0: the motion starts in contact (t = 0);
//   - a pair the query does not re-check is apart along the whole straight motion: no joint on
//     its path moved (its pose is the same all along), or its travel bound is below its
//     clearance at both ends, and that bound, sum_j |q_j - q_eval_j| reach[p, j] (+ E ...), is
//     convex in q: below the clearance on the whole segment (planning.cpp checks the segment
//     when a slider moved E);
//   - a pair it re-checks and finds apart with clearance c1, whose gap at q0 was c0
//     (planning.cpp: record_gap), is apart all along when c0 + c1 exceeds the step's bound r
//     (the distance at t is at least max(c0 - t r, c1 - (1 - t) r)), or when c0 and its
//     distance at q, measured (MOTION_MEASURE_AHEAD), do; that distance becomes its clearance;
//   - every other pair marches along the step (check_step_motion).
void Engine::update_motion(const double* q, StepResult& result) {
    const Model& m = model_;
    MotionResult& motion = result.motion;
    clear(motion);
    const int64_t bad = unusable_variable(m.kin, q, m.n_joints);
    if (bad >= 0) {
        motion.bad.row = 0;
        motion.bad.variable = bad;
        result.query = QueryResult();
        result.query.bad_variable = bad;
        result.query.status_version = status_version_;
        return;
    }
    if (state_.flags[QUERY_CHECKED_ONCE] && state_.forced_mode != FORCED_NONE) {
        // A scene change since the last state forced pairs whose statuses are the old scene's:
        // the last state is checked again first (only the forced pairs are re-checked), so
        // that the motion starts from that state as the scene is now.
        motion_work_.size_for(m);
        std::vector<double>& q0 = motion_work_.q_prev;
        std::copy(state_.q_last, state_.q_last + m.n_joints, q0.begin());
        run(q0.data(), false);
    }
    bool contact = false;
    for (int64_t p = 0; p < m.n_pairs && !contact; ++p) contact = state_.status[p] != 0;
    uint8_t* pairs = motion.pairs.data();
    if (!state_.flags[QUERY_CHECKED_ONCE] || contact) {
        // In contact at the start (t = 0: the start's pairs), or no state before (the motion
        // is the instant q: its pairs).
        if (contact)
            for (int64_t p = 0; p < m.n_pairs; ++p) pairs[p] = uint8_t(state_.status[p]);
        result.query = run(q, false);
        if (!contact) {
            for (int64_t p = 0; p < m.n_pairs; ++p) {
                pairs[p] = uint8_t(state_.status[p]);
                contact |= state_.status[p] != 0;
            }
        }
        motion.contact = contact;
        return;
    }
    motion_work_.size_for(m);
    std::vector<double>& q0 = motion_work_.q_prev;
    std::copy(state_.q_last, state_.q_last + m.n_joints, q0.begin());
    const double extension_before = state_.extension[0];
    MotionRecord record = motion_work_.record();
    result.query = run(q, false, &record);
    MotionContext c = motion_context();
    motion.contact = check_step_motion(c, q0.data(), q, scratch_.todo.data(),
                                       result.query.rechecked, extension_before, &motion.t,
                                       pairs) != 0;
    // The distances it measured at q are clearances there, where each pair's travel now
    // starts from (the query re-checked it at q: planning.cpp, account_travel).
    for (size_t k = 0; k < motion_work_.measured.size(); ++k) {
        const int64_t p = motion_work_.measured[k];
        if (motion_work_.measured_gap[k] > state_.clearance[p]) {
            state_.clearance[p] = motion_work_.measured_gap[k];
            state_.travel[2 * p] = state_.travel[2 * p + 1] = 0.0;
        }
    }
}

void Engine::path(const double* Q, int64_t n, MotionResult& result) {
    const int64_t J = model_.n_joints;
    clear(result);
    // All rows first: a bad row answers before any work.
    result.bad = first_bad_row(model_.kin, Q, n, J);
    if (result.refused() || n < 1) return;
    MotionContext c = motion_context();
    if (n == 1) {  // one waypoint: its instant
        result.contact = check_straight_motion(c, Q, Q, nullptr, model_.n_pairs, &result.t,
                                               result.pairs.data()) != 0;
        if (result.contact) result.segment = 0;
        return;
    }
    double along;  // in [0, n - 1]: segment k at [k, k + 1]
    if (!check_polyline_motion(c, Q, n, &along, result.pairs.data())) return;
    const int64_t k = along > 0.0 ? std::min(int64_t(std::ceil(along)) - 1, n - 2) : 0;
    result.contact = true;
    result.segment = k;
    result.t = std::min(std::max(along - double(k), 0.0), 1.0);
}

void Engine::spline(const double* coef, int64_t n, MotionResult& result) {
    const Model& m = model_;
    const int64_t J = m.n_joints;
    clear(result);
    motion_work_.size_for(m);
    std::vector<double>& q = motion_work_.q_prev;
    for (int64_t i = 0; i < n; ++i) {  // every segment first: a bad one answers before any work
        const double* c = coef + 6 * J * i;
        bool usable = true;
        for (int64_t k = 0; k < 6 * J && usable; ++k) usable = std::isfinite(c[k]);
        const SplinePath path{c, J};
        for (int64_t l = 0; l < m.n_links && usable; ++l) {
            const int64_t kind = m.kin.joint_type[l];
            if (kind != JOINT_PLANAR && kind != JOINT_FLOATING) continue;
            for (int64_t v = 0; v < joint_variable_count(kind); ++v)
                usable = usable && !path.moves(m.kin.q_index[l] + v);
        }
        for (double end : {0.0, 1.0}) {
            if (!usable) break;
            path.at(end, q.data());
            usable = unusable_variable(m.kin, q.data(), J) < 0;
        }
        if (!usable) {
            result.bad.row = i;
            return;
        }
    }
    first_contact(
        n,
        [coef, J](MotionContext& c, int64_t i, double* t, uint8_t* pairs) {
            return check_spline_motion(c, coef + 6 * J * i, t, pairs);
        },
        result);
}

// On one chunk: the segments in turn in the engine's own context, until one is not free.
// On k >= 2: each chunk checks its segments in turn until one is not free, or until an
// earlier chunk found one (its own answer could then only be later); the answer is the
// earliest chunk's first, which is the first segment not free, as on one thread (every chunk
// before it ran to its end).
void Engine::first_contact(int64_t n, const SegmentCheck& check, MotionResult& result) {
    const int64_t k = chunks(BATCH_SEGMENTS, n);
    const Clock::time_point start = Clock::now();
    if (k <= 1) {
        MotionContext c = motion_context();
        for (int64_t i = 0; i < n; ++i) {
            if (check(c, i, &result.t, result.pairs.data())) {
                planner_.learn(BATCH_SEGMENTS, i + 1, seconds_since(start));
                result.contact = true;
                result.segment = i;
                return;
            }
        }
        planner_.learn(BATCH_SEGMENTS, n, seconds_since(start));
        return;
    }
    ready_workers(k);
    for (int64_t w = 0; w < k; ++w) workers_[w]->motion.size_for(model_);
    std::atomic<int64_t> first(k);  // the earliest chunk that met contact so far
    int64_t first_done = 0;
    double first_seconds = 0.0;
    run_chunks(k, [&](int64_t w) {
        Worker& worker = *workers_[w];
        worker.segment = -1;
        MotionContext c = {view(), worker.scratch, worker.motion};
        const Chunk segments = chunk_of(w, k, n);
        int64_t i = segments.begin;
        for (; i < segments.end && first.load(std::memory_order_relaxed) > w; ++i) {
            if (!check(c, i, &worker.t, worker.pairs.data())) continue;
            worker.segment = i;
            int64_t known = first.load();
            while (known > w && !first.compare_exchange_weak(known, w)) {
            }
            ++i;
            break;
        }
        if (w == 0) {
            first_done = i - segments.begin;
            first_seconds = seconds_since(start);
        }
    });
    planner_.learn(BATCH_SEGMENTS, first_done, first_seconds);
    gather_counters(k);
    const int64_t w = first.load();
    if (w >= k) return;
    const Worker& worker = *workers_[w];
    result.contact = true;
    result.segment = worker.segment;
    result.t = worker.t;
    std::copy(worker.pairs.begin(), worker.pairs.end(), result.pairs.begin());
}

}  // namespace collision_sensor
