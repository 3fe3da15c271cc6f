// Oriented-box / oriented-box overlap: the paper's three-type test (sec. 5) and the 15-axis SAT.
//
// Arguments shared by every test here (coal's convention: [R, t] = [R1'R2, R1'(T2 - T1)]):
//   ha, hb : half extents of box A and box B, >= 0; 0 is allowed (a flat box, a segment).
//   R      : proper rotation from F_B to F_A, row-major (R[3 i + j]): column j is B's axis j
//            in F_A, so R = R_A' R_B with R_A, R_B box-to-world.
//   t      : B's centre in F_A: t = R_A' (c_B - c_A).
// Box A is centred at the origin of F_A and axis-aligned there. Each test returns true iff a
// separating plane exists with a clear gap, false when the closed boxes meet (touching counts
// as overlap). None allocates.
//
// Tolerance rule (tolerances.hpp), the same in both tests: with s the sum of the six half
// extents and tol = BOX_EPS_REL s, the boxes are separated along a candidate axis L
// (unnormalised: a face normal has |L| = 1, an edge-edge axis a_i x b_j has |L| = sin of the
// angle between the edges) iff
//     |t . L| - r_A(L) - r_B(L)  >  tol (|L| + BOX_EPS_PARALLEL),
// the floor tol BOX_EPS_PARALLEL being coal's |R| + eps: an axis built from two nearly parallel
// edges, whose direction is rounding noise, cannot separate. Both tests consider the same axes:
// A's and B's face normals, and a_i x b_j for every i with ha[i] > 0 (a box with no extent along
// a_i has no edge along it). Type 1 and type 2 are evaluated in the very same floating-point
// operations as the SAT's six face axes (bit-identical decisions); type 3 and the edge-edge
// axes compute the same quantity in different ways, so they can disagree only within rounding
// (~1e-15 s) of the threshold. Input with a NaN or an infinity is never separated.
#pragma once

#include <cmath>

#include "inlining.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

constexpr int BOX_TEST_PAPER = 0, BOX_TEST_SAT = 1;

namespace box_detail {

// Paper Table 1 (sec. 5.1.3), restated in NOTES.md: row i is the silhouette hexagon of a box
// seen along a direction in which vertex i has the smallest coordinate; vertices i and 7 - i
// are hidden. Vertex numbering: bit k of the index selects min (0) or max (1) along box axis
// k. Every row runs counter-clockwise seen from the tip of the view direction, so in view
// coordinates (u, v) with u x v = view axis the inside is on the left of each edge, and the
// division-free edge function f = alpha u + beta v + gamma is > 0 exactly outside.
constexpr int HEXAGON[8][6] = {
    {1, 3, 2, 6, 4, 5}, {0, 4, 5, 7, 3, 2}, {3, 7, 6, 4, 0, 1}, {2, 0, 1, 5, 7, 6},
    {5, 1, 0, 2, 6, 7}, {4, 6, 7, 3, 1, 0}, {7, 5, 4, 0, 2, 3}, {6, 2, 3, 1, 5, 4},
};
// The box axis of an edge between two vertices, indexed by their xor (1, 2 or 4).
constexpr int AXIS_OF_BIT[8] = {0, 0, 1, 1, 2, 2, 2, 2};

// True iff none of the inputs is NaN or infinite: x * 0 is NaN exactly for those. Called
// only on the way to answering "separated", so the overlapping path pays nothing for it.
CS_ALWAYS_INLINE bool finite(const double* ha, const double* hb, const double* R,
                             const double* t) {
    double acc = 0.0;
    for (int k = 0; k < 3; ++k) {
        acc += ha[k] * 0.0 + hb[k] * 0.0 + t[k] * 0.0;
        acc += R[3 * k] * 0.0 + R[3 * k + 1] * 0.0 + R[3 * k + 2] * 0.0;
    }
    return acc == 0.0;
}

// Coordinate of the 8 vertices of a box along one axis: c + ((+-w0 +- w1) +- w2), the sign of
// w_k chosen by bit k of the vertex index. The association is fixed on purpose: the extreme
// vertex then equals c -+ ((|w0| + |w1|) + |w2|) to the last bit, which is exactly the radius
// the SAT computes, so type 1 / type 2 decide exactly as the SAT's face axes.
CS_ALWAYS_INLINE void vertex_coordinates(double c, double w0, double w1, double w2, double* out) {
    for (int i = 0; i < 8; ++i) {
        const double s0 = (i & 1) ? w0 : -w0;
        const double s1 = (i & 2) ? w1 : -w1;
        const double s2 = (i & 4) ? w2 : -w2;
        out[i] = ((s0 + s1) + s2) + c;
    }
}

// True iff all 8 coordinates lie beyond the face plane +h (x - h > thr) or all beyond -h
// (-h - x > thr): sec. 5.1.1, at least 8 and at most 16 inequalities per axis.
CS_ALWAYS_INLINE bool beyond_face_planes(const double* x, double h, double thr) {
    bool inside = false;
    for (int i = 0; i < 8; ++i) {
        if (!(x[i] - h > thr)) {
            inside = true;
            break;
        }
    }
    if (!inside) return true;
    for (int i = 0; i < 8; ++i) {
        if (!(-h - x[i] > thr)) return false;
    }
    return true;
}

// Edge-edge axis L = e_i x b_j (i1, i2 and j1, j2 the other indices, cyclic):
//   t . L = t[i2] R[i1, j] - t[i1] R[i2, j]
//   r_A   = ha[i1] |R[i2, j]| + ha[i2] |R[i1, j]|
//   r_B   = hb[j1] |R[i, j2]| + hb[j2] |R[i, j1]|
//   |L|   = sqrt(R[i, j1]^2 + R[i, j2]^2)   (a_i in F_B minus its b_j component)
// Q holds |R|, taken once by the caller; i and j are constants, so each of the nine axes
// compiles to its own straight code.
template <int i, int j>
CS_ALWAYS_INLINE bool edge_axis_separates(const double* ha, const double* hb, const double* R,
                                          const double* Q, const double* t, double tol) {
    constexpr int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
    const double d = (std::fabs(t[i2] * R[3 * i1 + j] - t[i1] * R[3 * i2 + j]) -
                      (ha[i1] * Q[3 * i2 + j] + ha[i2] * Q[3 * i1 + j])) -
                     (hb[j1] * Q[3 * i + j2] + hb[j2] * Q[3 * i + j1]);
    if (d > tol * BOX_EPS_PARALLEL) {
        const double r_ij1 = R[3 * i + j1], r_ij2 = R[3 * i + j2];
        return d > tol * (std::sqrt(r_ij1 * r_ij1 + r_ij2 * r_ij2) + BOX_EPS_PARALLEL);
    }
    return false;
}

// finite() summed pairwise: a short dependency chain on the way to "separated".
CS_ALWAYS_INLINE bool finite_pairwise(const double* ha, const double* hb, const double* R,
                                      const double* t) {
    const double s0 = (ha[0] * 0.0 + ha[1] * 0.0) + (ha[2] * 0.0 + hb[0] * 0.0);
    const double s1 = (hb[1] * 0.0 + hb[2] * 0.0) + (R[0] * 0.0 + R[1] * 0.0);
    const double s2 = (R[2] * 0.0 + R[3] * 0.0) + (R[4] * 0.0 + R[5] * 0.0);
    const double s3 = (R[6] * 0.0 + R[7] * 0.0) + (R[8] * 0.0 + t[0] * 0.0);
    return ((s0 + s1) + (s2 + s3)) + (t[1] * 0.0 + t[2] * 0.0) == 0.0;
}

// The first of the nine edge-edge axes e_i x b_j (from 6 + 3 i0 on) that separates, or -1.
template <int i>
CS_ALWAYS_INLINE int edge_axes_of(const double* ha, const double* hb, const double* R,
                                  const double* Q, const double* t, double tol) {
    if (!(ha[i] > 0.0)) return -1;   // A has no edge along e_i
    if (edge_axis_separates<i, 0>(ha, hb, R, Q, t, tol)) return 6 + 3 * i;
    if (edge_axis_separates<i, 1>(ha, hb, R, Q, t, tol)) return 7 + 3 * i;
    if (edge_axis_separates<i, 2>(ha, hb, R, Q, t, tol)) return 8 + 3 * i;
    return -1;
}

}  // namespace box_detail

// The first axis of the 15-axis test that separates boxes A and B, or -1. Axes are numbered
// in the order they are tried: 0-2 A's face normals e_k, 3-5 B's face normals b_j, 6 + 3 i + j
// the edge-edge axis e_i x b_j. The traversal keeps the axis of a node pair it pruned, and an
// incremental re-check tries that axis alone first (traversal.hpp: axis_gap, the same
// arithmetic).
CS_ALWAYS_INLINE int separating_axis(const double* ha, const double* hb, const double* R,
                                     const double* t) {
    using std::fabs;
    const double tol = BOX_EPS_REL * (ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]);
    const double thr_face = tol * (1.0 + BOX_EPS_PARALLEL);
    // |R|, taken once rather than per use: |r h| = |r| h to the last bit for h >= 0 (rounding
    // is symmetric in sign), so every margin below is the number it was with |r h|, and the
    // face axes still decide exactly as the paper's type 1 and type 2.
    double Q[9];
    for (int k = 0; k < 9; ++k) Q[k] = fabs(R[k]);
    int k = -1;
    // L = e_k: r_A = ha_k, r_B = sum_j |R[k, j]| hb_j.
    for (int a = 0; a < 3 && k < 0; ++a)
        if ((fabs(t[a]) - ((Q[3 * a] * hb[0] + Q[3 * a + 1] * hb[1]) + Q[3 * a + 2] * hb[2])) -
                ha[a] > thr_face)
            k = a;
    // L = b_j: t . b_j = (R' t)_j, r_A = sum_k |R[k, j]| ha_k, r_B = hb_j.
    for (int j = 0; j < 3 && k < 0; ++j)
        if ((fabs((R[j] * t[0] + R[3 + j] * t[1]) + R[6 + j] * t[2]) -
             ((Q[j] * ha[0] + Q[3 + j] * ha[1]) + Q[6 + j] * ha[2])) -
                hb[j] > thr_face)
            k = 3 + j;
    // L = e_i x b_j, only where A has edges along e_i (ha[i] > 0).
    if (k < 0) k = box_detail::edge_axes_of<0>(ha, hb, R, Q, t, tol);
    if (k < 0) k = box_detail::edge_axes_of<1>(ha, hb, R, Q, t, tol);
    if (k < 0) k = box_detail::edge_axes_of<2>(ha, hb, R, Q, t, tol);
    if (k >= 0 && box_detail::finite_pairwise(ha, hb, R, t)) return k;
    return -1;
}

// True iff boxes A and B are separated: the classical 15-axis test.
CS_ALWAYS_INLINE bool boxes_disjoint_sat(const double* ha, const double* hb, const double* R,
                                         const double* t) {
    return separating_axis(ha, hb, R, t) >= 0;
}

// True iff boxes A and B are separated: the paper's sec. 5 test.
//
// Type 1: B's 8 vertices in F_A all beyond one of A's six face planes. Type 2: the same with
// A's vertices in F_B (R' x - R' t). Type 3: with A's vertices in F_B, in the views along B's
// three axes, all 4 corners of B's rectangle strictly outside one edge line of A's silhouette
// hexagon (Table 1). Gaps count only beyond the tolerance rule above.
inline bool boxes_disjoint_paper(const double* ha, const double* hb, const double* R,
                                 const double* t) {
    using namespace box_detail;
    const double tol = BOX_EPS_REL * (ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]);
    const double thr_face = tol * (1.0 + BOX_EPS_PARALLEL);
    double b_in_a[3][8];
    double a_in_b[3][8];  // coordinate k of A's vertex i in F_B: a_in_b[k][i]

    // Type 1 (sec. 5.1.1). Coordinate k of B's vertex i in F_A is t_k + sum_j +-R[k, j] hb_j;
    // one coordinate at a time, so an early exit skips the rest.
    for (int k = 0; k < 3; ++k) {
        vertex_coordinates(t[k], R[3 * k] * hb[0], R[3 * k + 1] * hb[1], R[3 * k + 2] * hb[2],
                           b_in_a[k]);
        if (beyond_face_planes(b_in_a[k], ha[k], thr_face)) return finite(ha, hb, R, t);
    }
    // Type 2: A's vertices in F_B, x_B = R' x_A - R' t; coordinate j of A's vertex i is
    // -(R' t)_j + sum_k +-R[k, j] ha_k.
    for (int j = 0; j < 3; ++j) {
        const double c = -((R[j] * t[0] + R[3 + j] * t[1]) + R[6 + j] * t[2]);
        vertex_coordinates(c, R[j] * ha[0], R[3 + j] * ha[1], R[6 + j] * ha[2], a_in_b[j]);
        if (beyond_face_planes(a_in_b[j], hb[j], thr_face)) return finite(ha, hb, R, t);
    }
    // Type 3 (sec. 5.1.2 - 5.1.4): views along B's axes; B is the rectangle [-hb_u, hb_u] x
    // [-hb_v, hb_v], A the hexagon of Table 1; (u, v) = ((j + 1) % 3, (j + 2) % 3), so that
    // u x v = +axis j.
    for (int j = 0; j < 3; ++j) {
        const int iu = (j + 1) % 3;
        const int iv = (j + 2) % 3;
        const double hu = hb[iu];
        const double hv = hb[iv];
        // The vertex of A with the smallest coordinate along b_j: bit k is set iff a_k points
        // against b_j (R[k, j] < 0); on a tie (R[k, j] = 0 or ha_k = 0) both rows are valid.
        int imin = 0;
        if (R[j] < 0.0) imin += 1;
        if (R[3 + j] < 0.0) imin += 2;
        if (R[6 + j] < 0.0) imin += 4;
        for (int m = 0; m < 6; ++m) {
            const int p0 = HEXAGON[imin][m];
            const int p1 = HEXAGON[imin][(m + 1) % 6];
            const int bit = p0 ^ p1;
            const int k = AXIS_OF_BIT[bit];
            // (u1 - u0, v1 - v0) is A's edge along a_k seen in the view: +-2 ha_k times row k
            // of R (a_k in F_B), formed directly rather than by subtracting two rounded
            // vertices, so a thin box keeps an accurate edge direction.
            const double e = (p1 & bit) ? 2.0 * ha[k] : -2.0 * ha[k];
            const double alpha = e * R[3 * k + iv];  // v1 - v0
            const double beta = -(e * R[3 * k + iu]);  // u0 - u1
            const double u0 = a_in_b[iu][p0];
            const double v0 = a_in_b[iv][p0];
            const double gamma = -(alpha * u0 + beta * v0);
            // All 4 corners strictly outside (f > 0); a zero-length edge has f = 0 everywhere.
            double fmin = alpha * hu + beta * hv + gamma;
            if (!(fmin > 0.0)) continue;
            double f = alpha * hu - beta * hv + gamma;
            if (!(f > 0.0)) continue;
            fmin = std::fmin(fmin, f);
            f = -alpha * hu + beta * hv + gamma;
            if (!(f > 0.0)) continue;
            fmin = std::fmin(fmin, f);
            f = -alpha * hu - beta * hv + gamma;
            if (!(f > 0.0)) continue;
            fmin = std::fmin(fmin, f);
            // f = |edge| (distance from the edge line) and |edge| = 2 ha_k |L|: the rule
            // gap > tol (1 + EPS_PARALLEL / |L|) reads fmin > tol (|edge| + 2 ha_k EPS_PARALLEL).
            if (fmin > tol * (std::sqrt(alpha * alpha + beta * beta) +
                              2.0 * ha[k] * BOX_EPS_PARALLEL))
                return finite(ha, hb, R, t);
        }
    }
    return false;
}

}  // namespace collision_sensor
