// A point cloud's voxels and their hierarchy (voxel_grid.hpp).
#include "voxel_grid.hpp"

#include <algorithm>
#include <cmath>

namespace collision_sensor {

namespace {

// The bits of x (< 2^21) spread to every third bit.
uint64_t spread_bits(uint64_t x) {
    x &= 0x1fffff;
    x = (x | x << 32) & 0x1f00000000ffffULL;
    x = (x | x << 16) & 0x1f0000ff0000ffULL;
    x = (x | x << 8) & 0x100f00f00f00f00fULL;
    x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
    x = (x | x << 2) & 0x1249249249249249ULL;
    return x;
}

// Sort keyed (code, index) by code: least significant byte first, skipping the bytes all
// codes share (a cloud spans a small part of the grid).
void radix_sort(std::vector<std::pair<uint64_t, int64_t>>& keyed,
                std::vector<std::pair<uint64_t, int64_t>>& spare) {
    const size_t n = keyed.size();
    spare.resize(n);
    for (int shift = 0; shift < 64; shift += 8) {
        size_t count[257] = {0};
        for (const auto& item : keyed) ++count[((item.first >> shift) & 0xff) + 1];
        bool one_bucket = false;
        for (int b = 1; b <= 256; ++b) one_bucket |= count[b] == n;
        if (one_bucket) continue;
        for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
        for (const auto& item : keyed) spare[count[(item.first >> shift) & 0xff]++] = item;
        keyed.swap(spare);
    }
}

struct HierarchyBuild {
    const uint64_t* codes;
    const double* lo;
    const double* hi;
    int64_t leaf_size;
    int64_t* nodes;     // (2 n, NODE_WIDTH), rows written in creation order
    double* node_lo;    // (2 n, 3)
    double* node_hi;
    int64_t count = 0;  // nodes so far
    int64_t depth = 0;

    // The first index of [first, end) whose code has the highest bit in which the range's
    // first and last codes differ (they share the bits above it: sorted); the middle when
    // they are equal.
    int64_t split(int64_t first, int64_t end) const {
        const uint64_t diff = codes[first] ^ codes[end - 1];
        if (diff == 0) return first + (end - first) / 2;
        const int bit = 63 - __builtin_clzll(diff);
        int64_t a = first, b = end - 1;  // codes[a] has the bit clear, codes[b] set
        while (b - a > 1) {
            const int64_t m = a + (b - a) / 2;
            if ((codes[m] >> bit) & 1)
                b = m;
            else
                a = m;
        }
        return b;
    }

    int64_t build(int64_t first, int64_t end, int64_t level) {
        const int64_t n = count++;
        depth = std::max(depth, level);
        int64_t* row = nodes + NODE_WIDTH * n;
        double* nlo = node_lo + 3 * n;
        double* nhi = node_hi + 3 * n;
        if (end - first <= leaf_size) {
            row[NODE_LEFT] = row[NODE_RIGHT] = -1;
            row[NODE_FIRST] = first;
            row[NODE_COUNT] = end - first;
            for (int k = 0; k < 3; ++k) {
                nlo[k] = lo[3 * first + k];
                nhi[k] = hi[3 * first + k];
            }
            for (int64_t v = first + 1; v < end; ++v) {
                for (int k = 0; k < 3; ++k) {
                    nlo[k] = std::min(nlo[k], lo[3 * v + k]);
                    nhi[k] = std::max(nhi[k], hi[3 * v + k]);
                }
            }
            return n;
        }
        const int64_t middle = split(first, end);
        const int64_t left = build(first, middle, level + 1);
        const int64_t right = build(middle, end, level + 1);
        row = nodes + NODE_WIDTH * n;
        row[NODE_LEFT] = left;
        row[NODE_RIGHT] = right;
        row[NODE_FIRST] = first;
        row[NODE_COUNT] = 0;
        for (int k = 0; k < 3; ++k) {
            nlo[k] = std::min(node_lo[3 * left + k], node_lo[3 * right + k]);
            nhi[k] = std::max(node_hi[3 * left + k], node_hi[3 * right + k]);
        }
        return n;
    }
};

}  // namespace

uint64_t morton_code(int64_t i, int64_t j, int64_t k) {
    return spread_bits(uint64_t(i + VOXEL_COORD_LIMIT)) |
           spread_bits(uint64_t(j + VOXEL_COORD_LIMIT)) << 1 |
           spread_bits(uint64_t(k + VOXEL_COORD_LIMIT)) << 2;
}

void aligned_box_row(const double* lo, const double* hi, double* row) {
    double hh = 0.0;
    for (int c = 0; c < BOX_WIDTH; ++c) row[c] = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double h = 0.5 * (hi[k] - lo[k]);
        row[BOX_CENTER + k] = 0.5 * (lo[k] + hi[k]);
        row[BOX_HALF + k] = h;
        row[BOX_AXES + 4 * k] = 1.0;
        hh += h * h;
    }
    row[BOX_RADIUS] = std::sqrt(hh);
}

int64_t build_box_hierarchy(const uint64_t* codes, const double* lo, const double* hi,
                            int64_t n, int64_t leaf_size, std::vector<int64_t>& nodes,
                            std::vector<double>& boxes) {
    if (n == 0) {
        nodes.clear();
        boxes.clear();
        return 0;
    }
    thread_local std::vector<double> node_lo, node_hi;
    nodes.resize(NODE_WIDTH * 2 * n);
    node_lo.resize(3 * 2 * n);
    node_hi.resize(3 * 2 * n);
    HierarchyBuild b{codes, lo, hi, std::max<int64_t>(leaf_size, 1), nodes.data(),
                     node_lo.data(), node_hi.data()};
    b.build(0, n, 1);
    nodes.resize(NODE_WIDTH * b.count);
    boxes.resize(BOX_WIDTH * b.count);
    for (int64_t m = 0; m < b.count; ++m)
        aligned_box_row(node_lo.data() + 3 * m, node_hi.data() + 3 * m,
                        boxes.data() + BOX_WIDTH * m);
    return b.depth;
}

void sort_by_code(VoxelSortWork& work) { radix_sort(work.keyed, work.spare); }

void build_voxel_grid(const int32_t* ijk, const double* seen, int64_t n, double size,
                      VoxelSortWork& work, VoxelGrid& grid) {
    grid.size = size;
    grid.count = n;
    work.keyed.resize(n);
    for (int64_t v = 0; v < n; ++v)
        work.keyed[v] = {morton_code(ijk[3 * v], ijk[3 * v + 1], ijk[3 * v + 2]), v};
    radix_sort(work.keyed, work.spare);
    grid.ijk.resize(3 * n);
    grid.seen.resize(n);
    work.codes.resize(n);
    work.lo.resize(3 * n);
    work.hi.resize(3 * n);
    for (int64_t v = 0; v < n; ++v) {
        const int64_t from = work.keyed[v].second;
        work.codes[v] = work.keyed[v].first;
        grid.seen[v] = seen[from];
        for (int k = 0; k < 3; ++k) {
            const int32_t c = ijk[3 * from + k];
            grid.ijk[3 * v + k] = c;
            work.lo[3 * v + k] = size * c;
            work.hi[3 * v + k] = size * (c + 1);
        }
    }
    grid.depth = build_box_hierarchy(work.codes.data(), work.lo.data(), work.hi.data(), n,
                                     VOXEL_LEAF_SIZE, grid.nodes, grid.boxes);
}

}  // namespace collision_sensor
