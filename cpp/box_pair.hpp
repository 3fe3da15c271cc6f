// The tests of one node pair of two trees at a pose (traversal.hpp): box B (body b at pose P
// in body a) against box A, by the spheres around them, by the box tests (box_test.hpp) in
// A's frame, by their gap along one axis, and a lower bound of their distance. A box is a
// pointer to its row of the forest's box table (obb_tree.hpp), a pose a pointer to its
// POSE_WIDTH numbers: R_ab row-major, then t_ab.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "box_test.hpp"
#include "inlining.hpp"
#include "obb_tree.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

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

}  // namespace collision_sensor
