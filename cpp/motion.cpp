// The march of a motion check (motion_query.hpp): each pair proven apart interval by interval
// along its path, or its first contact found; the state and the two sides of a pair at an
// interval, and whether it is apart over it (pair_within).
#include "motion.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "cloud_queries.hpp"
#include "containment.hpp"
#include "motion_query.hpp"
#include "motion_within.hpp"
#include "planning.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

namespace motion_detail {

// The state of the path at hand and the two sides of a pair there: every interval of a
// march asks for them, so they live beside the march.

// Evaluate the link poses at q from now on (computed on demand, link_pose): unless q is the
// state evaluated already (the pairs' first intervals share their midpoint), whose poses stay.
void MotionQuery::evaluate(const double* q) {
    const size_t bytes = sizeof(double) * size_t(m_.n_joints);
    if (w_.evaluated && std::memcmp(q, w_.q.data(), bytes) == 0) return;
    std::memcpy(w_.q.data(), q, bytes);
    w_.evaluated = true;
    ++w_.tag;
}

// Link i's world pose at the evaluated state: it and the ancestors not yet computed, top down.
void MotionQuery::link_pose(int64_t i) {
    int64_t n = 0;
    for (int64_t k = i; k >= 0 && w_.stamp[k] != w_.tag; k = m_.kin.parent[k]) w_.chain[n++] = k;
    for (int64_t t = n - 1; t >= 0; --t) {
        set_link_pose(m_.kin, w_.chain[t], w_.q.data(), w_.T.data(), w_.turn.data());
        w_.stamp[w_.chain[t]] = w_.tag;
    }
}

// Pair p's two sides: the joints between each body and the pair's lowest common ancestor
// (none above a world object: it is the world's), lowest first, those moving at the evaluated
// part of the path, with their speeds per unit of the parameter. Returns whether any of those
// joints moves anywhere on the path.
bool MotionQuery::sides(int64_t p) {
    const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
    int64_t common = -1;
    if (!m_.is_world_object(b)) {
        int64_t x = a, y = b;
        while (w_.depth[x] > w_.depth[y]) x = m_.kin.parent[x];
        while (w_.depth[y] > w_.depth[x]) y = m_.kin.parent[y];
        while (x != y) {
            x = m_.kin.parent[x];
            y = m_.kin.parent[y];
        }
        common = x;
    }
    bool moves = false;
    for (int s = 0; s < 2; ++s) {
        const int64_t x = s == 0 ? a : b;
        int64_t n = 0;
        if (s == 0 || !m_.is_world_object(b)) {
            for (int64_t k = x; k > 0 && k != common; k = m_.kin.parent[k]) {
                moves |= w_.moving[k] != 0;
                if (w_.trans[k] > 0.0 || w_.rot[k] > 0.0) {
                    w_.side_link[s][n] = k;
                    w_.side_trans[s][n] = w_.trans[k];
                    w_.side_rot[s][n] = w_.rot[k];
                    w_.side_speed[s][n] = w_.speed[k];
                    w_.side_accel[s][n] = w_.accel[k];
                    ++n;
                }
            }
        }
        w_.side_n[s] = n;
        // How fast each joint's own frame turns: the turns of the joints above it, summed.
        double above = 0.0;
        for (int64_t i = n - 1; i >= 0; --i) {
            w_.side_above[s][i] = above;
            above += w_.side_rot[s][i];
        }
    }
    return moves;
}

// Pair p's motion margin at the evaluated state (pair_pose computed its poses): each side's
// joints placed in the world (MotionMargin).
void MotionQuery::margin(int64_t p, double h2) {
    MotionMargin& mm = w_.margin;
    for (int s = 0; s < 2; ++s) {
        const int64_t x = s == 0 ? m_.pair_a[p] : m_.pair_b[p];
        SideMotion& side = mm.side[s];
        side.first_order = w_.first_order;
        side.omega[0] = side.omega[1] = side.omega[2] = 0.0;
        for (int64_t i = 0; i < w_.side_n[s]; ++i) {
            const int64_t k = w_.side_link[s][i];
            link_pose(k);
            const double* T = w_.T.data() + 16 * k;
            double* o = w_.side_origin[s].data() + 3 * i;
            double* u = w_.side_axis[s].data() + 3 * i;
            o[0] = T[3];
            o[1] = T[7];
            o[2] = T[11];
            // The axis in the world: the joint frame's (revolute, prismatic: axis[k]; planar:
            // z), which the child frame shares, turned by the child's world rotation.
            const int64_t kind = m_.kin.joint_type[k];
            double v[3] = {0.0, 0.0, 0.0};
            if (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC) {
                v[0] = m_.kin.axis[3 * k];
                v[1] = m_.kin.axis[3 * k + 1];
                v[2] = m_.kin.axis[3 * k + 2];
            } else if (kind == JOINT_PLANAR) {
                v[2] = 1.0;
            }
            for (int r = 0; r < 3; ++r)
                u[r] = T[4 * r] * v[0] + T[4 * r + 1] * v[1] + T[4 * r + 2] * v[2];
            if (kind == JOINT_REVOLUTE) {
                for (int r = 0; r < 3; ++r) side.omega[r] += w_.side_speed[s][i] * u[r];
            } else if (kind != JOINT_PRISMATIC) {
                side.first_order = false;  // planar, floating: the zeroth order only
            }
        }
        side.n = w_.side_n[s];
        side.origin = w_.side_origin[s].data();
        side.axis = w_.side_axis[s].data();
        side.trans = w_.side_trans[s].data();
        side.rot = w_.side_rot[s].data();
        side.speed = w_.side_speed[s].data();
        side.accel = w_.side_accel[s].data();
        side.above = w_.side_above[s].data();
        side.T = m_.is_world_object(x) ? c_.view.state.poses.T_world_body + 16 * x
                                       : w_.T.data() + 16 * x;
        mm.cache[s] = w_.node_motion[s].data();
        mm.stamp[s] = w_.node_stamp[s].data();
    }
    mm.h2 = h2;
    ++mm.tag;
}

// One step of pair s.p's march along the path: the pair is proven apart on [0, s.t). The
// interval [t, t + length] is tested at its midpoint m over its half-width h (pair_within):
// apart, the pair is proven apart on the whole interval and further, on [m, m + reach], and
// the next interval is sized from that reach (its half-width a factor of it, which grows while
// intervals pass and shrinks when one does not: near an obstacle the distance, and so the
// reach, shrinks from one interval to the next). Within its margin: the interval is halved,
// and once twice the margin is at most the touching tolerance, the state at t is within the
// tolerance of contact: the first contact. Returns MARCH_*. Inline: compiled into its one
// caller, march_pairs, whose loop runs it at every step.
template <class Path>
inline int MotionQuery::march_step(MotionWork::March& s, const Path& path, double t_end) {
    const int64_t a = m_.pair_a[s.p], b = m_.pair_b[s.p];
    double pose[POSE_WIDTH];
    if (waypoint_leap(path, s)) return s.t >= t_end ? MARCH_FREE : MARCH_ON;
    // A polyline's interval ends at the next waypoint: beyond it the speeds change (the crude
    // bound across waypoints is waypoint_leap's).
    const double hi = path.clip(s.t, std::min(s.t + s.length, t_end));
    const double m = 0.5 * (s.t + hi);
    const double h = 0.5 * (hi - s.t);
    double crude_reach;
    WithinResult w;
    path.at(m, w_.q_next.data());
    evaluate(w_.q_next.data());
    pair_pose(a, b, pose);
    if (crude_apart(path, s.p, pose, h, &crude_reach)) {
        w = {false, 0.0, crude_reach};
    } else {
        const double h2 = path.room(m, h);
        path_speeds(path, m, h2);
        sides(s.p);
        margin(s.p, h2);
        w = pair_within(s.p, pose, m, h, crude_or_none(path, s.p));
    }
    if (!w.within) {
        if (hi >= t_end) return MARCH_FREE;
        const double next = std::max(hi, m + w.reach * (1.0 - MOTION_BOUND_REL));
        s.length = 2.0 * s.factor * (next - m);
        s.factor = std::min(MARCH_GROW * s.factor, MARCH_FACTOR_MAX);
        s.t = next;
        return MARCH_ON;
    }
    if (2.0 * w.margin <= MOTION_TOUCH_TOLERANCE) return MARCH_CONTACT;
    s.length = 0.5 * (hi - s.t);
    s.factor = std::max(MARCH_SHRINK * s.factor, MARCH_FACTOR_MIN);
    return MARCH_ON;
}

// The pairs march side by side, the one proven apart least far first (a heap on t): a contact
// found bounds every other march, so no later contact is ever localised.
template <class Path>
int64_t MotionQuery::march_pairs(const int64_t* list, int64_t n, const Path& path,
                                 const double* q0, double* best) {
    *best = INF;
    int64_t best_pair = -1;
    double pose[POSE_WIDTH];
    std::vector<MotionWork::March>& heap = w_.heap;
    heap.clear();
    for (const int64_t p : w_.swept) w_.swept_at[p] = NAN;
    w_.swept.clear();
    const auto known_apart = [this](int64_t p) { return w_.start_known && w_.start_apart[p]; };
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = list ? list[i] : i;
        if (known_apart(p)) continue;  // check_step_motion set its front and proofs
        w_.front[p].clear();
        w_.front_until[p].clear();
        w_.front_measure[p].clear();
    }
    const auto later = [](const MotionWork::March& x, const MotionWork::March& y) {
        return x.t > y.t;
    };
    // The start first, as an instant: a pair in contact there is the first contact (marching
    // would only halve its way down to it), and a pair nothing moves is as it is there all
    // along.
    evaluate(q0);
    const auto at_start = [&](int64_t p) {
        w_.side_n[0] = w_.side_n[1] = 0;
        pair_pose(m_.pair_a[p], m_.pair_b[p], pose);
        margin(p, 0.0);
        return pair_within(p, pose, 0.0, 0.0, crude_or_none(path, p)).within;
    };
    w_.sweeping.clear();
    if constexpr (std::is_same_v<Path, StraightPath>) {
        // A pair a sweep takes is not checked here: its sweep starts at the start, where
        // being within reach (rho + SWEEP_EPS) is met as contact at 0, as the instant's
        // contact would be (sweep: hulls, and test vertices in solids).
        for (int64_t i = 0; i < n; ++i) {
            const int64_t p = list ? list[i] : i;
            const bool moves = sides(p);
            if (moves && sweepable(path, p)) continue;
            if (!known_apart(p) && at_start(p)) {
                *best = 0.0;
                return p;
            }
            if (moves) heap.push_back({p, 0.0, 1.0, 1.0});
        }
    } else {
        for (int64_t i = 0; i < n; ++i) {
            const int64_t p = list ? list[i] : i;
            if (!known_apart(p) && at_start(p)) {
                *best = 0.0;
                return p;
            }
        }
        path_speeds(path, 0.5, 0.5);
        for (int64_t i = 0; i < n; ++i) {
            const int64_t p = list ? list[i] : i;
            if (sides(p)) heap.push_back({p, 0.0, 1.0, 1.0});  // only straight paths sweep
        }
    }
    if (!w_.sweeping.empty()) sweep_pairs(best, &best_pair);
    std::make_heap(heap.begin(), heap.end(), later);
    while (!heap.empty() && heap.front().t < *best) {
        std::pop_heap(heap.begin(), heap.end(), later);
        MotionWork::March& s = heap.back();
        const int state = march_step(s, path, std::min(*best, path.end()));
        if (state == MARCH_ON) {
            std::push_heap(heap.begin(), heap.end(), later);
            continue;
        }
        if (state == MARCH_CONTACT && s.t < *best) {
            *best = s.t;
            best_pair = s.p;
        }
        heap.pop_back();
    }
    return best_pair;
}

template <class Path>
void MotionQuery::contacts(const int64_t* list, int64_t n, const Path& path, double t,
                           double extra, uint8_t* pairs) {
    double pose[POSE_WIDTH];
    std::fill(pairs, pairs + m_.n_pairs, uint8_t(0));
    path.at(t, w_.q_next.data());
    evaluate(w_.q_next.data());
    w_.side_n[0] = w_.side_n[1] = 0;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = list ? list[i] : i;
        // A swept pair is within the tolerance of contact at t when its sweep's first
        // contact (within SWEEP_EPS of it) is less than the rest of the tolerance away; at
        // the start, it is as the instant is (check's pairs there).
        const double swept = w_.swept_at[p];
        if (!std::isnan(swept) && t > 0.0) {
            pairs[p] = (swept - t) * w_.swept_span[p] <= extra - SWEEP_EPS ? 1 : 0;
            continue;
        }
        pair_pose(m_.pair_a[p], m_.pair_b[p], pose);
        margin(p, 0.0);
        pairs[p] = pair_within(p, pose, t, 0.0, crude_or_none(path, p), extra).within ? 1 : 0;
    }
}

double distance_at(MotionContext& c, int64_t p, const double* pose, double floor, double cap) {
    const Model& m = c.view.model;
    const int64_t a = m.pair_a[p], b = m.pair_b[p];
    const double rounding = clearance_margin(m, a, b, pose);
    NearestPoints best;
    best.found = false;
    best.ia = best.ib = -1;
    best.distance = cap + rounding;
    const DistanceTraversal node = {m.forest, pose, m.padding[a], m.padding[b],
                                    c.scratch.traversal(), c.scratch.distance_work(m)};
    const double stop = floor + rounding;
    for (int64_t ea = m.elem_start[a]; ea < m.elem_end[a] && best.distance > stop; ++ea)
        for (int64_t eb = m.elem_start[b]; eb < m.elem_end[b] && best.distance > stop; ++eb)
            trees_distance(node, m.roots[ea], m.roots[eb], best, stop);
    return best.distance - rounding;
}

bool MotionQuery::measure_pair(int64_t p) {
    const double rate = crude_rate(p);
    if (!(rate < INF) || !(rate > 0.0)) return false;
    if (w_.rates_pair == p) return true;
    double* rates = w_.pair_rates.data();
    for (int64_t j = 0; j < m_.n_joints; ++j)  // a variable that never moves adds nothing
        rates[j] = w_.var[j] > 0.0 ? variable_reach(m_, p, j, w_.extension_max) *
                                         (1.0 + MOTION_BOUND_REL)
                                   : 0.0;
    w_.rates_pair = p;
    return true;
}

// The smallest distance from a solid element of one body to the first vertex of an element
// of the other (containment.hpp's test vertex), INF if neither body has a solid element.
double MotionQuery::solid_gap(int64_t a, int64_t b, const double* P) const {
    double best = INF;
    for (int64_t ea = m_.elem_start[a]; ea < m_.elem_end[a]; ++ea) {
        for (int64_t eb = m_.elem_start[b]; eb < m_.elem_end[b]; ++eb) {
            if (m_.elem_tris[2 * ea] == m_.elem_tris[2 * ea + 1] ||
                m_.elem_tris[2 * eb] == m_.elem_tris[2 * eb + 1])
                continue;  // an element without triangles
            if (m_.elem_solid[SOLID_WIDTH * ea] != SOLID_NONE) {  // eb's vertex, in body a
                const double* v = m_.elem_solid + SOLID_WIDTH * eb + SOLID_PROBE;
                double x[3];
                for (int i = 0; i < 3; ++i)
                    x[i] = P[3 * i] * v[0] + P[3 * i + 1] * v[1] + P[3 * i + 2] * v[2] + P[9 + i];
                best = std::min(best, solid_distance(m_.elem_solid + SOLID_WIDTH * ea, x));
            }
            if (m_.elem_solid[SOLID_WIDTH * eb] != SOLID_NONE) {  // ea's vertex, in body b
                const double* v = m_.elem_solid + SOLID_WIDTH * ea + SOLID_PROBE;
                const double d0 = v[0] - P[9], d1 = v[1] - P[10], d2 = v[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                best = std::min(best, solid_distance(m_.elem_solid + SOLID_WIDTH * eb, y));
            }
        }
    }
    return best;
}

// Is pair p (body b at pose in body a) within its motion margin of contact over the
// half-width h of the path (margin(): triangles within padding + margin + extra, or a test
// vertex within its margin of a solid element)? Else over what half-width is it apart? The
// body boxes first; then the trees from the pair's front (the node pairs where its last
// descent stopped), kept while it stays small and costs no more than a descent from the roots.
// A node pair of the front proven apart up to the interval's end already (front_until: its own
// reach, or the pair's crude rate against its gap, from the midpoint m of the test that proved
// it) is not tested again. Intervals only move forward along a path, and each proof covers its
// test's whole interval, so such a node pair is apart over [m - h, m + h].
WithinResult MotionQuery::pair_within(int64_t p, const double* pose, double m, double h,
                                      double crude, double extra) {
    const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
    MotionMargin& mm = w_.margin;
    const int box_test = c_.view.options.box_test;
    if (m_.is_cloud(b)) {  // a point cloud's voxels (cloud_queries.hpp)
        const IntervalTest cloud = {pose, mm.side[0].T, h, extra, mm, box_test};
        return cloud_pair_within(m_, a, *m_.clouds[b], cloud, counters_);
    }
    const IntervalTest test = {pose, mm.side[0].T, h, extra, mm, box_test};
    const double* A = m_.body_box(a);
    const double* B = m_.body_box(b);
    const BoxMotion ma = mm.box_motion(A, 0), mb = mm.box_motion(B, 1);
    const double rate = ma.rate + mb.rate;
    const double r = h * rate + extra;
    NodePairApart bodies;
    if (node_pair_apart(test, A, B, ma, mb, bodies)) return {false, 0.0, bodies.reach};
    double reach = mm.h2;
    if (m_.body_solid[a] || m_.body_solid[b]) {
        // A test vertex of one body moves no farther than the body's box allows.
        const double solid = solid_gap(a, b, pose);
        const double solid_reach = rate > 0.0 ? (solid - extra) / rate : (solid > extra ? INF : 0.0);
        if (solid <= r) return {true, r, std::max(solid_reach, 0.0)};
        reach = std::min(reach, solid_reach);
    }
    std::vector<int64_t>& front = w_.front[p];
    std::vector<double>& until = w_.front_until[p];
    std::vector<double>& until_measure = w_.front_measure[p];
    const bool from_front = !front.empty();
    int64_t* stack = w_.stack.data();
    int64_t n_seeds = 0;
    w_.recorded.clear();
    w_.recorded_reach.clear();
    w_.recorded_gap.clear();
    // Along a polyline a node pair proven apart by gap g at m stays so while the pair's
    // measure (measure_pair) grows by less than g: across waypoints, as far as the segments'
    // own variations allow, where the crude rate takes the largest of them everywhere.
    const bool measured = poly_ != nullptr && crude > 0.0 && measure_pair(p);
    const double guard = measured ? measure_guard() : 0.0;
    const double measure_end = measured ? measure(m + h) + guard : INF;
    // The front's node pairs proven apart over the whole interval already (in this query,
    // and by at least extra) are not tested again: they stay in the front as they are.
    std::vector<double>& kept = w_.kept_until;
    std::vector<double>& kept_measure = w_.kept_measure;
    kept.clear();
    kept_measure.clear();
    if (from_front) {
        if (until.size() * 2 != front.size()) until.assign(front.size() / 2, -INF);
        if (until_measure.size() * 2 != front.size())
            until_measure.assign(front.size() / 2, -INF);
        for (size_t k = 0; k < front.size(); k += 2) {
            const double u = until[k / 2];
            const double um = until_measure[k / 2];
            if (extra == 0.0 && (u >= m + h || um > measure_end)) {
                w_.recorded.push_back(front[k]);
                w_.recorded.push_back(front[k + 1]);
                kept.push_back(u);
                kept_measure.push_back(um);
                reach = std::min(reach, std::max(u, m + h) - m);
                continue;
            }
            seed_pair(stack, n_seeds++, front[k], front[k + 1]);
        }
    } else {
        for (int64_t ea = m_.elem_start[a]; ea < m_.elem_end[a]; ++ea) {
            for (int64_t eb = m_.elem_start[b]; eb < m_.elem_end[b]; ++eb) {
                seed_pair(stack, n_seeds++, m_.roots[ea], m_.roots[eb]);
            }
        }
    }
    const int64_t before = counters_[COUNT_BOX_TESTS];
    const WithinRequest request = {box_test, c_.view.options.expansion,
                                   m_.padding[a] + m_.padding[b], h, extra};
    WithinFront recorded = {w_.recorded, w_.recorded_reach, w_.recorded_gap, crude, measured};
    const WithinTraversal node = {m_.forest, pose,      request,  mm, {stack, counters_},
                                  c_.scratch.distance_work(m_), recorded};
    WithinResult trees = trees_within(node, n_seeds);
    if (trees.within) return trees;  // an incomplete descent: the front stays as it was
    trees.reach = std::min(trees.reach, reach);
    const int64_t cost = counters_[COUNT_BOX_TESTS] - before;
    if (!from_front) w_.front_cost[p] = cost;
    if (int64_t(w_.recorded.size()) <= 2 * MOTION_FRONT_MAX && cost <= w_.front_cost[p]) {
        front.swap(w_.recorded);
        // The kept node pairs come first in the front, then those tested now.
        until.swap(kept);
        for (const double x : w_.recorded_reach) until.push_back(extra == 0.0 ? m + x : -INF);
        until_measure.swap(kept_measure);
        if (measured && extra == 0.0) {
            const double at = measure(m);
            for (const double g : w_.recorded_gap)
                until_measure.push_back(g > guard ? at + (g - guard) * (1.0 - MOTION_BOUND_REL)
                                                  : -INF);
        } else {
            until_measure.resize(until.size(), -INF);
        }
    } else {
        front.clear();
        until.clear();
        until_measure.clear();
    }
    return trees;
}

// The checks (motion_checks.cpp) run these on each kind of path.
template int64_t MotionQuery::march_pairs(const int64_t*, int64_t, const StraightPath&,
                                          const double*, double*);
template int64_t MotionQuery::march_pairs(const int64_t*, int64_t, const PolylinePath&,
                                          const double*, double*);
template int64_t MotionQuery::march_pairs(const int64_t*, int64_t, const SplinePath&,
                                          const double*, double*);
template void MotionQuery::contacts(const int64_t*, int64_t, const StraightPath&, double, double,
                                    uint8_t*);
template void MotionQuery::contacts(const int64_t*, int64_t, const PolylinePath&, double, double,
                                    uint8_t*);
template void MotionQuery::contacts(const int64_t*, int64_t, const SplinePath&, double, double,
                                    uint8_t*);

}  // namespace motion_detail

}  // namespace collision_sensor
