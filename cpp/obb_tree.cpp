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

// Write keys[t] = the projection of triangle t's centroid on axis k of the box axes a
// (column k of the row-major 3x3) for the triangles order[start .. end - 1]; return their mean.
double project_centroids(const double* centroids, const double* a, int k, double* keys,
                         const int64_t* order, int64_t start, int64_t end) {
    double total = 0.0;
    for (int64_t i = start; i < end; ++i) {
        const int64_t t = order[i];
        keys[t] = centroids[3 * t + 0] * a[k] + centroids[3 * t + 1] * a[3 + k] +
                  centroids[3 * t + 2] * a[6 + k];
        total += keys[t];
    }
    return total / static_cast<double>(end - start);
}

// Half the surface (h0 h1 + h1 h2 + h2 h0) of the box on axes a (row-major 3x3, column k is
// axis k) around triangles order[start .. end - 1]: the parent's axes stand in for the child's
// own principal axes, a cheap measure of how large the child's box will be.
double surface_on_axes(const double* tris, const int64_t* order, int64_t start, int64_t end,
                       const double* a) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = start; i < end; ++i) {
        const double* tri = tris + 9 * order[i];
        for (int v = 0; v < 3; ++v) {
            const double* x = tri + 3 * v;
            for (int k = 0; k < 3; ++k) {
                const double s = x[0] * a[k] + x[1] * a[3 + k] + x[2] * a[6 + k];
                lo[k] = std::min(lo[k], s);
                hi[k] = std::max(hi[k], s);
            }
        }
    }
    const double h0 = 0.5 * (hi[0] - lo[0]), h1 = 0.5 * (hi[1] - lo[1]),
                 h2 = 0.5 * (hi[2] - lo[2]);
    return h0 * h1 + h1 * h2 + h2 * h0;
}

}  // namespace

TreeSize build_obb_tree(const double* tris, int64_t m, int64_t leaf_size, const TreeArrays& out) {
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
    std::vector<double> keys(m);
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
        // descent (scenario 13's two meshes near but apart: 356 box tests a check with the
        // first axis alone, 110 with the best of three). An axis leaving a side empty (all
        // centroids on one side of the mean: only when they coincide along it) is skipped.
        int64_t cut = p.start;
        int best_axis = -1;
        double best_surface = 0.0, best_split = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double split =
                project_centroids(centroids.data(), a, k, keys.data(), order, p.start, p.end);
            cut = partition(keys.data(), order, p.start, p.end, split);
            if (!(p.start < cut && cut < p.end)) continue;
            const double surface = surface_on_axes(tris, order, p.start, cut, a) +
                                   surface_on_axes(tris, order, cut, p.end, a);
            if (best_axis < 0 || surface < best_surface) {
                best_axis = k;
                best_surface = surface;
                best_split = split;
            }
        }
        if (best_axis < 0) {
            // All centroids coincide along every axis: split the list in halves.
            cut = p.start + n / 2;
        } else if (best_axis != 2) {
            // The order holds the last axis' partition: partition again on the best axis, at
            // the same split (a mean summed in another order could round to another number).
            project_centroids(centroids.data(), a, best_axis, keys.data(), order, p.start, p.end);
            cut = partition(keys.data(), order, p.start, p.end, best_split);
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
