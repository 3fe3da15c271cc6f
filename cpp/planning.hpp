// Re-check planning (paper sec. 4.2, taken further by the clearance): which pairs a query
// re-checks.
//
// A query decides which joint variables moved (by more than the motion tolerance) since the
// state the carried statuses describe (q_ref), takes their new values into q_ref, and lists
// only the pairs whose relative pose can have changed: those with a moved variable on the
// tree path between their two bodies, minus those whose recorded clearance the motion cannot
// have closed; every other pair keeps its status. Contract of plan_update:
//     moved = |q - q_ref| > tolerance;  q_ref[moved] = q[moved]
//     stale[links below a moved joint] = 1          (poses follow on demand, poses.hpp)
//     todo = [p for p in pairs if moved[path(p)].any()
//             and not (status[p] == 0 and travel(p) < clearance[p])]
// A pair re-checked incrementally and found apart keeps clearance[p], a lower bound of the
// distance between its two bodies' triangles, and q_eval[p] = q_ref then (full checks record
// none). Moving variable j by dq moves no point of either body by more than
// |dq| (reach[p, j] + reach_ext[p, j] E) relative to the other (E: the sum of the prismatic
// joints' |value| at q_ref; the checker computes reach: collision_sensor/engine/pair_reach.py),
// so while the sum of these, travel(p) from q_eval[p] to q_ref, stays below clearance[p] the
// pair is still apart. Each pair keeps the two sums of |dq| times reach and times reach_ext,
// travel(p) = fixed + E ext, so a slider moving changes E without touching any sum. Only the
// pairs on a moved variable's list are visited, and their sums move by that variable's terms
// alone. The running sums are recomputed exactly when a pair's travel comes within
// TRAVEL_GUARD of its clearance, and every TRAVEL_RESYNC_CALLS calls.
//
// Running sums and huge motions: a skipped pair's sum is below its clearance, so every term
// in it is too, and its rounding is a few ulps of the clearance. A motion that takes a term
// past the clearance makes the pair due at once (needs_recheck then resyncs and re-checks
// it, which sets q_eval to the new state and restarts its sums), so no sum ever carries a
// huge term forward for a later motion to cancel. needs_recheck is NaN-safe for the same
// reason: without that, an infinite extension times a zero sum (a NaN) once let such pairs
// through unchecked, and the next motion back cancelled a huge term against itself.
//
// A scene change (an object added, moved or replaced) leaves pairs whose carried status,
// clearance and front describe the scene as it was: they are forced (State::forced), and the
// next query re-checks them whatever the joints did (an incremental one from their roots: a
// front's untils and a clearance measured the old scene).
#pragma once

#include <cstdint>

#include "context.hpp"

namespace collision_sensor {

// A skipped pair's running travel sum is replaced by the exact sum once it reaches
// TRAVEL_GUARD of the pair's clearance (tolerances.hpp), and every tracked pair's at least
// once in this many incremental calls.
constexpr int64_t TRAVEL_RESYNC_CALLS = int64_t(1) << 24;

// Start a full check: take all of q into q_ref, recompute every link pose and E.
void plan_full(CheckContext& c, const double* q);

// Take the variables of q that moved into q_ref; list the pairs to re-check in
// scratch.todo; return how many (the contract above).
int64_t plan_update(CheckContext& c, const double* q);

// Append the forced pairs not yet in todo[:n] to it, dropping their fronts; clear the forced
// flags. Return the new length.
int64_t add_forced(CheckContext& c, int64_t n);

// Clear every forced flag (a full check re-checks every pair anyway).
void clear_forced(State& state, int64_t n_pairs);

// For pair p, about to be re-checked incrementally: its travel since its last incremental
// re-check joins its front's running sum (which restarts when it has no front: the sum then
// never grows without bound), and q_eval[p] becomes q_ref.
void account_travel(CheckContext& c, int64_t p);

}  // namespace collision_sensor
