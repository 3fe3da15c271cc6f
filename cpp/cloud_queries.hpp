// The queries on a pair of a body and a point cloud's voxels: what recheck.hpp,
// proximity.hpp and motion.hpp do for two trees, for a body's trees against a VoxelGrid
// (voxel_grid.hpp), whose world-aligned cubes are solid.
//
// A cloud is a world object without trees; its voxels live in the engine's side structure
// (voxel_cloud.hpp), and the engine's queries hand its pairs here (the hooks: one line in
// each). The pair's pose P is the cloud's (the world's) in body a's frame, as for any world
// object; body a's triangles are taken to the world frame at the leaves, where the cubes are
// axis-aligned boxes (triangle_box.hpp).
//
// Contact rule, as for two bodies: a pair is in contact when a triangle of body a comes within
// its padding of a voxel's cube (touching counts), or a corner of a cube lies in a solid element
// of body a (a primitive as the true shape, a closed mesh with mesh_containment): the corners
// of a cube that meets no triangle are all inside a solid or none of them is, but in the thin
// sliver between an inscribed tessellation and its true surface, the same rule as for a mesh
// element's vertex.
#pragma once

#include <cstdint>

#include "context.hpp"
#include "motion_bounds.hpp"
#include "proximity.hpp"
#include "voxel_grid.hpp"

namespace collision_sensor {


struct CloudPairResult {
    bool hit;
    int64_t triangle, voxel;  // a meeting pair (-1, -1 for a solid, or none)
    double gap;               // not hit, tracked: a lower bound of the padded distance
};

// Is body a within pad of the cubes of grid (at pose P in a's frame)? Tests the witness
// (triangle, voxel) first when it has one. With track, gap is a lower bound of the distance
// minus pad when not (0 once an unpadded leaf pair was tested: as collide_trees).
CloudPairResult collide_body_cloud(const Model& m, int64_t a, const VoxelGrid& grid,
                                   const double* P, double pad, bool track,
                                   int64_t witness_triangle, int64_t witness_voxel,
                                   int64_t* counters);

// recheck_pairs for pair p of link a and cloud body b (the hook in recheck.cpp): its status,
// witness and clearance, as recheck_pairs records them for two trees.
void recheck_cloud_pair(CheckContext& c, int64_t p, int64_t a, int64_t b, const double* pose,
                        bool track, bool* changed);

// measure_proximity for pair p of link a and cloud body b (the hook in proximity.cpp):
// result.distance[p] (the padded distance if below max_distance, else INF) and its points.
void measure_cloud_pair(const Model& m, const State& s, int64_t p, const double* pose,
                        double max_distance, const ProximityResult& result);

// pair_within for link a and a cloud (the hook in motion.cpp), test.P the cloud's pose in body
// a: the cloud does not move.
WithinResult cloud_pair_within(const Model& m, int64_t a, const VoxelGrid& grid,
                               const IntervalTest& test, int64_t* counters);

}  // namespace collision_sensor
