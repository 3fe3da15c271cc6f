// The refined box fit (bounding_volumes.hpp: fit_obb_refined): the principal-axes box,
// tightened by the smallest-area rectangle around each principal axis (rotating calipers on
// the points' 2D hull).
#include "bounding_volumes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace collision_sensor {

namespace {

// Convex hull of 2D points xy (k, 2) by Andrew's monotone chain, counter-clockwise, without
// collinear points; written to hull (capacity k + 1 rows), its size returned. Sorts xy.
int64_t hull_2d(std::vector<std::array<double, 2>>& xy, std::vector<std::array<double, 2>>& hull) {
    std::sort(xy.begin(), xy.end());
    const int64_t k = static_cast<int64_t>(xy.size());
    hull.resize(2 * k + 1);
    auto cross = [](const std::array<double, 2>& o, const std::array<double, 2>& a,
                    const std::array<double, 2>& b) {
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    };
    int64_t h = 0;
    for (int64_t i = 0; i < k; ++i) {  // lower chain
        while (h >= 2 && cross(hull[h - 2], hull[h - 1], xy[i]) <= 0.0) --h;
        hull[h++] = xy[i];
    }
    for (int64_t i = k - 2, low = h + 1; i >= 0; --i) {  // upper chain
        while (h >= low && cross(hull[h - 2], hull[h - 1], xy[i]) <= 0.0) --h;
        hull[h++] = xy[i];
    }
    return h > 1 ? h - 1 : h;  // the last point repeats the first
}

struct Rectangle {
    double area, c, s;  // a side along (c, s), unit
};

// The smallest-area rectangle around a convex polygon hull[0 .. h - 1] (counter-clockwise,
// h >= 2) with a side on one of its edges; a zero-length edge is skipped.
Rectangle smallest_rectangle(const std::vector<std::array<double, 2>>& hull, int64_t h) {
    auto along = [&](int64_t i, double dx, double dy) { return hull[i][0] * dx + hull[i][1] * dy; };
    auto next = [h](int64_t i) { return i + 1 == h ? 0 : i + 1; };
    Rectangle best = {INFINITY, 1.0, 0.0};
    int64_t right = 0, top = 0, left = 0;
    bool started = false;
    for (int64_t e = 0; e < h; ++e) {
        const auto& a = hull[e];
        const auto& b = hull[next(e)];
        double dx = b[0] - a[0], dy = b[1] - a[1];
        const double len = std::sqrt(dx * dx + dy * dy);
        if (!(len > 0.0)) continue;
        dx /= len;
        dy /= len;
        const double nx = -dy, ny = dx;  // the inside is on the left
        if (!started) {  // the first edge: the three extremes by a full scan
            for (int64_t m = 0; m < h; ++m) {
                if (along(m, dx, dy) > along(right, dx, dy)) right = m;
                if (along(m, nx, ny) > along(top, nx, ny)) top = m;
                if (along(m, dx, dy) < along(left, dx, dy)) left = m;
            }
            started = true;
        } else {
            for (int64_t k = 0; k < h && along(next(right), dx, dy) > along(right, dx, dy); ++k)
                right = next(right);
            for (int64_t k = 0; k < h && along(next(top), nx, ny) > along(top, nx, ny); ++k)
                top = next(top);
            for (int64_t k = 0; k < h && along(next(left), dx, dy) < along(left, dx, dy); ++k)
                left = next(left);
        }
        const double width = along(right, dx, dy) - along(left, dx, dy);
        const double height = along(top, nx, ny) - (a[0] * nx + a[1] * ny);
        const double area = width * height;
        if (area < best.area) best = {area, dx, dy};
    }
    return best;
}

// Box volume, then surface (flat boxes all have volume 0), as one comparable key.
bool smaller_box(const double* h, const double* best) {
    const double v = h[0] * h[1] * h[2], vb = best[0] * best[1] * best[2];
    if (v != vb) return v < vb;
    return h[0] * h[1] + h[1] * h[2] + h[2] * h[0] < best[0] * best[1] + best[1] * best[2] +
                                                         best[2] * best[0];
}

}  // namespace

namespace {

// The box of one triangle (points (3, 3)) with the least area among those with a side along
// one of its edges, in its plane (half[2] = 0); left as it is (the principal-axes box) when
// the triangle has no area or that box is smaller.
void fit_triangle(const double* points, double* center, double* axes, double* half) {
    const double* p0 = points;
    const double* p1 = points + 3;
    const double* p2 = points + 6;
    const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    double nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                     e1[0] * e2[1] - e1[1] * e2[0]};
    const double nn = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(nn > 0.0)) return;
    for (double& x : nrm) x /= nn;
    const double* corner[3] = {p0, p1, p2};
    double best_area = INFINITY, best_d[3] = {0.0, 0.0, 0.0};
    for (int e = 0; e < 3; ++e) {
        const double* a = corner[e];
        const double* b = corner[(e + 1) % 3];
        double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 0.0)) continue;
        for (double& x : d) x /= len;
        const double w[3] = {nrm[1] * d[2] - nrm[2] * d[1], nrm[2] * d[0] - nrm[0] * d[2],
                             nrm[0] * d[1] - nrm[1] * d[0]};
        double lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY;
        for (const double* x : corner) {
            const double u = x[0] * d[0] + x[1] * d[1] + x[2] * d[2];
            const double v = x[0] * w[0] + x[1] * w[1] + x[2] * w[2];
            lo_u = std::min(lo_u, u);
            hi_u = std::max(hi_u, u);
            lo_v = std::min(lo_v, v);
            hi_v = std::max(hi_v, v);
        }
        const double area = (hi_u - lo_u) * (hi_v - lo_v);
        if (area < best_area) {
            best_area = area;
            std::copy(d, d + 3, best_d);
        }
    }
    if (!(best_area < INFINITY)) return;
    // Axes: the longer in-plane side first, then the other, the normal last (zero extent):
    // decreasing variance for a flat box, right-handed by frame_from_eigenvectors.
    const double w[3] = {nrm[1] * best_d[2] - nrm[2] * best_d[1],
                         nrm[2] * best_d[0] - nrm[0] * best_d[2],
                         nrm[0] * best_d[1] - nrm[1] * best_d[0]};
    double V[9];
    for (int i = 0; i < 3; ++i) {
        V[3 * i] = best_d[i];
        V[3 * i + 1] = w[i];
        V[3 * i + 2] = nrm[i];
    }
    double var[2];
    for (int c = 0; c < 2; ++c) {
        double m = 0.0, m2 = 0.0;
        for (const double* x : corner) {
            const double s = x[0] * V[c] + x[1] * V[3 + c] + x[2] * V[6 + c];
            m += s;
            m2 += s * s;
        }
        var[c] = m2 / 3.0 - (m / 3.0) * (m / 3.0);
    }
    const int64_t order[3] = {var[0] >= var[1] ? 0 : 1, var[0] >= var[1] ? 1 : 0, 2};
    double cand_axes[9], cand_center[3], cand_half[3];
    frame_from_eigenvectors(V, order, cand_axes);
    box_on_axes(points, 3, cand_axes, cand_center, cand_half);
    if (smaller_box(cand_half, half)) {
        std::copy(cand_center, cand_center + 3, center);
        std::copy(cand_axes, cand_axes + 9, axes);
        std::copy(cand_half, cand_half + 3, half);
    }
}

}  // namespace

void fit_obb_refined(const double* points, int64_t n, double* center, double* axes,
                     double* half) {
    // Nodes of 2 to REFINE_FROM / 3 triangles keep the principal box: they are most of a
    // tree's nodes, and refining them costs most of the build for few box tests saved.
    constexpr int64_t REFINE_FROM = 48;
    // At most REFINE_POINTS points (a stride through them) choose the box's axes; the
    // extents always come from every point, so only the tightness depends on the sample.
    constexpr int64_t REFINE_POINTS = 256;
    // Rounds: a tilted principal axis is kept by every candidate of the first round; the next
    // keeps each axis of the box found instead, which turns the tilt out (a square prism's
    // sampled long axis). Up to REFINE_ROUNDS, while a round shrinks the box by REFINE_GAIN.
    constexpr int REFINE_ROUNDS = 3;
    constexpr double REFINE_GAIN = 0.001;
    check_points(points, n);
    double C[9];
    covariance(points, n, C);
    principal_frame(C, axes);
    // The sample: every point, or a stride through them plus the points extreme along 7
    // directions of the principal frame (its axes and its box's diagonals), both ways: a
    // stride misses the corners that the rectangles rest on.
    const int64_t stride = (n + REFINE_POINTS - 1) / REFINE_POINTS;
    if (n <= REFINE_FROM || stride == 1) box_on_axes(points, n, axes, center, half);
    if (n < 3) return;
    if (n == 3) {  // one triangle (a leaf): the rectangle rests on one of its three edges
        fit_triangle(points, center, axes, half);
        return;
    }
    if (n <= REFINE_FROM) return;
    std::vector<double> gathered;
    const double* S = points;
    int64_t ns = n;
    if (stride > 1) {
        // One pass finds the extremes and the principal box (box_on_axes' sums, about the
        // first point, from the first three directions' extremes).
        constexpr int DIRS = 7;
        const int signs[DIRS][3] = {{1, 0, 0},  {0, 1, 0},   {0, 0, 1},  {1, 1, 1},
                                    {1, 1, -1}, {1, -1, 1},  {1, -1, -1}};
        int64_t lo[DIRS] = {0}, hi[DIRS] = {0};
        double lo_v[DIRS], hi_v[DIRS];
        for (int d = 0; d < DIRS; ++d) lo_v[d] = INFINITY, hi_v[d] = -INFINITY;
        const double o0 = points[0], o1 = points[1], o2 = points[2];
        for (int64_t i = 0; i < n; ++i) {
            const double x0 = points[3 * i + 0] - o0;
            const double x1 = points[3 * i + 1] - o1;
            const double x2 = points[3 * i + 2] - o2;
            // Each direction's coordinate is a signed sum of the three axis coordinates.
            const double c[3] = {x0 * axes[0] + x1 * axes[3] + x2 * axes[6],
                                 x0 * axes[1] + x1 * axes[4] + x2 * axes[7],
                                 x0 * axes[2] + x1 * axes[5] + x2 * axes[8]};
            for (int d = 0; d < DIRS; ++d) {
                const double v = d < 3 ? c[d] : signs[d][0] * c[0] + signs[d][1] * c[1] +
                                                    signs[d][2] * c[2];
                if (v < lo_v[d]) lo_v[d] = v, lo[d] = i;
                if (v > hi_v[d]) hi_v[d] = v, hi[d] = i;
            }
        }
        box_from_projections(points, axes, lo_v, hi_v, center, half);
        gathered.reserve(3 * (n / stride + 2 * DIRS + 1));
        auto take = [&](int64_t i) { gathered.insert(gathered.end(), points + 3 * i, points + 3 * i + 3); };
        for (int64_t i = 0; i < n; i += stride) take(i);
        for (int d = 0; d < DIRS; ++d) take(lo[d]), take(hi[d]);
        S = gathered.data();
        ns = static_cast<int64_t>(gathered.size() / 3);
    }
    // Rounds on the sample: its box (sample_half) is what each candidate must beat.
    double frame[9], sample_center[3], sample_half[3];
    std::copy(axes, axes + 9, frame);
    box_on_axes(S, ns, frame, sample_center, sample_half);
    std::vector<std::array<double, 2>> xy, hull;
    xy.reserve(ns);
    bool moved = false;
    for (int round = 0; round < REFINE_ROUNDS; ++round) {
        const double base[9] = {frame[0], frame[1], frame[2], frame[3], frame[4],
                                frame[5], frame[6], frame[7], frame[8]};
        // The candidate of least volume on the sample: the rectangle's area times the
        // sample box's extent along the axis kept.
        double best_volume = 8.0 * sample_half[0] * sample_half[1] * sample_half[2];
        double best_V[9];
        bool found = false;
        for (int k = 0; k < 3; ++k) {
            // Keep the box's axis k; (p, q, w) = (axis k+1, axis k+2, axis k): right-handed.
            const int ip = (k + 1) % 3, iq = (k + 2) % 3;
            const double p[3] = {base[ip], base[3 + ip], base[6 + ip]};
            const double q[3] = {base[iq], base[3 + iq], base[6 + iq]};
            xy.clear();
            for (int64_t i = 0; i < ns; ++i) {
                const double* x = S + 3 * i;
                xy.push_back({x[0] * p[0] + x[1] * p[1] + x[2] * p[2],
                              x[0] * q[0] + x[1] * q[1] + x[2] * q[2]});
            }
            const int64_t h = hull_2d(xy, hull);
            if (h < 2) continue;
            // The smallest-area rectangle has a side on a hull edge (Freeman & Shapira 1975);
            // every edge is tried, the other three sides by rotating calipers (Toussaint
            // 1983): the extreme points along the edge, across it and against it only move
            // forward around the hull, so all edges cost O(h).
            const Rectangle r = smallest_rectangle(hull, h);
            const double volume = r.area * 2.0 * sample_half[k];
            if (!(volume < best_volume)) continue;
            best_volume = volume;
            found = true;
            // u = c p + s q, v = -s p + c q, w = p x q = axis k: columns (u, v, w).
            for (int i = 0; i < 3; ++i) {
                best_V[3 * i + 0] = r.c * p[i] + r.s * q[i];
                best_V[3 * i + 1] = -r.s * p[i] + r.c * q[i];
                best_V[3 * i + 2] = base[3 * i + k];
            }
        }
        if (!found) break;
        // The box convention: axes by decreasing variance of the points along them, u' C u.
        double var[3];
        for (int c = 0; c < 3; ++c) {
            const double u0 = best_V[c], u1 = best_V[3 + c], u2 = best_V[6 + c];
            var[c] = u0 * (C[0] * u0 + C[1] * u1 + C[2] * u2) +
                     u1 * (C[3] * u0 + C[4] * u1 + C[5] * u2) +
                     u2 * (C[6] * u0 + C[7] * u1 + C[8] * u2);
        }
        int64_t order[3] = {0, 1, 2};
        for (int i = 1; i < 3; ++i)
            for (int j = i; j > 0 && var[order[j]] > var[order[j - 1]]; --j)
                std::swap(order[j], order[j - 1]);
        double cand_axes[9], cand_center[3], cand_half[3];
        frame_from_eigenvectors(best_V, order, cand_axes);
        box_on_axes(S, ns, cand_axes, cand_center, cand_half);
        if (!smaller_box(cand_half, sample_half)) break;
        const double before = sample_half[0] * sample_half[1] * sample_half[2];
        std::copy(cand_axes, cand_axes + 9, frame);
        std::copy(cand_half, cand_half + 3, sample_half);
        moved = true;
        if (!(sample_half[0] * sample_half[1] * sample_half[2] < (1.0 - REFINE_GAIN) * before))
            break;
    }
    if (!moved) return;
    // The extents from every point; the principal box stays if it is still the smaller.
    double cand_center[3], cand_half[3];
    box_on_axes(points, n, frame, cand_center, cand_half);
    if (smaller_box(cand_half, half)) {
        std::copy(cand_center, cand_center + 3, center);
        std::copy(frame, frame + 9, axes);
        std::copy(cand_half, cand_half + 3, half);
    }
}

}  // namespace collision_sensor
