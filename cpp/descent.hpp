// The descent of two trees (paper sec. 4.1), written once: every query on a pair of
// hierarchies is this descent with a node of its own (coal's traversal nodes: the node owns
// the two trees, the pose, what is asked and what is found; the descent takes the node and the
// node pairs to start from):
//   collide_trees   traversal.hpp        do any triangles meet (within a padding)?
//   trees_distance  distance.hpp         the nearest triangles (branch and bound)
//   trees_within    motion_within.hpp    apart over an interval of a path?
//   a body against a point cloud's voxels, and the cloud's self-filter: cloud_queries.cpp,
//   cloud_self_filter.cpp (tree b a VoxelGrid's hierarchy, or the filter's).
//
// Node pairs wait on a stack of rows (na, nb, word), int64: na a node of tree a, nb one of
// tree b, and a word the node keeps with the pair (the depth of the descent, for the expansion
// rules; the bits of the pair's lower bound, for the distance). The stack's first rows are the
// seeds (a pair's root pairs, or a front); the descent pops a row and asks the node, in turn:
//
//   apart(na, nb, word, seen)     true: nothing under the pair needs testing (its boxes apart,
//                                 or its bound no better than the best so far): the pair is
//                                 settled there (and recorded, by a node that keeps a front);
//   leaves(na, nb, row_a, row_b, seen)   both are leaves (node rows of obb_tree.hpp): test
//                                 what they hold; true: the search is over (a hit, or a best
//                                 that is good enough), the rows left on the stack untested;
//   split_a(na, nb, word, seen)   neither is a leaf: true to expand na (its two children
//                                 against nb), false to expand nb; a leaf is never expanded;
//   order(na, nb, word, split_a, children, seen)   the two child pairs: which is visited
//                                 first, the words they carry, whether each is visited at all
//                                 (the distance visits the pair of lower bound first and
//                                 drops one whose bound is no better than the best: its branch
//                                 and bound is this order, not a descent of its own).
//
// `seen` is the node's Seen, a fresh one per pair: what apart found that the later hooks reuse
// (the boxes, their centres' offset). A node also gives node_a(n), node_b(n): the node rows of
// its two trees (a Forest, a VoxelGrid's hierarchy, the self-filter's); WHOLE_A: tree a is
// taken whole, its root's box for everything under it (a solid element), never expanded.
//
// The descent and every node's hooks are forced inline (descend is a template; each node is
// defined beside the one query that uses it): each query's loop must compile into one
// function, with the node's fields in registers (a hook left out of line would pass the node by
// address, and every field would then be read from memory at each pair, across the stack's
// writes, which may alias them).
#pragma once

#include <cstdint>
#include <limits>
#include <utility>

#include "inlining.hpp"
#include "obb_tree.hpp"

namespace collision_sensor {

constexpr double INF = std::numeric_limits<double>::infinity();

// A pose: body b in body a's frame, R_ab row-major, then t_ab.
constexpr int POSE_WIDTH = 12;

// counters[COUNT_*]: work done, for the benchmarks and tests.
constexpr int COUNT_BOX_TESTS = 0, COUNT_TRIANGLE_TESTS = 1, COUNT_SPHERE_SKIPS = 2,
              COUNT_FRONT_STARTS = 3, COUNT_FRONT_UNTESTED = 4, COUNT_SWEEPS = 5,
              COUNT_SWEEP_STEPS = 6, COUNT_MEASURES = 7, N_COUNTERS = 8;

// A descent's stack rows: (na, nb, word).
constexpr int PAIR_ROW = 3;

// Where a descent works: stack (rows, PAIR_ROW) int64, and counters (N_COUNTERS,) it adds to.
// A descent from n seeds holds at most n + depth(a) + depth(b) rows: each pair it expands
// replaces itself by two one level down.
struct TraversalWork {
    int64_t* stack;
    int64_t* counters;
};

// The two child pairs of an expanded pair: children of na (split_a) against nb, or of nb
// against na. On entry to order, first is the left child and second the right, both visited,
// words unset; order decides.
struct ChildPairs {
    int64_t first, second;
    int64_t word_first, word_second;
    bool visit_first, visit_second;

    // Visit the right child first.
    CS_ALWAYS_INLINE void swap() { std::swap(first, second); }
};

// Descend from the n_seeds pairs on top of stack (the rows below them are not read) until no
// pair is left or node.leaves ends the search. See the file's header for the hooks.
template <class Node>
CS_ALWAYS_INLINE void descend(Node& node, int64_t* stack, int64_t n_seeds) {
    int64_t top = n_seeds;
    while (top > 0) {
        --top;
        int64_t* row = stack + PAIR_ROW * top;
        const int64_t na = row[0], nb = row[1], word = row[2];
        typename Node::Seen seen;
        if (node.apart(na, nb, word, seen)) continue;
        const int64_t* row_a = node.node_a(na);
        const int64_t* row_b = node.node_b(nb);
        const bool leaf_a = Node::WHOLE_A || row_a[NODE_LEFT] < 0;
        const bool leaf_b = row_b[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            if (node.leaves(na, nb, row_a, row_b, seen)) return;
            continue;
        }
        const bool on_a = !leaf_a && (leaf_b || node.split_a(na, nb, word, seen));
        const int64_t* split = on_a ? row_a : row_b;
        ChildPairs c = {split[NODE_LEFT], split[NODE_RIGHT], 0, 0, true, true};
        node.order(na, nb, word, on_a, c, seen);
        // The first child pair goes on top: popped next.
        if (c.visit_second) {
            row[0] = on_a ? c.second : na;
            row[1] = on_a ? nb : c.second;
            row[2] = c.word_second;
            row += PAIR_ROW;
            ++top;
        }
        if (c.visit_first) {
            row[0] = on_a ? c.first : na;
            row[1] = on_a ? nb : c.first;
            row[2] = c.word_first;
            ++top;
        }
    }
}

// Write the seed row (na, nb, word) at row `at` of stack.
CS_ALWAYS_INLINE void seed_pair(int64_t* stack, int64_t at, int64_t na, int64_t nb,
                                int64_t word = 0) {
    int64_t* row = stack + PAIR_ROW * at;
    row[0] = na;
    row[1] = nb;
    row[2] = word;
}

// The paper's node expansion consideration (sec. 4.1), for two trees of a forest: which
// node of an overlapping pair is expanded. Only the work depends on the rule, never the
// answer; the benchmarks (python -m benchmarks) measure which is fastest.
//   EXPAND_SAME       always expand the first tree until it reaches a leaf, then the second;
//   EXPAND_ALTERNATE  alternate sides with the depth of the descent;
//   EXPAND_LARGER     expand the node with the larger box volume;
//   EXPAND_PROMISING  expand the node whose volume most exceeds the sum of its children's
//                     volumes (the paper's "most promising node");
//   EXPAND_WIDER      expand the node with the larger half diagonal |half| (its sphere's
//                     radius): unlike the volume, it sees the size of a flat box (the box of
//                     a few coplanar triangles has almost none), as FCL's rule does.
constexpr int EXPAND_SAME = 0, EXPAND_ALTERNATE = 1, EXPAND_LARGER = 2, EXPAND_PROMISING = 3,
              EXPAND_WIDER = 4;

// True iff the pair (na, nb), neither a leaf, of boxes A and B at depth `level` of the
// descent is expanded on side a by the rule `expansion` (EXPAND_*).
CS_ALWAYS_INLINE bool expand_first(const Forest& f, int64_t na, int64_t nb, const double* A,
                                   const double* B, int64_t level, int expansion) {
    switch (expansion) {
        case EXPAND_SAME:
            return true;
        case EXPAND_ALTERNATE:
            return level % 2 == 0;
        case EXPAND_LARGER:
            return f.volume[na] >= f.volume[nb];
        case EXPAND_WIDER:
            return A[BOX_RADIUS] >= B[BOX_RADIUS];
        default:
            return f.gain[na] >= f.gain[nb];
    }
}

// True iff the centre of box row m is nearer the point x than box row n's (same frame): a
// descent visits first the child nearer the other box (more likely to meet it: a colliding
// pair stops at its first meeting triangles).
CS_ALWAYS_INLINE bool nearer(const double* bm, const double* bn, double x0, double x1,
                             double x2) {
    const double a0 = bm[0] - x0, a1 = bm[1] - x1, a2 = bm[2] - x2;
    const double b0 = bn[0] - x0, b1 = bn[1] - x1, b2 = bn[2] - x2;
    return a0 * a0 + a1 * a1 + a2 * a2 < b0 * b0 + b1 * b1 + b2 * b2;
}

}  // namespace collision_sensor
