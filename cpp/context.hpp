// What a query runs in, besides the model (model.hpp): its options, the carried incremental
// state, and the work areas of one context.
//
// The three are kept apart so that a query can run in a context of its own: the model is
// read-only during a query; the state is what one incremental check leaves for the next
// (paper sec. 4.2); a Scratch is everything a query works in and forgets (its stack, lists,
// culling verdicts, counters, distance rows). A query that is not the incremental check
// (proximity.hpp; a motion check, or the rows of a batch on other threads) reads the model
// and the state through an EngineView and works in a Scratch of its own, made from the model
// alone.
#pragma once

#include <cstdint>
#include <vector>

#include "box_test.hpp"
#include "distance.hpp"
#include "layout.hpp"
#include "model.hpp"
#include "traversal.hpp"

namespace collision_sensor {

// The options a query runs with (the checker's settings), as named fields.
struct Options {
    int box_test = BOX_TEST_SAT;   // BOX_TEST_PAPER or BOX_TEST_SAT
    int expansion = EXPAND_WIDER;  // EXPAND_*
    // A joint counts as moved when it changed by more than this (rad or m) since q_ref.
    double motion_tolerance = 0.0;
    // Threads a batch's rows run on (workers.hpp); 0: the machine's hardware threads (the
    // engine resolves it when it is made), 1: the calling thread alone.
    int64_t threads = 1;
    // A batch is split only into chunks of at least this much estimated work (us;
    // workers.hpp: SplitPlanner); 0: into as many chunks as threads (or items).
    double min_chunk_us = 0.0;
};

// Body poses and whether each is behind its joints (poses.hpp): T_world_body (B, 4, 4) and
// stale (B,) (world objects are never stale).
struct Poses {
    double* T_world_body;
    int64_t* stale;
};

// The pairs' fronts (recheck.cpp: trees_of_pair): pair p's node pairs in rows [p F, p F +
// length), F = capacity. Never carried over a scene change (a new engine starts without), so
// they are the engine's own, not packed.
struct Fronts {
    int64_t capacity = 0;
    std::vector<int64_t> pairs;   // (P F, 3) node pairs (na, nb, how)
    std::vector<double> until;    // (P F,)
    // (P, 2): (its length, 0: none; the tests its last descent from the roots made).
    std::vector<int64_t> state;
    // (P,) the pair's running travel sum, which its untils are relative to.
    std::vector<double> travel;

    // Rows for n_pairs pairs, capacity each: FRONT_POOL_ROWS over the pairs, clipped.
    void size_for(int64_t n_pairs);
};

// A front's rows, per pair, and the bounds the capacity is chosen within.
constexpr int64_t FRONT_POOL_ROWS = int64_t(1) << 16;
constexpr int64_t FRONT_ROWS_MIN = 64, FRONT_ROWS_MAX = 1024;

// How the pairs to re-check whatever the joints did are known (State::forced_mode).
constexpr int FORCED_NONE = 0;    // none is
constexpr int FORCED_SCAN = 1;    // some forced[p] is set: every pair is looked at
constexpr int FORCED_LISTED = 2;  // every forced[p] set is in forced_list (move_world_body)

// The carried incremental state: the packed arrays of layout.hpp's state group, the fronts,
// and the forced pairs' listing.
struct State {
    double* q_last;       // (J,) the last call's q
    double* q_ref;        // (J,) the q the statuses describe
    double* extension;    // (1,) E at q_ref (planning.hpp)
    Poses poses;          // at q_ref, lazily (poses.hpp)
    int64_t* flags;       // (N_QUERY_FLAGS,) QUERY_*
    int64_t* status;      // (P,) 1: in contact
    int64_t* witness;     // (P, 2) the triangles that met, or -1
    int64_t* forced;      // (P,) 1: re-check at the next query whatever the joints do
    double* clearance;    // (P,) a lower bound of the pair's distance, 0: none known
    double* q_eval;       // (P, J) q_ref at the pair's last incremental re-check
    double* travel;       // (P, 2) running travel sums since q_eval (planning.hpp)
    Fronts fronts;
    int forced_mode = FORCED_NONE;
    std::vector<int64_t> forced_list;
};

// The state of a resolved layout (its fronts sized for the model's pairs, forced_mode from
// the forced array).
State make_state(const ResolvedLayout& layout, const Model& model);

// One context's work areas. The engine's own context keeps counters, scene_culled and nearest
// in the packed buffers (layout.hpp's work group: the checker reads them); another context
// (Scratch(model)) owns all of its areas.
struct Scratch {
    int64_t* counters;      // (N_COUNTERS,) COUNT_*: work done
    int64_t* scene_culled;  // (W, L) culling.hpp: 1 where world object w misses link l's subtree
    int64_t* nearest;       // (P, 2) proximity's warm start: the triangles nearest last time
    std::vector<int64_t> stack;          // (rows, PAIR_ROW) a descent's node pairs
    std::vector<int64_t> todo, pending;  // (P,) the pairs to re-check; pending all 0 between
    std::vector<int64_t> moved, chain;   // (J,) moved variables; (L,) links to pose
    std::vector<double> subtree_boxes;   // (L, BOX_WIDTH) culling.hpp
    std::vector<int64_t> front_pairs;    // (F, 3) where a front is recorded
    std::vector<double> front_until;     // (F,)
    // The proximity traversal's rows (distance.hpp: DistanceWork), sized on first use.
    std::vector<double> placed, support;
    std::vector<int64_t> placed_stamp, support_stamp;
    DistanceWork distance_rows = {nullptr, nullptr, nullptr, nullptr, 0, 0};

    // A context for the model with areas of its own; counters, scene_culled and nearest in
    // the given rows instead, when given.
    explicit Scratch(const Model& model, int64_t front_capacity = FRONT_ROWS_MAX,
                     int64_t* counters = nullptr, int64_t* scene_culled = nullptr,
                     int64_t* nearest = nullptr);
    Scratch(const Scratch&) = delete;
    Scratch& operator=(const Scratch&) = delete;

    TraversalWork traversal() { return {stack.data(), counters}; }
    // The distance rows, sized for the model's nodes on the first call.
    DistanceWork& distance_work(const Model& model);

   private:
    std::vector<int64_t> own_counters_, own_scene_culled_, own_nearest_;
};

// What an incremental check records for the motion check that follows it (motion.hpp:
// update_motion): each pair's gap at the last state, before its travel sums move (prev_gap,
// (P,); -INF: in contact, or forced by a scene change), and those sums (prev_sums, (P, 2)).
struct MotionRecord {
    double* prev_gap;
    double* prev_sums;
};

// One check's context (coal's traversal node, for a whole query): the model it reads, the
// state it carries forward, the areas it works in, the options it runs with, and (update_motion
// only) where it records the pairs' gaps at the last state.
struct CheckContext {
    const Model& model;
    State& state;
    Scratch& scratch;
    const Options& options;
    MotionRecord* record = nullptr;
    // A full check tries each pair's carried witness first (the two triangles that met at its
    // last check): tested at the current pose, they decide only how soon a colliding pair is
    // found, never its answer; its descent, if they do not meet, orders children by distance
    // as without them. Off for a batch's rows, whose work is one thread's whatever the chunks
    // (each chunk starts from a copy of the carried witnesses).
    bool witness_hints = false;
};

// What a query other than the incremental check may read of an engine: its model and its
// carried state, read-only.
struct EngineView {
    const Model& model;
    const State& state;
    const Options& options;
};

}  // namespace collision_sensor
