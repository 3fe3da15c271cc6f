// The self-filter and the voxelisation of a point cloud (cloud_filter.hpp).
#include "cloud_filter.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "containment.hpp"
#include "inlining.hpp"
#include "motion.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"
#include "triangle_box.hpp"
#include "workers.hpp"

namespace collision_sensor {

namespace {

constexpr uint64_t EMPTY_KEY = ~uint64_t(0);
// A voxel's class: its points kept untested, removed untested, or tested one by one.
constexpr uint8_t KEEP = 0, DROP = 1, MIXED = 2;
// The hash table's least capacity (slots; a power of 2).
constexpr int64_t MIN_TABLE = 4096;
// The fewest rows a thread of the first pass takes (about 0.4 ms of work, against tens of
// microseconds to start and join a thread); fewer rows run on fewer threads.
constexpr int64_t MIN_CHUNK_ROWS = 20000;
// Entries of the first pass's table of recent voxels (a power of 2).
constexpr int64_t RECENT = 1024;
// The fewest near voxels per thread collecting candidates (about 0.4 ms of traversal), and
// the fewest candidates per thread classifying the voxels (about 0.2 ms of distances).
constexpr int64_t MIN_NEAR_VOXELS = 256;
constexpr int64_t MIN_CLASSIFIED = 10000;
// Numbers cached per robot node in collect_candidates (its world boxes).
constexpr int64_t NODE_WORLD = 18;

uint64_t pack_key(int64_t i, int64_t j, int64_t k) {
    return uint64_t(i + VOXEL_COORD_LIMIT) | uint64_t(j + VOXEL_COORD_LIMIT) << 21 |
           uint64_t(k + VOXEL_COORD_LIMIT) << 42;
}

// The slot of key in a table of 2^(64 - shift) slots: Fibonacci hashing, the product's top
// bits (each depends on every bit of the key; bits 24 to 39 of it, as taken before
// 2026-11-26, miss k, so a column of voxels (i, j, *) shared one slot and chains of ~17
// probes formed along walls).
CS_ALWAYS_INLINE int64_t table_index(uint64_t key, int shift) {
    return int64_t((key * 0x9E3779B97F4A7C15ULL) >> shift);
}

int log2_of(int64_t power_of_two) { return 63 - __builtin_clzll(uint64_t(power_of_two)); }

// Row r's x, y, z.
CS_ALWAYS_INLINE bool read_row(const CloudPoints& c, int64_t r, double* x) {
    const char* row = c.data + r * c.row_stride;
    if (c.float32) {
        float v[3];
        for (int k = 0; k < 3; ++k) std::memcpy(&v[k], row + k * c.column_stride, sizeof(float));
        x[0] = v[0];
        x[1] = v[1];
        x[2] = v[2];
    } else {
        for (int k = 0; k < 3; ++k)
            std::memcpy(&x[k], row + k * c.column_stride, sizeof(double));
    }
    return std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]);
}

// x in the frame of pose (12 numbers: R row-major, t): R x + t.
CS_ALWAYS_INLINE void apply(const double* P, const double* x, double* y) {
    for (int i = 0; i < 3; ++i)
        y[i] = P[3 * i] * x[0] + P[3 * i + 1] * x[1] + P[3 * i + 2] * x[2] + P[9 + i];
}

// floor(g) for |g| < 2^62, without a library call (std::floor is one without SSE4.1).
CS_ALWAYS_INLINE int64_t floor_to_int(double g) {
    const int64_t i = int64_t(g);
    return i - (double(i) > g ? 1 : 0);
}

int64_t next_power_of_two(int64_t n) {
    int64_t p = 1;
    while (p < n) p <<= 1;
    return p;
}

}  // namespace

void CloudBuilder::Tally::clear(int64_t capacity) {
    n = 0;
    invalid = out_of_range = 0;
    if (int64_t(keys.size()) != capacity) {
        keys.assign(capacity, EMPTY_KEY);
        slots.assign(capacity, -1);
        size_for(capacity);
    } else {
        std::fill(keys.begin(), keys.end(), EMPTY_KEY);
    }
}

void CloudBuilder::Tally::size_for(int64_t capacity) {
    mask = capacity - 1;
    shift = 64 - log2_of(capacity);
    const int64_t most = capacity / 2 + 1;  // voxels before the table grows
    ijk.resize(3 * most);
    lo.resize(3 * most);
    hi.resize(3 * most);
    count.resize(most);
    near_count.resize(most);
}

void CloudBuilder::Tally::rehash(int64_t capacity) {
    keys.assign(capacity, EMPTY_KEY);
    slots.assign(capacity, -1);
    size_for(capacity);
    for (int64_t v = 0; v < n; ++v) {
        const uint64_t key = pack_key(ijk[3 * v], ijk[3 * v + 1], ijk[3 * v + 2]);
        int64_t at = table_index(key, shift);
        while (keys[at] != EMPTY_KEY) at = (at + 1) & mask;
        keys[at] = key;
        slots[at] = int32_t(v);
    }
}

int64_t CloudBuilder::Tally::slot_of(uint64_t key) {
    int64_t at = table_index(key, shift);
    while (keys[at] != EMPTY_KEY) {
        if (keys[at] == key) return slots[at];
        at = (at + 1) & mask;
    }
    const int64_t v = n++;
    keys[at] = key;
    slots[at] = int32_t(v);
    const int64_t L = VOXEL_COORD_LIMIT;
    ijk[3 * v] = int32_t(int64_t(key & 0x1fffff) - L);
    ijk[3 * v + 1] = int32_t(int64_t((key >> 21) & 0x1fffff) - L);
    ijk[3 * v + 2] = int32_t(int64_t((key >> 42) & 0x1fffff) - L);
    for (int a = 0; a < 3; ++a) {
        lo[3 * v + a] = INF;
        hi[3 * v + a] = -INF;
    }
    count[v] = near_count[v] = 0;
    if (2 * n > mask + 1) rehash(2 * (mask + 1));
    return v;
}

void CloudBuilder::tally_rows(const RowPass& p, int64_t begin, int64_t end, Tally& tally,
                              int32_t* row_voxel) {
    // Locals, not p's fields: the writes below through double* could alias them.
    const CloudPoints points = *p.points;
    const int64_t step = p.step;
    double frame[12], region_lo[3], region_hi[3];
    std::copy(p.frame, p.frame + 12, frame);
    std::copy(p.region_lo, p.region_lo + 3, region_lo);
    std::copy(p.region_hi, p.region_hi + 3, region_hi);
    const double inv = p.inv, range2 = p.range2, limit = double(VOXEL_COORD_LIMIT);
    int64_t invalid = 0, out_of_range = 0;
    uint64_t last_key = EMPTY_KEY;
    int64_t last_voxel = -1;
    // The voxels met lately, direct-mapped: an organised cloud's next image row meets the
    // voxels of the last few again, and this small table stays in the L1 cache, where the
    // hash table (tens of thousands of slots) does not (a third of the lookups reach it).
    uint64_t recent_key[RECENT];
    int32_t recent_voxel[RECENT];
    std::fill(recent_key, recent_key + RECENT, EMPTY_KEY);
    for (int64_t t = begin; t < end; ++t) {
        row_voxel[t] = -1;
        double x[3], w[3];
        if (!read_row(points, t * step, x)) {
            ++invalid;
            continue;
        }
        if (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > range2) {
            ++out_of_range;
            continue;
        }
        apply(frame, x, w);
        const double gi = w[0] * inv, gj = w[1] * inv, gk = w[2] * inv;
        if (!(std::fabs(gi) < limit && std::fabs(gj) < limit && std::fabs(gk) < limit)) {
            ++out_of_range;
            continue;
        }
        const uint64_t key = pack_key(floor_to_int(gi), floor_to_int(gj), floor_to_int(gk));
        int64_t v = last_voxel;
        if (key != last_key) {
            const int64_t at = int64_t(key ^ key >> 18 ^ key >> 39) & (RECENT - 1);
            if (recent_key[at] == key) {
                v = recent_voxel[at];
            } else {
                v = tally.slot_of(key);
                recent_key[at] = key;
                recent_voxel[at] = int32_t(v);
            }
            last_key = key;
            last_voxel = v;
        }
        row_voxel[t] = int32_t(v);
        ++tally.count[v];
        if (w[0] >= region_lo[0] && w[0] <= region_hi[0] && w[1] >= region_lo[1] &&
            w[1] <= region_hi[1] && w[2] >= region_lo[2] && w[2] <= region_hi[2]) {
            ++tally.near_count[v];
            double* lo = tally.lo.data() + 3 * v;
            double* hi = tally.hi.data() + 3 * v;
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], w[k]);
                hi[k] = std::max(hi[k], w[k]);
            }
        }
    }
    tally.invalid += invalid;
    tally.out_of_range += out_of_range;
}

// Every (voxel, body, triangle or solid) whose tree node's box, grown by r, may come near the
// voxel's points' box: the robot's trees against the filter's hierarchy (leaves: one voxel
// each, world-aligned boxes), a robot node's box grown by r at the cloud's state tested on
// the world's axes and its own (a broad phase; classify measures the distances). The elements
// are shared out to up to `threads` threads, one at a time to whichever is free (their work
// differs by orders of magnitude); sorted_ then gathers each voxel's candidates in element
// order.
void CloudBuilder::collect_candidates(const Model& m, const double* T_links, double r,
                                      int64_t threads) {
    node_world_.resize(NODE_WORLD * m.n_nodes);
    node_stamp_.resize(m.n_nodes, 0);
    ++stamp_;
    elements_.clear();
    for (int64_t b = 0; b < m.n_links; ++b)
        for (int64_t e = m.elem_start[b]; e < m.elem_end[b]; ++e) elements_.push_back({b, e});
    const int64_t n_elements = int64_t(elements_.size());
    found_.resize(n_elements);
    const int64_t n_near = int64_t(order_.size());
    const int64_t k = std::max<int64_t>(
        1, std::min({threads, n_elements, n_near / MIN_NEAR_VOXELS}));
    if (int64_t(work_.size()) < k) work_.resize(k);
    std::atomic<int64_t> next{0};
    run_chunks(k, [&](int64_t c) {
        FilterWork& work = work_[c];
        work.found.clear();
        for (int64_t i = next++; i < n_elements; i = next++) {
            const int64_t begin = int64_t(work.found.size());
            element_candidates(m, T_links, r, elements_[i].first, elements_[i].second, work);
            found_[i] = {c, begin, int64_t(work.found.size())};
        }
    });
    // By voxel (counting sort), the elements in order.
    start_.assign(tally_.n + 1, 0);
    for (const Found& at : found_)
        for (int64_t j = at.begin; j < at.end; ++j) ++start_[work_[at.thread].found[j].voxel + 1];
    for (int64_t v = 0; v < tally_.n; ++v) start_[v + 1] += start_[v];
    sorted_.resize(start_[tally_.n]);
    std::vector<int64_t>& next_at = work_[0].stack;
    next_at.assign(start_.begin(), start_.end() - 1);
    for (const Found& at : found_) {
        const Candidate* found = work_[at.thread].found.data();
        for (int64_t j = at.begin; j < at.end; ++j) sorted_[next_at[found[j].voxel]++] = found[j];
    }
}

// Element e of body b against the filter's hierarchy: its candidates appended to work.found.
void CloudBuilder::element_candidates(const Model& m, const double* T_links, double r,
                                      int64_t b, int64_t e, FilterWork& work) {
    const Forest& f = m.forest;
    const double* tree_boxes = filter_boxes_.data();
    const int64_t* tree_nodes = filter_nodes_.data();
    auto fbox = [&](int64_t n) { return tree_boxes + BOX_WIDTH * n; };
    auto fnode = [&](int64_t n) { return tree_nodes + NODE_WIDTH * n; };
    const double* T = T_links + 16 * b;
    // A robot node's world-aligned box (centre, half extents) and its own box's world axes
    // and half extents, both grown by r (NODE_WORLD numbers: c, e, W (W[3k + i]: axis k's
    // world coordinate i), h).
    auto world_box = [&](int64_t n) {
        double* out = node_world_.data() + NODE_WORLD * n;
        if (node_stamp_[n] == stamp_) return out;
        node_stamp_[n] = stamp_;
        const double* box = f.box(n);
        double* W = out + 6;
        for (int i = 0; i < 3; ++i) {
            double c = T[4 * i + 3], e = r;
            for (int k = 0; k < 3; ++k) {
                c += T[4 * i + k] * box[BOX_CENTER + k];
                const double axis = T[4 * i] * box[BOX_AXES + k] +
                                    T[4 * i + 1] * box[BOX_AXES + 3 + k] +
                                    T[4 * i + 2] * box[BOX_AXES + 6 + k];
                W[3 * k + i] = axis;
                e += std::fabs(axis) * box[BOX_HALF + k];
            }
            out[i] = c;
            const double rounding = BOUND_ROUNDING_REL * std::fabs(c);  // err wide
            out[3 + i] = e * (1.0 + BOUND_ROUNDING_REL) + rounding;
            out[15 + i] = (box[BOX_HALF + i] + r) * (1.0 + BOUND_ROUNDING_REL) + rounding;
        }
        return out;
    };
    // False when a robot node's box grown by r and a box row of the hierarchy (world-aligned)
    // are apart on a world axis or on an axis k of the node's box (the row reaches
    // sum_i |W_k[i]| half_i along it). The node's axes cut 30 % of scenario 12's candidates
    // (44,518 -> 31,615 on a cloud), which its world box, up to sqrt(3) wider than the node
    // on each axis when tilted, lets through. Both err wide (rounding).
    auto overlap = [](const double* A, const double* B) {
        const double* h = B + BOX_HALF;
        const double d[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]};
        if (!(std::fabs(d[0]) <= A[3] + h[0] && std::fabs(d[1]) <= A[4] + h[1] &&
              std::fabs(d[2]) <= A[5] + h[2]))
            return false;
        const double slack =
            BOUND_ROUNDING_REL * (std::fabs(B[0]) + std::fabs(B[1]) + std::fabs(B[2]));
        for (int k = 0; k < 3; ++k) {
            const double* w = A + 6 + 3 * k;
            const double along = w[0] * d[0] + w[1] * d[1] + w[2] * d[2];
            const double reach =
                std::fabs(w[0]) * h[0] + std::fabs(w[1]) * h[1] + std::fabs(w[2]) * h[2];
            if (std::fabs(along) > A[15 + k] + reach * (1.0 + BOUND_ROUNDING_REL) + slack)
                return false;
        }
        return true;
    };
    if (!overlap(world_box(m.roots[e]), fbox(0))) return;
    std::vector<int64_t>& stack = work.stack;
    std::vector<Candidate>& out = work.found;
    const bool solid = m.elem_solid[SOLID_WIDTH * e] != SOLID_NONE;
    // The element's triangles against the voxels (its solid, with its root box).
    for (int pass = 0; pass < (solid ? 2 : 1); ++pass) {
        stack.clear();
        stack.push_back(m.roots[e]);
        stack.push_back(0);
        while (!stack.empty()) {
            const int64_t nb = stack.back();
            stack.pop_back();
            const int64_t na = stack.back();
            stack.pop_back();
            const double* A = world_box(na);
            const double* B = fbox(nb);
            if (!overlap(A, B)) continue;
            const int64_t* node_a = f.node(na);
            const int64_t* node_b = fnode(nb);
            const bool leaf_a = pass == 1 || node_a[NODE_LEFT] < 0;
            const bool leaf_b = node_b[NODE_LEFT] < 0;
            if (leaf_a && leaf_b) {
                const int64_t voxel = order_[node_b[NODE_FIRST]];
                if (pass == 1) {
                    out.push_back({voxel, b, -1 - e});
                } else {
                    for (int64_t t = node_a[NODE_FIRST];
                         t < node_a[NODE_FIRST] + node_a[NODE_COUNT]; ++t)
                        out.push_back({voxel, b, t});
                }
                continue;
            }
            const double ra = A[3] + A[4] + A[5];
            const double rb = B[BOX_HALF] + B[BOX_HALF + 1] + B[BOX_HALF + 2];
            if (!leaf_a && (leaf_b || ra >= rb)) {
                stack.insert(stack.end(), {node_a[NODE_LEFT], nb, node_a[NODE_RIGHT], nb});
            } else {
                stack.insert(stack.end(), {na, node_b[NODE_LEFT], na, node_b[NODE_RIGHT]});
            }
        }
    }
}

// Every voxel's class (class_) and the MIXED ones' nearby lists (near_, near_start_): the
// voxels in up to `threads` contiguous runs of about as many candidates each, every run's
// lists in its thread's work, then joined in voxel order (the one thread's lists).
void CloudBuilder::classify_voxels(const Model& m, double r, int64_t threads) {
    const int64_t V = tally_.n, total = start_[V];
    const int64_t k = std::max<int64_t>(1, std::min(threads, total / MIN_CLASSIFIED));
    if (int64_t(work_.size()) < k) work_.resize(k);
    near_start_.assign(V + 1, 0);
    // Run c: voxels [first[c], first[c + 1]), from the first voxel whose candidates start at
    // or past c total / k.
    std::vector<int64_t>& first = work_[0].stack;
    first.assign(k + 1, V);
    first[0] = 0;
    for (int64_t c = 1; c < k; ++c)
        first[c] = std::lower_bound(start_.begin(), start_.end() - 1, c * total / k) -
                   start_.begin();
    run_chunks(k, [&](int64_t c) {
        std::vector<Nearby>& near = work_[c].near;
        near.clear();
        for (int64_t v = first[c]; v < first[c + 1]; ++v) {
            near_start_[v] = int64_t(near.size());
            if (start_[v] < start_[v + 1]) class_[v] = uint8_t(classify(m, v, r, near));
        }
    });
    near_.clear();
    for (int64_t c = 0; c < k; ++c) {
        const int64_t offset = int64_t(near_.size());
        for (int64_t v = first[c]; v < first[c + 1]; ++v) near_start_[v] += offset;
        near_.insert(near_.end(), work_[c].near.begin(), work_[c].near.end());
    }
    near_start_[V] = int64_t(near_.size());
}

// Voxel v's class (KEEP, DROP, MIXED) from its candidates, with its nearby list (distances
// from its points' box centre, nearest first) for MIXED.
int CloudBuilder::classify(const Model& m, int64_t v, double r, std::vector<Nearby>& near) {
    const double* lo = tally_.lo.data() + 3 * v;
    const double* hi = tally_.hi.data() + 3 * v;
    const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double h0 = 0.5 * (hi[0] - lo[0]), h1 = 0.5 * (hi[1] - lo[1]),
                 h2 = 0.5 * (hi[2] - lo[2]);
    const double h = std::sqrt(h0 * h0 + h1 * h1 + h2 * h2);
    const int64_t first = near.size();
    bool far = true, closed_mesh = false;
    for (int64_t k = start_[v]; k < start_[v + 1]; ++k) {
        const Candidate& cand = sorted_[k];
        double x[3], y[3];
        apply(body_pose_.data() + 12 * cand.body, c, x);
        double d;
        if (cand.item >= 0) {
            d = std::sqrt(triangle_box_detail::closest_on_triangle(
                x, triangle_at(m.forest.tris, cand.item), y));
        } else {
            const double* s = m.elem_solid + SOLID_WIDTH * (-1 - cand.item);
            if (int(s[0]) == SOLID_CLOSED_MESH) {
                closed_mesh = true;
                near.push_back({INF, cand.body, cand.item});
                continue;
            }
            d = solid_distance(s, x);
        }
        if (d + h <= r) {
            near.resize(first);
            return DROP;
        }
        far &= d - h > r;
        near.push_back({d, cand.body, cand.item});
    }
    if (far) {
        // No surface comes within r of the points' box: every point is on the same side of
        // each closed mesh; the centre tells which.
        bool inside = false;
        if (closed_mesh) {
            for (int64_t k = first; k < int64_t(near.size()) && !inside; ++k) {
                if (near[k].distance < INF) continue;
                double x[3];
                apply(body_pose_.data() + 12 * near[k].body, c, x);
                inside = inside_solid(m, -1 - near[k].item, x);
            }
        }
        near.resize(first);
        return inside ? DROP : KEEP;
    }
    std::sort(near.begin() + first, near.end(),
              [](const Nearby& a, const Nearby& b) { return a.distance < b.distance; });
    return MIXED;
}

// True iff point x (world) of a MIXED voxel is removed: within r of a nearby triangle or
// solid, or inside a nearby closed mesh. near: the voxel's list, distances from centre.
bool CloudBuilder::removed(const Model& m, const double* x, double r, const Nearby* near,
                           int64_t n_near, const double* centre) {
    const double dx = x[0] - centre[0], dy = x[1] - centre[1], dz = x[2] - centre[2];
    const double offset = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double r2 = r * r;
    for (int64_t k = 0; k < n_near; ++k) {
        const Nearby& n = near[k];
        if (n.distance == INF) break;  // closed meshes last (sorted)
        // |x - c| bounds how much nearer than the centre x can be (distance is 1-Lipschitz).
        if (n.distance - offset > r) break;
        double xb[3], y[3];
        apply(body_pose_.data() + 12 * n.body, x, xb);
        if (n.item >= 0) {
            if (triangle_box_detail::closest_on_triangle(xb, triangle_at(m.forest.tris, n.item),
                                                         y) <= r2)
                return true;
        } else if (solid_distance(m.elem_solid + SOLID_WIDTH * (-1 - n.item), xb) <= r) {
            return true;
        }
    }
    for (int64_t k = n_near - 1; k >= 0 && near[k].distance == INF; --k) {
        double xb[3];
        apply(body_pose_.data() + 12 * near[k].body, x, xb);
        if (inside_solid(m, -1 - near[k].item, xb)) return true;
    }
    return false;
}

CloudStats CloudBuilder::build(const Model& m, const double* T_links, const CloudPoints& pts,
                               const CloudSettings& s, const VoxelGrid& previous,
                               VoxelGrid& out, std::vector<float>* kept) {
    CloudStats stats;
    stats.points = pts.rows;
    const int64_t step = pts.rows > s.max_points ? (pts.rows + s.max_points - 1) / s.max_points
                                                 : 1;
    const int64_t taken = pts.rows > 0 ? (pts.rows + step - 1) / step : 0;
    stats.capped = pts.rows - taken;
    const double size = s.voxel_size, inv = 1.0 / size, r = s.filter_padding;
    const double range2 = s.max_range * s.max_range;

    // World -> body poses at the cloud's state, and the frame's pose.
    body_pose_.resize(12 * m.n_links);
    for (int64_t b = 0; b < m.n_links; ++b) {
        const double* T = T_links + 16 * b;
        double* P = body_pose_.data() + 12 * b;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) P[3 * i + j] = T[4 * j + i];
            P[9 + i] = -(T[i] * T[3] + T[4 + i] * T[7] + T[8 + i] * T[11]);
        }
    }
    RowPass pass{&pts, step, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, inv, range2, {}, {}};
    double* frame = pass.frame;
    if (s.frame >= 0) {
        const double* T = T_links + 16 * s.frame;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) frame[3 * i + j] = T[4 * i + j];
            frame[9 + i] = T[4 * i + 3];
        }
    }

    // The region the robot's geometry grown by r can reach: the world box around its bodies'
    // boxes. Points outside it are kept untested, and only voxels with points in it (near
    // voxels) are looked at further.
    double* region_lo = pass.region_lo;
    double* region_hi = pass.region_hi;
    for (int i = 0; i < 3; ++i) {
        region_lo[i] = INF;
        region_hi[i] = -INF;
    }
    for (int64_t b = 0; b < m.n_links; ++b) {
        if (m.elements(b) == 0) continue;
        const double* T = T_links + 16 * b;
        const double* box = m.body_box(b);
        for (int i = 0; i < 3; ++i) {
            double c = T[4 * i + 3], e = r;
            for (int k = 0; k < 3; ++k) {
                c += T[4 * i + k] * box[BOX_CENTER + k];
                const double axis = T[4 * i] * box[BOX_AXES + k] +
                                    T[4 * i + 1] * box[BOX_AXES + 3 + k] +
                                    T[4 * i + 2] * box[BOX_AXES + 6 + k];
                e += std::fabs(axis) * box[BOX_HALF + k];
            }
            e += BOUND_ROUNDING_REL * (std::fabs(c) + e);  // rounding: err toward near
            region_lo[i] = std::min(region_lo[i], c - e);
            region_hi[i] = std::max(region_hi[i], c + e);
        }
    }
    auto in_region = [&](const double* w) {
        return w[0] >= region_lo[0] && w[0] <= region_hi[0] && w[1] >= region_lo[1] &&
               w[1] <= region_hi[1] && w[2] >= region_lo[2] && w[2] <= region_hi[2];
    };

    // Points into voxels (the hash tables sized for the last cloud's voxels): the rows in k
    // contiguous chunks, chunk 0 into tally_, chunk c >= 1 into chunks_[c - 1] on a thread of
    // its own, merged into tally_ in chunk order. Voxels are numbered as one pass would number
    // them (in the order their first point comes: chunk 0's, then each later chunk's new
    // ones in its own order), and counts, boxes (min, max) and rows merge exactly, so the
    // grid is the same on any number of threads.
    const int64_t expected = std::max<int64_t>(MIN_TABLE, next_power_of_two(4 * out.count + 1));
    const int64_t k = std::max<int64_t>(
        1, std::min<int64_t>(s.threads, taken / MIN_CHUNK_ROWS));
    tally_.clear(expected);
    if (int64_t(chunks_.size()) < k - 1) {
        chunks_.resize(k - 1);
        chunk_voxel_.resize(k - 1);
    }
    row_voxel_.resize(taken);
    run_chunks(k, [&](int64_t c) {
        const Chunk rows = chunk_of(c, k, taken);
        Tally& tally = c == 0 ? tally_ : chunks_[c - 1];
        if (c > 0) tally.clear(expected);
        tally_rows(pass, rows.begin, rows.end, tally, row_voxel_.data());
    });
    for (int64_t c = 1; c < k; ++c) {
        const Tally& from = chunks_[c - 1];
        std::vector<int32_t>& to = chunk_voxel_[c - 1];
        to.resize(from.n);
        for (int64_t u = 0; u < from.n; ++u) {
            const int32_t* ijk = from.ijk.data() + 3 * u;
            const int64_t v = tally_.slot_of(pack_key(ijk[0], ijk[1], ijk[2]));
            to[u] = int32_t(v);
            tally_.count[v] += from.count[u];
            tally_.near_count[v] += from.near_count[u];
            for (int a = 0; a < 3; ++a) {
                tally_.lo[3 * v + a] = std::min(tally_.lo[3 * v + a], from.lo[3 * u + a]);
                tally_.hi[3 * v + a] = std::max(tally_.hi[3 * v + a], from.hi[3 * u + a]);
            }
        }
        tally_.invalid += from.invalid;
        tally_.out_of_range += from.out_of_range;
    }
    // Row t of chunk c >= 1 holds its voxel's number in chunks_[c - 1]; the second pass (the
    // same chunks) reads it through chunk_voxel_[c - 1].
    const int64_t row_chunks = k;
    stats.invalid = tally_.invalid;
    stats.out_of_range = tally_.out_of_range;
    old_seen_.assign(tally_.n, -INF);
    // Earlier voxels still within the persistence, not seen in this cloud: their centres.
    if (s.persistence > 0.0 && previous.size == size) {
        for (int64_t v = 0; v < previous.count; ++v) {
            if (!(previous.seen[v] >= s.stamp - s.persistence)) continue;
            const int32_t* c = previous.ijk.data() + 3 * v;
            const int64_t u = tally_.slot_of(pack_key(c[0], c[1], c[2]));
            old_seen_.resize(tally_.n, -INF);
            if (tally_.count[u] > 0) continue;
            old_seen_[u] = std::max(old_seen_[u], previous.seen[v]);
            double centre[3];
            for (int k = 0; k < 3; ++k) centre[k] = size * (c[k] + 0.5);
            if (in_region(centre)) {
                tally_.near_count[u] = 1;
                for (int k = 0; k < 3; ++k) tally_.lo[3 * u + k] = tally_.hi[3 * u + k] = centre[k];
            }
        }
    }

    // The filter's hierarchy over the near voxels, each with the box of its near points.
    const int64_t V = tally_.n;
    sort_.keyed.clear();
    for (int64_t v = 0; v < V; ++v)
        if (tally_.near_count[v] > 0)
            sort_.keyed.push_back(
                {morton_code(tally_.ijk[3 * v], tally_.ijk[3 * v + 1], tally_.ijk[3 * v + 2]), v});
    sort_by_code(sort_);
    const int64_t n_near = int64_t(sort_.keyed.size());
    codes_.resize(n_near);
    order_.resize(n_near);
    item_lo_.resize(3 * n_near);
    item_hi_.resize(3 * n_near);
    for (int64_t i = 0; i < n_near; ++i) {
        const int64_t v = sort_.keyed[i].second;
        codes_[i] = sort_.keyed[i].first;
        order_[i] = v;
        for (int k = 0; k < 3; ++k) {
            item_lo_[3 * i + k] = tally_.lo[3 * v + k];
            item_hi_[3 * i + k] = tally_.hi[3 * v + k];
        }
    }
    build_box_hierarchy(codes_.data(), item_lo_.data(), item_hi_.data(), n_near, 1,
                        filter_nodes_, filter_boxes_);
    if (n_near > 0) collect_candidates(m, T_links, r, s.threads);
    else start_.assign(V + 1, 0);

    // Each near voxel's class (its near points kept, removed, or tested one by one); the
    // others keep theirs. Points are read again only where needed.
    class_.assign(V, KEEP);
    kept_.assign(V, 0);
    classify_voxels(m, r, s.threads);
    bool again = kept && s.keep_points;
    for (int64_t v = 0; v < V; ++v)
        again |= class_[v] == MIXED || (class_[v] == DROP && tally_.near_count[v] < tally_.count[v]);
    if (kept) kept->clear();
    const bool keep_rows = kept && s.keep_points;
    // Voxels kept or removed whole need no row read: their counts first.
    for (int64_t v = 0; v < V; ++v) {
        if (class_[v] == KEEP) {
            kept_[v] = tally_.count[v];
            stats.kept_points += tally_.count[v];
        } else if (class_[v] == DROP && tally_.near_count[v] == tally_.count[v]) {
            stats.self_filtered += tally_.count[v];
        }
    }
    if (again) {
        // The other rows (and every row when they are written) in the first pass's chunks:
        // chunk 0 into kept_ and kept, chunk c >= 1 into rows_[c - 1], added and appended in
        // chunk order (the one thread's counts and rows).
        const int64_t k = row_chunks;
        if (int64_t(rows_.size()) < k - 1) rows_.resize(k - 1);
        run_chunks(k, [&](int64_t c) {
            const Chunk rows = chunk_of(c, k, taken);
            const int32_t* merged = c == 0 ? nullptr : chunk_voxel_[c - 1].data();
            KeptRows* own = c == 0 ? nullptr : &rows_[c - 1];
            if (own) {
                own->counts.assign(V, 0);
                own->points.clear();
                own->self_filtered = 0;
            }
            int32_t* counts = own ? own->counts.data() : kept_.data();
            std::vector<float>* points = own ? &own->points : kept;
            int64_t self_filtered = 0;
            for (int64_t t = rows.begin; t < rows.end; ++t) {
                const int64_t u = row_voxel_[t];
                if (u < 0) continue;
                const int64_t v = merged ? merged[u] : u;
                const uint8_t cls = class_[v];
                if (cls == KEEP ? !keep_rows
                                : cls == DROP && tally_.near_count[v] == tally_.count[v])
                    continue;  // counted above
                double x[3], w[3];
                read_row(pts, t * step, x);
                apply(frame, x, w);
                if (cls != KEEP && in_region(w)) {
                    const double* lo = tally_.lo.data() + 3 * v;
                    const double* hi = tally_.hi.data() + 3 * v;
                    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                              0.5 * (lo[2] + hi[2])};
                    if (cls == DROP || removed(m, w, r, near_.data() + near_start_[v],
                                               near_start_[v + 1] - near_start_[v], centre)) {
                        ++self_filtered;
                        continue;
                    }
                }
                if (cls != KEEP) ++counts[v];
                if (keep_rows)
                    points->insert(points->end(), {float(w[0]), float(w[1]), float(w[2])});
            }
            if (own) own->self_filtered = self_filtered;
            else stats.self_filtered += self_filtered;
        });
        for (int64_t c = 1; c < k; ++c) {
            const KeptRows& from = rows_[c - 1];
            for (int64_t v = 0; v < V; ++v) kept_[v] += from.counts[v];
            stats.self_filtered += from.self_filtered;
            if (keep_rows) kept->insert(kept->end(), from.points.begin(), from.points.end());
        }
        for (int64_t v = 0; v < V; ++v)
            if (class_[v] != KEEP) stats.kept_points += kept_[v];
    }

    // The voxels kept: those with a point kept, and earlier ones whose centre is kept.
    out_ijk_.clear();
    out_seen_.clear();
    for (int64_t v = 0; v < V; ++v) {
        const bool earlier = tally_.count[v] == 0;
        if (earlier ? class_[v] != KEEP : kept_[v] == 0) continue;
        out_ijk_.insert(out_ijk_.end(), {tally_.ijk[3 * v], tally_.ijk[3 * v + 1], tally_.ijk[3 * v + 2]});
        out_seen_.push_back(earlier ? old_seen_[v] : s.stamp);
        stats.persisted += earlier ? 1 : 0;
    }
    build_voxel_grid(out_ijk_.data(), out_seen_.data(), int64_t(out_seen_.size()), size, sort_,
                     out);
    stats.voxels = out.count;
    return stats;
}

}  // namespace collision_sensor
