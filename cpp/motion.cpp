// Certified motion checks (motion.hpp).
#include "motion.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "cloud_queries.hpp"
#include "convex_sweep.hpp"
#include "planning.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

void MotionWork::size_for(const Model& m) {
    if (sized) return;
    const int64_t J = m.n_joints, L = m.n_links, N = m.n_nodes, P = m.n_pairs;
    delta.assign(J, 0.0);
    var.assign(J, 0.0);
    quat0.assign(J, 0.0);
    q.assign(J, 0.0);
    q_prev.assign(J, 0.0);
    q_next.assign(J, 0.0);
    crude.assign(P, -1.0);
    T.assign(16 * L, 0.0);
    turn.assign(3 * L, NAN);
    stamp.assign(L, 0);
    chain.assign(L, 0);
    trans.assign(L, 0.0);
    rot.assign(L, 0.0);
    speed.assign(L, 0.0);
    accel.assign(L, 0.0);
    moving.assign(L, 0);
    depth.assign(L, 0);
    for (int64_t i = 1; i < L; ++i) depth[i] = depth[m.kin.parent[i]] + 1;
    for (int s = 0; s < 2; ++s) {
        side_link[s].assign(L, 0);
        for (auto* v : {&side_trans[s], &side_rot[s], &side_speed[s], &side_accel[s],
                        &side_above[s]})
            v->assign(L, 0.0);
        side_origin[s].assign(3 * L, 0.0);
        side_axis[s].assign(3 * L, 0.0);
        node_motion[s].assign(N, BoxMotion{});
        node_stamp[s].assign(N, 0);
    }
    heap.reserve(P);
    front.assign(P, {});
    front_until.assign(P, {});
    front_measure.assign(P, {});
    front_cost.assign(P, 0);
    marched.reserve(P);
    prev_gap.assign(P, 0.0);
    swept.reserve(P);
    swept_at.assign(P, NAN);
    swept_span.assign(P, 0.0);
    hulls.assign(m.n_elements, Hull{});
    hull_state.assign(m.n_elements, -1);
    body_hull_state.assign(m.n_bodies, -1);
    start_apart.assign(P, 0);
    prev_sums.assign(2 * P, 0.0);
    // A descent from at most MOTION_FRONT_MAX seeds (or a pair's root pairs) holds at most
    // one node pair per level of each tree on top of them.
    stack.assign(3 * (std::max(MOTION_FRONT_MAX, m.most_seeds) + 2 * m.depth + 2), 0);
    tag = 0;
    margin.tag = 0;
    sized = true;
}

namespace {

// How far pair p's bodies can move relative to each other per unit of variable j, with E
// (planning.hpp) at most e: the planning's reach rows, reach[p, j] + e reach_ext[p, j].
inline double variable_reach(const Model& m, int64_t p, int64_t j, double e) {
    const int64_t k = m.n_joints * p + j;
    return m.reach[k] + e * m.reach_ext[k];
}

// [R_ab, t_ab] = T_world_a^-1 T_world_b = [Ra' Rb, Ra' (tb - ta)] (POSE_WIDTH numbers).
void relative_pose(const double* Ta, const double* Tb, double* pose) {
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            pose[3 * i + j] = Ta[i] * Tb[j] + Ta[4 + i] * Tb[4 + j] + Ta[8 + i] * Tb[8 + j];
        pose[9 + i] = Ta[i] * (Tb[3] - Ta[3]) + Ta[4 + i] * (Tb[7] - Ta[7]) +
                      Ta[8 + i] * (Tb[11] - Ta[11]);
    }
}

// A motion query over one context: the model, the path's states and the pairs' marches.
class MotionQuery {
   public:
    explicit MotionQuery(MotionContext& c)
        : c_(c), m_(c.view.model), w_(c.work), counters_(c.scratch.counters) {
        w_.size_for(m_);
        w_.evaluated = false;   // the model's joint origins may have changed since
        w_.first_order = true;  // until a polyline's interval spans segments
        std::fill(w_.crude.begin(), w_.crude.end(), -1.0);
    }

    // The straight path q0 -> q1 prepared: each link's joint's speed per unit of the
    // parameter (constant along it).
    void straight_speeds(const double* q0) {
        w_.extension_max = extension_bound(q0, w_.delta.data());
        for (int64_t k = 0; k < m_.n_links; ++k) {
            double speeds[3];
            link_speeds(k, w_.delta.data(), w_.var.data(), speeds);
            w_.trans[k] = speeds[0];
            w_.rot[k] = speeds[1];
            w_.speed[k] = speeds[2];
            w_.accel[k] = 0.0;
            w_.moving[k] = (speeds[0] > 0.0 || speeds[1] > 0.0) ? 1 : 0;
        }
    }

    // The polyline prepared: its segments' speeds per link (path_speeds picks an interval's
    // largest), var[j] the largest of its segments' (the crude bound's rate, per unit of the
    // parameter everywhere) and E's bound the largest of its straight segments'.
    void polyline_speeds(const PolylinePath& path) {
        poly_ = &path;
        w_.rates_pair = -1;
        const int64_t J = m_.n_joints, L = m_.n_links;
        std::fill(w_.var.begin(), w_.var.end(), 0.0);
        std::fill(w_.moving.begin(), w_.moving.end(), uint8_t(0));
        w_.extension_max = 0.0;
        for (int64_t s = 0; s < path.segments; ++s) {
            const double* delta = path.delta + J * s;
            const double* var = path.var + J * s;
            w_.extension_max =
                std::max(w_.extension_max, extension_bound(path.Q + J * s, delta));
            for (int64_t j = 0; j < J; ++j) w_.var[j] = std::max(w_.var[j], var[j]);
            const double* before = w_.poly_cum.data() + J * s;
            double* after = w_.poly_cum.data() + J * (s + 1);
            for (int64_t j = 0; j < J; ++j) after[j] = before[j] + var[j];
            for (int64_t k = 0; k < L; ++k) {
                double* speeds = w_.poly_speeds.data() + 3 * (L * s + k);
                link_speeds(k, delta, var, speeds);
                if (speeds[0] > 0.0 || speeds[1] > 0.0) w_.moving[k] = 1;
            }
        }
    }

    // The links a spline moves (revolute and prismatic joints whose variable is not
    // constant).
    void spline_moving(const SplinePath& path) {
        for (int64_t k = 0; k < m_.n_links; ++k) {
            const int64_t kind = m_.kin.joint_type[k];
            w_.moving[k] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC) &&
                           path.moves(m_.kin.q_index[k]);
        }
    }

    // update_motion's second bound for pair p along the straight step prepared
    // (straight_speeds): how far its bodies' points can move relative to each other over the
    // step, bounded at its end q1 (MotionMargin's zeroth order over the whole step: the levers
    // of this configuration, not the planning's configuration-free reach).
    double step_reach(int64_t p, const double* q1) {
        const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
        double pose[POSE_WIDTH];
        evaluate(q1);
        pair_pose(a, b, pose);
        sides(p);
        margin(p, 1.0);
        const BoxMotion ma = w_.margin.box_motion(m_.body_box(a), 0);
        const BoxMotion mb = w_.margin.box_motion(m_.body_box(b), 1);
        return (ma.rate + mb.rate) * (1.0 + MOTION_BOUND_REL);
    }

    // Pair p's solid_gap with body b at pose in body a (INF without a solid element).
    double pair_solid_gap(int64_t p, const double* pose) const {
        const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
        return m_.body_solid[a] || m_.body_solid[b] ? solid_gap(a, b, pose) : INF;
    }

    // Pairs list[:n] (null: all) marched along path; returns the pair of the first contact
    // (-1: none), its parameter in *best.
    template <class Path>
    int64_t march_pairs(const int64_t* list, int64_t n, const Path& path, const double* q0,
                        double* best);

    // pairs[p] = 1 for the pairs list[:n] in contact at path(t), or within the touching
    // tolerance: a margin of MOTION_TOUCH_TOLERANCE everywhere; 0 for every other pair.
    template <class Path>
    void contacts(const int64_t* list, int64_t n, const Path& path, double t, double extra,
                  uint8_t* pairs);

    template <class Path>
    int64_t check(const int64_t* list, int64_t n, const Path& path, const double* q0, double* t,
                  uint8_t* pairs) {
        double best;
        const int64_t best_pair = march_pairs(list, n, path, q0, &best);
        if (best_pair < 0) return 0;
        // In contact at the start: the pairs in contact there, as a check of the start gives
        // them; else the pairs within the touching tolerance of contact.
        contacts(list, n, path, best, best == 0.0 ? 0.0 : MOTION_TOUCH_TOLERANCE, pairs);
        // A sweep may meet its pair at the start within SWEEP_EPS of contact, not in it: that
        // pair is named only if the start has no pair in contact.
        if (best > 0.0 || std::find(pairs, pairs + m_.n_pairs, uint8_t(1)) == pairs + m_.n_pairs)
            pairs[best_pair] = 1;
        *t = best;
        return 1;
    }

   private:
    static constexpr int MARCH_ON = 0, MARCH_FREE = 1, MARCH_CONTACT = 2;

    // E (planning.hpp: the prismatic joints' |value|, summed) along the straight motion from
    // q0 by delta: at most its larger end's.
    double extension_bound(const double* q0, const double* delta) const {
        double e0 = 0.0, e1 = 0.0;
        for (int64_t k = 0; k < m_.n_links; ++k) {
            if (m_.kin.joint_type[k] != JOINT_PRISMATIC) continue;
            const int64_t j = m_.kin.q_index[k];
            const double mult = m_.kin.multiplier[k], off = m_.kin.offset[k];
            e0 += std::fabs(mult * q0[j] + off);
            e1 += std::fabs(mult * (q0[j] + delta[j]) + off);
        }
        return std::max(e0, e1) * (1.0 + MOTION_BOUND_REL);
    }

    // Link k's joint along a straight motion (StraightPath's delta, var): {trans, rot, signed
    // speed} per unit of the parameter.
    void link_speeds(int64_t k, const double* delta, const double* var, double* out) const {
        const int64_t kind = m_.kin.joint_type[k];
        const int64_t j = m_.kin.q_index[k];
        double trans = 0.0, rot = 0.0;
        if (kind == JOINT_REVOLUTE) {
            rot = std::fabs(m_.kin.multiplier[k]) * var[j];
        } else if (kind == JOINT_PRISMATIC) {
            trans = std::fabs(m_.kin.multiplier[k]) * var[j];
        } else if (kind == JOINT_PLANAR) {
            trans = std::hypot(delta[j], delta[j + 1]);
            rot = var[j + 2];
        } else if (kind == JOINT_FLOATING) {
            trans = std::sqrt(delta[j] * delta[j] + delta[j + 1] * delta[j + 1] +
                              delta[j + 2] * delta[j + 2]);
            rot = var[j + 3];
        }
        out[0] = trans * (1.0 + MOTION_BOUND_REL);
        out[1] = rot * (1.0 + MOTION_BOUND_REL);
        out[2] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC)
                     ? m_.kin.multiplier[k] * delta[j]
                     : 0.0;
    }

    // Whether pair p can be swept along a straight path: no joint between its bodies turns
    // (sides(p) has just listed them), so they only translate relative to each other, and
    // each body's elements are convex hulls. A pair that can joins w_.sweeping, with its
    // pose at the evaluated state (the path's start) and its translation to the end
    // (pair_shift) in w_.sweep_poses.
    bool sweepable(const StraightPath&, int64_t p);
    // The pairs in w_.sweeping: their first contacts by ray casts (convex_sweep.hpp) instead
    // of marches; the first contact lowers *best (its pair in *best_pair), and a pair a sweep
    // cannot decide joins the marches (heap).
    void sweep_pairs(double* best, int64_t* best_pair);
    // Sweepable pair p's translation d (3,) of body b relative to body a along the straight
    // path, in a's frame, from its sides (sides(p) has just listed them) and the poses at the
    // evaluated state (its start, which pair_pose has just placed).
    void pair_shift(int64_t p, double* d);
    // Pair p's sweep from the pose of b in a at the start along the translation d:
    // SWEEP_CONTACT (*t), SWEEP_FREE, or SWEEP_UNKNOWN (march it).
    int sweep(int64_t p, const double* pose0, const double* d, double* t);
    // Whether every element of body b has a hull (built now if not yet asked).
    bool body_hulls(int64_t b) {
        int8_t& state = w_.body_hull_state[b];
        if (state < 0) {
            bool all = m_.elements(b) > 0;
            for (int64_t e = m_.elem_start[b]; all && e < m_.elem_end[b]; ++e) {
                if (w_.hull_state[e] < 0) w_.hull_state[e] = element_hull(m_, e, w_.hulls[e]);
                all = w_.hull_state[e] == 1;
            }
            state = all ? 1 : 0;
        }
        return state == 1;
    }

    void evaluate(const double* q);
    void link_pose(int64_t i);
    void pair_pose(int64_t a, int64_t b, double* pose);
    bool sides(int64_t p);
    void margin(int64_t p, double h2);
    WithinResult pair_within(int64_t p, const double* pose, double m, double h, double crude,
                             double extra = 0.0);
    // The crude rate (crude_rate) where the path has one, else 0.
    double crude_or_none(const SplinePath&, int64_t) { return 0.0; }
    template <class Path>
    double crude_or_none(const Path&, int64_t p) { return crude_rate(p); }
    double solid_gap(int64_t a, int64_t b, const double* pose) const;
    bool crude_apart(const SplinePath&, int64_t, const double*, double, double*) {
        return false;
    }
    bool crude_apart(const PolylinePath&, int64_t p, const double* pose, double h,
                     double* reach) {
        return crude_apart(p, pose, h, reach);
    }
    bool crude_apart(const StraightPath&, int64_t p, const double* pose, double h,
                     double* reach) {
        return crude_apart(p, pose, h, reach);
    }
    bool crude_apart(int64_t p, const double* pose, double h, double* reach);
    double crude_rate(int64_t p);
    double sphere_gap(int64_t p, const double* pose) const;
    bool waypoint_leap(const StraightPath&, MotionWork::March&) { return false; }
    bool waypoint_leap(const SplinePath&, MotionWork::March&) { return false; }
    bool waypoint_leap(const PolylinePath& path, MotionWork::March& s);
    void path_speeds(const StraightPath&, double, double) {}  // constant (straight_speeds)
    void path_speeds(const SplinePath& path, double t, double h2);
    void path_speeds(const PolylinePath& path, double t, double h2);
    template <class Path>
    int march_step(MotionWork::March& s, const Path& path, double t_end);

    // Along a polyline, pair p's measure: U(t) = sum_j rate_j var_j(t), var_j(t) variable
    // j's variation along the path up to t (MotionWork::poly_cum, linear within a segment)
    // and rate_j its reach rows (the crude bound's), so that between parameters u < v the
    // pair's bodies move relative to each other by at most U(v) - U(u). measure_pair readies
    // p's (false: it bounds nothing, a floating joint's INF rows); measure_guard is the
    // rounding of its prefix sums, to take off any gap it is compared with.
    bool measure_pair(int64_t p);
    double measure_at(int64_t k) const;  // at waypoint k
    double measure(double t) const;
    double measure_guard() const;

    const PolylinePath* poly_ = nullptr;  // the polyline at hand (polyline_speeds)
    MotionContext& c_;
    const Model& m_;
    MotionWork& w_;
    int64_t* counters_;
};

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

double MotionQuery::measure_at(int64_t k) const {
    const int64_t J = m_.n_joints;
    const double* c = w_.poly_cum.data() + J * k;
    const double* rates = w_.pair_rates.data();
    double u = 0.0;
    for (int64_t j = 0; j < J; ++j) u += rates[j] * c[j];
    return u;
}

double MotionQuery::measure(double t) const {
    const int64_t k = poly_->segment_of(t);
    const int64_t J = m_.n_joints;
    const double* v = poly_->var + J * k;
    const double* rates = w_.pair_rates.data();
    double du = 0.0;
    for (int64_t j = 0; j < J; ++j) du += rates[j] * v[j];
    const double x = std::min(std::max(t - double(k), 0.0), 1.0);
    return measure_at(k) + x * du;
}

double MotionQuery::measure_guard() const {
    // At most a few ulps of the total per term summed.
    return 4.0 * double(poly_->segments + m_.n_joints) * DBL_EPSILON *
           measure_at(poly_->segments);
}

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

// Body b's pose in body a's frame at the evaluated state (a is a link; b a link, or a world
// object, which no joint moves: its pose is the carried state's).
void MotionQuery::pair_pose(int64_t a, int64_t b, double* pose) {
    link_pose(a);
    const double* Tb = c_.view.state.poses.T_world_body + 16 * b;
    if (!m_.is_world_object(b)) {
        link_pose(b);
        Tb = w_.T.data() + 16 * b;
    }
    relative_pose(w_.T.data() + 16 * a, Tb, pose);
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
    if (m_.is_cloud(b))  // a point cloud's voxels (cloud_queries.hpp)
        return cloud_pair_within(m_, a, *m_.clouds[b], pose, h, extra, w_.margin,
                                 c_.view.options.box_test, counters_);
    MotionMargin& mm = w_.margin;
    const double* A = m_.body_box(a);
    const double* B = m_.body_box(b);
    const int box_test = c_.view.options.box_test;
    const BoxMotion ma = mm.box_motion(A, 0), mb = mm.box_motion(B, 1);
    const double rate = ma.rate + mb.rate;
    const double r = h * rate + extra;
    double reach = mm.h2;
    if (node_pair_apart(A, B, pose, mm.side[0].T, ma, mb, h, extra, mm, box_test, &reach))
        return {false, 0.0, reach};
    reach = mm.h2;
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
            int64_t* row = stack + 3 * n_seeds++;
            row[0] = front[k];
            row[1] = front[k + 1];
            row[2] = 0;
        }
    } else {
        for (int64_t ea = m_.elem_start[a]; ea < m_.elem_end[a]; ++ea) {
            for (int64_t eb = m_.elem_start[b]; eb < m_.elem_end[b]; ++eb) {
                int64_t* row = stack + 3 * n_seeds++;
                row[0] = m_.roots[ea];
                row[1] = m_.roots[eb];
                row[2] = 0;
            }
        }
    }
    const int64_t before = counters_[COUNT_BOX_TESTS];
    WithinResult trees = trees_within(n_seeds, pose, m_.forest, box_test,
                                      c_.view.options.expansion, stack, counters_, h, extra,
                                      mm, c_.scratch.distance_work(m_),
                                      m_.padding[a] + m_.padding[b], &w_.recorded,
                                      &w_.recorded_reach, crude,
                                      measured ? &w_.recorded_gap : nullptr);
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

bool MotionQuery::sweepable(const StraightPath&, int64_t p) {
    const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
    for (int s = 0; s < 2; ++s)
        for (int64_t i = 0; i < w_.side_n[s]; ++i)
            if (w_.side_rot[s][i] != 0.0) return false;
    if (m_.is_cloud(b) || m_.elements(a) * m_.elements(b) > SWEEP_MAX_ELEMENT_PAIRS ||
        !body_hulls(a) || !body_hulls(b))
        return false;
    w_.sweeping.push_back(p);
    std::vector<double>& poses = w_.sweep_poses;
    poses.resize((POSE_WIDTH + 3) * w_.sweeping.size());
    double* pose = poses.data() + poses.size() - (POSE_WIDTH + 3);
    pair_pose(a, b, pose);
    pair_shift(p, pose + POSE_WIDTH);
    return true;
}

void MotionQuery::sweep_pairs(double* best, int64_t* best_pair) {
    const std::vector<int64_t>& pairs = w_.sweeping;
    for (size_t i = 0; i < pairs.size(); ++i) {
        const double* pose = w_.sweep_poses.data() + (POSE_WIDTH + 3) * i;
        double t;
        const int swept = sweep(pairs[i], pose, pose + POSE_WIDTH, &t);
        if (swept == SWEEP_UNKNOWN) {
            w_.heap.push_back({pairs[i], 0.0, 1.0, 1.0});
        } else if (swept == SWEEP_CONTACT && t < *best) {
            *best = t;
            *best_pair = pairs[i];
        }
    }
}

// Nothing between a sweepable pair's bodies turns: each joint that moves slides its side by
// its own translation (kinematics.hpp: set_link_pose's prismatic, planar and floating
// steps), turned into the world by its parent's rotation at the evaluated state, which the
// motion keeps. Body b's shift less body a's, in a's frame.
void MotionQuery::pair_shift(int64_t p, double* d) {
    const double* delta = w_.delta.data();
    double world[3] = {0.0, 0.0, 0.0};
    for (int s = 0; s < 2; ++s) {
        const double sign = s == 0 ? -1.0 : 1.0;
        for (int64_t i = 0; i < w_.side_n[s]; ++i) {
            const int64_t k = w_.side_link[s][i];
            const int64_t j = m_.kin.q_index[k];
            double u[3] = {0.0, 0.0, 0.0};  // in the joint's frame
            switch (m_.kin.joint_type[k]) {
                case JOINT_PRISMATIC:
                    for (int c = 0; c < 3; ++c)
                        u[c] = m_.kin.multiplier[k] * delta[j] * m_.kin.axis[3 * k + c];
                    break;
                case JOINT_PLANAR:
                    u[0] = delta[j];
                    u[1] = delta[j + 1];
                    break;
                case JOINT_FLOATING:
                    u[0] = delta[j];
                    u[1] = delta[j + 1];
                    u[2] = delta[j + 2];
                    break;
                default:  // a turn: none on a sweepable pair's sides
                    break;
            }
            const double* J = m_.kin.T_parent_joint + 16 * k;
            const double* P = w_.T.data() + 16 * m_.kin.parent[k];
            double v[3];  // in the parent's frame
            for (int r = 0; r < 3; ++r) v[r] = J[4 * r] * u[0] + J[4 * r + 1] * u[1] + J[4 * r + 2] * u[2];
            for (int r = 0; r < 3; ++r)
                world[r] += sign * (P[4 * r] * v[0] + P[4 * r + 1] * v[1] + P[4 * r + 2] * v[2]);
        }
    }
    const double* A = w_.T.data() + 16 * m_.pair_a[p];
    for (int c = 0; c < 3; ++c) d[c] = A[c] * world[0] + A[4 + c] * world[1] + A[8 + c] * world[2];
}

int MotionQuery::sweep(int64_t p, const double* pose0, const double* d, double* t) {
    const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
    // No shift (joints on both sides moving alike) is no exception: the cast and the probes
    // then decide the start, which is the whole motion.
    const double rho = m_.padding[a] + m_.padding[b];
    const auto hull = [this](int64_t e) {
        const Hull& h = w_.hulls[e];
        return HullView{h.vertices.data(), int64_t(h.vertices.size() / 3), h.adj_start.data(),
                        h.adj.data(), h.seeds.data(), h.centre, h.radius,
                        h.corner.empty() ? nullptr : h.axes.data(),
                        h.corner.empty() ? nullptr : h.corner.data()};
    };
    // A box's hull is its solid (its eight corners): a test vertex of the other element
    // enters it no sooner than that element's hull meets it, so only a round solid, which
    // holds its hull with room to spare, is probed.
    const auto solid = [this](int64_t e) {
        const int kind = int(m_.elem_solid[SOLID_WIDTH * e]);
        return kind == SOLID_SPHERE || kind == SOLID_CYLINDER;
    };
    // The surfaces (the hulls: apart at the start, they first meet on their surfaces), and
    // each element's test vertex against the other's true solid, as solid_gap counts it.
    double first = INF;
    const auto cast = [&](int64_t ea, int64_t eb) {
        double s;
        // Beyond the first contact found so far nothing counts.
        const int r = sweep_first_contact(hull(ea), hull(eb), pose0, pose0 + 9, d, rho,
                                          SWEEP_EPS, std::min(first, 1.0), &s,
                                          &counters_[COUNT_SWEEP_STEPS]);
        if (r == SWEEP_CONTACT) first = std::min(first, s);
        return r != SWEEP_UNKNOWN;
    };
    // Element e's solid (in a's frame when solid_in_a) against element x's test vertex.
    const auto probe = [&](int64_t e, int64_t x, bool solid_in_a) {
        double s;
        if (probe_first_contact(m_.elem_solid + SOLID_WIDTH * e,
                                m_.elem_solid + SOLID_WIDTH * x + SOLID_PROBE, solid_in_a,
                                pose0, pose0 + 9, d, SWEEP_EPS, std::min(first, 1.0),
                                &s) == SWEEP_CONTACT)
            first = std::min(first, s);
    };
    for (int64_t ea = m_.elem_start[a]; ea < m_.elem_end[a]; ++ea) {
        for (int64_t eb = m_.elem_start[b]; eb < m_.elem_end[b]; ++eb) {
            if (!cast(ea, eb)) return SWEEP_UNKNOWN;
            if (solid(ea)) probe(ea, eb, true);
            if (solid(eb)) probe(eb, ea, false);
        }
    }
    ++counters_[COUNT_SWEEPS];
    w_.swept.push_back(p);
    w_.swept_at[p] = first;
    w_.swept_span[p] = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (first > 1.0) return SWEEP_FREE;
    *t = first;
    return SWEEP_CONTACT;
}

// A spline's speeds around t (SplinePath::rates over [t - h2, t + h2]).
void MotionQuery::path_speeds(const SplinePath& path, double t, double h2) {
    for (int64_t k = 0; k < m_.n_links; ++k) {
        w_.trans[k] = w_.rot[k] = w_.speed[k] = w_.accel[k] = 0.0;
        if (!w_.moving[k]) continue;
        double speed, speed_max, accel_max;
        path.rates(m_.kin.q_index[k], t, h2, &speed, &speed_max, &accel_max);
        const double mult = m_.kin.multiplier[k];
        const double scale = std::fabs(mult) * (1.0 + MOTION_BOUND_REL);
        if (m_.kin.joint_type[k] == JOINT_REVOLUTE)
            w_.rot[k] = scale * speed_max;
        else
            w_.trans[k] = scale * speed_max;
        w_.speed[k] = mult * speed;
        w_.accel[k] = scale * accel_max;
    }
}

// A polyline's speeds over [t - h2, t + h2]: per link the largest of the segments it meets;
// within one segment its straight motion's (signed speeds, first-order bounds), else speeds
// 0 and the zeroth order only (the direction changes at a waypoint).
void MotionQuery::path_speeds(const PolylinePath& path, double t, double h2) {
    const int64_t L = m_.n_links;
    const int64_t k0 = path.segment_of(t - h2);
    // The segment holding the window's end (an end at waypoint k: segment k - 1).
    const int64_t k1 = std::max(k0, std::min(int64_t(std::ceil(t + h2)) - 1, path.segments - 1));
    w_.first_order = k0 == k1;
    for (int64_t k = 0; k < L; ++k) {
        double trans = 0.0, rot = 0.0;
        for (int64_t s = k0; s <= k1; ++s) {
            const double* speeds = w_.poly_speeds.data() + 3 * (L * s + k);
            trans = std::max(trans, speeds[0]);
            rot = std::max(rot, speeds[1]);
        }
        w_.trans[k] = trans;
        w_.rot[k] = rot;
        w_.speed[k] = k0 == k1 ? w_.poly_speeds[3 * (L * k0 + k) + 2] : 0.0;
        w_.accel[k] = 0.0;
    }
}

// The cheapest proof first, before the pair's joints are even looked at: the planning's
// configuration-free bound of how far each variable moves the pair (model.hpp: reach,
// reach_ext, E at most its largest along the path), against the gap of the spheres around
// the two bodies. Pairs far apart pass whole motions so. INF reach rows (a floating joint's
// quaternion) prove nothing here.
double MotionQuery::crude_rate(int64_t p) {
    double& rate = w_.crude[p];
    if (rate < 0.0) {
        double sum = 0.0;
        for (int64_t j = 0; j < m_.n_joints; ++j)
            if (w_.var[j] > 0.0) sum += w_.var[j] * variable_reach(m_, p, j, w_.extension_max);
        rate = sum * (1.0 + MOTION_BOUND_REL);
    }
    return rate;
}

// The gap between the spheres around pair p's two bodies (body b at pose in body a).
double MotionQuery::sphere_gap(int64_t p, const double* pose) const {
    const double* A = m_.body_box(m_.pair_a[p]);
    const double* B = m_.body_box(m_.pair_b[p]);
    double d[3];
    centre_offset(A, B, pose, d);
    return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) -
           (A[BOX_RADIUS] + B[BOX_RADIUS]) * (1.0 + SPHERE_EPS_REL);
}

bool MotionQuery::crude_apart(int64_t p, const double* pose, double h, double* reach) {
    const double rate = crude_rate(p);
    if (!(rate < INF)) return false;
    const double gap = sphere_gap(p, pose);
    if (!(gap > rate * h)) return false;
    *reach = rate > 0.0 ? gap / rate : INF;
    return true;
}

// A polyline's crude bound at the waypoints around s.t (their poses shared by every pair and
// computed once): a pair whose spheres are g apart at waypoint k stays apart wherever its
// measure is within g of the measure at k (measure_pair). Takes s.t as far as such a stretch
// around waypoint floor(s.t) or the next one goes, if it holds s.t; false when none takes it
// further.
bool MotionQuery::waypoint_leap(const PolylinePath& path, MotionWork::March& s) {
    if (!measure_pair(s.p)) return false;
    const int64_t L = m_.n_links, S = path.segments;
    const int64_t a = m_.pair_a[s.p], b = m_.pair_b[s.p];
    const double u_end = measure_at(S);
    const double guard = measure_guard();
    const double u_t = measure(s.t);
    const int64_t lo = path.segment_of(s.t);
    double best = s.t;
    for (int64_t k = lo; k <= std::min(lo + 1, S); ++k) {
        double* T = w_.poly_T.data() + 16 * L * k;
        if (!w_.poly_posed[k]) {
            forward_kinematics(m_.kin, path.Q + path.n * k, T);
            w_.poly_posed[k] = 1;
        }
        const double* Tb = m_.is_world_object(b) ? c_.view.state.poses.T_world_body + 16 * b
                                                 : T + 16 * b;
        double pose[POSE_WIDTH];
        relative_pose(T + 16 * a, Tb, pose);
        // The bodies' boxes' gap where their spheres meet (a link's sphere is loose).
        const double u_k = measure_at(k);
        double gap = sphere_gap(s.p, pose);
        if (!(gap * (1.0 - MOTION_BOUND_REL) - guard > std::fabs(u_k - u_t))) {
            double F[12];
            const double* A = m_.body_box(a);
            const double* B = m_.body_box(b);
            box_in_frame(A, B, pose, F);
            gap = std::max(gap, projected_gap(A, B, F, nullptr));
        }
        const double g = gap * (1.0 - MOTION_BOUND_REL) - guard;
        if (!(g > 0.0)) continue;
        if (!(std::fabs(u_k - u_t) < g)) continue;  // waypoint k's stretch must hold s.t
        // The largest t >= k with U(t) - U(k) <= g: the last waypoint i within, then the
        // fraction of its segment (U is linear there).
        if (u_end - u_k <= g) {
            best = path.end();
            break;
        }
        // Galloping from k (a leap is mostly a few segments), then halving.
        int64_t i = k, j = S, stride = 1;  // U(i) - u_k <= g < U(j) - u_k
        while (i + stride < S) {
            if (measure_at(i + stride) - u_k > g) {
                j = i + stride;
                break;
            }
            i += stride;
            stride *= 2;
        }
        while (j - i > 1) {
            const int64_t mid = (i + j) / 2;
            if (measure_at(mid) - u_k <= g) i = mid;
            else j = mid;
        }
        const double u_i = measure_at(i), u_next = measure_at(i + 1);
        const double x = u_next > u_i ? (u_k + g - u_i) / (u_next - u_i) : 1.0;
        best = std::max(best, double(i) + std::min(std::max(x, 0.0), 1.0) *
                                              (1.0 - MOTION_BOUND_REL));
    }
    if (!(best > s.t)) return false;
    s.t = best;
    return true;
}

// One step of pair s.p's march along the path: the pair is proven apart on [0, s.t). The
// interval [t, t + length] is tested at its midpoint m over its half-width h (pair_within):
// apart, the pair is proven apart on the whole interval and further, on [m, m + reach], and
// the next interval is sized from that reach (its half-width a factor of it, which grows while
// intervals pass and shrinks when one does not: near an obstacle the distance, and so the
// reach, shrinks from one interval to the next). Within its margin: the interval is halved,
// and once twice the margin is at most the touching tolerance, the state at t is within the
// tolerance of contact: the first contact. Returns MARCH_*.
template <class Path>
int MotionQuery::march_step(MotionWork::March& s, const Path& path, double t_end) {
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

// Pair p's padded distance with body b at pose in body a, less the rounding allowed for a
// clearance (poses.hpp: clearance_margin), when below cap; else cap less that. The search
// stops once the distance is known to be at most floor.
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

}  // namespace

int64_t check_straight_motion(MotionContext& c, const double* q0, const double* q1,
                              const int64_t* list, int64_t n, double* t, uint8_t* pairs) {
    MotionQuery query(c);
    MotionWork& w = c.work;
    StraightPath path{q0, c.view.model.motion_kind, c.view.model.n_joints, w.delta.data(),
                      w.var.data(), w.quat0.data()};
    path.prepare(q1);
    query.straight_speeds(q0);
    return query.check(list, list ? n : c.view.model.n_pairs, path, q0, t, pairs);
}

int64_t check_polyline_motion(MotionContext& c, const double* Q, int64_t n, double* t,
                              uint8_t* pairs) {
    MotionQuery query(c);
    MotionWork& w = c.work;
    const Model& m = c.view.model;
    const int64_t J = m.n_joints, S = n - 1;
    for (auto* v : {&w.poly_delta, &w.poly_var, &w.poly_quat0}) v->assign(S * J, 0.0);
    w.poly_speeds.assign(3 * S * m.n_links, 0.0);
    w.poly_T.resize(16 * (S + 1) * m.n_links);
    w.poly_posed.assign(S + 1, 0);
    w.poly_cum.assign((S + 1) * J, 0.0);
    w.pair_rates.assign(J, 0.0);
    PolylinePath path{Q, m.motion_kind, J, S, w.poly_delta.data(), w.poly_var.data(),
                      w.poly_quat0.data()};
    path.prepare();
    query.polyline_speeds(path);
    return query.check(nullptr, m.n_pairs, path, Q, t, pairs);
}

int64_t check_spline_motion(MotionContext& c, const double* coef, double* t, uint8_t* pairs) {
    MotionQuery query(c);
    const SplinePath path{coef, c.view.model.n_joints};
    path.at(0.0, c.work.q_prev.data());
    query.spline_moving(path);
    return query.check(nullptr, c.view.model.n_pairs, path, c.work.q_prev.data(), t, pairs);
}

int64_t check_step_motion(MotionContext& c, const double* q0, const double* q1,
                          const int64_t* rechecked, int64_t n, double extension_before,
                          double* t, uint8_t* pairs) {
    const Model& m = c.view.model;
    const State& s = c.view.state;
    MotionWork& w = c.work;
    w.size_for(m);
    w.measured.clear();
    w.measured_gap.clear();
    // The query's skipped pairs are apart along the straight motion in q, which is this one
    // unless a continuous joint goes the shorter way round the other way: then all march.
    for (int64_t j = 0; j < m.n_joints; ++j) {
        const double d = q1[j] - q0[j];
        if (m.motion_kind[j] == MOTION_WRAP &&
            std::fabs(std::remainder(d, 2.0 * M_PI)) != std::fabs(d))
            return check_straight_motion(c, q0, q1, nullptr, m.n_pairs, t, pairs);
    }
    if (n == 0) return 0;  // nothing re-checked: every pair is apart all along
    StraightPath path{q0, m.motion_kind, m.n_joints, w.delta.data(), w.var.data(),
                      w.quat0.data()};
    path.prepare(q1);
    const double e_max = std::max(extension_before, s.extension[0]);
    MotionQuery query(c);
    bool speeds = false;  // query.straight_speeds, for step_reach: only once one needs them
    w.marched.clear();
    const int64_t J = m.n_joints;
    // The step's bound for pair p: sum_j |dq_j| (reach[p, j] + E_max reach_ext[p, j]), how
    // far any point of either body can move relative to the other over it (in the units of
    // the pair's travel, planning.hpp).
    const auto step_bound = [&](int64_t p) {
        double r = 0.0;
        for (int64_t j = 0; j < J; ++j)
            if (w.var[j] > 0.0) r += w.var[j] * variable_reach(m, p, j, e_max);
        return r * (1.0 + MOTION_BOUND_REL);
    };
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = rechecked[i];
        if (s.status[p] == 0 && w.prev_gap[p] > -INF) {
            // Apart all along when its gaps at the two ends exceed the step's bound, the
            // planning's or the levers' at q1 (step_reach); or, its clearance at q1 being
            // the query's descent's, when its distance measured there does.
            const double gaps = w.prev_gap[p] + s.clearance[p];
            double r = step_bound(p);
            if (gaps > r) continue;
            if (!speeds) query.straight_speeds(q0);
            speeds = true;
            r = std::min(r, query.step_reach(p, q1));
            if (gaps > r) continue;
            const int64_t a = m.pair_a[p], b = m.pair_b[p];
            const double need = r - w.prev_gap[p];
            const double cap = MOTION_MEASURE_AHEAD * need;
            const bool front = s.fronts.state[2 * p] != 0;
            if (!m.is_cloud(b) && !front &&
                cap <= MOTION_MEASURE_SCALE *
                           (m.body_box(a)[BOX_RADIUS] + m.body_box(b)[BOX_RADIUS])) {
                // At q1, where the incremental query placed the bodies; a test vertex nearer
                // a solid than the triangles are counts (pair_within).
                double pose[POSE_WIDTH];
                write_pair_pose(s.poses.T_world_body, a, b, pose);
                const double d = std::min(distance_at(c, p, pose, need, cap),
                                          query.pair_solid_gap(p, pose));
                ++c.scratch.counters[COUNT_MEASURES];
                if (d > need) {
                    w.measured.push_back(p);
                    w.measured_gap.push_back(d);
                    continue;
                }
            }
        }
        w.marched.push_back(p);
    }
    if (w.marched.empty()) return 0;
    // A marched pair the carried state had apart at q0 (its gap recorded, not -INF) is not
    // checked there again, and its march starts from the node pairs where the query's descent
    // at q1 stopped (its front: they cover every pair of triangles, whatever the poses). Each
    // of them is apart at q1 by at least its until less the pair's travel (traversal.hpp:
    // front_scan), so by more than the step's bound apart all along the step: the march
    // never tests it (its proof reaches the step's end).
    const Fronts& fronts = s.fronts;
    for (const int64_t p : w.marched) {
        w.start_apart[p] = w.prev_gap[p] > -INF ? 1 : 0;
        std::vector<int64_t>& front = w.front[p];
        front.clear();
        w.front_until[p].clear();
        w.front_measure[p].clear();
        const int64_t rows = fronts.state[2 * p];
        if (!w.start_apart[p] || rows == 0 || rows > MOTION_FRONT_MAX || m.is_cloud(m.pair_b[p]))
            continue;
        const int64_t* row = fronts.pairs.data() + 3 * p * fronts.capacity;
        const double* until = fronts.until.data() + p * fronts.capacity;
        const double travel = fronts.travel[p];
        const double r = step_bound(p);
        std::vector<double>& proven = w.front_until[p];
        for (int64_t e = 0; e < rows; ++e) {
            front.push_back(row[3 * e]);
            front.push_back(row[3 * e + 1]);
            const double margin = until[e] - travel - FRONT_GUARD_REL * std::fabs(until[e]);
            proven.push_back(margin > r ? 1.0 : -INF);
        }
        w.front_cost[p] = fronts.state[2 * p + 1];
    }
    w.start_known = true;
    const int64_t hit = check_straight_motion(c, q0, q1, w.marched.data(),
                                              int64_t(w.marched.size()), t, pairs);
    w.start_known = false;
    return hit;
}

}  // namespace collision_sensor
