// Worker contexts and the chunked run (workers.hpp).
#include "workers.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <mutex>
#include <string>
#include <system_error>
#include <thread>

namespace collision_sensor {

int64_t resolve_threads(int64_t setting) {
    if (setting > 0) return setting;
    const unsigned cores = std::thread::hardware_concurrency();
    return cores > 0 ? int64_t(cores) : 1;
}

int64_t SplitPlanner::chunks(BatchKind kind, int64_t n, int64_t threads,
                             double min_chunk_ns) const {
    const int64_t most = std::min(threads, n);
    if (most <= 1) return 1;
    const double estimate = ns_per_item[kind];
    if (!(estimate > 0.0)) return most;
    const double k = std::floor(double(n) * estimate / std::max(min_chunk_ns, 1e-9));
    return k >= double(most) ? most : std::max<int64_t>(1, int64_t(k));
}

void SplitPlanner::learn(BatchKind kind, int64_t items, double seconds) {
    if (items <= 0 || !(seconds > 0.0)) return;
    const double ns = seconds * 1e9 / double(items);
    double& estimate = ns_per_item[kind];
    estimate = estimate > 0.0 ? 0.5 * (estimate + ns) : ns;
}

namespace {

template <class T>
T* copied(std::vector<T>& to, const T* from, int64_t n) {
    to.assign(from, from + n);
    return to.data();
}

}  // namespace

void OwnedState::size_for(const Model& m, const Fronts& fronts) {
    const int64_t J = m.n_joints, P = m.n_pairs, B = m.n_bodies;
    q_last_.resize(J);
    q_ref_.resize(J);
    extension_.resize(1);
    T_world_body_.resize(16 * B);
    stale_.resize(B);
    flags_.resize(N_QUERY_FLAGS);
    status_.resize(P);
    witness_.resize(2 * P);
    forced_.resize(P);
    clearance_.resize(P);
    q_eval_.resize(P * J);
    travel_.resize(2 * P);
    state_.fronts.state.resize(fronts.state.size());
    state_.fronts.travel.resize(fronts.travel.size());
    state_.fronts.pairs.resize(fronts.pairs.size());
    state_.fronts.until.resize(fronts.until.size());
    state_.forced_list.reserve(P);
}

void OwnedState::copy_from(const State& from, const Model& m, bool with_fronts) {
    const int64_t J = m.n_joints, P = m.n_pairs, B = m.n_bodies;
    State& s = state_;
    s.q_last = copied(q_last_, from.q_last, J);
    s.q_ref = copied(q_ref_, from.q_ref, J);
    s.extension = copied(extension_, from.extension, 1);
    s.poses.T_world_body = copied(T_world_body_, from.poses.T_world_body, 16 * B);
    s.poses.stale = copied(stale_, from.poses.stale, B);
    s.flags = copied(flags_, from.flags, N_QUERY_FLAGS);
    s.status = copied(status_, from.status, P);
    s.witness = copied(witness_, from.witness, 2 * P);
    s.forced = copied(forced_, from.forced, P);
    s.clearance = copied(clearance_, from.clearance, P);
    s.q_eval = copied(q_eval_, from.q_eval, P * J);
    s.travel = copied(travel_, from.travel, 2 * P);
    const Fronts& f = from.fronts;
    s.fronts.capacity = f.capacity;
    s.fronts.state = f.state;
    s.fronts.travel = f.travel;
    if (with_fronts) {
        s.fronts.pairs = f.pairs;
        s.fronts.until = f.until;
    } else {  // sized once, contents never read before a full check resets them
        s.fronts.pairs.resize(f.pairs.size());
        s.fronts.until.resize(f.until.size());
    }
    s.forced_mode = from.forced_mode;
    s.forced_list = from.forced_list;
}

Worker::Worker(const Model& m, const Fronts& fronts)
    : gap_before(CACHE_GAP), scratch(m, fronts.capacity, counters), pairs(m.n_pairs, 0) {
    state.size_for(m, fronts);
    gap_after.assign(CACHE_GAP, 0);
}

void run_chunks(int64_t k, const std::function<void(int64_t)>& job) {
    std::mutex guard;
    std::exception_ptr failure;
    std::string what;
    auto guarded = [&](int64_t c) {
        try {
            job(c);
        } catch (...) {
            std::lock_guard<std::mutex> hold(guard);
            if (!failure) {
                failure = std::current_exception();
                try {
                    throw;
                } catch (const std::exception& e) {
                    what = e.what();
                } catch (...) {
                    what = "unknown error";
                }
            }
        }
    };
    std::vector<std::thread> threads;
    std::vector<int64_t> inline_chunks;
    threads.reserve(k > 0 ? k - 1 : 0);
    for (int64_t c = 1; c < k; ++c) {
        try {
            threads.emplace_back(guarded, c);
        } catch (const std::system_error&) {  // no thread to be had: run it here instead
            inline_chunks.push_back(c);
        }
    }
    if (k > 0) guarded(0);
    for (int64_t c : inline_chunks) guarded(c);
    for (std::thread& t : threads) t.join();
    if (failure)
        throw WorkerError("the engine's worker thread failed (" + what +
                          "); nothing was answered: retry with fewer rows per call or the "
                          "setting threads: 1");
}

}  // namespace collision_sensor
