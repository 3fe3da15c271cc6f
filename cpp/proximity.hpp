// The proximity query: every checked pair's padded distance and nearest points.
//
// A query of its own over an engine's model and carried state, read through an EngineView
// (context.hpp), working in a Scratch: the engine brings the statuses and poses up to date
// with q first (engine.hpp: Engine::read_at), then measure_proximity reads them.
#pragma once

#include <cstdint>

#include "context.hpp"

namespace collision_sensor {

struct ProximityRequest {
    // Only pairs nearer than this (m) are measured; INF: every pair.
    double max_distance;
};

// Where the answers go: distance (P,) and points (P, 6) (a point on body pair_a, then one on
// body pair_b, world frame).
struct ProximityResult {
    double* distance;
    double* points;
};

// For each pair, the padded distance (the triangles' distance minus the two bodies'
// paddings) if it is below max_distance (else INF), and the nearest points of the padded
// bodies in the world (root) frame.
//
// A pair the query found in contact (status 1) has a padded distance <= 0: without padding 0
// and a point where the triangles meet (its witness triangles) or a vertex inside a solid
// element; with padding, the triangles' distance minus the padding (exact: the traversal runs
// from the witness down to 0 distance) or, for a body inside a solid without surfaces
// within the padding, -padding at that vertex. A pair apart: its body boxes are tried first
// (a pair whose boxes are max_distance apart costs one bound), then the triangles nearest
// last time (scratch.nearest, updated) seed the traversal (under coherent motion nearly the
// answer, so the traversal mostly only proves it). Every pose must be current.
void measure_proximity(const EngineView& view, const ProximityRequest& request,
                       Scratch& scratch, const ProximityResult& result);

}  // namespace collision_sensor
