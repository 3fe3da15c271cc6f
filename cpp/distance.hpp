// Distances with nearest points between two OBB trees, for the proximity query.
//
// trees_distance: the smallest triangle distance between two OBB trees (obb_tree.hpp's
// tables), found by the descent (descent.hpp) with a lower bound per node pair, pruning every
// node pair whose bound is not below the best distance found so far, which starts at the
// caller's cutoff (max_distance, or the best over the pair's other trees, or the distance of
// the triangles nearest last time): a pair with nothing nearer than the cutoff costs only the
// node pairs that prove it. The nearer child pair is visited first. Leaves are measured with
// triangle_distance (triangle_distance.hpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "box_pair.hpp"
#include "descent.hpp"
#include "inlining.hpp"
#include "leaf_pair.hpp"
#include "triangle_distance.hpp"

namespace collision_sensor {

// The nearest triangles found by trees_distance: the padded distance (the triangles'
// distance minus the pair's padding), the points on each (x in body a's frame on tree a's
// triangle, y on tree b's, also in body a's frame), and the two triangles' rows of tris.
struct NearestPoints {
    double distance;
    double x[3], y[3];
    int64_t ia, ib;
    bool found;  // false: nothing nearer than the cutoff

    // Take triangles ia, ib at distance d, nearest points x, y, as the best so far.
    void take(double d, int64_t tri_a, int64_t tri_b, const double* px, const double* py) {
        distance = d;
        found = true;
        ia = tri_a;
        ib = tri_b;
        std::memcpy(x, px, sizeof x);
        std::memcpy(y, py, sizeof y);
    }
};

// A lower bound of the distance between boxes A and B, B in A's box frame (T: R, t as
// box_in_frame). The boxes' gap along a unit axis bounds their distance whatever the axis;
// this one aims at the nearest points by alternating projection (x, the point of A nearest
// B's centre; y, the point of B nearest x; x again, the point of A nearest y; u = y - x:
// more rounds converge to a nearest pair, but prune no more node pairs). The gap along u is (min over B of u.p) - (max over A of u.p), with each box's support
// |u . axis_k| h_k. (The face axes' gap would add almost nothing on top of it.)
// Boxes whose projection meets (overlapping, or nearly) get face_gap. With dir, u / |u| (A's
// box frame) is written there, or 0 for face_gap's answer.
CS_ALWAYS_INLINE double projected_gap(const double* A, const double* B, const double* T,
                                      double* dir = nullptr) {
    using std::fabs;
    const double* ha = A + BOX_HALF;
    const double* hb = B + BOX_HALF;
    const double* R = T;  // column k: B's axis k in A's box frame
    const double* t = T + 9;
    auto clamp = [](double v, double h) { return v < -h ? -h : (v > h ? h : v); };
    double x[3], y[3], z[3];
    for (int i = 0; i < 3; ++i) x[i] = clamp(t[i], ha[i]);
    // y: x taken to B's box frame (R' (x - t)), clamped, and back (R z + t).
    const double w0 = x[0] - t[0], w1 = x[1] - t[1], w2 = x[2] - t[2];
    for (int k = 0; k < 3; ++k) z[k] = clamp(R[k] * w0 + R[3 + k] * w1 + R[6 + k] * w2, hb[k]);
    for (int i = 0; i < 3; ++i)
        y[i] = R[3 * i] * z[0] + R[3 * i + 1] * z[1] + R[3 * i + 2] * z[2] + t[i];
    for (int i = 0; i < 3; ++i) x[i] = clamp(y[i], ha[i]);
    const double u0 = y[0] - x[0], u1 = y[1] - x[1], u2 = y[2] - x[2];
    const double uu = u0 * u0 + u1 * u1 + u2 * u2;
    if (!(uu > 0.0)) {
        if (dir) dir[0] = dir[1] = dir[2] = 0.0;
        return face_gap(A, B, T);
    }
    // The gap along u / |u|, computed along u and divided once.
    double g = u0 * t[0] + u1 * t[1] + u2 * t[2] -
               (ha[0] * fabs(u0) + ha[1] * fabs(u1) + ha[2] * fabs(u2));
    for (int k = 0; k < 3; ++k) g -= hb[k] * fabs(R[k] * u0 + R[3 + k] * u1 + R[6 + k] * u2);
    const double norm = std::sqrt(uu);
    if (dir) {
        dir[0] = u0 / norm;
        dir[1] = u1 / norm;
        dir[2] = u2 / norm;
    }
    return g / norm;
}

// Tree b's boxes placed in body a's frame, each computed once per traversal (a node of tree b
// meets many of tree a's): rows (N, PLACED_WIDTH), the centre R_ab cb + t_ab, then the axes
// R_ab Eb (row-major, column k is axis k); a row is current iff stamp[n] == tag.
constexpr int PLACED_WIDTH = 12;

// A node pair's bound along the slab direction (below) is trusted without the boxes' own
// bound (projected_gap, which costs as much as the rest of the node pair) once it comes within
// this fraction of the best distance: the pair is then near the best along the direction of
// the nearest points, where a direction of its own rarely proves more. Only the work depends
// on it, never the answer.
constexpr double SLAB_TRUST_REL = 0.05;

// Work rows of the proximity traversal, one per node of the forest (proximity.cpp sizes them
// on the first call): placed boxes (placed, placed_stamp) and each node's support along the
// slab direction (support, support_stamp). A row is current iff its stamp equals the tag.
struct DistanceWork {
    double* placed;
    int64_t* placed_stamp;
    double* support;
    int64_t* support_stamp;
    int64_t placed_tag, support_tag;
};

// The slab direction of a traversal: a unit vector u in body a's frame, from the nearest
// point on body a to the one on body b found so far; ub = R_ab' u (body b's frame) and
// offset = u . t_ab. For p under a node of tree a and q under one of tree b,
//     |q - p| >= u . (q - p) >= min_q (u . q) - max_p (u . p)
// so each node's support along u (max for tree a, min for tree b, padding included) bounds
// every node pair it is in, for one subtraction per pair: the cheap bound of this traversal.
// Far apart bodies are exactly where the boxes' own bound is dear (thousands of triangle pairs
// within a few per cent of the nearest), and there the nearest points' direction is nearly
// every near node pair's own.
struct Slab {
    bool active;
    double u[3], ub[3], offset;
    double pad_a, pad_b;
};

// Node n's support along the slab direction: max of u . p over tree a's node (side_b false),
// min over tree b's (side_b true: in body a's frame, as u . (R_ab q + t_ab) = ub . q +
// offset), the padded geometry's: a leaf's triangles' vertices moved by the padding, an inner
// node's box (already grown by it, see obb_tree's padded boxes in the checker).
CS_ALWAYS_INLINE double node_support(const Forest& f, int64_t n, const Slab& s, bool side_b,
                                     DistanceWork& work) {
    if (work.support_stamp[n] == work.support_tag) return work.support[n];
    const double* u = side_b ? s.ub : s.u;
    const int64_t* node = f.node(n);
    double v;
    if (node[NODE_LEFT] < 0) {
        const double* x = f.tris + 9 * node[NODE_FIRST];
        const double* end = x + 9 * node[NODE_COUNT];
        v = u[0] * x[0] + u[1] * x[1] + u[2] * x[2];
        for (x += 3; x < end; x += 3) {
            const double w = u[0] * x[0] + u[1] * x[1] + u[2] * x[2];
            v = side_b ? std::min(v, w) : std::max(v, w);
        }
        v = side_b ? v - s.pad_b : v + s.pad_a;
    } else {
        const double* B = f.box(n);
        const int e = BOX_AXES, h = BOX_HALF;
        double r = 0.0;
        for (int k = 0; k < 3; ++k)
            r += B[h + k] *
                 std::fabs(u[0] * B[e + k] + u[1] * B[e + 3 + k] + u[2] * B[e + 6 + k]);
        const double c = u[0] * B[0] + u[1] * B[1] + u[2] * B[2];
        v = side_b ? c - r : c + r;
    }
    if (side_b) v += s.offset;
    work.support_stamp[n] = work.support_tag;
    work.support[n] = v;
    return v;
}

// Aim the slab at the nearest points of best (body b at pose P); every support is stale then.
// Points that coincide give no direction: the slab stays as it was.
inline void aim_slab(const NearestPoints& best, const double* P, Slab& s, DistanceWork& work) {
    const double w0 = best.y[0] - best.x[0], w1 = best.y[1] - best.x[1],
                 w2 = best.y[2] - best.x[2];
    const double ww = w0 * w0 + w1 * w1 + w2 * w2;
    if (!(ww > 0.0)) return;
    const double k = 1.0 / std::sqrt(ww);
    s.u[0] = w0 * k;
    s.u[1] = w1 * k;
    s.u[2] = w2 * k;
    for (int j = 0; j < 3; ++j) s.ub[j] = P[j] * s.u[0] + P[3 + j] * s.u[1] + P[6 + j] * s.u[2];
    s.offset = s.u[0] * P[9] + s.u[1] * P[10] + s.u[2] * P[11];
    s.active = true;
    ++work.support_tag;
}

// Node nb's box (tree b at pose P) placed in body a's frame: its work row (PLACED_WIDTH),
// computed on first need in a traversal (work.placed_tag, which the traversal advances).
CS_ALWAYS_INLINE const double* placed_row(const Forest& f, int64_t nb, const double* P,
                                          DistanceWork& work) {
    double* row = work.placed + PLACED_WIDTH * nb;
    if (work.placed_stamp[nb] != work.placed_tag) {
        work.placed_stamp[nb] = work.placed_tag;
        const double* B = f.box(nb);
        const int e = BOX_AXES;
        for (int i = 0; i < 3; ++i) {
            row[i] = P[3 * i] * B[0] + P[3 * i + 1] * B[1] + P[3 * i + 2] * B[2] + P[9 + i];
            for (int k = 0; k < 3; ++k)
                row[3 + 3 * i + k] = P[3 * i] * B[e + k] + P[3 * i + 1] * B[e + 3 + k] +
                                     P[3 * i + 2] * B[e + 6 + k];
        }
    }
    return row;
}

// box_in_frame from B's placed row: [R, t] = [Ea' (R_ab Eb), Ea' d], d = (R_ab cb + t_ab) - ca
// (centre_offset), which the caller has.
CS_ALWAYS_INLINE void placed_in_frame(const double* A, const double* row, const double* d,
                                      double* T) {
    const int e = BOX_AXES;
    const double* M = row + 3;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k)
            T[3 * i + k] = A[e + i] * M[k] + A[e + 3 + i] * M[3 + k] + A[e + 6 + i] * M[6 + k];
        T[9 + i] = A[e + i] * d[0] + A[e + 3 + i] * d[1] + A[e + 6 + i] * d[2];
    }
}

// Lower bound of the distance between node na's box (tree a) and node nb's (tree b at pose
// P): projected_gap, with nb's placement taken from (or put into) the work rows.
CS_ALWAYS_INLINE double placed_node_gap(const Forest& f, int64_t na, int64_t nb,
                                        const double* P, DistanceWork& work) {
    const double* A = f.box(na);
    const double* row = placed_row(f, nb, P, work);
    const double d[3] = {row[0] - A[0], row[1] - A[1], row[2] - A[2]};
    double T[12];
    placed_in_frame(A, row, d, T);
    return projected_gap(A, f.box(nb), T);
}

// The smallest padded distance (triangle distance minus pad_a + pad_b) between the triangles
// under node ra (body a) and under node rb (body b at pose P in body a's frame), if it is
// below best.distance: then best is replaced (points in body a's frame, on the triangles).
// Stops once the triangles touch or cross (padded distance -pad_a - pad_b, the least there
// is). The boxes must hold the padded geometry (the checker grows each body's boxes by its
// padding): every bound is then one of the padded distance.
//
// Bounds, cheapest first: once a nearest pair is known (from the caller's seed, or the first
// leaf reached), the slab's (node_support), and, unless that one comes within SLAB_TRUST_REL
// of the best, the boxes' own (placed_node_gap); the larger decides.
//
// A distance traversal node (as traversal.hpp's TreePairTraversal): the forest holding both
// trees, body b's pose in body a's frame, the two bodies' paddings, and the work areas.
// work.stack: rows >= depth(a) + depth(b) + 2, each (na, nb, bits of the node pair's lower
// bound); work.counters: COUNT_BOX_TESTS (node pairs bounded by their boxes) and
// COUNT_TRIANGLE_TESTS (triangle pairs measured) grow. rows: one per node of the forest (its
// tags are advanced).
struct DistanceTraversal {
    const Forest& forest;
    const double* pose;
    double pad_a, pad_b;
    TraversalWork work;
    DistanceWork& rows;
};

// The distance's node for the descent (descent.hpp): branch and bound, as its order. Each
// child pair's lower bound is computed when its parent is expanded, and kept with it on the
// stack (the word: the bound's bits); the pair of the lower bound is visited first, one whose
// bound is not below the best distance is never pushed, and one whose bound the best has
// passed since it was pushed is dropped when popped.
struct DistanceNode {
    static constexpr bool WHOLE_A = false;
    struct Seen {
        double bound;  // the popped pair's lower bound
    };

    const Forest& f;
    const double* P;
    const double pad;
    const double stop;
    DistanceWork& work;
    NearestPoints& best;
    Slab slab;
    int64_t n_boxes = 0, n_triangles = 0;

    DistanceNode(const DistanceTraversal& t, NearestPoints& best, double floor)
        : f(t.forest),
          P(t.pose),
          pad(t.pad_a + t.pad_b),
          stop(std::max(-(t.pad_a + t.pad_b), floor)),
          work(t.rows),
          best(best),
          slab{false, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, 0.0, t.pad_a, t.pad_b} {
        if (best.found) aim_slab(best, P, slab, work);
    }

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return f.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const { return f.node(n); }

    // The pair's lower bound: the slab's, and the boxes' own unless the slab's is within
    // SLAB_TRUST_REL of the best (or not below it).
    CS_ALWAYS_INLINE double bound(int64_t na, int64_t nb) {
        double g = -INF;
        if (slab.active) {
            g = node_support(f, nb, slab, true, work) - node_support(f, na, slab, false, work);
            if (!(g < best.distance) ||
                g > best.distance - SLAB_TRUST_REL * std::fabs(best.distance))
                return g;
        }
        ++n_boxes;
        return std::max(g, placed_node_gap(f, na, nb, P, work));
    }

    static CS_ALWAYS_INLINE int64_t word_of(double bound) {
        int64_t word;
        std::memcpy(&word, &bound, sizeof word);
        return word;
    }

    CS_ALWAYS_INLINE bool apart(int64_t, int64_t, int64_t word, Seen& seen) const {
        std::memcpy(&seen.bound, &word, sizeof seen.bound);
        return seen.bound >= best.distance;  // the best improved since it was pushed
    }

    // Every triangle pair measured; the search ends once the best is at most the floor.
    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t* node_a, const int64_t* node_b,
                                 const Seen& seen) {
        each_triangle_pair(f.tris, node_a, node_b, P,
                           [&](const Triangle& A, const Triangle& Q, int64_t ia, int64_t ib) {
            ++n_triangles;
            // bound > 0: the padded geometry apart, so the triangles too.
            double x[3], y[3];
            const double d = triangle_distance(A, Q, x, y, seen.bound > 0.0) - pad;
            if (d < best.distance) {
                best.take(d, ia, ib, x, y);
                aim_slab(best, P, slab, work);
            }
            return false;
        });
        return !(best.distance > stop);
    }

    // The larger box (EXPAND_WIDER's rule).
    CS_ALWAYS_INLINE bool split_a(int64_t na, int64_t nb, int64_t, const Seen&) const {
        return f.box(na)[BOX_RADIUS] >= f.box(nb)[BOX_RADIUS];
    }

    // The child pair of the lower bound first (the right one on a tie); a child pair whose
    // bound is not below the best is not visited.
    CS_ALWAYS_INLINE void order(int64_t na, int64_t nb, int64_t, bool on_a, ChildPairs& c,
                                const Seen&) {
        const double g_left = on_a ? bound(c.first, nb) : bound(na, c.first);
        const double g_right = on_a ? bound(c.second, nb) : bound(na, c.second);
        double g_first = g_left, g_second = g_right;
        if (!(g_left < g_right)) {
            c.swap();
            std::swap(g_first, g_second);
        }
        c.word_first = word_of(g_first);
        c.word_second = word_of(g_second);
        c.visit_first = g_first < best.distance;
        c.visit_second = g_second < best.distance;
    }
};

// trees_distance's floor: the search stops once best.distance is at most floor (a caller that
// only asks whether the distance exceeds floor has its answer then; -INF: the smallest).
// Forced inline, into its callers' loops over a pair's trees (proximity.cpp, motion.cpp): left
// out of line, the callers' own box tests compile to more instructions.
CS_ALWAYS_INLINE void trees_distance(const DistanceTraversal& traversal, int64_t ra,
                                     int64_t rb, NearestPoints& best, double floor = -INF) {
    ++traversal.rows.placed_tag;
    DistanceNode node(traversal, best, floor);
    const double root = node.bound(ra, rb);
    if (root < best.distance && best.distance > node.stop) {
        seed_pair(traversal.work.stack, 0, ra, rb, DistanceNode::word_of(root));
        descend(node, traversal.work.stack, 1);
    }
    traversal.work.counters[COUNT_BOX_TESTS] += node.n_boxes;
    traversal.work.counters[COUNT_TRIANGLE_TESTS] += node.n_triangles;
}

}  // namespace collision_sensor
