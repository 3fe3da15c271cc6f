// The query engine over the checker's packed buffers (paper sec. 2, 4.1, 4.2): its entry
// points.
//
// A query takes joint positions and
// 1. decides which joint variables moved and lists only the pairs whose relative pose can
//    have changed, minus those whose clearance the motion cannot have closed
//    (planning.hpp; a full check takes every pair);
// 2. re-checks the listed pairs (recheck.hpp): (full checks) culling by the volumes spanning
//    several links (culling.hpp), (incremental calls) the pair's last meeting triangle pair,
//    then the two bodies' boxes, then each sub-group tree against each (traversal.hpp),
//    an incremental call from the pair's front when it is in near contact; a body inside a
//    solid of the other collides too (containment.hpp).
// Poses follow the joints lazily (poses.hpp).
//
// The engine reads the checker's arrays in place (layout.hpp: the packed buffers; model.hpp,
// context.hpp: what it cuts them into), so the checker can inspect any of them as a numpy
// view, and a query allocates nothing. A query never moves a world object: the engine's scene
// methods do, between queries, and force the pairs that must be re-checked whatever the joints
// do (collision_sensor/engine/dynamic_scene.py).
//
// Every entry point is plain C++: it takes its input as contiguous arrays and answers with a
// result struct (below), so a C++ caller (a sensor core in the same extension) runs queries on
// the same engine as the Python checker, under lock(), between the checker's calls; the
// checker's cached answer follows status_version().
//
// Adding a query: a function of its own file over an EngineView and a Scratch (as
// proximity.hpp: measure_proximity), run by read() or read_at() below (as proximity()), its
// binding and the checker's method (collision_sensor/engine/checker.py). The motion checks
// (motion.hpp) are entry points here: they keep work areas of their own (MotionWork), and
// update_motion runs the incremental query itself.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "context.hpp"
#include "layout.hpp"
#include "model.hpp"
#include "motion.hpp"
#include "proximity.hpp"
#include "tolerances.hpp"
#include "workers.hpp"
#include "voxel_cloud.hpp"

namespace collision_sensor {

// The rigid transforms the scene methods take (dynamic_scene.py: checked_pose, the same
// arithmetic): finite, the position within MAX_COORDINATE (m) of the origin on each axis
// (as PRISMATIC_VALUE_MAX bounds the joints: every coordinate then stays far from overflow),
// last row (0, 0, 0, 1), |R^T R - I| <= ROTATION_TOLERANCE entrywise, det R >= 0.
bool is_rigid_transform(const double* T);

// The results of the entry points, by name (coal's request/result shape). A value the engine
// cannot honour (kinematics.hpp: unusable_variable) is answered before any work: nothing ran
// and nothing changed then.

// What Engine::query did.
struct QueryResult {
    int64_t rechecked = 0;       // pairs re-checked
    bool changed = false;        // some pair's status changed
    int64_t bad_variable = -1;   // the first variable of q not usable (-1: none)
    // Engine::status_version() after the query: an answer built from the statuses at one
    // version still holds at the same version, whoever ran queries in between.
    uint64_t status_version = 0;
    bool refused() const { return bad_variable >= 0; }
};

// The value a call with several configurations refused: row (a batch's or a path's row, a
// motion's end: 0 q0, 1 q1; a spline's segment) and its variable (-1: the segment as a
// whole: a coefficient not finite, or a planar or floating joint moving).
struct BadValue {
    int64_t row = -1;
    int64_t variable = -1;
    bool any() const { return row >= 0; }
};

// What a motion check found. pairs is (P,) once a check ran (a caller that keeps its result
// between calls allocates it once).
struct MotionResult {
    bool contact = false;        // some state of the motion is in contact (false: proven free)
    double t = 0.0;              // contact: the first contact's fraction of the motion (of its
                                 // segment, for a path or a spline)
    int64_t segment = -1;        // path, spline: the first segment not free (-1: none)
    std::vector<uint8_t> pairs;  // 1 for the pairs in contact (or within the touching
                                 // tolerance, MOTION_TOUCH_TOLERANCE) at t, 0 else
    BadValue bad;                // the value refused (nothing ran then)
    bool refused() const { return bad.any(); }
};

// Engine::update_motion's answer: the motion's, and the query's at its end.
struct StepResult {
    MotionResult motion;
    QueryResult query;
};

// Where Engine::batch writes each row's answer: statuses (n, P) uint8, rechecked (n,) and
// changed (n,) uint8 as QueryResult's.
struct BatchRows {
    uint8_t* statuses;
    int64_t* rechecked;
    uint8_t* changed;
};

struct BatchResult {
    int64_t rows = 0;  // rows run: all of them, or none (bad)
    BadValue bad;
    bool refused() const { return bad.any(); }
};

// A checked pair's two body names, the first sorted first (the checker's checked_pairs).
struct PairName {
    std::string a, b;
};

class Engine {
   public:
    // Cut the buffers F and I (layout.hpp; their layout rows f_layout (N_FLOAT_SLOTS,
    // LAYOUT_WIDTH), i_layout likewise) into the model and the state and check them: throws
    // LayoutError for a layout that is not the tables', std::invalid_argument for a model
    // with an index out of range or options out of range, each naming the culprit.
    Engine(double* F, int64_t f_size, const int64_t* f_layout, int64_t* I, int64_t i_size,
           const int64_t* i_layout, const Options& options);

    // Validate q (J values), copy it to q_last, bring the statuses up to date with it: a full
    // check re-checks every pair, an incremental one only what the motion can have changed.
    // The first call always checks in full.
    QueryResult query(const double* q, bool full);
    // query() on each row of Q (n, J) in turn, each row's answer into rows. Every row is
    // validated before any is run (a bad row: nothing ran). On options.threads threads
    // (workers.hpp), cut into chunks as workers.hpp's SplitPlanner says (options.min_chunk_us
    // of work each), with the single thread's statuses and changed flags (each row's against
    // the row before; the first's against the carried state):
    //   full   the rows in workers' copies of the state: the carried state is left as it was;
    //   !full  in turn from the carried state, as query(), on one thread when the motion
    //          tolerance is not 0 (a row's statuses then depend on the rows before); else
    //          chunk 0 goes on from a copy of the carried state, every later chunk starts with
    //          a full check at its first row (whose statuses are any incremental check's: its
    //          rechecked counts every pair re-checked there), the last one in the engine's own
    //          state, which ends at the last row as with one thread.
    BatchResult batch(const double* Q, int64_t n, bool full, const BatchRows& rows);
    // Bring every link pose up to date (incremental calls compute them only on demand).
    void refresh_all_poses();

    // Motion checks (motion.hpp), none of which changes the carried state but update_motion.
    // Each fills result (MotionResult): contact or proven free, the first contact's fraction
    // and the pairs there.
    // The straight motion q0 -> q1 (bad row 0: q0's value, 1: q1's).
    void motion(const double* q0, const double* q1, MotionResult& result);
    // The motion from the carried state (the last query's q; none before the first: the
    // instant q) to q, then query(q, false): result.query its answer (bad_variable: q's, in
    // result.query and result.motion.bad alike).
    void update_motion(const double* q, StepResult& result);
    // The straight motions Q[0] -> Q[1] -> ... -> Q[n - 1] (n >= 1; one row: its instant),
    // marched as one path (check_polyline_motion) on the calling thread: segment the first
    // not free, t the first contact's fraction of it.
    void path(const double* Q, int64_t n, MotionResult& result);
    // The spline segments coef (n, J, 6) (SplinePath) in turn until one is not free, as path
    // answers; a segment with a coefficient that is not finite, moving a planar or floating
    // joint, or starting or ending at a value that is not usable is refused (bad: row the
    // segment, variable -1). Segments run on options.threads threads in contiguous chunks (a
    // chunk stops once an earlier one met contact); the answer is the first segment's, as on
    // one thread.
    void spline(const double* coef, int64_t n, MotionResult& result);

    // query(q, false), then every pair's distance and nearest points (proximity.hpp:
    // measure_proximity) into result; returns the query's answer (refused: nothing measured).
    QueryResult proximity(const double* q, const ProximityRequest& request,
                          const ProximityResult& result);

    // How many times a query changed a status since the engine was made: the same number
    // means the same statuses (QueryResult::status_version).
    uint64_t status_version() const { return status_version_; }

    // The checked pairs' names, one per pair in the pairs' order (the checker's
    // checked_pairs); throws std::invalid_argument for another count.
    void name_pairs(std::vector<PairName> names);
    // Pair p's names (name_pairs; empty before).
    const PairName& pair_name(int64_t p) const { return pair_names_[p]; }
    bool pairs_named() const { return int64_t(pair_names_.size()) == model_.n_pairs; }

    // Run a query of another kind, query(view, scratch): over the model and the carried state
    // as they are (read-only), in the engine's own context. The caller holds lock().
    template <class Query>
    void read(Query&& query) {
        query(view(), scratch_);
    }
    // The same at q: query(q, false) first (the statuses up to date with q), every pose then
    // current. Returns query()'s answer; the query does not run when it refused q.
    template <class Query>
    QueryResult read_at(const double* q, Query&& query) {
        const QueryResult answer = this->query(q, false);
        if (answer.refused()) return answer;
        refresh_all_poses();
        read(query);
        return answer;
    }

    // The scene methods: each answers whether it did it (false: nothing changed).
    // Give world object b the pose T (4, 4, row-major) and force its pairs, if T is a rigid
    // transform (is_rigid_transform) and b a world object.
    bool move_world_body(int64_t b, const double* T);
    // Give attached object b (a link on a fixed joint, without links below it) the pose T in
    // its link's frame, its pairs pairs[:n] the reach rows reach, reach_ext (n, J) (the
    // checker's lever arms run through the object's origin:
    // collision_sensor/engine/pair_reach.py), and force those pairs; refused when b is no such
    // link, T no rigid transform, a pair not one of b's or a reach not finite and >= 0.
    bool place_attached_body(int64_t b, const double* T, const int64_t* pairs, int64_t n,
                             const double* reach, const double* reach_ext);

    // Point clouds (voxel_cloud.hpp). Make world object b, a body without trees, the obstacle
    // of `cloud` (its current grid), and force its pairs (refused when b is no such body).
    bool attach_cloud(int64_t b, std::shared_ptr<VoxelCloud> cloud);
    // Make build `ticket` of body b's cloud current (VoxelCloud::swap) and force the cloud's
    // pairs only (refused when b has no cloud or the ticket is not its last build to commit).
    bool commit_cloud(int64_t b, int64_t ticket);

    const Model& model() const { return model_; }
    // The threads a batch runs on (options.threads resolved: >= 1).
    int64_t threads() const { return options_.threads; }
    EngineView view() const { return {model_, state_, options_}; }
    std::mutex& lock() { return lock_; }

   private:
    // query() on a usable q.
    QueryResult run(const double* q, bool full, MotionRecord* record = nullptr);
    MotionContext motion_context() { return {view(), scratch_, motion_work_}; }
    void force(int64_t p);
    // Chunks for n items of kind (planner_, options_).
    int64_t chunks(BatchKind kind, int64_t n) const {
        return planner_.chunks(kind, n, options_.threads, 1e3 * options_.min_chunk_us);
    }
    // Workers 0 .. k - 1, made on first use (workers.hpp).
    void ready_workers(int64_t k);
    // Add workers 0 .. k - 1's counters to the engine's, and zero theirs.
    void gather_counters(int64_t k);
    // Check the static pairs (Model::static_pairs) at q in worker 0 (made), their statuses
    // into static_status_; return whether one differs from the carried state's.
    bool static_statuses(const double* q);
    // The incremental batch on k >= 2 threads (batch()).
    void update_batch(const double* Q, int64_t n, int64_t k, const BatchRows& rows);
    // Segment check i in context c: 1 contact (*t, pairs), 0 free.
    using SegmentCheck = std::function<int64_t(MotionContext& c, int64_t i, double* t,
                                               uint8_t* pairs)>;
    // Segments [0, n) in chunks (one: in turn, in the engine's own context), the first not
    // free answered (spline()).
    void first_contact(int64_t n, const SegmentCheck& check, MotionResult& result);
    // result cleared for a check: no contact, pairs (P,) zero.
    void clear(MotionResult& result) const;
    // The first row of Q (n, J) with a value that is not usable, and that value (bad.row -1:
    // none).
    static BadValue first_bad_row(const KinematicTree& kin, const double* Q, int64_t n,
                                  int64_t J);
    void show_cloud(int64_t b);

    std::mutex lock_;
    ResolvedLayout layout_;  // the buffers' slots, writable (the scene methods write the model)
    Options options_;
    Model model_;
    State state_;
    Scratch scratch_;  // the engine's own context (its work group slots packed)
    MotionWork motion_work_;  // the motion checks' own areas, sized on their first use
    std::vector<std::unique_ptr<Worker>> workers_;  // the batches' other contexts
    SplitPlanner planner_;                          // how many chunks a batch is cut into
    std::vector<uint8_t> static_status_;            // (P,) a full batch's static pairs' answers
    std::vector<std::shared_ptr<VoxelCloud>> clouds_;  // (B,) the clouds Model::clouds show
    std::vector<PairName> pair_names_;                 // (P,) name_pairs
    uint64_t status_version_ = 0;                      // status_version()
};

}  // namespace collision_sensor
