// OBB tree build; layouts and the splitting rule in obb_tree.hpp.
#include "obb_tree.hpp"

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
        // Split at the mean centroid projection on axis k (sec. 3: the box's longest-variance
        // axis first); a side left empty (all centroids on one side of the mean: only when they
        // coincide along that axis) tries the next axis.
        int64_t cut = p.start;
        for (int k = 0; k < 3; ++k) {
            double total = 0.0;
            for (int64_t i = p.start; i < p.end; ++i) {
                const int64_t t = order[i];
                keys[t] = centroids[3 * t + 0] * a[k] + centroids[3 * t + 1] * a[3 + k] +
                          centroids[3 * t + 2] * a[6 + k];
                total += keys[t];
            }
            cut = partition(keys.data(), order, p.start, p.end, total / static_cast<double>(n));
            if (p.start < cut && cut < p.end) break;
        }
        if (!(p.start < cut && cut < p.end)) {
            // All centroids coincide along every axis: split the list in halves.
            cut = p.start + n / 2;
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
