// A point cloud's obstacle: the occupied voxels of a world-aligned grid, solid
// cubes, with a hierarchy of boxes over them.
//
// Voxel (i, j, k) is the cube [i s, (i + 1) s] x [j s, (j + 1) s] x [k s, (k + 1) s] of the
// world frame (s: the edge, the checker's voxel_size), so the voxels of one source's clouds
// always lie on the same grid: a cloud that follows another changes the set of cubes, never
// their places. Integer coordinates fit VOXEL_COORD_BITS signed bits each; a point beyond
// the grid's reach (|x| >= 2^(VOXEL_COORD_BITS - 1) s) is dropped as out of range.
//
// The hierarchy is the engine's tree format (obb_tree.hpp): rows of BOX_WIDTH (centre, axes,
// half extents, radius; here the identity axes: world-aligned boxes) and NODE_WIDTH (left,
// right, first voxel, count), a node's children after it, node 0 the root. Voxels are sorted
// by their Morton code (the bits of i, j, k interleaved) and split at the highest bit in which
// a node's first and last codes differ: the tree is an octree's cells, binarised, with leaves
// of at most VOXEL_LEAF_SIZE voxels, each box the exact box of its voxels' cubes. Building it
// is a sort and one pass (Karras 2012, "Maximizing parallelism in the construction of BVHs,
// octrees and k-d trees", top down).
#pragma once

#include <cstdint>
#include <vector>

#include "obb_tree.hpp"

namespace collision_sensor {

constexpr int VOXEL_COORD_BITS = 21;
constexpr int64_t VOXEL_COORD_LIMIT = int64_t(1) << (VOXEL_COORD_BITS - 1);
// Most voxels in a leaf of the hierarchy.
constexpr int64_t VOXEL_LEAF_SIZE = 4;

// The Morton code of voxel (i, j, k): the bits of i, j and k (shifted to be >= 0) interleaved,
// i's lowest. Sorting by it keeps voxels near each other in space near each other in order.
uint64_t morton_code(int64_t i, int64_t j, int64_t k);

// One cloud's voxels and their hierarchy (see the file's header).
struct VoxelGrid {
    double size = 0.0;           // the cubes' edge (m); 0 before any cloud
    int64_t count = 0;           // V, voxels
    std::vector<int32_t> ijk;    // (V, 3) each voxel's integer coordinates, in leaf order
    std::vector<double> seen;    // (V,) the stamp of the cloud that last saw it
    std::vector<double> boxes;   // (N, BOX_WIDTH) world-aligned boxes
    std::vector<int64_t> nodes;  // (N, NODE_WIDTH)
    int64_t depth = 0;           // the tree's depth (0: no voxel)

    bool empty() const { return count == 0; }
    const double* box(int64_t n) const { return boxes.data() + BOX_WIDTH * n; }
    const int64_t* node(int64_t n) const { return nodes.data() + NODE_WIDTH * n; }
    // Voxel v's cube, [lo, hi].
    void cube(int64_t v, double* lo, double* hi) const {
        for (int k = 0; k < 3; ++k) {
            lo[k] = size * ijk[3 * v + k];
            hi[k] = size * (ijk[3 * v + k] + 1);
        }
    }
    void centre(int64_t v, double* c) const {
        for (int k = 0; k < 3; ++k) c[k] = size * (ijk[3 * v + k] + 0.5);
    }
};

// A box row (BOX_WIDTH) for the world-aligned box [lo, hi].
void aligned_box_row(const double* lo, const double* hi, double* row);

// Build grid's hierarchy over n items, given sorted by their Morton codes (codes, (n,)), each
// with its own box [lo, hi] (lo, hi: (n, 3)), leaves of at most leaf_size items: into nodes
// and boxes (resized), returning the depth (0 for n = 0). Items are the voxels of a grid
// (boxes: their cubes) or, for the self-filter, voxels with the box of their points.
int64_t build_box_hierarchy(const uint64_t* codes, const double* lo, const double* hi,
                            int64_t n, int64_t leaf_size, std::vector<int64_t>& nodes,
                            std::vector<double>& boxes);

// Sort the voxels ijk (n, 3), with their seen stamps, by Morton code into grid (its size
// given), and build its hierarchy. work: scratch of the caller's, reused across calls.
struct VoxelSortWork {
    std::vector<uint64_t> codes;
    std::vector<int64_t> order;
    std::vector<double> lo, hi;
    std::vector<std::pair<uint64_t, int64_t>> keyed, spare;
};
// Sort work.keyed (Morton code, index) by code.
void sort_by_code(VoxelSortWork& work);
void build_voxel_grid(const int32_t* ijk, const double* seen, int64_t n, double size,
                      VoxelSortWork& work, VoxelGrid& grid);

}  // namespace collision_sensor
