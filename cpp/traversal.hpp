// Hierarchy-versus-hierarchy traversal of two OBB trees (paper sec. 4.1).
//
// Two trees, each in its own body frame, are tested from their roots down. When two boxes
// overlap, one of them is expanded (its two children are tested against the other box); when
// both are leaves, their triangles are tested exactly. Which side is expanded is the paper's
// "node expansion consideration"; five rules are offered (the answer never depends on the
// rule, only the work done; collision_sensor_bench measures which is fastest):
//   EXPAND_SAME       always expand the first tree until it reaches a leaf, then the second;
//   EXPAND_ALTERNATE  alternate sides with the depth of the descent;
//   EXPAND_LARGER     expand the node with the larger box volume;
//   EXPAND_PROMISING  expand the node whose volume most exceeds the sum of its children's
//                     volumes (the paper's "most promising node");
//   EXPAND_WIDER      expand the node with the larger half diagonal |half| (its sphere's
//                     radius): unlike the volume, it sees the size of a flat box (the box of
//                     a few coplanar triangles has almost none), as FCL's rule does.
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

#include "box_test.hpp"
#include "inlining.hpp"
#include "obb_tree.hpp"
#include "tolerances.hpp"
#include "triangle_distance.hpp"
#include "triangle_test.hpp"

namespace collision_sensor {

constexpr int POSE_WIDTH = 12;
constexpr int EXPAND_SAME = 0, EXPAND_ALTERNATE = 1, EXPAND_LARGER = 2, EXPAND_PROMISING = 3,
              EXPAND_WIDER = 4;

// counters[COUNT_*]: work done, for the benchmarks and tests.
constexpr int COUNT_BOX_TESTS = 0, COUNT_TRIANGLE_TESTS = 1, COUNT_SPHERE_SKIPS = 2,
              COUNT_FRONT_STARTS = 3, COUNT_FRONT_UNTESTED = 4, COUNT_SWEEPS = 5,
              COUNT_SWEEP_STEPS = 6, COUNT_MEASURES = 7, N_COUNTERS = 8;

// A front is a table of node pairs (na, nb, how): how is the axis of the 15-axis test that
// separated the pair's boxes (0-14, see separating_axis), or one of these.
constexpr int64_t FRONT_LEAF = -1;    // a leaf pair tested triangle by triangle (apart then)
constexpr int64_t FRONT_SPHERE = -2;  // the spheres around the two boxes were apart
constexpr int64_t FRONT_BOX = -3;     // the paper's box test separated them (names no axis)

constexpr double INF = std::numeric_limits<double>::infinity();

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

// Where a traversal works: stack (rows, 3) int64, and counters (N_COUNTERS,) it adds to.
struct TraversalWork {
    int64_t* stack;
    int64_t* counters;
};

// The paper's node expansion consideration (sec. 4.1): true iff node pair (na, nb), whose
// boxes A and B overlap, is expanded on side a (a's two children against nb).
CS_ALWAYS_INLINE bool expand_first(const Forest& f, int64_t na, int64_t nb, const double* A,
                                   const double* B, bool leaf_a, bool leaf_b, int64_t level,
                                   int expansion) {
    if (leaf_a) return false;
    if (leaf_b) return true;
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

// d = R_ab cb + t_ab - ca: B's centre relative to A's, in body a's frame.
CS_ALWAYS_INLINE void centre_offset(const double* A, const double* B, const double* P, double* d) {
    const int c = BOX_CENTER;
    d[0] = P[0] * B[c] + P[1] * B[c + 1] + P[2] * B[c + 2] + P[9] - A[c];
    d[1] = P[3] * B[c] + P[4] * B[c + 1] + P[5] * B[c + 2] + P[10] - A[c + 1];
    d[2] = P[6] * B[c] + P[7] * B[c + 1] + P[8] * B[c + 2] + P[11] - A[c + 2];
}

// The sphere pre-test: the sphere around a box (centre the box centre, radius |half|) holds
// it, so spheres clearly apart means boxes apart. Keeps |d|^2, the radii and d for reuse.
struct Spheres {
    bool apart;
    double dd, radii;
    double d[3];
};

CS_ALWAYS_INLINE Spheres spheres(const double* A, const double* B, const double* P) {
    Spheres s;
    centre_offset(A, B, P, s.d);
    s.dd = s.d[0] * s.d[0] + s.d[1] * s.d[1] + s.d[2] * s.d[2];
    s.radii = A[BOX_RADIUS] + B[BOX_RADIUS];
    const double reach = s.radii * (1.0 + SPHERE_EPS_REL);
    s.apart = s.dd > reach * reach;
    return s;
}

// Box B (body b, at pose P in body a) in box A's frame, T: R row-major then t. With box
// frames [Ea, ca], [Eb, cb]:   [R, t] = [Ea' R_ab Eb, Ea' (R_ab cb + t_ab - ca)]
CS_ALWAYS_INLINE void box_in_frame(const double* A, const double* B, const double* P, double* T) {
    double d[3];
    centre_offset(A, B, P, d);
    const int e = BOX_AXES;
    // M = R_ab Eb: B's axes (columns) in body a's frame.
    double M[9];
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k)
            M[3 * r + k] = P[3 * r] * B[e + k] + P[3 * r + 1] * B[e + 3 + k] +
                           P[3 * r + 2] * B[e + 6 + k];
    // R = Ea' M, t = Ea' d: row i of both uses A's axis i, column i of Ea.
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k)
            T[3 * i + k] = A[e + i] * M[k] + A[e + 3 + i] * M[3 + k] + A[e + 6 + i] * M[6 + k];
        T[9 + i] = A[e + i] * d[0] + A[e + 3 + i] * d[1] + A[e + 6 + i] * d[2];
    }
}

// A lower bound of the distance between boxes of half extents ha and hb (B in A's frame: T):
// the largest gap of the two boxes' projections on the six face normals (unit axes, so each
// gap is at most the Euclidean distance; <= 0 if no face axis separates them). Rounding is
// the caller's.
CS_ALWAYS_INLINE double face_gap_of(const double* ha, const double* hb, const double* T) {
    using std::fabs;
    const double a0 = ha[0], a1 = ha[1], a2 = ha[2], b0 = hb[0], b1 = hb[1], b2 = hb[2];
    const double r00 = T[0], r01 = T[1], r02 = T[2], r10 = T[3], r11 = T[4], r12 = T[5],
                 r20 = T[6], r21 = T[7], r22 = T[8], t0 = T[9], t1 = T[10], t2 = T[11];
    double g = fabs(t0) - a0 - (fabs(r00) * b0 + fabs(r01) * b1 + fabs(r02) * b2);
    g = std::max(g, fabs(t1) - a1 - (fabs(r10) * b0 + fabs(r11) * b1 + fabs(r12) * b2));
    g = std::max(g, fabs(t2) - a2 - (fabs(r20) * b0 + fabs(r21) * b1 + fabs(r22) * b2));
    g = std::max(g, fabs(r00 * t0 + r10 * t1 + r20 * t2) - b0 -
                        (fabs(r00) * a0 + fabs(r10) * a1 + fabs(r20) * a2));
    g = std::max(g, fabs(r01 * t0 + r11 * t1 + r21 * t2) - b1 -
                        (fabs(r01) * a0 + fabs(r11) * a1 + fabs(r21) * a2));
    g = std::max(g, fabs(r02 * t0 + r12 * t1 + r22 * t2) - b2 -
                        (fabs(r02) * a0 + fabs(r12) * a1 + fabs(r22) * a2));
    return g;
}

// face_gap_of with the boxes' own half extents.
CS_ALWAYS_INLINE double face_gap(const double* A, const double* B, const double* T) {
    return face_gap_of(A + BOX_HALF, B + BOX_HALF, T);
}

// A lower bound of the distance between boxes A and B (body b at pose P): the larger of the
// spheres' gap and face_gap; <= 0 when neither separates.
CS_ALWAYS_INLINE double box_pair_gap(const double* A, const double* B, const double* P) {
    double d[3];
    centre_offset(A, B, P, d);
    const double g = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) -
                     (A[BOX_RADIUS] + B[BOX_RADIUS]);
    double T[12];
    box_in_frame(A, B, P, T);
    return std::max(g, face_gap(A, B, T));
}

// The axis that separates boxes A and B (separating_axis), or -1; B in A's frame: T.
CS_ALWAYS_INLINE int sat_axis(const double* A, const double* B, const double* T) {
    return separating_axis(A + BOX_HALF, B + BOX_HALF, T, T + 9);
}

// True iff the paper's test separates boxes A and B (B in A's frame: T).
CS_ALWAYS_INLINE bool paper_separates(const double* A, const double* B, const double* T) {
    return boxes_disjoint_paper(A + BOX_HALF, B + BOX_HALF, T, T + 9);
}

// True iff boxes A (body a) and B (body b at pose P in body a) are apart, by the spheres
// around them or by the box test.
inline bool boxes_apart(int box_test, const double* A, const double* B, const double* P) {
    if (spheres(A, B, P).apart) return true;
    double T[12];
    box_in_frame(A, B, P, T);
    if (box_test == BOX_TEST_PAPER) return paper_separates(A, B, T);
    return sat_axis(A, B, T) >= 0;
}

// boxes_apart, and when apart their gap (the larger of the spheres' gap and face_gap, a lower
// bound of their distance) into gap, the two sharing the work.
inline bool boxes_apart_gap(int box_test, const double* A, const double* B, const double* P,
                            double* gap) {
    const Spheres s = spheres(A, B, P);
    double T[12];
    box_in_frame(A, B, P, T);
    if (!s.apart && (box_test == BOX_TEST_PAPER ? !paper_separates(A, B, T)
                                                : sat_axis(A, B, T) < 0))
        return false;
    *gap = std::max(std::sqrt(s.dd) - s.radii, face_gap(A, B, T));
    return true;
}

// separating_axis's decision for axis k alone, for boxes A (body a) and B (body b at pose P),
// on only the entries of box_in_frame the axis needs (a front re-check tries one axis per node
// pair); gap is then the boxes' gap along the unit axis, a lower bound of their distance.
struct AxisGap {
    bool separated;
    double gap;
};

inline AxisGap axis_gap(int64_t k, const double* A, const double* B, const double* P) {
    using std::fabs;
    const int h = BOX_HALF;
    const int e = BOX_AXES;
    const double ha[3] = {A[h], A[h + 1], A[h + 2]};
    const double hb[3] = {B[h], B[h + 1], B[h + 2]};
    const double tol = BOX_EPS_REL * (ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]);
    double dv[3];
    centre_offset(A, B, P, dv);
    const double d0 = dv[0], d1 = dv[1], d2 = dv[2];
    if (k < 3) {  // L = e_k: row k of R is A's axis k, taken to body b, against B's axes
        const double x0 = A[e + k], x1 = A[e + 3 + k], x2 = A[e + 6 + k];
        const double u0 = P[0] * x0 + P[3] * x1 + P[6] * x2;
        const double u1 = P[1] * x0 + P[4] * x1 + P[7] * x2;
        const double u2 = P[2] * x0 + P[5] * x1 + P[8] * x2;
        const double r0 = u0 * B[e] + u1 * B[e + 3] + u2 * B[e + 6];
        const double r1 = u0 * B[e + 1] + u1 * B[e + 4] + u2 * B[e + 7];
        const double r2 = u0 * B[e + 2] + u1 * B[e + 5] + u2 * B[e + 8];
        const double d = (fabs(x0 * d0 + x1 * d1 + x2 * d2) -
                          ((fabs(r0 * hb[0]) + fabs(r1 * hb[1])) + fabs(r2 * hb[2]))) - ha[k];
        return {d > tol * (1.0 + BOX_EPS_PARALLEL), d};
    }
    const int64_t j = (k - 3) % 3;  // B's axis j (k < 6), or the b_j of e_i x b_j
    const double m0 = P[0] * B[e + j] + P[1] * B[e + 3 + j] + P[2] * B[e + 6 + j];
    const double m1 = P[3] * B[e + j] + P[4] * B[e + 3 + j] + P[5] * B[e + 6 + j];
    const double m2 = P[6] * B[e + j] + P[7] * B[e + 3 + j] + P[8] * B[e + 6 + j];
    if (k < 6) {  // L = b_j: column j of R, and all of t
        const double r0 = A[e] * m0 + A[e + 3] * m1 + A[e + 6] * m2;
        const double r1 = A[e + 1] * m0 + A[e + 4] * m1 + A[e + 7] * m2;
        const double r2 = A[e + 2] * m0 + A[e + 5] * m1 + A[e + 8] * m2;
        const double t0 = A[e] * d0 + A[e + 3] * d1 + A[e + 6] * d2;
        const double t1 = A[e + 1] * d0 + A[e + 4] * d1 + A[e + 7] * d2;
        const double t2 = A[e + 2] * d0 + A[e + 5] * d1 + A[e + 8] * d2;
        const double d = (fabs((r0 * t0 + r1 * t1) + r2 * t2) -
                          ((fabs(r0 * ha[0]) + fabs(r1 * ha[1])) + fabs(r2 * ha[2]))) - hb[j];
        return {d > tol * (1.0 + BOX_EPS_PARALLEL), d};
    }
    // L = e_i x b_j (see box_test.hpp: edge_axis_separates): R[i1, j], R[i2, j], R[i, j1],
    // R[i, j2], t[i1], t[i2], with i1, i2 and j1, j2 the other indices, cyclic.
    const int64_t i = (k - 6) / 3;
    const int64_t i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
    const double r_i1j = A[e + i1] * m0 + A[e + 3 + i1] * m1 + A[e + 6 + i1] * m2;
    const double r_i2j = A[e + i2] * m0 + A[e + 3 + i2] * m1 + A[e + 6 + i2] * m2;
    const double x0 = A[e + i], x1 = A[e + 3 + i], x2 = A[e + 6 + i];
    const double u0 = P[0] * x0 + P[3] * x1 + P[6] * x2;
    const double u1 = P[1] * x0 + P[4] * x1 + P[7] * x2;
    const double u2 = P[2] * x0 + P[5] * x1 + P[8] * x2;
    const double r_ij1 = u0 * B[e + j1] + u1 * B[e + 3 + j1] + u2 * B[e + 6 + j1];
    const double r_ij2 = u0 * B[e + j2] + u1 * B[e + 3 + j2] + u2 * B[e + 6 + j2];
    const double t_i1 = A[e + i1] * d0 + A[e + 3 + i1] * d1 + A[e + 6 + i1] * d2;
    const double t_i2 = A[e + i2] * d0 + A[e + 3 + i2] * d1 + A[e + 6 + i2] * d2;
    const double d = (fabs(t_i2 * r_i1j - t_i1 * r_i2j) -
                      (ha[i1] * fabs(r_i2j) + ha[i2] * fabs(r_i1j))) -
                     (hb[j1] * fabs(r_ij2) + hb[j2] * fabs(r_ij1));
    const double length = std::sqrt(r_ij1 * r_ij1 + r_ij2 * r_ij2);
    if (ha[i] > 0.0 && d > tol * BOX_EPS_PARALLEL && d > tol * (length + BOX_EPS_PARALLEL))
        return {true, d / length};
    return {false, d};
}

// Triangle row ib (body b), taken to body a's frame by the pose.
CS_ALWAYS_INLINE void triangle_in_a(const double* tris, int64_t ib, const double* pose,
                                    Triangle& Q) {
    const double* t = tris + 9 * ib;
    for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i)
            Q[k][i] = pose[3 * i] * t[3 * k] + pose[3 * i + 1] * t[3 * k + 1] +
                      pose[3 * i + 2] * t[3 * k + 2] + pose[9 + i];
}

CS_ALWAYS_INLINE const Triangle&  triangle_at(const double* tris, int64_t i) {
    return *reinterpret_cast<const Triangle*>(tris + 9 * i);
}

// True iff triangle P is within pad of triangle Q (pad > 0: the padded contact rule, the
// triangles' distance against the pair's padding, distance <= pad), or (pad 0) meets it.
CS_ALWAYS_INLINE bool triangles_within(const Triangle& P, const Triangle& Q, double pad,
                                       double& distance) {
    if (pad > 0.0) {
        double x[3], y[3];
        distance = triangle_distance(P, Q, x, y);
        return distance <= pad;
    }
    distance = 0.0;
    return triangles_intersect(P, Q);
}

// True iff triangle ia (body a) meets triangle ib (body b, at pose), or comes within pad.
inline bool triangle_pair_collides(const double* tris, int64_t ia, int64_t ib,
                                   const double* pose, double pad) {
    Triangle Q;
    triangle_in_a(tris, ib, pose, Q);
    double distance;
    return triangles_within(triangle_at(tris, ia), Q, pad, distance);
}

// Every triangle of leaf a against every triangle of leaf b (body b at pose), by the padded
// rule (triangles_within): the first pair in contact (-1, -1 if none), the number of triangle
// pairs tested, and, with pad > 0 or measure and none in contact, the smallest distance minus
// pad (the leaf pair's clearance; 0 otherwise, where no distance is measured). Without padding
// the intersection test decides and the distance only bounds: an incremental query measures
// it (measure), since a leaf pair's clearance of 0 would have its pair re-checked at every
// state, and its motion swept at every step (update_motion), while it stays that near.
struct LeafResult {
    bool hit;
    int64_t ia, ib, tested;
    double gap;
};

inline LeafResult leaves_collide(const double* tris, const int64_t* leaf_a,
                                 const int64_t* leaf_b, const double* pose, double pad,
                                 bool measure = false) {
    Triangle Q;
    int64_t tested = 0;
    double nearest = INF;
    const int64_t first_a = leaf_a[NODE_FIRST], end_a = first_a + leaf_a[NODE_COUNT];
    const int64_t first_b = leaf_b[NODE_FIRST], end_b = first_b + leaf_b[NODE_COUNT];
    for (int64_t ib = first_b; ib < end_b; ++ib) {
        triangle_in_a(tris, ib, pose, Q);
        for (int64_t ia = first_a; ia < end_a; ++ia) {
            ++tested;
            double distance;
            const Triangle& P = triangle_at(tris, ia);
            if (triangles_within(P, Q, pad, distance)) return {true, ia, ib, tested, 0.0};
            if (measure && !(pad > 0.0)) {
                double x[3], y[3];
                distance = triangle_distance(P, Q, x, y);
            }
            nearest = std::min(nearest, distance);
        }
    }
    return {false, -1, -1, tested, (pad > 0.0 || measure) ? nearest - pad : 0.0};
}

// True iff box m's centre is nearer the point x than box n's (same body frame).
CS_ALWAYS_INLINE bool closer(const Forest& f, int64_t m, int64_t n, double x0, double x1,
                             double x2) {
    const double* bm = f.box(m);
    const double* bn = f.box(n);
    const double a0 = bm[0] - x0, a1 = bm[1] - x1, a2 = bm[2] - x2;
    const double b0 = bn[0] - x0, b1 = bn[1] - x1, b2 = bn[2] - x2;
    return a0 * a0 + a1 * a1 + a2 * a2 < b0 * b0 + b1 * b1 + b2 * b2;
}

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

// Box row A grown by g (half extents and sphere radius) into the row `into`, when g > 0 (a
// request's inflation / 2); else A itself.
CS_ALWAYS_INLINE const double* grown(const double* A, double g, double* into) {
    if (!(g > 0.0)) return A;
    std::copy(A, A + BOX_WIDTH, into);
    into[BOX_HALF] += g;
    into[BOX_HALF + 1] += g;
    into[BOX_HALF + 2] += g;
    into[BOX_RADIUS] += std::sqrt(3.0) * g;
    return into;
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
//
// (Inflated: whether the request inflates the boxes, a constant of each of the two copies of
// the descent: the collision queries do not, and pay nothing for it.)
template <bool Inflated>
inline TreesResult collide_trees_as(const TreePairTraversal& node, int64_t n_seeds) {
    // The request's fields as locals: the loop below writes through pointers that could
    // otherwise alias them.
    const TraversalRequest& request = node.request;
    const Forest& f = node.forest;
    const double* P = node.pose;
    const int box_test = request.box_test, expansion = request.expansion;
    const bool track = request.track;
    const int64_t wa = request.witness_a, wb = request.witness_b;
    const double pad = request.pad + request.inflation, grow = 0.5 * request.inflation;
    const double base = request.travel - request.rounding;
    int64_t* stack = node.work.stack;
    FrontRecord no_front = {{nullptr, nullptr, 0}, -1};
    FrontRecord& front = node.front ? *node.front : no_front;
    double best = track ? INF : 0.0;
    int64_t n_boxes = 0, n_spheres = 0, n_triangles = 0;
    bool hit = false;
    int64_t ia = -1, ib = -1;
    int64_t top = n_seeds;
    double grown_a[BOX_WIDTH], grown_b[BOX_WIDTH];
    while (top > 0) {
        --top;
        int64_t* slot = stack + 3 * top;
        const int64_t na = slot[0], nb = slot[1], level = slot[2];
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
            continue;
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
            continue;
        }
        const int64_t* node_a = f.node(na);
        const int64_t* node_b = f.node(nb);
        const bool leaf_a = node_a[NODE_LEFT] < 0;
        const bool leaf_b = node_b[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            const LeafResult leaf = leaves_collide(f.tris, node_a, node_b, P, pad, track);
            n_triangles += leaf.tested;
            if (leaf.hit) {
                hit = true;
                ia = leaf.ia;
                ib = leaf.ib;
                break;
            }
            record(front, na, nb, FRONT_LEAF, base + leaf.gap);
            best = std::min(best, leaf.gap);
            continue;
        }
        const bool expand_a = expand_first(f, na, nb, A, B, leaf_a, leaf_b, level, expansion);
        // Visit first the child nearer the other box's centre (more likely to meet it: a
        // colliding pair stops at its first meeting triangles), or the one holding the last
        // witness.
        int64_t first, second;
        bool swap;
        if (expand_a) {
            first = node_a[NODE_LEFT];
            second = node_a[NODE_RIGHT];
            if (wa >= 0) {
                swap = wa >= f.node(second)[NODE_FIRST];
            } else {  // B's centre in body a
                swap = closer(f, second, first, A[0] + s.d[0], A[1] + s.d[1], A[2] + s.d[2]);
            }
            if (swap) std::swap(first, second);
            slot[0] = second;
            slot[1] = nb;
            slot[2] = level + 1;
            slot[3] = first;
            slot[4] = nb;
        } else {
            first = node_b[NODE_LEFT];
            second = node_b[NODE_RIGHT];
            if (wb >= 0) {
                swap = wb >= f.node(second)[NODE_FIRST];
            } else {  // A's centre in body b: R_ab' (ca - t_ab)
                const double e0 = A[0] - P[9], e1 = A[1] - P[10], e2 = A[2] - P[11];
                swap = closer(f, second, first, P[0] * e0 + P[3] * e1 + P[6] * e2,
                              P[1] * e0 + P[4] * e1 + P[7] * e2,
                              P[2] * e0 + P[5] * e1 + P[8] * e2);
            }
            if (swap) std::swap(first, second);
            slot[0] = na;
            slot[1] = second;
            slot[2] = level + 1;
            slot[3] = na;
            slot[4] = first;
        }
        slot[5] = level + 1;
        top += 2;
    }
    int64_t* counters = node.work.counters;
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_SPHERE_SKIPS] += n_spheres;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
    return {hit, ia, ib, best};
}

inline TreesResult collide_trees(const TreePairTraversal& node, int64_t n_seeds) {
    return node.request.inflation > 0.0 ? collide_trees_as<true>(node, n_seeds)
                                        : collide_trees_as<false>(node, n_seeds);
}

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
            int64_t* row = stack + 3 * n_seeds;
            row[0] = na;
            row[1] = nb;
            row[2] = 0;
            ++n_seeds;
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
