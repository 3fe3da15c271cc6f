// The collision test of two OBB trees (paper sec. 4.1): the descent (descent.hpp) with the
// node that tests boxes and triangles, and the front it records and re-settles.
//
// Two trees, each in its own body frame, are tested from their roots down. When two boxes
// overlap, one of them is expanded (its two children are tested against the other box, the
// request's expansion rule: descent.hpp, EXPAND_*); when both are leaves, their triangles are
// tested exactly.
//
// As coal's queries: a traversal is asked by a request (TraversalRequest: its options as named
// fields) and runs as a node (TreePairTraversal: the two trees' forest, body b's pose in body
// a's frame, the request, the work areas), descending from node pairs seeded on its stack.
// Trees are obb_tree.hpp's tables; a box is passed as a pointer to its row, a pose as a
// pointer to its POSE_WIDTH numbers: body b in body a's frame, R_ab row-major, then t_ab.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "box_pair.hpp"
#include "box_test.hpp"
#include "descent.hpp"
#include "inlining.hpp"
#include "leaf_pair.hpp"
#include "obb_tree.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

// A front is a table of node pairs (na, nb, how): how is the axis of the 15-axis test that
// separated the pair's boxes (0-14, see separating_axis), or one of these.
constexpr int64_t FRONT_LEAF = -1;    // a leaf pair tested triangle by triangle (apart then)
constexpr int64_t FRONT_SPHERE = -2;  // the spheres around the two boxes were apart
constexpr int64_t FRONT_BOX = -3;     // the paper's box test separated them (names no axis)

// What a traversal of two trees is asked (coal's CollisionRequest, for one body pair).
struct TraversalRequest {
    int box_test = BOX_TEST_SAT;   // BOX_TEST_PAPER or BOX_TEST_SAT: how two boxes are tested
    int expansion = EXPAND_WIDER;  // EXPAND_*: which node of an overlapping pair is expanded
    // The pair's two paddings summed: triangles within pad of each other meet
    // (triangles_within); the boxes must hold the padded geometry (the checker grows each
    // body's boxes by its padding), so that boxes apart prove the padded bodies apart.
    double pad = 0.0;
    // An extra distance (m, >= 0) within which the two bodies count as meeting, beyond pad:
    // every box of both trees is taken grown by inflation / 2 (half extents and sphere
    // radius), leaves within pad + inflation meet, and a gap is one of the padded distance
    // minus inflation. 0 for the collision queries.
    double inflation = 0.0;
    // Measure the gap: a lower bound of the distance when no triangles meet (collide_trees).
    bool track = false;
    // Triangles (rows of tris, or -1) that met last time: the descent visits first the
    // children holding them.
    int64_t witness_a = -1, witness_b = -1;
    // A front is recorded with each node pair's until = travel - rounding + its gap (the
    // pair's travel now, and its rounding margin); see collide_trees and front_scan.
    double travel = 0.0;
    double rounding = 0.0;
};

// Rows where a front is recorded: node pairs (rows, 3) and their until (rows,).
struct FrontRows {
    int64_t* pairs;
    double* until;
    int64_t rows;
};

// A front being recorded: its rows and its length so far, -1 when none is recorded (or the
// rows overflowed: the front is then incomplete).
struct FrontRecord {
    FrontRows rows;
    int64_t length;
};

// A traversal node (coal's MeshCollisionTraversalNode): the forest holding both trees, body
// b's pose in body a's frame, what is asked, where it works, and the front it records
// (nullptr: none).
struct TreePairTraversal {
    const Forest& forest;
    const double* pose;
    const TraversalRequest& request;
    TraversalWork work;
    FrontRecord* front;
};

// Append (na, nb, how) and until to the front being recorded (nothing once its length is -1,
// which it becomes when the rows overflow).
CS_ALWAYS_INLINE void record(FrontRecord& front, int64_t na, int64_t nb, int64_t how,
                             double until) {
    if (front.length < 0) return;
    if (front.length >= front.rows.rows) {
        front.length = -1;
        return;
    }
    int64_t* row = front.rows.pairs + 3 * front.length;
    row[0] = na;
    row[1] = nb;
    row[2] = how;
    front.rows.until[front.length] = until;
    ++front.length;
}

struct TreesResult {
    bool hit;
    int64_t ia, ib;
    double gap;
};


// Does any triangle under the node pairs on the stack (its first n_seeds rows: na in tree a,
// nb in tree b, a level) meet one of the other's, and if not, how far apart are they at least?
//
// Contract, for a seed the two roots of a body's sub-group trees:
//     hit = any(triangles_within(P, R_ab Q + t_ab, pad + inflation) for P in triangles(na)
//               for Q in triangles(nb) for (na, nb) in seeds)
// computed by descending both trees and pruning node pairs whose boxes are disjoint; ia, ib
// are the rows of tris of the first meeting pair found (-1 if none), a witness the caller may
// test first next time.
//
// With request.track, gap is a lower bound of the distance between the two trees' triangles
// (minus inflation) when they do not meet: the smallest gap of the node pairs pruned (sphere
// gap |d| - r_a - r_b, or face_gap for a box test, or the gap along the edge axis that
// separated them, or a leaf pair's smallest triangle distance minus padding). Not rounded
// down: the caller allows for that. Without track (full checks), gap
// is 0 and costs nothing.
//
// The front: when node.front records (length >= 0), every node pair where the descent stopped
// (pruned, or a leaf pair found apart) is recorded with how it was settled and until = travel
// - rounding + its gap: the pair's travel up to which it is still apart. When no triangles
// meet, those pairs cover every pair of triangles under the seeds exactly once, whatever the
// pose: a later re-check may start from them instead of the roots (front_scan).
//
// Which child is visited first (only the work depends on it, never the answer): with a
// witness, the one whose triangles include it; without one, the child whose centre is nearer
// the other box's centre. A colliding pair stops at its first meeting triangles, so this
// finds them sooner.
//
// Padding: triangles count as meeting when they are within pad of each other
// (triangles_within), and the boxes must hold the padded geometry, so that boxes apart still
// prove the padded bodies apart and every gap is one of the padded distance. A padded leaf
// pair found apart has its distance measured: its gap is that distance minus pad, not 0.
//
// stack: rows >= n_seeds + depth(a) + depth(b) + 2.
inline TreesResult collide_trees(const TreePairTraversal& node, int64_t n_seeds);

struct FrontScan {
    int64_t n_seeds, n_kept;
    double gap;
};


// Re-settle a front (see collide_trees) at the node's pose, cheaply where it can.
//
// The pair's travel (request.travel) is a running sum of bounds of how far any point of one
// body can have moved relative to the other (paper sec. 4.2, planning.hpp), so a node pair
// whose gap, when last settled, exceeds the travel since then is still apart untested: its
// until (the travel then plus the gap) is above travel. Every other node pair is tried the way
// it was settled last time: its one separating axis (axis_gap), or its spheres. Those still
// apart are copied to kept (until = travel - rounding + gap); the others (leaf pairs among
// them: a triangle test has no cheaper proof) go on the node's stack as seeds for
// collide_trees. Under coherent motion most node pairs stay apart, and no node pair above the
// front is tested again.
//
// old: a complete front (its rows: the node pairs); stack rows >= old.rows; kept rows >=
// old.rows. gap: a lower bound of the distance between the kept node pairs' triangles (INF if
// none). The request's inflation is honoured as collide_trees honours it.
inline FrontScan front_scan(const TreePairTraversal& node, const FrontRows& old,
                           const FrontRows& kept);

// The definitions, inline: each runs at every pair a query re-checks (recheck.cpp), inside
// its loop.

// The collision test's node for the descent (descent.hpp): the traversal's fields as locals
// of the query (the stack's writes could alias them otherwise), what it has found, and the
// hooks. Inflated: the boxes are grown by the request's inflation (a constant of each of the
// two copies of the descent: the collision queries do not inflate, and pay nothing for it).
template <bool Inflated>
struct CollideNode {
    static constexpr bool WHOLE_A = false;
    // What apart() saw of a pair its boxes did not settle: the boxes (grown when Inflated) and
    // B's centre relative to A's, in body a (Spheres::d).
    struct Seen {
        const double* A;
        const double* B;
        double d[3];
    };

    const Forest& f;
    const double* P;
    const int box_test, expansion;
    const bool track;
    const int64_t wa, wb;
    const double pad, grow, base;
    FrontRecord& front;
    double best;
    int64_t n_boxes = 0, n_spheres = 0, n_triangles = 0;
    bool hit = false;
    int64_t ia = -1, ib = -1;
    double grown_a[BOX_WIDTH], grown_b[BOX_WIDTH];

    CollideNode(const TreePairTraversal& t, FrontRecord& front)
        : f(t.forest),
          P(t.pose),
          box_test(t.request.box_test),
          expansion(t.request.expansion),
          track(t.request.track),
          wa(t.request.witness_a),
          wb(t.request.witness_b),
          pad(t.request.pad + t.request.inflation),
          grow(0.5 * t.request.inflation),
          base(t.request.travel - t.request.rounding),
          front(front),
          best(t.request.track ? INF : 0.0) {}

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return f.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const { return f.node(n); }

    // The spheres, then the box test; a pair they separate goes to the front with its gap.
    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nb, int64_t, Seen& seen) {
        const double* A = Inflated ? grown(f.box(na), grow, grown_a) : f.box(na);
        const double* B = Inflated ? grown(f.box(nb), grow, grown_b) : f.box(nb);
        const Spheres s = spheres(A, B, P);
        if (s.apart) {
            ++n_spheres;
            if (front.length >= 0) {
                const double g = std::sqrt(s.dd) - s.radii;
                record(front, na, nb, FRONT_SPHERE, base + g);
                best = std::min(best, g);
            } else if (track && best > 0.0) {
                const double bound = best + s.radii;  // sqrt only when it can lower the bound
                if (s.dd < bound * bound) best = std::sqrt(s.dd) - s.radii;
            }
            return true;
        }
        ++n_boxes;
        double T[12];
        box_in_frame(A, B, P, T);
        int64_t how;
        if (box_test == BOX_TEST_PAPER)
            how = paper_separates(A, B, T) ? FRONT_BOX : FRONT_LEAF;
        else
            how = sat_axis(A, B, T);
        if (how != FRONT_LEAF) {
            if (track) {
                double g = face_gap(A, B, T);
                if (how >= 6) g = std::max(g, axis_gap(how, A, B, P).gap);
                best = std::min(best, g);
                record(front, na, nb, how, base + g);
            }
            return true;
        }
        seen.A = A;
        seen.B = B;
        seen.d[0] = s.d[0];
        seen.d[1] = s.d[1];
        seen.d[2] = s.d[2];
        return false;
    }

    // The triangles; the first meeting pair ends the descent.
    CS_ALWAYS_INLINE bool leaves(int64_t na, int64_t nb, const int64_t* row_a,
                                 const int64_t* row_b, Seen&) {
        const LeafResult leaf = leaves_collide(f.tris, row_a, row_b, P, pad, track);
        n_triangles += leaf.tested;
        if (leaf.hit) {
            hit = true;
            ia = leaf.ia;
            ib = leaf.ib;
            return true;
        }
        record(front, na, nb, FRONT_LEAF, base + leaf.gap);
        best = std::min(best, leaf.gap);
        return false;
    }

    CS_ALWAYS_INLINE bool split_a(int64_t na, int64_t nb, int64_t level, const Seen& seen) const {
        return expand_first(f, na, nb, seen.A, seen.B, level, expansion);
    }

    // First the child holding the last witness, or else the one nearer the other box's
    // centre (B's in body a; A's in body b: R_ab' (ca - t_ab)).
    CS_ALWAYS_INLINE void order(int64_t, int64_t, int64_t level, bool on_a, ChildPairs& c,
                                const Seen& seen) const {
        const double* A = seen.A;
        bool swap;
        if (on_a) {
            if (wa >= 0)
                swap = wa >= f.node(c.second)[NODE_FIRST];
            else
                swap = nearer(f.box(c.second), f.box(c.first), A[0] + seen.d[0],
                              A[1] + seen.d[1], A[2] + seen.d[2]);
        } else {
            if (wb >= 0) {
                swap = wb >= f.node(c.second)[NODE_FIRST];
            } else {
                const double e0 = A[0] - P[9], e1 = A[1] - P[10], e2 = A[2] - P[11];
                swap = nearer(f.box(c.second), f.box(c.first),
                              P[0] * e0 + P[3] * e1 + P[6] * e2,
                              P[1] * e0 + P[4] * e1 + P[7] * e2,
                              P[2] * e0 + P[5] * e1 + P[8] * e2);
            }
        }
        if (swap) c.swap();
        c.word_first = c.word_second = level + 1;
    }
};

// Forced inline, into its caller's loop over the pairs (recheck.cpp): left out of line, the
// box test inside the descent compiles to more instructions (its registers spill).
template <bool Inflated>
CS_ALWAYS_INLINE TreesResult collide_trees_as(const TreePairTraversal& traversal,
                                              int64_t n_seeds) {
    FrontRecord no_front = {{nullptr, nullptr, 0}, -1};
    CollideNode<Inflated> node(traversal, traversal.front ? *traversal.front : no_front);
    descend(node, traversal.work.stack, n_seeds);
    int64_t* counters = traversal.work.counters;
    counters[COUNT_BOX_TESTS] += node.n_boxes;
    counters[COUNT_SPHERE_SKIPS] += node.n_spheres;
    counters[COUNT_TRIANGLE_TESTS] += node.n_triangles;
    return {node.hit, node.ia, node.ib, node.best};
}


inline TreesResult collide_trees(const TreePairTraversal& node, int64_t n_seeds) {
    return node.request.inflation > 0.0 ? collide_trees_as<true>(node, n_seeds)
                                        : collide_trees_as<false>(node, n_seeds);
}

inline FrontScan front_scan(const TreePairTraversal& node, const FrontRows& old,
                            const FrontRows& kept) {
    const Forest& f = node.forest;
    const double* P = node.pose;
    const double travel = node.request.travel, rounding = node.request.rounding;
    const double grow = 0.5 * node.request.inflation;
    int64_t* stack = node.work.stack;
    double best = INF;
    int64_t n_seeds = 0, n_kept = 0, n_boxes = 0, n_spheres = 0, n_untested = 0;
    double grown_a[BOX_WIDTH], grown_b[BOX_WIDTH];
    for (int64_t e = 0; e < old.rows; ++e) {
        const int64_t na = old.pairs[3 * e], nb = old.pairs[3 * e + 1], how = old.pairs[3 * e + 2];
        double until = old.until[e];
        bool apart = until - travel > FRONT_GUARD_REL * until;
        double g = 0.0;
        if (apart) {
            g = until - travel;
            ++n_untested;
        } else if (how >= 0) {
            ++n_boxes;
            const double* A = grown(f.box(na), grow, grown_a);
            const double* B = grown(f.box(nb), grow, grown_b);
            const AxisGap ag = axis_gap(how, A, B, P);
            apart = ag.separated;
            g = ag.gap;
            if (apart) {
                // One axis can leave a small gap to boxes that moved far apart along another:
                // the spheres' gap may say more.
                double d[3];
                centre_offset(A, B, P, d);
                g = std::max(g, std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) -
                                    A[BOX_RADIUS] - B[BOX_RADIUS]);
                until = travel - rounding + g;
            }
        } else if (how == FRONT_SPHERE) {
            ++n_spheres;
            const Spheres s = spheres(grown(f.box(na), grow, grown_a),
                                      grown(f.box(nb), grow, grown_b), P);
            apart = s.apart;
            if (apart) {
                g = std::sqrt(s.dd) - s.radii;
                until = travel - rounding + g;
            }
        }
        if (apart) {
            int64_t* row = kept.pairs + 3 * n_kept;
            row[0] = na;
            row[1] = nb;
            row[2] = how;
            kept.until[n_kept] = until;
            ++n_kept;
            best = std::min(best, g);
        } else {
            seed_pair(stack, n_seeds++, na, nb);
        }
    }
    int64_t* counters = node.work.counters;
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_SPHERE_SKIPS] += n_spheres;
    counters[COUNT_FRONT_STARTS] += 1;
    counters[COUNT_FRONT_UNTESTED] += n_untested;
    return {n_seeds, n_kept, best};
}

}  // namespace collision_sensor
