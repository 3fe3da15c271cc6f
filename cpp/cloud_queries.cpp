// A body's trees against a point cloud's voxels (cloud_queries.hpp).
#include "cloud_queries.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "containment.hpp"
#include "distance.hpp"
#include "inlining.hpp"
#include "poses.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"
#include "triangle_box.hpp"

namespace collision_sensor {

namespace {

// The traversals' stacks, one per thread (a batch's rows may run on threads of their own):
// (na, nv) rows, grown once to the deepest descent.
thread_local std::vector<int64_t> cloud_stack;

// Triangle t of body a taken to the cloud's (world) frame: x_w = R' (x_a - t_ab).
CS_ALWAYS_INLINE void triangle_in_cloud(const double* tris, int64_t t, const double* P,
                                        Triangle& W) {
    const double* v = tris + 9 * t;
    for (int k = 0; k < 3; ++k) {
        const double d0 = v[3 * k] - P[9], d1 = v[3 * k + 1] - P[10], d2 = v[3 * k + 2] - P[11];
        for (int i = 0; i < 3; ++i) W[k][i] = P[i] * d0 + P[3 + i] * d1 + P[6 + i] * d2;
    }
}

// Which node of an overlapping pair is expanded: the larger sphere (EXPAND_WIDER's rule).
CS_ALWAYS_INLINE bool expand_body(const double* A, const double* B, bool leaf_a, bool leaf_b) {
    return !leaf_a && (leaf_b || A[BOX_RADIUS] >= B[BOX_RADIUS]);
}

// Push the two children of the expanded node, the one whose centre is nearer the other
// box's last (popped first).
void push_children(const Forest& f, const VoxelGrid& g, int64_t na, int64_t nv, bool on_a,
                   const double* P, std::vector<int64_t>& stack) {
    if (on_a) {
        int64_t first = f.node(na)[NODE_LEFT], second = f.node(na)[NODE_RIGHT];
        const double* B = g.box(nv);  // B's centre in body a: R c + t
        const double x0 = P[0] * B[0] + P[1] * B[1] + P[2] * B[2] + P[9];
        const double x1 = P[3] * B[0] + P[4] * B[1] + P[5] * B[2] + P[10];
        const double x2 = P[6] * B[0] + P[7] * B[1] + P[8] * B[2] + P[11];
        if (closer(f, second, first, x0, x1, x2)) std::swap(first, second);
        stack.insert(stack.end(), {second, nv, first, nv});
    } else {
        int64_t first = g.node(nv)[NODE_LEFT], second = g.node(nv)[NODE_RIGHT];
        const double* A = f.box(na);  // A's centre in the cloud: R' (c - t)
        const double d0 = A[0] - P[9], d1 = A[1] - P[10], d2 = A[2] - P[11];
        const double x[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2, P[1] * d0 + P[4] * d1 + P[7] * d2,
                             P[2] * d0 + P[5] * d1 + P[8] * d2};
        auto dist2 = [&](int64_t n) {
            const double* b = g.box(n);
            return (b[0] - x[0]) * (b[0] - x[0]) + (b[1] - x[1]) * (b[1] - x[1]) +
                   (b[2] - x[2]) * (b[2] - x[2]);
        };
        if (dist2(second) < dist2(first)) std::swap(first, second);
        stack.insert(stack.end(), {na, second, na, first});
    }
}

// The smallest distance from a solid element of body a (its true shape) to a corner of a cube
// of the grid within `limit` of the element's root box (INF if none), and that corner (world
// frame) in x. A body without solids: INF.
double solid_corner_distance(const Model& m, int64_t a, const VoxelGrid& g, const double* P,
                             double limit, double* x) {
    double best = INF;
    if (!m.body_solid[a] || g.empty()) return best;
    std::vector<int64_t>& stack = cloud_stack;
    double grown_a[BOX_WIDTH];
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e) {
        const double* s = m.elem_solid + SOLID_WIDTH * e;
        if (int(s[0]) == SOLID_NONE) continue;
        const double* A = grown(m.forest.box(m.roots[e]), std::max(limit, 0.0), grown_a);
        stack.assign({0});
        while (!stack.empty()) {
            const int64_t nv = stack.back();
            stack.pop_back();
            if (boxes_apart(BOX_TEST_SAT, A, g.box(nv), P)) continue;
            const int64_t* node = g.node(nv);
            if (node[NODE_LEFT] >= 0) {
                stack.insert(stack.end(), {node[NODE_LEFT], node[NODE_RIGHT]});
                continue;
            }
            for (int64_t v = node[NODE_FIRST]; v < node[NODE_FIRST] + node[NODE_COUNT]; ++v) {
                double lo[3], hi[3];
                g.cube(v, lo, hi);
                for (int c = 0; c < 8; ++c) {
                    const double w[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1],
                                         c & 4 ? hi[2] : lo[2]};
                    double y[3];  // in body a: R w + t
                    for (int i = 0; i < 3; ++i)
                        y[i] = P[3 * i] * w[0] + P[3 * i + 1] * w[1] + P[3 * i + 2] * w[2] +
                               P[9 + i];
                    const double d = int(s[0]) == SOLID_CLOSED_MESH
                                         ? (inside_solid(m, e, y) ? 0.0 : INF)
                                         : solid_distance(s, y);
                    if (d < best) {
                        best = d;
                        std::copy(w, w + 3, x);
                        if (d <= 0.0) return 0.0;
                    }
                }
            }
        }
    }
    return best;
}

// The padded distance between body a and the grid, with nearest points (world frame) into
// best when below best.distance (its cutoff on entry).
void distance_body_cloud(const Model& m, int64_t a, const VoxelGrid& g, const double* P,
                         double pad, NearestPoints& best) {
    const Forest& f = m.forest;
    std::vector<int64_t>& stack = cloud_stack;
    stack.clear();
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e)
        stack.insert(stack.end(), {m.roots[e], 0});
    while (!stack.empty()) {
        const int64_t nv = stack.back();
        stack.pop_back();
        const int64_t na = stack.back();
        stack.pop_back();
        const double* A = f.box(na);
        const double* B = g.box(nv);
        double T[12];
        box_in_frame(A, B, P, T);
        if (!(projected_gap(A, B, T) - pad < best.distance)) continue;
        const bool leaf_a = f.node(na)[NODE_LEFT] < 0, leaf_b = g.node(nv)[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            const int64_t* node_a = f.node(na);
            const int64_t* node_v = g.node(nv);
            for (int64_t t = node_a[NODE_FIRST]; t < node_a[NODE_FIRST] + node_a[NODE_COUNT];
                 ++t) {
                Triangle W;
                triangle_in_cloud(f.tris, t, P, W);
                for (int64_t v = node_v[NODE_FIRST];
                     v < node_v[NODE_FIRST] + node_v[NODE_COUNT]; ++v) {
                    double lo[3], hi[3], x[3], y[3];
                    g.cube(v, lo, hi);
                    const double d = triangle_box_distance(W, lo, hi, x, y) - pad;
                    if (d < best.distance) best.take(d, t, v, x, y);
                }
            }
            continue;
        }
        push_children(f, g, na, nv, expand_body(A, B, leaf_a, leaf_b), P, stack);
    }
}

}  // namespace

CloudPairResult collide_body_cloud(const Model& m, int64_t a, const VoxelGrid& g,
                                   const double* P, double pad, bool track,
                                   int64_t witness_triangle, int64_t witness_voxel,
                                   int64_t* counters) {
    const Forest& f = m.forest;
    if (g.empty()) return {false, -1, -1, INF};
    if (witness_triangle >= 0 && witness_voxel >= 0 && witness_voxel < g.count) {
        Triangle W;
        triangle_in_cloud(f.tris, witness_triangle, P, W);
        double lo[3], hi[3], d;
        g.cube(witness_voxel, lo, hi);
        ++counters[COUNT_TRIANGLE_TESTS];
        if (triangle_box_within(W, lo, hi, pad, &d))
            return {true, witness_triangle, witness_voxel, 0.0};
    }
    std::vector<int64_t>& stack = cloud_stack;
    stack.clear();
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e)
        stack.insert(stack.end(), {m.roots[e], 0});
    double best = track ? INF : 0.0;
    int64_t n_boxes = 0, n_spheres = 0, n_triangles = 0;
    CloudPairResult out = {false, -1, -1, 0.0};
    while (!stack.empty() && !out.hit) {
        const int64_t nv = stack.back();
        stack.pop_back();
        const int64_t na = stack.back();
        stack.pop_back();
        const double* A = f.box(na);
        const double* B = g.box(nv);
        const Spheres sp = spheres(A, B, P);
        if (sp.apart) {
            ++n_spheres;
            if (track) best = std::min(best, std::sqrt(sp.dd) - sp.radii);
            continue;
        }
        ++n_boxes;
        double T[12];
        box_in_frame(A, B, P, T);
        const int axis = sat_axis(A, B, T);
        if (axis >= 0) {
            if (track) {
                double gap = face_gap(A, B, T);
                if (axis >= 6) gap = std::max(gap, axis_gap(axis, A, B, P).gap);
                best = std::min(best, gap);
            }
            continue;
        }
        const int64_t* node_a = f.node(na);
        const int64_t* node_v = g.node(nv);
        const bool leaf_a = node_a[NODE_LEFT] < 0, leaf_b = node_v[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            for (int64_t t = node_a[NODE_FIRST];
                 t < node_a[NODE_FIRST] + node_a[NODE_COUNT] && !out.hit; ++t) {
                Triangle W;
                triangle_in_cloud(f.tris, t, P, W);
                for (int64_t v = node_v[NODE_FIRST];
                     v < node_v[NODE_FIRST] + node_v[NODE_COUNT]; ++v) {
                    double lo[3], hi[3], d;
                    g.cube(v, lo, hi);
                    ++n_triangles;
                    if (triangle_box_within(W, lo, hi, pad, &d)) {
                        out = {true, t, v, 0.0};
                        break;
                    }
                    if (track) best = std::min(best, d - pad);
                }
            }
            continue;
        }
        push_children(f, g, na, nv, expand_body(A, B, leaf_a, leaf_b), P, stack);
    }
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_SPHERE_SKIPS] += n_spheres;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
    if (out.hit) return out;
    double corner[3];
    if (solid_corner_distance(m, a, g, P, 0.0, corner) <= 0.0) return {true, -1, -1, 0.0};
    out.gap = best;
    return out;
}

void recheck_cloud_pair(CheckContext& c, int64_t p, int64_t a, int64_t b, const double* pose,
                        bool track, bool* changed) {
    const Model& m = c.model;
    State& s = c.state;
    const VoxelGrid& grid = *m.clouds[b];
    const CloudPairResult r =
        collide_body_cloud(m, a, grid, pose, m.padding[a], track, track ? s.witness[2 * p] : -1,
                           track ? s.witness[2 * p + 1] : -1, c.scratch.counters);
    s.witness[2 * p] = r.hit ? r.triangle : -1;
    s.witness[2 * p + 1] = r.hit ? r.voxel : -1;
    double gap = 0.0;
    if (track && !r.hit) {
        // The rounding margin of the pair's coordinates: the body's reach, the cloud's box.
        const double* B = grid.empty() ? nullptr : grid.box(0);
        const double reach =
            B ? std::sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]) + B[BOX_RADIUS] : 0.0;
        const double t = std::sqrt(pose[9] * pose[9] + pose[10] * pose[10] + pose[11] * pose[11]);
        gap = std::min(r.gap, MAX_CLOUD_CLEARANCE) -
              CLEARANCE_EPS_REL * (t + m.body_reach[a] + reach);
    }
    s.clearance[p] = gap > 0.0 ? gap : 0.0;
    if (s.clearance[p] > 0.0) s.travel[2 * p] = s.travel[2 * p + 1] = 0.0;
    *changed |= (s.status[p] != 0) != r.hit;
    s.status[p] = r.hit ? 1 : 0;
}

void measure_cloud_pair(const Model& m, const State& s, int64_t p, const double* pose,
                        double max_distance, const ProximityResult& result) {
    const int64_t a = m.pair_a[p];
    const VoxelGrid& grid = *m.clouds[m.pair_b[p]];
    const double pad = m.padding[a];
    const bool contact = s.status[p] != 0;
    result.distance[p] = INF;
    if (grid.empty()) return;
    NearestPoints best;
    best.found = false;
    best.distance = contact ? INF : max_distance;
    distance_body_cloud(m, a, grid, pose, pad, best);
    double corner[3];
    if (contact && !(best.found && best.distance <= 0.0) &&
        solid_corner_distance(m, a, grid, pose, 0.0, corner) <= 0.0) {
        // Contact through a solid, no triangle within the padding: the corner inside it.
        best.take(-pad, -1, -1, corner, corner);
    }
    if (!best.found) return;
    if (contact) best.distance = std::min(best.distance, 0.0);
    // Points of the padded bodies (world frame): apart, the body's moved towards the cloud
    // by its padding; in contact, one point of both (the cloud is not padded: on the cube).
    double* row = result.points + 6 * p;
    double w[3], gap2 = 0.0;
    for (int i = 0; i < 3; ++i) {
        w[i] = best.y[i] - best.x[i];
        gap2 += w[i] * w[i];
    }
    const double gap = std::sqrt(gap2);
    for (int i = 0; i < 3; ++i) {
        if (best.distance > 0.0) {
            row[i] = best.x[i] + (gap > 0.0 ? pad / gap : 0.0) * w[i];
        } else {
            row[i] = pad > 0.0 ? best.y[i] : 0.5 * (best.x[i] + best.y[i]);
        }
        row[3 + i] = best.distance > 0.0 ? best.y[i] : row[i];
    }
    result.distance[p] = best.distance;
}

WithinResult cloud_pair_within(const Model& m, int64_t a, const VoxelGrid& g, const double* P,
                               double h, double extra, MotionMargin& motion, int box_test,
                               int64_t* counters) {
    double reach = motion.h2;
    if (g.empty()) return {false, 0.0, reach};
    const Forest& f = m.forest;
    const double pad = m.padding[a];
    const double* Ta = motion.side[0].T;
    const BoxMotion still{0.0, {0.0, 0.0, 0.0}, 0.0};  // the cloud does not move
    // Solids first: a cube's corner moves no farther than the body's box allows.
    {
        const BoxMotion body = motion.box_motion(m.body_box(a), 0);
        const double r = h * body.rate + extra;
        double corner[3];
        const double solid = solid_corner_distance(m, a, g, P, motion.h2 * body.rate + extra,
                                                   corner);
        const double solid_reach =
            body.rate > 0.0 ? (solid - extra) / body.rate : (solid > extra ? INF : 0.0);
        if (solid <= r) return {true, r, std::max(solid_reach, 0.0)};
        reach = std::min(reach, solid_reach);
    }
    std::vector<int64_t>& stack = cloud_stack;
    stack.clear();
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e)
        stack.insert(stack.end(), {m.roots[e], 0});
    int64_t n_boxes = 0, n_triangles = 0;
    while (!stack.empty()) {
        const int64_t nv = stack.back();
        stack.pop_back();
        const int64_t na = stack.back();
        stack.pop_back();
        const double* A = f.box(na);
        const double* B = g.box(nv);
        const BoxMotion& ma = motion.node(f, na, 0);
        ++n_boxes;
        double x;
        if (node_pair_apart(A, B, P, Ta, ma, still, h, extra, motion, box_test, &x)) {
            reach = std::min(reach, x);
            continue;
        }
        const int64_t* node_a = f.node(na);
        const int64_t* node_v = g.node(nv);
        const bool leaf_a = node_a[NODE_LEFT] < 0, leaf_b = node_v[NODE_LEFT] < 0;
        if (leaf_a && leaf_b) {
            const double rate = ma.rate;
            const double r = h * rate + extra;
            for (int64_t t = node_a[NODE_FIRST]; t < node_a[NODE_FIRST] + node_a[NODE_COUNT];
                 ++t) {
                Triangle W;
                triangle_in_cloud(f.tris, t, P, W);
                for (int64_t v = node_v[NODE_FIRST];
                     v < node_v[NODE_FIRST] + node_v[NODE_COUNT]; ++v) {
                    double lo[3], hi[3], xa[3], yb[3];
                    g.cube(v, lo, hi);
                    ++n_triangles;
                    const double distance = triangle_box_distance(W, lo, hi, xa, yb) - pad;
                    double got = rate > 0.0 ? std::min((distance - extra) / rate, motion.h2)
                                            : (distance > extra ? motion.h2 : -1.0);
                    if (!(distance > r) && distance > extra) {
                        // Along the nearest points' direction (world) the two are distance
                        // apart.
                        const double n[3] = {(yb[0] - xa[0]) / (distance + pad),
                                             (yb[1] - xa[1]) / (distance + pad),
                                             (yb[2] - xa[2]) / (distance + pad)};
                        got = std::max(got, motion.first_order_reach(n, distance, extra,
                                                                     A[BOX_RADIUS], ma,
                                                                     B[BOX_RADIUS], still, h));
                    }
                    if (!(got >= h)) {
                        counters[COUNT_BOX_TESTS] += n_boxes;
                        counters[COUNT_TRIANGLE_TESTS] += n_triangles;
                        return {true, r, std::max(got, 0.0)};
                    }
                    reach = std::min(reach, got);
                }
            }
            continue;
        }
        push_children(f, g, na, nv, expand_body(A, B, leaf_a, leaf_b), P, stack);
    }
    counters[COUNT_BOX_TESTS] += n_boxes;
    counters[COUNT_TRIANGLE_TESTS] += n_triangles;
    return {false, 0.0, reach};
}

}  // namespace collision_sensor
