// Rays against the engine's OBB trees: what a simulated depth camera sees, for the
// demo cell, the benchmarks and the tests of point clouds (collision_sensor/tools/depth_camera.py).
//
// Contract, for each ray o + t d (|d| = 1), t in (0, max_range]:
//     t_hit = min t over the triangles of every tree e at pose T[e] that the ray meets
// (INF when none). Each tree is descended with the ray in its node boxes' frames (the slab
// test: a box the ray misses, or meets only beyond the nearest hit so far, is skipped), the
// leaves' triangles by Moeller-Trumbore.
#pragma once

#include <cstdint>

#include "obb_tree.hpp"

namespace collision_sensor {

// Cast n rays from origin (3,) along dirs (n, 3) (unit vectors, world frame) against the trees
// roots[:n_trees] of forest, tree e placed at T[16 e .. 16 e + 15] (world pose of its body,
// row-major); write each ray's nearest hit distance to t (n,), INF beyond max_range.
void cast_rays(const Forest& forest, const int64_t* roots, const double* T, int64_t n_trees,
               const double* origin, const double* dirs, int64_t n, double max_range,
               double* t);

}  // namespace collision_sensor
