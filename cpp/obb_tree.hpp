// Oriented-bounding-box trees over triangle meshes, built top-down (paper sec. 2 and 3).
//
// The C++ side of collision_sensor/obb_tree.py (build_tree_kernel); the forest layout and its
// conventions are documented there. Arrays are contiguous, row-major:
//
//   tris   : (m, 3, 3) float64   triangle t's vertex j is tris[9 * t + 3 * j .. + 2]
//   center : (cap, 3) float64    node n's box centre, in the mesh's (body) frame
//   axes   : (cap, 3, 3) float64 axes[9 * n + 3 * i + k] is row i of node n's axis k
//   half   : (cap, 3) float64    half extents
//   left, right, first, count : (cap,) int64
//   order  : (m,) int64          work array; on return the triangle order of the leaves
//
// with cap >= 2 m - 1 (a binary tree whose leaves hold at least one triangle each has at
// most 2 m - 1 nodes). Nodes are numbered in creation order: a node's children always have
// larger indices than the node, the root is node 0. left[n] == -1 marks a leaf, holding
// triangles tris[order[first[n] .. first[n] + count[n] - 1]]; an inner node has count 0 and
// first = the start of its range.
#pragma once

#include <cstdint>

namespace collision_sensor {

//: Node count and depth of a built tree (a lone leaf has depth 1).
struct TreeSize {
    int64_t nodes;
    int64_t depth;
};

//: Copy the vertices of triangles tris[order[start .. end - 1]] into points ((end - start) * 3,
//: 3), in that order, three rows per triangle.
void gather_points(const double* tris, const int64_t* order, int64_t start, int64_t end,
                   double* points);

//: Reorder order[start .. end - 1] so that the triangles t with keys[t] < split come first
//: (relative order not kept: swaps, as a quicksort partition); return the cut, the index of the
//: first triangle with keys[t] >= split. keys: (m,) indexed by triangle.
int64_t partition(const double* keys, int64_t* order, int64_t start, int64_t end, double split);

//: Build one OBB tree over the m >= 1 triangles tris into the preallocated node arrays (layouts
//: above); return its node count and depth.
//:
//: The root covers all triangles; a node with more than leaf_size (>= 1) triangles is split in
//: two along its box's first axis at the mean of its triangles' centroid projections (the
//: second, then the third axis if a side would be empty; halves of the list if all three
//: would); each node's box is fit_obb_pca of the vertices beneath it (bounding_volumes.hpp).
//: Throws std::invalid_argument on NaN / infinity in tris, m < 1 or leaf_size < 1.
TreeSize build_obb_tree(const double* tris, int64_t m, int64_t leaf_size, double* center,
                        double* axes, double* half, int64_t* left, int64_t* right,
                        int64_t* first, int64_t* count, int64_t* order);

}  // namespace collision_sensor
