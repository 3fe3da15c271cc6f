// OBB tree build; layouts and the splitting rule in obb_tree.hpp.
#include "obb_tree.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "bounding_volumes.hpp"

namespace collision_sensor {

void gather_points(const double* tris, const int64_t* order, int64_t start, int64_t end,
                   double* points) {
    for (int64_t i = start; i < end; ++i) {
        const double* tri = tris + 9 * order[i];
        double* out = points + 9 * (i - start);
        for (int j = 0; j < 9; ++j) out[j] = tri[j];
    }
}

int64_t partition(const double* keys, int64_t* order, int64_t start, int64_t end, double split) {
    int64_t cut = start;
    for (int64_t i = start; i < end; ++i) {
        if (keys[order[i]] < split) {
            const int64_t tmp = order[i];
            order[i] = order[cut];
            order[cut] = tmp;
            ++cut;
        }
    }
    return cut;
}

namespace {

// The three candidate cuts of a node (obb_tree.hpp: the splitting rule), in two passes over
// its triangles order[start .. end - 1]: first each centroid's projection on the box's three
// axes (into keys3, (m, 3)) and their means; then, per axis k, the extents along the three
// axes of the triangles on either side of axis k's mean. Returns the axis whose two sides have
// the least surface summed (h0 h1 + h1 h2 + h2 h0 of each side's extents), -1 when every axis
// leaves a side empty (centroids coinciding along it); its mean into *split.
int best_cut(const double* tris, const double* centroids, const double* a,
             const int64_t* order, int64_t start, int64_t end, double* keys3, double* split) {
    double total[3] = {0.0, 0.0, 0.0};
    for (int64_t i = start; i < end; ++i) {
        const int64_t t = order[i];
        const double* c = centroids + 3 * t;
        for (int k = 0; k < 3; ++k) {
            keys3[3 * t + k] = c[0] * a[k] + c[1] * a[3 + k] + c[2] * a[6 + k];
            total[k] += keys3[3 * t + k];
        }
    }
    const double n = static_cast<double>(end - start);
    const double mean[3] = {total[0] / n, total[1] / n, total[2] / n};
    // lo / hi[k][side][j]: side 0 below axis k's mean, 1 at or above it; j the extent's axis.
    double lo[3][2][3], hi[3][2][3];
    int64_t below[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
        for (int side = 0; side < 2; ++side)
            for (int j = 0; j < 3; ++j) {
                lo[k][side][j] = INFINITY;
                hi[k][side][j] = -INFINITY;
            }
    for (int64_t i = start; i < end; ++i) {
        const int64_t t = order[i];
        const double* tri = tris + 9 * t;
        double tlo[3] = {INFINITY, INFINITY, INFINITY}, thi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int v = 0; v < 3; ++v) {
            const double* x = tri + 3 * v;
            for (int j = 0; j < 3; ++j) {
                const double s = x[0] * a[j] + x[1] * a[3 + j] + x[2] * a[6 + j];
                tlo[j] = std::min(tlo[j], s);
                thi[j] = std::max(thi[j], s);
            }
        }
        for (int k = 0; k < 3; ++k) {
            const int side = keys3[3 * t + k] < mean[k] ? 0 : 1;
            below[k] += 1 - side;
            for (int j = 0; j < 3; ++j) {
                lo[k][side][j] = std::min(lo[k][side][j], tlo[j]);
                hi[k][side][j] = std::max(hi[k][side][j], thi[j]);
            }
        }
    }
    int best = -1;
    double best_surface = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (below[k] == 0 || below[k] == end - start) continue;
        double surface = 0.0;
        for (int side = 0; side < 2; ++side) {
            const double h0 = 0.5 * (hi[k][side][0] - lo[k][side][0]);
            const double h1 = 0.5 * (hi[k][side][1] - lo[k][side][1]);
            const double h2 = 0.5 * (hi[k][side][2] - lo[k][side][2]);
            surface += h0 * h1 + h1 * h2 + h2 * h0;
        }
        if (best < 0 || surface < best_surface) {
            best = k;
            best_surface = surface;
        }
    }
    if (best >= 0) *split = mean[best];
    return best;
}

}  // namespace

TreeSize build_obb_tree(const double* tris, int64_t m, int64_t leaf_size, const TreeArrays& out,
                        bool refine) {
    if (m < 1) {
        throw std::invalid_argument("OBB tree: a mesh without triangles has no tree");
    }
    if (leaf_size < 1) {
        throw std::invalid_argument("OBB tree: leaf_size must be at least 1");
    }
    if (out.capacity < 2 * m - 1) {
        throw std::invalid_argument("OBB tree: node arrays of " + std::to_string(out.capacity) +
                                    " rows, it needs 2 m - 1 = " + std::to_string(2 * m - 1));
    }
    double* center = out.center;
    double* axes = out.axes;
    double* half = out.half;
    int64_t* left = out.left;
    int64_t* right = out.right;
    int64_t* first = out.first;
    int64_t* count = out.count;
    int64_t* order = out.order;
    check_points(tris, 3 * m);
    // Build-time work arrays (allocation is fine here; the query path never builds trees).
    std::vector<double> centroids(3 * m);
    for (int64_t t = 0; t < m; ++t) {
        order[t] = t;
        for (int d = 0; d < 3; ++d) {
            centroids[3 * t + d] =
                (tris[9 * t + d] + tris[9 * t + 3 + d] + tris[9 * t + 6 + d]) / 3.0;
        }
    }
    std::vector<double> keys(m), keys3(3 * m);
    std::vector<double> points(9 * m);  // the root's vertices are the most any node gathers
    // Explicit stack of (node, start, end, depth): trees can be deep, and a pending entry is
    // popped before its two children are pushed, so it never holds more than m + 1 entries.
    struct Pending {
        int64_t node, start, end, depth;
    };
    std::vector<Pending> stack;
    stack.reserve(m + 1);
    stack.push_back({0, 0, m, 1});
    int64_t n_nodes = 1;
    int64_t max_depth = 1;
    while (!stack.empty()) {
        const Pending p = stack.back();
        stack.pop_back();
        if (p.depth > max_depth) max_depth = p.depth;
        const int64_t n = p.end - p.start;
        gather_points(tris, order, p.start, p.end, points.data());
        double* a = axes + 9 * p.node;
        // Refined at the top of the tree only (nodes holding more than 1/64 of its
        // triangles): those are tested on every descent, and refining every node would make
        // a large mesh's build several times as long.
        if (refine && 64 * n > m)
            fit_obb_refined(points.data(), 3 * n, center + 3 * p.node, a, half + 3 * p.node);
        else
            fit_obb_pca(points.data(), 3 * n, center + 3 * p.node, a, half + 3 * p.node);
        if (n <= leaf_size) {
            left[p.node] = -1;
            right[p.node] = -1;
            first[p.node] = p.start;
            count[p.node] = n;
            continue;
        }
        // Split at the mean centroid projection on one of the box's three axes: the one whose
        // two halves have the least surface summed (h0 h1 + h1 h2 + h2 h0 of each half's extents
        // along this box's axes).
        // The longest-variance axis alone (sec. 3) can cut a mesh into two long, overlapping
        // halves; trying all three keeps the children apart and small, which is what prunes a
        // descent of two meshes near but apart. An axis leaving a side empty (all
        // centroids on one side of the mean: only when they coincide along it) is skipped.
        int64_t cut = p.start + n / 2;  // all centroids coincide along every axis: halves
        double split = 0.0;
        const int best = best_cut(tris, centroids.data(), a, order, p.start, p.end,
                                  keys3.data(), &split);
        if (best >= 0) {
            for (int64_t i = p.start; i < p.end; ++i) {
                const int64_t t = order[i];
                keys[t] = keys3[3 * t + best];
            }
            cut = partition(keys.data(), order, p.start, p.end, split);
        }
        left[p.node] = n_nodes;
        right[p.node] = n_nodes + 1;
        first[p.node] = p.start;
        count[p.node] = 0;
        // Left pushed first, right on top: the same visiting order as the Python original.
        stack.push_back({n_nodes, p.start, cut, p.depth + 1});
        stack.push_back({n_nodes + 1, cut, p.end, p.depth + 1});
        n_nodes += 2;
    }
    return {n_nodes, max_depth};
}

}  // namespace collision_sensor
