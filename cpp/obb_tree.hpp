// Oriented-bounding-box trees over triangle meshes, built top-down (paper sec. 2 and 3).
//
// The C++ side of collision_sensor/engine/obb_tree.py (build_tree_kernel); the forest's
// conventions are documented there. The build writes one tree into node arrays, contiguous,
// row-major:
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
//
// The engine reads every tree of a checker from two tables (obb_tree.py: box_table,
// node_table), one row per node, its numbers side by side in memory:
//   boxes : (N, BOX_WIDTH) centre (3), axes (9, row-major: column k is axis k), half extents
//           (3), radius of the sphere around the box |half| (1), in the body frame
//   nodes : (N, NODE_WIDTH) int64 left child (-1 for a leaf), right child, first triangle,
//           count (0 for an inner node)
//   tris  : (T, 3, 3) triangles in their body frames, in leaf order
#pragma once

#include <cstdint>

namespace collision_sensor {

constexpr int BOX_CENTER = 0, BOX_AXES = 3, BOX_HALF = 12, BOX_RADIUS = 15, BOX_WIDTH = 16;
constexpr int NODE_LEFT = 0, NODE_RIGHT = 1, NODE_FIRST = 2, NODE_COUNT = 3, NODE_WIDTH = 4;

// Every tree of a checker, as the engine reads it; volume and gain score the expansion rules
// (traversal.hpp).
struct Forest {
    const double* boxes;   // (N, BOX_WIDTH)
    const int64_t* nodes;  // (N, NODE_WIDTH)
    const double* volume;  // (N,) box volumes
    const double* gain;    // (N,) volume minus the children's volumes (0 for a leaf)
    const double* tris;    // (T, 3, 3)
    const double* box(int64_t n) const { return boxes + BOX_WIDTH * n; }
    const int64_t* node(int64_t n) const { return nodes + NODE_WIDTH * n; }
};

// The node arrays one build writes (layouts above), of capacity rows each, and order (m,).
struct TreeArrays {
    double* center;
    double* axes;
    double* half;
    int64_t* left;
    int64_t* right;
    int64_t* first;
    int64_t* count;
    int64_t capacity;
    int64_t* order;   // work; on return the triangle order of the leaves
};

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
//: above, capacity >= 2 m - 1); return its node count and depth.
//:
//: The root covers all triangles; a node with more than leaf_size (>= 1) triangles is split in
//: two at the mean of its triangles' centroid projections on one of its box's three axes: the
//: axis whose two halves have the least surface summed (h0 h1 + h1 h2 + h2 h0 of each half's
//: vertex extents along the node's axes; the first such axis on a tie; an axis that would
//: leave a side empty is skipped, and halves of the list are taken if all three would); each
//: node's box is fit_obb_pca of the vertices beneath it, or, when refine is set, fit_obb_refined
//: for the nodes holding more than m / 64 triangles (the top of the tree) (bounding_volumes.hpp).
//: Throws std::invalid_argument on NaN / infinity in tris, m < 1, leaf_size < 1 or too
//: small a capacity.
TreeSize build_obb_tree(const double* tris, int64_t m, int64_t leaf_size, const TreeArrays& out,
                        bool refine = false);

}  // namespace collision_sensor
