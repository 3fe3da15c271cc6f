// A batch's rows on several threads: worker contexts and the chunked run.
//
// A query writes only its context: the carried state (context.hpp: State) and the work areas
// (Scratch; MotionWork for the motion checks). The model, the options and, for a motion check
// or a full check, the engine's state are only read. So rows that do not depend on each
// other's carried state can run at once, each thread in a Worker of its own (a copy of the
// engine's state, a Scratch and a MotionWork), over a contiguous chunk of the rows; nothing a
// thread writes is shared (each writes its own rows of the output), and the engine's lock is
// held by the caller for the whole batch, so no scene method or other query runs meanwhile.
//
// Answers are the single thread's: every query's answer depends only on its row, the model and
// the state it starts from, never on the work areas' history (their caches are stamped, the
// motion checks start each call afresh).
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <vector>

#include "context.hpp"
#include "model.hpp"
#include "motion.hpp"

namespace collision_sensor {


// The threads a setting asks for: 0 -> the machine's hardware threads
// (std::thread::hardware_concurrency, 1 when it is not known), else the setting itself.
int64_t resolve_threads(int64_t setting);

// A worker thread failed (memory ran out in its work areas): the batch has no answer. The
// binding raises it as EngineWorkerError.
struct WorkerError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// A carried state with arrays of its own (the engine's lives in the packed buffers), made a
// copy of another: every array, the fronts' bookkeeping and the forced pairs. with_fronts:
// the fronts' node pairs too (an incremental check goes on from them); without, they are only
// sized (a full check sets every pair's front length to 0 and starts afresh).
class OwnedState {
   public:
    // Allocate every array for the model (copy_from then reuses them).
    void size_for(const Model& m, const Fronts& fronts);
    void copy_from(const State& from, const Model& m, bool with_fronts);
    State& state() { return state_; }

   private:
    std::vector<double> q_last_, q_ref_, extension_, T_world_body_, clearance_, q_eval_, travel_;
    std::vector<int64_t> stale_, flags_, status_, witness_, forced_;
    State state_{};
};

// One thread's context: its state, its work areas, its motion work, and its answer rows for
// the motion checks (pairs (P,) and t, segment). Counters start at 0 and are added to the
// engine's after each batch.
struct Worker {
    // Every area a batch of rows writes is allocated here, on the thread that makes the
    // workers, one worker after the other, with a gap of CACHE_GAP bytes before and after: no
    // cache line holds two workers' data (what one thread writes at every test would slow the
    // other). The motion work is sized on its first use (Engine::first_contact, on that
    // thread too): it grows with the forest's nodes, and batches of rows never use it.
    Worker(const Model& m, const Fronts& fronts);
    static constexpr size_t CACHE_GAP = 256;
    std::vector<char> gap_before;
    // The counters every box and triangle test adds to: a cache line of their own, away from
    // another thread's (made before scratch, which counts into them).
    alignas(64) int64_t counters[N_COUNTERS + (8 - N_COUNTERS % 8) % 8] = {};
    OwnedState state;
    Scratch scratch;
    MotionWork motion;
    std::vector<uint8_t> pairs;
    double t = 0.0;
    int64_t segment = -1;
    std::vector<char> gap_after;
};

// How many chunks a batch is cut into: a thread costs tens of microseconds to start and to
// join (more on a loaded machine), so a batch is split only into chunks of at least
// min_chunk_ns of work, as estimated from the items of the engine's earlier batches of the
// same kind (the calling thread's chunk, timed). Only the split depends on it, never an answer.
enum BatchKind : int { BATCH_FULL, BATCH_UPDATE, BATCH_SEGMENTS, N_BATCH_KINDS };

struct SplitPlanner {
    double ns_per_item[N_BATCH_KINDS] = {};  // 0: not known yet (the first batch is split)

    // Chunks for n items of kind on up to threads threads: in [1, min(threads, n)].
    int64_t chunks(BatchKind kind, int64_t n, int64_t threads, double min_chunk_ns) const;
    // Learn from items done in seconds on one thread (half the old estimate, half the new).
    void learn(BatchKind kind, int64_t items, double seconds);
};

// Row range [begin, end) of chunk c of k over n rows: contiguous, sizes differing by at most 1.
struct Chunk {
    int64_t begin, end;
};
inline Chunk chunk_of(int64_t c, int64_t k, int64_t n) {
    const int64_t q = n / k, r = n % k;
    const int64_t begin = c * q + std::min(c, r);
    return {begin, begin + q + (c < r ? 1 : 0)};
}

// Run job(c) for every chunk c in [0, k): chunk 0 on the calling thread, the others on threads
// of their own (a thread that cannot be started: its chunk on the calling thread afterwards),
// and return once all are done. The first exception a job throws is rethrown here, after every
// thread has been joined, as a WorkerError naming it.
void run_chunks(int64_t k, const std::function<void(int64_t)>& job);

}  // namespace collision_sensor
