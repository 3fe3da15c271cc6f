// The query engine's entry points (engine.hpp).
#include "engine.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "planning.hpp"
#include "poses.hpp"
#include "recheck.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

namespace {

const Options& checked(const Options& o) {
    if (o.box_test != BOX_TEST_PAPER && o.box_test != BOX_TEST_SAT)
        throw std::invalid_argument("box_test: " + std::to_string(o.box_test) +
                                    " is not BOX_TEST_PAPER or BOX_TEST_SAT");
    if (o.expansion < EXPAND_SAME || o.expansion > EXPAND_WIDER)
        throw std::invalid_argument("expansion: " + std::to_string(o.expansion) +
                                    " is not one of EXPAND_*");
    if (!(o.motion_tolerance >= 0.0 && std::isfinite(o.motion_tolerance)))
        throw std::invalid_argument("motion_tolerance: not a finite number >= 0");
    if (o.threads < 0 || o.threads > MAX_THREADS)
        throw std::invalid_argument("threads: " + std::to_string(o.threads) +
                                    " is not 0 (every core) or a count from 1 to " +
                                    std::to_string(MAX_THREADS));
    if (!(o.min_chunk_us >= 0.0 && std::isfinite(o.min_chunk_us)))
        throw std::invalid_argument("min_chunk_us: not a finite number >= 0");
    return o;
}

Options resolved(const Options& o) {
    Options out = checked(o);
    out.threads = resolve_threads(o.threads);
    return out;
}

// Bring the context's statuses up to date with q (usable): Engine::query's answer (its
// status_version left to the engine). With moving_only (a full check of a batch's row), only
// the model's moving pairs are re-checked: the static pairs' statuses must already be those
// of a full check in this scene.
QueryResult run_query(CheckContext& c, const double* q, bool full, bool moving_only = false) {
    const Model& m = c.model;
    State& s = c.state;
    full = full || s.flags[QUERY_CHECKED_ONCE] == 0;
    bool any_moved = full;
    const double tolerance = c.options.motion_tolerance;
    for (int64_t j = 0; j < m.n_joints; ++j) {
        s.q_last[j] = q[j];
        if (std::fabs(q[j] - s.q_ref[j]) > tolerance) any_moved = true;
    }
    const bool forced = s.forced_mode != FORCED_NONE;
    QueryResult answer;
    if (!any_moved && !forced) return answer;
    s.flags[QUERY_CHECKED_ONCE] = 1;
    int64_t n;
    const int64_t* full_list = nullptr;
    if (full) {
        plan_full(c, s.q_last);
        n = m.n_pairs;
        if (moving_only) {
            full_list = m.moving_pairs.data();
            n = int64_t(m.moving_pairs.size());
        }
        if (forced) clear_forced(s, m.n_pairs);  // every pair is re-checked from scratch
    } else {
        n = any_moved ? plan_update(c, s.q_last) : 0;
        if (forced) n = add_forced(c, n);
        if (n == 0) return answer;
    }
    answer.rechecked = recheck_pairs(c, n, full, &answer.changed, full_list);
    return answer;
}

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Rows [begin, end) of a batch in context c, their answers out; the first row a full check
// when first_full. Full rows re-check only the moving pairs (the static ones hold the
// batch's answer for them: static_statuses).
void run_rows(CheckContext& c, const double* Q, int64_t begin, int64_t end, bool full,
              bool first_full, const BatchRows& rows) {
    const int64_t J = c.model.n_joints, P = c.model.n_pairs;
    for (int64_t i = begin; i < end; ++i) {
        const QueryResult answer =
            run_query(c, Q + J * i, full || (first_full && i == begin), full);
        rows.rechecked[i] = answer.rechecked;
        rows.changed[i] = uint8_t(answer.changed);
        for (int64_t p = 0; p < P; ++p) rows.statuses[P * i + p] = uint8_t(c.state.status[p]);
    }
}

// Row i's changed flag (i >= 1) as one thread sets it: against the row before (its block or
// chunk started from another state).
void restate_changed_at(int64_t i, int64_t P, const BatchRows& rows) {
    rows.changed[i] =
        uint8_t(std::memcmp(rows.statuses + P * i, rows.statuses + P * (i - 1), P) != 0);
}

// The changed flag of the first row of chunks 1 .. k - 1 as one thread sets it.
void restate_changed(int64_t n, int64_t k, int64_t P, const BatchRows& rows) {
    for (int64_t c = 1; c < k; ++c) restate_changed_at(chunk_of(c, k, n).begin, P, rows);
}

// A full batch's rows go to the threads in blocks of about n / (threads x
// FULL_BLOCKS_PER_THREAD) rows, at least FULL_BLOCK_MIN.
constexpr int64_t FULL_BLOCKS_PER_THREAD = 8;
constexpr int64_t FULL_BLOCK_MIN = 16;

}  // namespace

bool is_rigid_transform(const double* T) {
    for (int k = 0; k < 12; ++k)
        if (!std::isfinite(T[k])) return false;
    const double x = T[3], y = T[7], z = T[11];
    if (std::max({std::fabs(x), std::fabs(y), std::fabs(z)}) > MAX_COORDINATE ||
        T[12] != 0.0 || T[13] != 0.0 || T[14] != 0.0 || T[15] != 1.0)
        return false;
    const double r00 = T[0], r01 = T[1], r02 = T[2], r10 = T[4], r11 = T[5], r12 = T[6],
                 r20 = T[8], r21 = T[9], r22 = T[10];
    const double error = std::max({std::fabs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0),
                                   std::fabs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
                                   std::fabs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0),
                                   std::fabs(r00 * r01 + r10 * r11 + r20 * r21),
                                   std::fabs(r00 * r02 + r10 * r12 + r20 * r22),
                                   std::fabs(r01 * r02 + r11 * r12 + r21 * r22)});
    const double det = r00 * (r11 * r22 - r12 * r21) - r01 * (r10 * r22 - r12 * r20) +
                       r02 * (r10 * r21 - r11 * r20);
    return error <= ROTATION_TOLERANCE && det >= 0.0;
}

Engine::Engine(double* F, int64_t f_size, const int64_t* f_layout, int64_t* I, int64_t i_size,
               const int64_t* i_layout, const Options& options)
    : layout_(resolve_layout(F, f_size, f_layout, I, i_size, i_layout)),
      options_(resolved(options)),
      model_(make_model(layout_)),
      state_(make_state(layout_, model_)),
      scratch_(model_, state_.fronts.capacity, layout_.i[slot::counters],
               layout_.i[slot::scene_culled], layout_.i[slot::nearest]) {}

// Force pair p: the next query re-checks it whatever the joints did (listed, when every
// forced pair so far is).
void Engine::force(int64_t p) {
    if (state_.forced_mode != FORCED_SCAN && !state_.forced[p]) state_.forced_list.push_back(p);
    state_.forced[p] = 1;
    if (state_.forced_mode == FORCED_NONE) state_.forced_mode = FORCED_LISTED;
}

bool Engine::move_world_body(int64_t b, const double* T) {
    if (!model_.is_world_object(b) || b >= model_.n_bodies || !is_rigid_transform(T))
        return false;
    std::memcpy(state_.poses.T_world_body + 16 * b, T, 16 * sizeof(double));
    for (int64_t k = model_.body_pairs_start[b]; k < model_.body_pairs_start[b + 1]; ++k)
        force(model_.body_pairs[k]);
    return true;
}

bool Engine::place_attached_body(int64_t b, const double* T, const int64_t* pairs,
                                    int64_t n, const double* reach_rows,
                                    const double* reach_ext_rows) {
    const Model& m = model_;
    if (b < 1 || b >= m.n_links || m.kin.joint_type[b] != JOINT_FIXED || !is_rigid_transform(T))
        return false;
    for (int64_t i = b + 1; i < m.n_links; ++i)   // a leaf: no pose below it to refresh
        if (m.kin.parent[i] == b) return false;
    const int64_t J = m.n_joints;
    for (int64_t k = 0; k < n; ++k) {
        const int64_t p = pairs[k];
        if (p < 0 || p >= m.n_pairs || (m.pair_a[p] != b && m.pair_b[p] != b))
            return false;
        for (int64_t j = 0; j < J; ++j)
            if (!(reach_rows[J * k + j] >= 0.0 && std::isfinite(reach_rows[J * k + j]) &&
                  reach_ext_rows[J * k + j] >= 0.0 && std::isfinite(reach_ext_rows[J * k + j])))
                return false;
    }
    std::memcpy(layout_.f[slot::T_parent_joint] + 16 * b, T, 16 * sizeof(double));
    state_.poses.stale[b] = 1;
    for (int64_t k = 0; k < n; ++k) {
        const int64_t p = pairs[k];
        std::copy(reach_rows + J * k, reach_rows + J * (k + 1), layout_.f[slot::reach] + J * p);
        std::copy(reach_ext_rows + J * k, reach_ext_rows + J * (k + 1),
                  layout_.f[slot::reach_ext] + J * p);
        force(p);
    }
    return true;
}

// Body b shows its cloud's current grid: Model::clouds, its body box (culling reads it), its
// pairs forced with no witness (a voxel index is the grid's own).
void Engine::show_cloud(int64_t b) {
    const VoxelGrid& grid = clouds_[b]->current();
    model_.clouds[b] = &grid;
    double* row = layout_.f[slot::body_boxes] + BOX_WIDTH * b;
    const double zero[3] = {0.0, 0.0, 0.0};
    if (grid.empty())
        aligned_box_row(zero, zero, row);
    else
        std::copy(grid.box(0), grid.box(0) + BOX_WIDTH, row);
    model_.body_reach[b] = std::sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2]) +
                           row[BOX_RADIUS];
    for (int64_t k = model_.body_pairs_start[b]; k < model_.body_pairs_start[b + 1]; ++k) {
        const int64_t p = model_.body_pairs[k];
        state_.witness[2 * p] = state_.witness[2 * p + 1] = -1;
        scratch_.nearest[2 * p] = scratch_.nearest[2 * p + 1] = -1;
        force(p);
    }
}

bool Engine::attach_cloud(int64_t b, std::shared_ptr<VoxelCloud> cloud) {
    if (!cloud || !model_.is_world_object(b) || b >= model_.n_bodies || model_.elements(b) != 0)
        return false;
    const double* T = state_.poses.T_world_body + 16 * b;
    for (int k = 0; k < 16; ++k)
        if (T[k] != (k % 5 == 0 ? 1.0 : 0.0)) return false;  // the world's own frame
    if (clouds_.empty()) clouds_.resize(model_.n_bodies);
    clouds_[b] = std::move(cloud);
    show_cloud(b);
    return true;
}

bool Engine::commit_cloud(int64_t b, int64_t ticket) {
    if (b < 0 || b >= int64_t(clouds_.size()) || !clouds_[b] || !clouds_[b]->swap(ticket))
        return false;
    show_cloud(b);
    return true;
}

void Engine::name_pairs(std::vector<PairName> names) {
    if (int64_t(names.size()) != model_.n_pairs)
        throw std::invalid_argument("names: " + std::to_string(names.size()) + " for " +
                                    std::to_string(model_.n_pairs) + " checked pairs");
    pair_names_ = std::move(names);
}

QueryResult Engine::query(const double* q, bool full) {
    const int64_t bad = unusable_variable(model_.kin, q, model_.n_joints);
    if (bad >= 0) {
        QueryResult refused;
        refused.bad_variable = bad;
        refused.status_version = status_version_;
        return refused;
    }
    return run(q, full);
}

QueryResult Engine::run(const double* q, bool full, MotionRecord* record) {
    CheckContext c = {model_, state_, scratch_, options_, record, true};
    QueryResult answer = run_query(c, q, full);
    status_version_ += answer.changed;
    answer.status_version = status_version_;
    return answer;
}

QueryResult Engine::proximity(const double* q, const ProximityRequest& request,
                              const ProximityResult& result) {
    return read_at(q, [&](const EngineView& view, Scratch& scratch) {
        measure_proximity(view, request, scratch, result);
    });
}

bool Engine::static_statuses(const double* q) {
    static_status_.assign(model_.n_pairs, 0);
    if (model_.static_pairs.empty()) return false;
    Worker& worker = *workers_[0];
    worker.state.copy_from(state_, model_, false);
    State& s = worker.state.state();
    CheckContext c = {model_, s, worker.scratch, options_, nullptr};
    plan_full(c, q);
    bool changed = false;
    recheck_pairs(c, int64_t(model_.static_pairs.size()), true, &changed,
                  model_.static_pairs.data());
    bool differs = false;
    for (const int64_t p : model_.static_pairs) {
        static_status_[p] = uint8_t(s.status[p] != 0);
        differs |= (state_.status[p] != 0) != (s.status[p] != 0);
    }
    return differs;
}

void Engine::ready_workers(int64_t k) {
    while (int64_t(workers_.size()) < k)
        workers_.push_back(std::make_unique<Worker>(model_, state_.fronts));
}

void Engine::gather_counters(int64_t k) {
    for (int64_t w = 0; w < k; ++w) {
        int64_t* counters = workers_[w]->scratch.counters;
        for (int i = 0; i < N_COUNTERS; ++i) {
            scratch_.counters[i] += counters[i];
            counters[i] = 0;
        }
    }
}

BadValue Engine::first_bad_row(const KinematicTree& kin, const double* Q, int64_t n,
                               int64_t J) {
    BadValue bad;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t j = unusable_variable(kin, Q + J * i, J);
        if (j >= 0) {
            bad.row = i;
            bad.variable = j;
            break;
        }
    }
    return bad;
}

BatchResult Engine::batch(const double* Q, int64_t n, bool full, const BatchRows& rows) {
    const int64_t J = model_.n_joints, P = model_.n_pairs;
    BatchResult result;
    // All rows first: a bad row changes nothing.
    result.bad = first_bad_row(model_.kin, Q, n, J);
    if (result.refused() || n == 0) return result;
    result.rows = n;
    if (full) {
        // Each row a full check, whose answer is its own: in the workers' copies of the
        // carried state (a full check reads of it only the scene's poses). The static pairs
        // are checked once, for every row; the rows re-check the moving ones.
        const int64_t k = chunks(BATCH_FULL, n);
        ready_workers(k);
        const bool static_changed = static_statuses(Q);
        // Rows cost unequal time (a row in contact descends further), so the threads take
        // blocks of rows in turn until none is left, rather than one half each: a thread that
        // finishes early takes the next block. The answers and the work are the same however
        // the blocks fall, every row being a full check of its own.
        const int64_t block = k == 1 ? n : std::max(FULL_BLOCK_MIN, n / (k * FULL_BLOCKS_PER_THREAD));
        const int64_t n_blocks = (n + block - 1) / block;
        std::atomic<int64_t> next{0};
        double first_seconds = 0.0;
        int64_t first_rows = 0;
        run_chunks(k, [&](int64_t w) {
            const Clock::time_point start = Clock::now();
            Worker& worker = *workers_[w];
            worker.state.copy_from(state_, model_, false);
            State& s = worker.state.state();
            for (const int64_t p : model_.static_pairs) s.status[p] = static_status_[p];
            CheckContext c = {model_, s, worker.scratch, options_, nullptr};
            int64_t done = 0;
            for (int64_t b = next.fetch_add(1); b < n_blocks; b = next.fetch_add(1)) {
                const int64_t begin = b * block, end = std::min(n, begin + block);
                run_rows(c, Q, begin, end, true, false, rows);
                done += end - begin;
            }
            if (w == 0) first_seconds = seconds_since(start), first_rows = done;
        });
        // Row 0 was the first of whichever thread took it, against the carried statuses (the
        // static ones apart); every other block's first row is set against the row before.
        if (static_changed) rows.changed[0] = 1;
        for (int64_t b = 1; b < n_blocks; ++b) restate_changed_at(b * block, P, rows);
        if (first_rows > 0) planner_.learn(BATCH_FULL, first_rows, first_seconds);
        gather_counters(k);
        return result;
    }
    const int64_t k = options_.motion_tolerance > 0.0 ? 1 : chunks(BATCH_UPDATE, n);
    if (k <= 1) {
        const Clock::time_point start = Clock::now();
        CheckContext c = {model_, state_, scratch_, options_, nullptr};
        run_rows(c, Q, 0, n, false, false, rows);
        planner_.learn(BATCH_UPDATE, n, seconds_since(start));
    } else {
        update_batch(Q, n, k, rows);
    }
    // The carried statuses are the last row's: changed when any row changed them.
    for (int64_t i = 0; i < n; ++i) {
        if (rows.changed[i]) {
            ++status_version_;
            break;
        }
    }
    return result;
}

// With motion_tolerance 0 a row's statuses are those of a full check at the row (the
// incremental check's contract), whatever state it starts from: chunks can start afresh.
void Engine::update_batch(const double* Q, int64_t n, int64_t k, const BatchRows& rows) {
    const int64_t P = model_.n_pairs;
    ready_workers(k - 1);
    // Copied before any chunk runs: the last one runs in the engine's own state.
    for (int64_t w = 0; w + 1 < k; ++w) workers_[w]->state.copy_from(state_, model_, w == 0);
    double first_seconds = 0.0;
    run_chunks(k, [&](int64_t w) {
        const Clock::time_point start = Clock::now();
        const Chunk chunk = chunk_of(w, k, n);
        if (w == k - 1) {
            CheckContext c = {model_, state_, scratch_, options_, nullptr};
            run_rows(c, Q, chunk.begin, chunk.end, false, true, rows);
            return;
        }
        Worker& worker = *workers_[w];
        CheckContext c = {model_, worker.state.state(), worker.scratch, options_, nullptr};
        run_rows(c, Q, chunk.begin, chunk.end, false, w > 0, rows);
        if (w == 0) first_seconds = seconds_since(start);
    });
    planner_.learn(BATCH_UPDATE, chunk_of(0, k, n).end, first_seconds);
    gather_counters(k - 1);
    restate_changed(n, k, P, rows);
}

void Engine::refresh_all_poses() {
    collision_sensor::refresh_all_poses(model_, state_.q_ref, state_.poses);
}

}  // namespace collision_sensor
