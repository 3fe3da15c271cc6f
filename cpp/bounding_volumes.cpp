// Bounding volumes of point sets; conventions and array layouts in bounding_volumes.hpp.
#include "bounding_volumes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace collision_sensor {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = std::numeric_limits<double>::epsilon();  // 2^-52
constexpr double kPi = 3.14159265358979323846;  // math.pi

// Make the largest-magnitude component of a (3,) positive (the first one on a tie), so that
// an axis' sign does not depend on what the eigen solver returned.
void fix_sign(double* a) {
    int k = 0;
    for (int m = 1; m < 3; ++m) {
        if (std::abs(a[m]) > std::abs(a[k])) k = m;
    }
    if (a[k] < 0.0) {
        for (int m = 0; m < 3; ++m) a[m] = -a[m];
    }
}

}  // namespace

double obb_volume(const double* half) { return 8.0 * half[0] * half[1] * half[2]; }

double sphere_volume(double r) { return 4.0 / 3.0 * kPi * r * r * r; }

void check_points(const double* points, int64_t n) {
    if (n <= 0) {
        throw std::invalid_argument(
            "bounding volume: no points; a bounding volume needs at least one point");
    }
    for (int64_t i = 0; i < 3 * n; ++i) {
        // Written so that NaN fails too: !(NaN < inf).
        if (!(std::abs(points[i]) < kInf)) {
            throw std::invalid_argument(
                "bounding volume: points contain NaN or infinity; "
                "check the mesh or the transform that produced them");
        }
    }
}

void covariance(const double* points, int64_t n, double* C) {
    // Two passes, mean first: sum((x - m)(x - m)^T) / n, which keeps its precision for clouds
    // far from the origin (the one-pass E[x x^T] - m m^T cancels catastrophically there).
    double m0 = 0.0, m1 = 0.0, m2 = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        m0 += points[3 * i + 0];
        m1 += points[3 * i + 1];
        m2 += points[3 * i + 2];
    }
    const double nd = static_cast<double>(n);
    m0 /= nd;
    m1 /= nd;
    m2 /= nd;
    double c00 = 0.0, c01 = 0.0, c02 = 0.0, c11 = 0.0, c12 = 0.0, c22 = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        const double x0 = points[3 * i + 0] - m0;
        const double x1 = points[3 * i + 1] - m1;
        const double x2 = points[3 * i + 2] - m2;
        c00 += x0 * x0;
        c01 += x0 * x1;
        c02 += x0 * x2;
        c11 += x1 * x1;
        c12 += x1 * x2;
        c22 += x2 * x2;
    }
    C[0] = c00 / nd;
    C[1] = c01 / nd;
    C[2] = c02 / nd;
    C[3] = C[1];
    C[4] = c11 / nd;
    C[5] = c12 / nd;
    C[6] = C[2];
    C[7] = C[5];
    C[8] = c22 / nd;
}

void symmetric_eigen3(const double* C, double* w, double* V) {
    // Cyclic Jacobi (Golub & Van Loan, Matrix Computations, sec. 8.5; Numerical Recipes,
    // sec. 11.1). Each rotation J in the (p, q) plane zeroes A[p][q]:
    //
    //   A' = J^T A J,  J = [[c, s], [-s, c]] in rows/columns p, q,
    //   theta = (A_qq - A_pp) / (2 A_pq),  t = tan = sgn(theta) / (|theta| + sqrt(theta^2 + 1))
    //   (the smaller root, |rotation| <= pi/4, which is what makes the sweeps converge),
    //   c = 1 / sqrt(t^2 + 1),  s = t c,
    //   A'_pp = A_pp - t A_pq,  A'_qq = A_qq + t A_pq,  A'_pq = 0,
    //   A'_rp = c A_rp - s A_rq,  A'_rq = s A_rp + c A_rq   (r != p, q),
    //
    // and V accumulates the rotations (V' = V J, same update on its rows), so that
    // C = V diag(w) V^T throughout. The off-diagonal norm falls quadratically once small; a 3x3
    // needs about five sweeps. Jacobi also computes small eigenvalues to high relative accuracy,
    // which flat point sets (one eigenvalue ~ 0) need.
    double A[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int k = i; k < 3; ++k) {
            const double x = C[3 * i + k];
            if (!(std::abs(x) < kInf)) {
                throw std::invalid_argument(
                    "bounding volume: covariance is not finite (the points are too far apart "
                    "for float64, or contain NaN)");
            }
            A[i][k] = A[k][i] = x;
        }
    }
    for (int i = 0; i < 9; ++i) V[i] = (i % 4 == 0) ? 1.0 : 0.0;
    static const int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    for (int sweep = 0; sweep < 64; ++sweep) {
        const double off = std::abs(A[0][1]) + std::abs(A[0][2]) + std::abs(A[1][2]);
        if (off == 0.0) break;
        for (const auto& pair : kPairs) {
            const int p = pair[0], q = pair[1];
            const double apq = A[p][q];
            if (apq == 0.0) continue;
            // An element at the rounding level of its diagonal entries is zero for all purposes
            // (LAPACK's deflation test, |A_pq| <= eps sqrt(|A_pp A_qq|)): set it so, rather than
            // rotating by a meaningless angle. This matters for symmetric meshes, whose
            // covariance has a repeated eigenvalue: A_qq - A_pp and A_pq are then both rounding
            // noise, theta is arbitrary, and rotating would tilt a box that the axis-aligned
            // frame fits tightly (a cylinder, a box; test_hull_pca_ignores_vertex_density).
            if (std::abs(apq) <= kEps * std::sqrt(std::abs(A[p][p] * A[q][q]))) {
                A[p][q] = A[q][p] = 0.0;
                continue;
            }
            // After a few sweeps, an element below the rounding of both diagonal entries is
            // zero too (Numerical Recipes' test; it ends the sweeps when one diagonal is 0).
            const double g = 100.0 * std::abs(apq);
            if (sweep > 3 && std::abs(A[p][p]) + g == std::abs(A[p][p]) &&
                std::abs(A[q][q]) + g == std::abs(A[q][q])) {
                A[p][q] = A[q][p] = 0.0;
                continue;
            }
            const double h = A[q][q] - A[p][p];
            double t;
            if (std::abs(h) + g == std::abs(h)) {
                t = apq / h;  // theta^2 would overflow: t ~ 1 / (2 theta)
            } else {
                const double theta = 0.5 * h / apq;
                t = 1.0 / (std::abs(theta) + std::sqrt(1.0 + theta * theta));
                if (theta < 0.0) t = -t;
            }
            const double c = 1.0 / std::sqrt(t * t + 1.0);
            const double s = t * c;
            A[p][p] -= t * apq;
            A[q][q] += t * apq;
            A[p][q] = A[q][p] = 0.0;
            const int r = 3 - p - q;  // the third index
            const double arp = A[r][p], arq = A[r][q];
            A[r][p] = A[p][r] = c * arp - s * arq;
            A[r][q] = A[q][r] = s * arp + c * arq;
            for (int i = 0; i < 3; ++i) {
                const double vip = V[3 * i + p], viq = V[3 * i + q];
                V[3 * i + p] = c * vip - s * viq;
                V[3 * i + q] = s * vip + c * viq;
            }
        }
    }
    for (int k = 0; k < 3; ++k) w[k] = A[k][k];
}

void frame_from_eigenvectors(const double* V, const int64_t* order, double* axes) {
    // Columns V[:, order[0]], V[:, order[1]] re-orthonormalised (Gram-Schmidt), signs fixed,
    // third axis the cross product: right-handed by construction, whatever the solver returned.
    double a0[3], a1[3];
    for (int i = 0; i < 3; ++i) {
        a0[i] = V[3 * i + order[0]];
        a1[i] = V[3 * i + order[1]];
    }
    const double n0 = std::sqrt(a0[0] * a0[0] + a0[1] * a0[1] + a0[2] * a0[2]);
    for (double& x : a0) x /= n0;
    const double d = a1[0] * a0[0] + a1[1] * a0[1] + a1[2] * a0[2];
    for (int i = 0; i < 3; ++i) a1[i] -= d * a0[i];
    const double n1 = std::sqrt(a1[0] * a1[0] + a1[1] * a1[1] + a1[2] * a1[2]);
    for (double& x : a1) x /= n1;
    fix_sign(a0);
    fix_sign(a1);
    for (int i = 0; i < 3; ++i) {
        axes[3 * i + 0] = a0[i];
        axes[3 * i + 1] = a1[i];
    }
    // axes[:, 2] = a0 x a1.
    axes[3 * 0 + 2] = a0[1] * a1[2] - a0[2] * a1[1];
    axes[3 * 1 + 2] = a0[2] * a1[0] - a0[0] * a1[2];
    axes[3 * 2 + 2] = a0[0] * a1[1] - a0[1] * a1[0];
}

void principal_frame(const double* C, double* axes) {
    if (C[0] == 0.0 && C[4] == 0.0 && C[8] == 0.0) {
        // Zero spread: one point, or all points equal. Any frame is correct; take the identity.
        for (int i = 0; i < 9; ++i) axes[i] = (i % 4 == 0) ? 1.0 : 0.0;
        return;
    }
    double w[3], V[9];
    symmetric_eigen3(C, w, V);
    // Order the columns by decreasing eigenvalue, stable on ties (a three-element insertion
    // sort, as numpy's argsort(-w) sorts three elements).
    int64_t order[3] = {0, 1, 2};
    for (int i = 1; i < 3; ++i) {
        for (int j = i; j > 0 && w[order[j]] > w[order[j - 1]]; --j) {
            const int64_t tmp = order[j];
            order[j] = order[j - 1];
            order[j - 1] = tmp;
        }
    }
    frame_from_eigenvectors(V, order, axes);
}

// The box on axes whose projections, about the point o, span [lo[k], hi[k]] along axis k.
void box_from_projections(const double* o, const double* axes, const double* lo,
                          const double* hi, double* center, double* half) {
    double mid[3];
    for (int k = 0; k < 3; ++k) {
        half[k] = 0.5 * (hi[k] - lo[k]);
        mid[k] = 0.5 * (hi[k] + lo[k]);
    }
    // center = o + axes @ mid: the mid point of the projections, back in the points' frame.
    for (int r = 0; r < 3; ++r)
        center[r] = o[r] + axes[3 * r] * mid[0] + axes[3 * r + 1] * mid[1] + axes[3 * r + 2] * mid[2];
}

void box_on_axes(const double* points, int64_t n, const double* axes, double* center,
                 double* half) {
    // Project about the first point so that far-from-origin clouds keep their precision.
    const double o0 = points[0], o1 = points[1], o2 = points[2];
    double lo[3] = {kInf, kInf, kInf};
    double hi[3] = {-kInf, -kInf, -kInf};
    for (int64_t i = 0; i < n; ++i) {
        const double x0 = points[3 * i + 0] - o0;
        const double x1 = points[3 * i + 1] - o1;
        const double x2 = points[3 * i + 2] - o2;
        for (int k = 0; k < 3; ++k) {
            const double s = x0 * axes[k] + x1 * axes[3 + k] + x2 * axes[6 + k];
            if (s < lo[k]) lo[k] = s;
            if (s > hi[k]) hi[k] = s;
        }
    }
    box_from_projections(points, axes, lo, hi, center, half);
}

void fit_obb_pca(const double* points, int64_t n, double* center, double* axes, double* half) {
    check_points(points, n);
    double C[9];
    covariance(points, n, C);
    principal_frame(C, axes);
    box_on_axes(points, n, axes, center, half);
}

double ritter_sphere(const double* points, int64_t n, double* center) {
    // Ritter: from an arbitrary point (the first) find the farthest point y, from y the farthest
    // z; start with the sphere on the diameter yz and grow it, in one pass, just enough to take
    // in each point outside it. The radius is then set to the largest distance from the final
    // centre (so containment is exact up to rounding), and if the axis-aligned box's
    // circumscribed sphere is smaller, that is returned instead (Ritter's sphere is ~5% above
    // the optimum, which can exceed the box's half diagonal on box-filling clouds).
    check_points(points, n);
    auto dist2 = [points](int64_t i, int64_t j) {
        const double d0 = points[3 * i + 0] - points[3 * j + 0];
        const double d1 = points[3 * i + 1] - points[3 * j + 1];
        const double d2 = points[3 * i + 2] - points[3 * j + 2];
        return d0 * d0 + d1 * d1 + d2 * d2;
    };
    int64_t y = 0;
    double best = -1.0;
    for (int64_t i = 0; i < n; ++i) {
        const double d = dist2(i, 0);
        if (d > best) {
            best = d;
            y = i;
        }
    }
    int64_t z = y;
    best = -1.0;
    for (int64_t i = 0; i < n; ++i) {
        const double d = dist2(i, y);
        if (d > best) {
            best = d;
            z = i;
        }
    }
    double c[3];
    for (int k = 0; k < 3; ++k) c[k] = 0.5 * (points[3 * y + k] + points[3 * z + k]);
    double r = 0.5 * std::sqrt(best);
    for (int64_t i = 0; i < n; ++i) {
        const double d0 = points[3 * i + 0] - c[0];
        const double d1 = points[3 * i + 1] - c[1];
        const double d2 = points[3 * i + 2] - c[2];
        const double d = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        if (d > r) {
            // New sphere: the old one and the point on its far side as a diameter.
            const double r_new = 0.5 * (r + d);
            const double s = (r_new - r) / d;
            c[0] += s * d0;
            c[1] += s * d1;
            c[2] += s * d2;
            r = r_new;
        }
    }
    auto radius_about = [points, n](const double* m) {
        double rr = 0.0;
        for (int64_t i = 0; i < n; ++i) {
            const double d0 = points[3 * i + 0] - m[0];
            const double d1 = points[3 * i + 1] - m[1];
            const double d2 = points[3 * i + 2] - m[2];
            rr = std::max(rr, std::sqrt(d0 * d0 + d1 * d1 + d2 * d2));
        }
        return rr;
    };
    r = radius_about(c);
    // The axis-aligned box's circumscribed sphere, when it is smaller.
    double lo[3] = {kInf, kInf, kInf};
    double hi[3] = {-kInf, -kInf, -kInf};
    for (int64_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], points[3 * i + k]);
            hi[k] = std::max(hi[k], points[3 * i + k]);
        }
    }
    double cb[3];
    for (int k = 0; k < 3; ++k) cb[k] = 0.5 * (lo[k] + hi[k]);
    const double rb = radius_about(cb);
    const double* best_center = (rb < r) ? cb : c;
    for (int k = 0; k < 3; ++k) center[k] = best_center[k];
    return (rb < r) ? rb : r;
}

}  // namespace collision_sensor