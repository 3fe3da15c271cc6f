// Re-checking the pairs a query planned (paper sec. 4.1): each pair's bodies, then each
// sub-group tree of one against each of the other's.
//
// A full check first rebuilds the volumes spanning several links and culls world objects with
// them (culling.hpp); it uses nothing carried over and records no clearance. An incremental
// call brings the two bodies' poses up to date (only those) and tests first the pair's
// witness, the triangle pair that met when the pair last collided (under small motion it
// usually still does, which then costs one triangle test instead of a descent; the answer is
// the same either way). Then the two bodies' boxes, then each sub-group tree against each
// (traversal.hpp), or, incrementally, from the pair's front; an incremental call records the
// clearance of each pair found apart (planning.hpp), and adds the pair's travel since its last
// incremental re-check to its front's.
#pragma once

#include <cstdint>

#include "context.hpp"

namespace collision_sensor {

// Re-check pairs scratch.todo[:n] (if full: every pair, or the n pairs of full_list, the
// others keeping their statuses); return how many, and set *changed when a status changed.
int64_t recheck_pairs(CheckContext& c, int64_t n, bool full, bool* changed,
                      const int64_t* full_list = nullptr);

}  // namespace collision_sensor
