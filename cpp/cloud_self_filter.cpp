// The self-filter of a point cloud (cloud_filter.hpp: CloudBuilder): the robot's triangles
// and solids near each occupied voxel (candidates), each voxel's class from them, and the test
// of a point of a voxel that is neither wholly kept nor wholly removed.
#include "cloud_filter.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "containment.hpp"
#include "descent.hpp"
#include "inlining.hpp"
#include "leaf_pair.hpp"
#include "tolerances.hpp"
#include "triangle_box.hpp"
#include "workers.hpp"

namespace collision_sensor {

using namespace cloud_detail;

namespace {

// The fewest near voxels per thread collecting candidates, and the fewest candidates per
// thread classifying the voxels: enough work to repay starting and joining a thread.
constexpr int64_t MIN_NEAR_VOXELS = 256;
constexpr int64_t MIN_CLASSIFIED = 10000;
// Numbers cached per robot node in collect_candidates (its world boxes).
constexpr int64_t NODE_WORLD = 18;

}  // namespace

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

// Element e of body b against the filter's hierarchy (the descent, descent.hpp): tree a the
// element's, each node's box at the cloud's state grown by r (world_box), tree b the
// filter's (leaves of one voxel, world-aligned boxes). A leaf pair is a candidate: the robot
// leaf's triangles, or the element's solid (Solid: the element taken whole, its root's box).
// The larger node is expanded (the sum of its half extents), its right child visited first.
template <bool Solid>
struct CloudBuilder::CandidateNode {
    static constexpr bool WHOLE_A = Solid;
    struct Seen {
        const double* A;  // world_box(na)
        const double* B;
    };

    const Forest& f;
    const double* tree_boxes;
    const int64_t* tree_nodes;
    const double* T;  // body b's world pose (4, 4)
    const double r;
    double* node_world;  // NODE_WORLD numbers per robot node, current where stamped
    int64_t* node_stamp;
    const int64_t stamp;
    const int64_t* voxel_of;  // hierarchy item -> voxel
    const int64_t b, e;
    std::vector<Candidate>& out;

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return f.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const {
        return tree_nodes + NODE_WIDTH * n;
    }
    CS_ALWAYS_INLINE const double* box_b(int64_t n) const { return tree_boxes + BOX_WIDTH * n; }

    // A robot node's world-aligned box (centre, half extents) and its own box's world axes
    // and half extents, both grown by r (NODE_WORLD numbers: c, e, W (W[3k + i]: axis k's
    // world coordinate i), h).
    CS_ALWAYS_INLINE const double* world_box(int64_t n) {
        double* out = node_world + NODE_WORLD * n;
        if (node_stamp[n] == stamp) return out;
        node_stamp[n] = stamp;
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
    }

    // False when a robot node's box grown by r (world_box) and a box row of the hierarchy
    // (world-aligned) are apart on a world axis or on an axis k of the node's box (the row
    // reaches sum_i |W_k[i]| half_i along it). The node's axes cut candidates its world box,
    // up to sqrt(3) wider than the node on each axis when tilted, lets through. Both err wide
    // (rounding).
    static CS_ALWAYS_INLINE bool overlap(const double* A, const double* B) {
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
    }

    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nb, int64_t, Seen& seen) {
        const double* A = world_box(na);
        const double* B = box_b(nb);
        if (!overlap(A, B)) return true;
        seen = {A, B};
        return false;
    }

    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t* node_a, const int64_t* node_b,
                                 const Seen&) {
        const int64_t voxel = voxel_of[node_b[NODE_FIRST]];
        if (Solid) {
            out.push_back({voxel, b, -1 - e});
        } else {
            for (int64_t t = node_a[NODE_FIRST]; t < node_a[NODE_FIRST] + node_a[NODE_COUNT]; ++t)
                out.push_back({voxel, b, t});
        }
        return false;
    }

    CS_ALWAYS_INLINE bool split_a(int64_t, int64_t, int64_t, const Seen& seen) const {
        const double* A = seen.A;
        const double* B = seen.B;
        return A[3] + A[4] + A[5] >= B[BOX_HALF] + B[BOX_HALF + 1] + B[BOX_HALF + 2];
    }

    CS_ALWAYS_INLINE void order(int64_t, int64_t, int64_t, bool, ChildPairs& c, const Seen&) const {
        c.swap();
        c.word_first = c.word_second = 0;
    }
};

// Element e of body b against the filter's hierarchy: its candidates appended to work.found.
void CloudBuilder::element_candidates(const Model& m, const double* T_links, double r,
                                      int64_t b, int64_t e, FilterWork& work) {
    const double* T = T_links + 16 * b;
    CandidateNode<false> node = {m.forest,         filter_boxes_.data(), filter_nodes_.data(),
                                 T,                r,                    node_world_.data(),
                                 node_stamp_.data(), stamp_,             order_.data(),
                                 b,                e,                    work.found};
    if (!node.overlap(node.world_box(m.roots[e]), node.box_b(0))) return;
    const size_t rows = size_t(PAIR_ROW * (1 + m.depth + filter_depth_ + 2));
    if (work.stack.size() < rows) work.stack.resize(rows);
    int64_t* stack = work.stack.data();
    // The element's triangles against the voxels, then its solid, with its root box.
    seed_pair(stack, 0, m.roots[e], 0);
    descend(node, stack, 1);
    if (m.elem_solid[SOLID_WIDTH * e] != SOLID_NONE) {
        CandidateNode<true> whole = {m.forest,         filter_boxes_.data(), filter_nodes_.data(),
                                     T,                r,                    node_world_.data(),
                                     node_stamp_.data(), stamp_,             order_.data(),
                                     b,                e,                    work.found};
        seed_pair(stack, 0, m.roots[e], 0);
        descend(whole, stack, 1);
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

}  // namespace collision_sensor
