// Re-checking the planned pairs (recheck.hpp).
#include "recheck.hpp"

#include <algorithm>

#include "cloud_queries.hpp"
#include "containment.hpp"
#include "culling.hpp"
#include "planning.hpp"
#include "poses.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"

namespace collision_sensor {


namespace {

// One pair's re-check: which pair, its two bodies, body b's pose in body a's frame, and what
// the traversal is asked (track: an incremental call, which measures a clearance and keeps
// fronts).
struct PairRecheck {
    int64_t p, a, b;
    const double* pose;
    TraversalRequest request;
};

// The work done so far, as the front's cost is counted.
int64_t tests_done(const int64_t* counters) {
    return counters[COUNT_BOX_TESTS] + counters[COUNT_SPHERE_SKIPS] +
           counters[COUNT_TRIANGLE_TESTS];
}

// Every sub-group tree of the pair's body a against every one of body b's.
//
// A full check descends from the roots. An incremental one starts from the pair's front when
// it has one (front_scan): the node pairs where its last descent that found it apart stopped.
// A front covers every pair of triangles whatever the poses, so it never goes stale, only
// costlier: it is kept while a re-check from it tests at most as many node pairs and triangle
// pairs as the last descent from the roots did; else the next re-check descends from the
// roots again and records a fresh one. Only a pair that was apart starts from its front (one
// that collided likely still does, and a descent towards its last meeting triangles stops at
// the first that meet), and only a pair whose clearance is tiny (FRONT_GAP_REL) keeps one (a
// pair with a real clearance is skipped for whole steps; a front's finer node pairs would
// only make that clearance smaller).
TreesResult trees_of_pair(CheckContext& c, const PairRecheck& r) {
    const Model& m = c.model;
    Fronts& fronts = c.state.fronts;
    Scratch& scratch = c.scratch;
    const int64_t p = r.p;
    const bool track = r.request.track;
    const int64_t F = fronts.capacity;
    const int64_t n_old = (track && c.state.status[p] == 0) ? fronts.state[2 * p] : 0;
    const int64_t done = track ? tests_done(scratch.counters) : 0;
    FrontRecord front = {{scratch.front_pairs.data(), scratch.front_until.data(), F},
                         track ? 0 : -1};
    const TreePairTraversal node = {m.forest, r.pose, r.request, scratch.traversal(), &front};
    int64_t n_seeds = 0;
    double gap = INF;
    if (n_old > 0) {
        const FrontRows old = {fronts.pairs.data() + 3 * p * F, fronts.until.data() + p * F,
                               n_old};
        const FrontScan scan = front_scan(node, old, front.rows);
        n_seeds = scan.n_seeds;
        front.length = scan.n_kept;
        gap = scan.gap;
    } else {
        int64_t* stack = scratch.stack.data();
        for (int64_t ea = m.elem_start[r.a]; ea < m.elem_end[r.a]; ++ea) {
            for (int64_t eb = m.elem_start[r.b]; eb < m.elem_end[r.b]; ++eb) {
                seed_pair(stack, n_seeds++, m.roots[ea], m.roots[eb]);
            }
        }
    }
    const TreesResult tree = collide_trees(node, n_seeds);
    if (tree.hit) return {true, tree.ia, tree.ib, 0.0};
    gap = std::min(gap, tree.gap);
    const double scale = m.body_box(r.a)[BOX_RADIUS] + m.body_box(r.b)[BOX_RADIUS];
    if (front.length < 0 || gap > FRONT_GAP_REL * scale) {
        // A full check, a front too large to keep, or a pair with a clearance that can skip
        // whole steps: a front's many finer node pairs would only make it smaller.
        if (track) fronts.state[2 * p] = 0;
        return {false, -1, -1, gap};
    }
    const int64_t cost = tests_done(scratch.counters) - done;
    if (n_old == 0) fronts.state[2 * p + 1] = cost;
    if (cost <= fronts.state[2 * p + 1]) {
        std::copy(front.rows.pairs, front.rows.pairs + 3 * front.length,
                  fronts.pairs.begin() + 3 * p * F);
        std::copy(front.rows.until, front.rows.until + front.length,
                  fronts.until.begin() + p * F);
        fronts.state[2 * p] = front.length;
    } else {
        fronts.state[2 * p] = 0;
    }
    return {false, -1, -1, gap};
}

}  // namespace

int64_t recheck_pairs(CheckContext& c, int64_t n, bool full, bool* changed,
                      const int64_t* full_list) {
    const Model& m = c.model;
    State& s = c.state;
    const bool track = !full;
    if (full) {  // a full check uses nothing carried over; fronts are recorded afresh after it
        for (int64_t p = 0; p < m.n_pairs; ++p) s.fronts.state[2 * p] = 0;
        if (m.n_bodies > m.n_links)
            refresh_culling(m, s.poses.T_world_body, c.options.box_test, c.scratch);
    }
    *changed = false;
    const int64_t* todo = c.scratch.todo.data();
    int64_t* chain = c.scratch.chain.data();
    double pose[POSE_WIDTH];
    for (int64_t t = 0; t < n; ++t) {
        const int64_t p = full ? (full_list ? full_list[t] : t) : todo[t];
        const int64_t a = m.pair_a[p];
        const int64_t b = m.pair_b[p];
        if (track) {
            refresh_pose(m, s.q_ref, s.poses, chain, a);
            refresh_pose(m, s.q_ref, s.poses, chain, b);
            account_travel(c, p);
        }
        if (m.is_cloud(b)) {  // a point cloud's voxels (cloud_queries.hpp)
            write_pair_pose(s.poses.T_world_body, a, b, pose);
            recheck_cloud_pair(c, p, a, b, pose, track, changed);
            continue;
        }
        bool hit = false;
        double gap = 0.0;
        if (track || !culled(m, c.scratch, a, b)) {
            write_pair_pose(s.poses.T_world_body, a, b, pose);
            PairRecheck r = {p, a, b, pose, {}};
            r.request.box_test = c.options.box_test;
            r.request.expansion = c.options.expansion;
            r.request.track = track;
            r.request.pad = m.padding[a] + m.padding[b];
            if (track) {
                r.request.witness_a = s.witness[2 * p];
                r.request.witness_b = s.witness[2 * p + 1];
            }
            // The last witness is tested first; a full check's descent then orders children
            // by distance, not by it (from an unrelated state it would lead astray).
            const int64_t wa = track || c.witness_hints ? s.witness[2 * p] : -1;
            const int64_t wb = track || c.witness_hints ? s.witness[2 * p + 1] : -1;
            if (wa >= 0) hit = triangle_pair_collides(m.forest.tris, wa, wb, pose, r.request.pad);
            if (!hit) {
                const double* A = m.body_box(a);
                const double* B = m.body_box(b);
                // A body of one sub-group has its tree's root box as body box: the traversal
                // tests that first, so the body box is only worth testing for several trees,
                // or for a tracked pair without a front to resume (new, forced by a scene
                // change, or last found apart at body level): apart, it needs no traversal
                // and no front, its clearance is the body boxes' gap.
                const bool single = m.elements(a) == 1 && m.elements(b) == 1;
                const bool fresh = track && s.fronts.state[2 * p] == 0;
                double box_gap = 0.0;
                const bool apart = fresh ? boxes_apart_gap(c.options.box_test, A, B, pose,
                                                           &box_gap)
                                         : !single && boxes_apart(c.options.box_test, A, B,
                                                                  pose);
                if (!apart) {
                    if (track) {
                        r.request.travel = s.fronts.travel[p];
                        r.request.rounding = clearance_margin(m, a, b, pose);
                    }
                    const TreesResult tree = trees_of_pair(c, r);
                    hit = tree.hit;
                    gap = tree.gap;
                    if (hit) {
                        s.witness[2 * p] = tree.ia;
                        s.witness[2 * p + 1] = tree.ib;
                    } else if (contained(m, a, b, pose)) {
                        hit = true;  // no triangle witness: the re-check descends again
                    }
                } else if (track) {
                    gap = fresh ? box_gap : box_pair_gap(A, B, pose);
                }
                if (track && !hit) gap -= clearance_margin(m, a, b, pose);
            }
        }
        if (!hit) s.witness[2 * p] = s.witness[2 * p + 1] = -1;
        s.clearance[p] = (track && !hit && gap > 0.0) ? gap : 0.0;
        if (s.clearance[p] > 0.0) s.travel[2 * p] = s.travel[2 * p + 1] = 0.0;
        *changed |= (s.status[p] != 0) != hit;
        s.status[p] = hit ? 1 : 0;
    }
    return n;
}

}  // namespace collision_sensor
