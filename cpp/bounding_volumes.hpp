// Bounding volumes of point sets: oriented boxes (paper sec. 3, Wu's principal axes) and spheres.
//
// The C++ side of collision_sensor/engine/bounding_volumes.py; its module docstring is the
// contract. Every array is contiguous, row-major float64:
//
//   points : (n, 3)   point i is points[3 * i + 0 .. 3 * i + 2]
//   C, V   : (3, 3)   element (i, k) is C[3 * i + k]
//   axes   : (3, 3)   axes[3 * i + k] is row i of axis (column) k, as numpy's axes[i, k]
//   center, half : (3,)
//
// Box convention (every fit here returns it; obb_tree relies on it):
//   * axes[:, 0] is the direction of largest variance of the points, axes[:, 1] the next;
//   * axes[:, 2] = axes[:, 0] x axes[:, 1]: right-handed (det = +1) by construction, never an
//     eigenvector's own sign;
//   * the largest-magnitude component of axes[:, 0] and of axes[:, 1] is positive;
//   * center is the box's mid point (not the mean of the points), half >= 0 its half extents,
//     from the minimum and maximum of the points projected on the axes, so every point is
//     inside up to rounding: |axes^T (x - center)| <= half.
//
// Degenerate input is handled on purpose: one point (or all points equal) gives a point box
// with the identity axes; two points or collinear points a segment box; coplanar points a flat
// box. No points, or NaN / infinity in them, throw std::invalid_argument (EngineInputError in
// Python).
#pragma once

#include <cstdint>

namespace collision_sensor {

//: Return the volume 8 hx hy hz of a box with half extents half (3,).
double obb_volume(const double* half);

//: Return the volume 4/3 pi r^3 of a sphere of radius r.
double sphere_volume(double r);

//: Throw std::invalid_argument if there are no points (n == 0) or a coordinate is NaN or
//: infinite. points: (n, 3).
void check_points(const double* points, int64_t n);

//: Write the (3, 3) covariance (1/n normalised, two-pass: mean first) of points (n, 3), n >= 1,
//: into C.
void covariance(const double* points, int64_t n, double* C);

//: Eigen-decompose a symmetric (3, 3) matrix C by cyclic Jacobi rotations: C = V diag(w) V^T,
//: V (3, 3) orthonormal with eigenvector k in column k (V[3 * i + k]), w (3,) unsorted.
//: Only the upper triangle of C is read. Throws std::invalid_argument if C is not finite.
void symmetric_eigen3(const double* C, double* w, double* V);

//: Write the box frame (3, 3) built from columns order[0] and order[1] of V: the first
//: normalised, the second made orthogonal to it (Gram-Schmidt) and normalised, both with their
//: largest-magnitude component made positive, and the third their cross product.
//: V: (3, 3); order: (2,) or longer, column indices in 0..2 (only the first two are read).
void frame_from_eigenvectors(const double* V, const int64_t* order, double* axes);

//: Write the box frame (3, 3) of a symmetric covariance C (3, 3): its eigenvectors, largest
//: eigenvalue first (for repeated eigenvalues any orthonormal basis of the eigenspace is
//: correct). A C with a zero diagonal (one point, or all points equal) gives the identity.
void principal_frame(const double* C, double* axes);

// The box on axes (3, 3) whose projections, about the point o (3,), span [lo[k], hi[k]] along
// axis k: its center (3,) and half extents (3,).
void box_from_projections(const double* o, const double* axes, const double* lo,
                          const double* hi, double* center, double* half);

//: Write center (3,) and half (3,) of the smallest box with the given axes (3, 3) containing
//: points (n, 3), n >= 1.
void box_on_axes(const double* points, int64_t n, const double* axes, double* center,
                 double* half);

//: Fit an oriented box by principal axes (Wu 1992, paper sec. 3), O(n): the eigenvectors of the
//: points' covariance as axes, the extents from the projections. points: (n, 3);
//: center (3,), axes (3, 3), half (3,) are written. Throws std::invalid_argument on no points
//: or NaN / infinity.
void fit_obb_pca(const double* points, int64_t n, double* center, double* axes, double* half);

//: Fit an oriented box by principal axes, then tighten it: with each principal axis kept in
//: turn, the two others turned to the smallest-area rectangle around the points projected on
//: the plane they span (a side on an edge of the projection's convex hull); the smallest box
//: of the four (volume, then surface) is kept, and the same is done around its axes, up to
//: three rounds while the box shrinks (a sampled principal axis can be tilted); written
//: under the box convention above. The axes are chosen on at most 256 of the points (a
//: stride) plus the 14 extremes along the principal axes and box diagonals, every edge of
//: their hull tried (rotating calipers); the extents come from all of them. One triangle:
//: the smallest box with a side along an edge; 4 to 48 points: the principal box. O(n)
//: plus sorts of the sample. Same arguments and errors as fit_obb_pca.
void fit_obb_refined(const double* points, int64_t n, double* center, double* axes,
                     double* half);

//: Return the radius of a near-minimal bounding sphere of points (n, 3) (Ritter 1990), O(n),
//: and write its centre into center (3,); or the axis-aligned box's circumscribed sphere when
//: that is smaller. Throws std::invalid_argument on no points or NaN / infinity.
double ritter_sphere(const double* points, int64_t n, double* center);

}  // namespace collision_sensor
