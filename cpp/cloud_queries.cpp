// A body's trees against a point cloud's voxels (cloud_queries.hpp).
#include "cloud_queries.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "box_pair.hpp"
#include "containment.hpp"
#include "descent.hpp"
#include "distance.hpp"
#include "inlining.hpp"
#include "poses.hpp"
#include "tolerances.hpp"
#include "triangle_box.hpp"

namespace collision_sensor {

namespace {

// The descents' stacks, one per thread (a batch's rows may run on threads of their own),
// grown once to the deepest descent.
thread_local std::vector<int64_t> cloud_stack;

// A stack of rows for a descent of n_seeds pairs between trees of depths depth_a, depth_b.
int64_t* stack_for(int64_t n_seeds, int64_t depth_a, int64_t depth_b) {
    const size_t size = size_t(PAIR_ROW * (n_seeds + depth_a + depth_b + 2));
    if (cloud_stack.size() < size) cloud_stack.resize(size);
    return cloud_stack.data();
}

// Body a's element roots against the grid's root, as the stack's seeds; returns their count.
int64_t seed_body(const Model& m, int64_t a, const VoxelGrid& g) {
    int64_t* stack = stack_for(m.elements(a), m.depth, g.depth);
    int64_t n = 0;
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e) seed_pair(stack, n++, m.roots[e], 0);
    return n;
}

// Triangle t of body a taken to the cloud's (world) frame: x_w = R' (x_a - t_ab).
CS_ALWAYS_INLINE void triangle_in_cloud(const double* tris, int64_t t, const double* P,
                                        Triangle& W) {
    const double* v = tris + 9 * t;
    for (int k = 0; k < 3; ++k) {
        const double d0 = v[3 * k] - P[9], d1 = v[3 * k + 1] - P[10], d2 = v[3 * k + 2] - P[11];
        for (int i = 0; i < 3; ++i) W[k][i] = P[i] * d0 + P[3 + i] * d1 + P[6 + i] * d2;
    }
}

// What the nodes of a body's trees against a grid share (the descent's hooks, descent.hpp,
// but apart and leaves): tree a the body's (a forest), tree b the grid's hierarchy, cloud P in
// body a; the node with the larger sphere is expanded (EXPAND_WIDER's rule), and the child
// whose centre is nearer the other box's is visited first.
struct BodyCloudNode {
    static constexpr bool WHOLE_A = false;
    struct Seen {
        const double* A;
        const double* B;
        const BoxMotion* ma;  // the within test's: A's motion
    };

    const Forest& f;
    const VoxelGrid& g;
    const double* P;

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return f.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const { return g.node(n); }

    CS_ALWAYS_INLINE bool split_a(int64_t, int64_t, int64_t, const Seen& seen) const {
        return seen.A[BOX_RADIUS] >= seen.B[BOX_RADIUS];
    }

    // B's centre in body a: R c + t; A's in the cloud: R' (c - t).
    CS_ALWAYS_INLINE void order(int64_t, int64_t, int64_t, bool on_a, ChildPairs& c,
                                const Seen& seen) const {
        bool swap;
        if (on_a) {
            const double* B = seen.B;
            const double x0 = P[0] * B[0] + P[1] * B[1] + P[2] * B[2] + P[9];
            const double x1 = P[3] * B[0] + P[4] * B[1] + P[5] * B[2] + P[10];
            const double x2 = P[6] * B[0] + P[7] * B[1] + P[8] * B[2] + P[11];
            swap = nearer(f.box(c.second), f.box(c.first), x0, x1, x2);
        } else {
            const double* A = seen.A;
            const double d0 = A[0] - P[9], d1 = A[1] - P[10], d2 = A[2] - P[11];
            swap = nearer(g.box(c.second), g.box(c.first), P[0] * d0 + P[3] * d1 + P[6] * d2,
                          P[1] * d0 + P[4] * d1 + P[7] * d2, P[2] * d0 + P[5] * d1 + P[8] * d2);
        }
        if (swap) c.swap();
        c.word_first = c.word_second = 0;
    }

    // visit(W, lo, hi, t, v) for each triangle t of leaf node_a (W: in the cloud's frame) and
    // each cube v (lo, hi) of leaf node_v, until a visit returns true (then true).
    template <class Visit>
    CS_ALWAYS_INLINE bool each_triangle_cube(const int64_t* node_a, const int64_t* node_v,
                                             Visit&& visit) const {
        for (int64_t t = node_a[NODE_FIRST]; t < node_a[NODE_FIRST] + node_a[NODE_COUNT]; ++t) {
            Triangle W;
            triangle_in_cloud(f.tris, t, P, W);
            for (int64_t v = node_v[NODE_FIRST]; v < node_v[NODE_FIRST] + node_v[NODE_COUNT];
                 ++v) {
                double lo[3], hi[3];
                g.cube(v, lo, hi);
                if (visit(W, lo, hi, t, v)) return true;
            }
        }
        return false;
    }
};

// collide_body_cloud's node: boxes by their spheres and the 15-axis test, leaves by the
// triangles against the cubes, within pad; the first meeting pair ends the descent.
struct CollideCloudNode : BodyCloudNode {
    const double pad;
    const bool track;
    double best;
    int64_t n_boxes = 0, n_spheres = 0, n_triangles = 0;
    CloudPairResult out = {false, -1, -1, 0.0};

    CollideCloudNode(const Forest& f, const VoxelGrid& g, const double* P, double pad, bool track)
        : BodyCloudNode{f, g, P}, pad(pad), track(track), best(track ? INF : 0.0) {}

    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nv, int64_t, Seen& seen) {
        const double* A = f.box(na);
        const double* B = g.box(nv);
        const Spheres sp = spheres(A, B, P);
        if (sp.apart) {
            ++n_spheres;
            if (track) best = std::min(best, std::sqrt(sp.dd) - sp.radii);
            return true;
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
            return true;
        }
        seen = {A, B, nullptr};
        return false;
    }

    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t* node_a, const int64_t* node_v,
                                 const Seen&) {
        return each_triangle_cube(node_a, node_v, [&](const Triangle& W, const double* lo,
                                                      const double* hi, int64_t t, int64_t v) {
            double d;
            ++n_triangles;
            if (triangle_box_within(W, lo, hi, pad, &d)) {
                out = {true, t, v, 0.0};
                return true;
            }
            if (track) best = std::min(best, d - pad);
            return false;
        });
    }
};

// distance_body_cloud's node: boxes by projected_gap against the best, leaves by the
// triangles' distance to the cubes.
struct DistanceCloudNode : BodyCloudNode {
    const double pad;
    NearestPoints& best;

    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nv, int64_t, Seen& seen) const {
        const double* A = f.box(na);
        const double* B = g.box(nv);
        double T[12];
        box_in_frame(A, B, P, T);
        if (!(projected_gap(A, B, T) - pad < best.distance)) return true;
        seen = {A, B, nullptr};
        return false;
    }

    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t* node_a, const int64_t* node_v,
                                 const Seen&) {
        each_triangle_cube(node_a, node_v, [&](const Triangle& W, const double* lo,
                                               const double* hi, int64_t t, int64_t v) {
            double x[3], y[3];
            const double d = triangle_box_distance(W, lo, hi, x, y) - pad;
            if (d < best.distance) best.take(d, t, v, x, y);
            return false;
        });
        return false;
    }
};

// cloud_pair_within's node: boxes by node_pair_apart (the cloud does not move), leaves by the
// triangles' distance to the cubes; one within ends the descent.
struct WithinCloudNode : BodyCloudNode {
    const IntervalTest test;
    const double h, extra, pad;
    MotionMargin& motion;
    const BoxMotion still{0.0, {0.0, 0.0, 0.0}, 0.0};  // the cloud does not move
    double reach;
    int64_t n_boxes = 0, n_triangles = 0;
    WithinResult within = {false, 0.0, 0.0};

    WithinCloudNode(const Forest& f, const VoxelGrid& g, const IntervalTest& test, double pad,
                    double reach)
        : BodyCloudNode{f, g, test.P},
          test(test),
          h(test.h),
          extra(test.extra),
          pad(pad),
          motion(test.motion),
          reach(reach) {}

    CS_ALWAYS_INLINE bool apart(int64_t na, int64_t nv, int64_t, Seen& seen) {
        const double* A = f.box(na);
        const double* B = g.box(nv);
        const BoxMotion& ma = motion.node(f, na, 0);
        ++n_boxes;
        NodePairApart proof;
        if (node_pair_apart(test, A, B, ma, still, proof)) {
            reach = std::min(reach, proof.reach);
            return true;
        }
        seen = {A, B, &ma};
        return false;
    }

    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t* node_a,
                                 const int64_t* node_v, const Seen& seen) {
        const BoxMotion& ma = *seen.ma;
        const double rate = ma.rate;
        const double r = h * rate + extra;
        return each_triangle_cube(node_a, node_v, [&](const Triangle& W, const double* lo,
                                                      const double* hi, int64_t, int64_t) {
            double xa[3], yb[3];
            ++n_triangles;
            const double distance = triangle_box_distance(W, lo, hi, xa, yb) - pad;
            double got = rate > 0.0 ? std::min((distance - extra) / rate, motion.h2)
                                    : (distance > extra ? motion.h2 : -1.0);
            if (!(distance > r) && distance > extra) {
                // Along the nearest points' direction (world) the two are distance apart.
                const double n[3] = {(yb[0] - xa[0]) / (distance + pad),
                                     (yb[1] - xa[1]) / (distance + pad),
                                     (yb[2] - xa[2]) / (distance + pad)};
                got = std::max(got, motion.first_order_reach(n, distance, extra,
                                                             seen.A[BOX_RADIUS], ma,
                                                             seen.B[BOX_RADIUS], still, h));
            }
            if (!(got >= h)) {
                within = {true, r, std::max(got, 0.0)};
                return true;
            }
            reach = std::min(reach, got);
            return false;
        });
    }
};

// solid_corner_distance's node: one solid element (tree a taken whole: its root box, grown)
// against the grid, the corners of the cubes under the boxes it meets measured against the
// element's true shape; a corner inside ends the descent. The grid's children are visited
// right first.
struct SolidCornerNode {
    static constexpr bool WHOLE_A = true;
    struct Seen {};

    const Model& m;
    const VoxelGrid& g;
    const double* P;
    const int64_t e;
    const double* A;  // the element's root box, grown by the limit
    const double* s;  // its solid row (SOLID_WIDTH)
    double best;
    double* x;

    CS_ALWAYS_INLINE const int64_t* node_a(int64_t n) const { return m.forest.node(n); }
    CS_ALWAYS_INLINE const int64_t* node_b(int64_t n) const { return g.node(n); }

    CS_ALWAYS_INLINE bool apart(int64_t, int64_t nv, int64_t, Seen&) const {
        return boxes_apart(BOX_TEST_SAT, A, g.box(nv), P);
    }

    CS_ALWAYS_INLINE bool leaves(int64_t, int64_t, const int64_t*, const int64_t* node,
                                 const Seen&) {
        for (int64_t v = node[NODE_FIRST]; v < node[NODE_FIRST] + node[NODE_COUNT]; ++v) {
            double lo[3], hi[3];
            g.cube(v, lo, hi);
            for (int c = 0; c < 8; ++c) {
                const double w[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1],
                                     c & 4 ? hi[2] : lo[2]};
                double y[3];  // in body a: R w + t
                for (int i = 0; i < 3; ++i)
                    y[i] = P[3 * i] * w[0] + P[3 * i + 1] * w[1] + P[3 * i + 2] * w[2] + P[9 + i];
                const double d = int(s[0]) == SOLID_CLOSED_MESH ? (inside_solid(m, e, y) ? 0.0 : INF)
                                                                : solid_distance(s, y);
                if (d < best) {
                    best = d;
                    std::copy(w, w + 3, x);
                    if (d <= 0.0) return true;
                }
            }
        }
        return false;
    }

    CS_ALWAYS_INLINE bool split_a(int64_t, int64_t, int64_t, const Seen&) const { return false; }

    CS_ALWAYS_INLINE void order(int64_t, int64_t, int64_t, bool, ChildPairs& c, const Seen&) const {
        c.swap();
        c.word_first = c.word_second = 0;
    }
};

// The smallest distance from a solid element of body a (its true shape) to a corner of a cube
// of the grid within `limit` of the element's root box (INF if none), and that corner (world
// frame) in x. A body without solids: INF.
double solid_corner_distance(const Model& m, int64_t a, const VoxelGrid& g, const double* P,
                             double limit, double* x) {
    double best = INF;
    if (!m.body_solid[a] || g.empty()) return best;
    int64_t* stack = stack_for(1, 1, g.depth);
    double grown_a[BOX_WIDTH];
    for (int64_t e = m.elem_start[a]; e < m.elem_end[a]; ++e) {
        const double* s = m.elem_solid + SOLID_WIDTH * e;
        if (int(s[0]) == SOLID_NONE) continue;
        const double* A = grown(m.forest.box(m.roots[e]), std::max(limit, 0.0), grown_a);
        SolidCornerNode node = {m, g, P, e, A, s, best, x};
        seed_pair(stack, 0, m.roots[e], 0);
        descend(node, stack, 1);
        best = node.best;
        if (best <= 0.0) return 0.0;
    }
    return best;
}

// The padded distance between body a and the grid, with nearest points (world frame) into
// best when below best.distance (its cutoff on entry).
void distance_body_cloud(const Model& m, int64_t a, const VoxelGrid& g, const double* P,
                         double pad, NearestPoints& best) {
    const int64_t n_seeds = seed_body(m, a, g);
    DistanceCloudNode node = {{m.forest, g, P}, pad, best};
    descend(node, cloud_stack.data(), n_seeds);
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
    const int64_t n_seeds = seed_body(m, a, g);
    CollideCloudNode node(f, g, P, pad, track);
    descend(node, cloud_stack.data(), n_seeds);
    counters[COUNT_BOX_TESTS] += node.n_boxes;
    counters[COUNT_SPHERE_SKIPS] += node.n_spheres;
    counters[COUNT_TRIANGLE_TESTS] += node.n_triangles;
    CloudPairResult out = node.out;
    if (out.hit) return out;
    double corner[3];
    if (solid_corner_distance(m, a, g, P, 0.0, corner) <= 0.0) return {true, -1, -1, 0.0};
    out.gap = node.best;
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

WithinResult cloud_pair_within(const Model& m, int64_t a, const VoxelGrid& g,
                               const IntervalTest& test, int64_t* counters) {
    const double* P = test.P;
    const double h = test.h, extra = test.extra;
    MotionMargin& motion = test.motion;
    double reach = motion.h2;
    if (g.empty()) return {false, 0.0, reach};
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
    const int64_t n_seeds = seed_body(m, a, g);
    WithinCloudNode node(m.forest, g, test, m.padding[a], reach);
    descend(node, cloud_stack.data(), n_seeds);
    counters[COUNT_BOX_TESTS] += node.n_boxes;
    counters[COUNT_TRIANGLE_TESTS] += node.n_triangles;
    return node.within.within ? node.within : WithinResult{false, 0.0, node.reach};
}

}  // namespace collision_sensor
