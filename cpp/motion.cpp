// Certified motion checks (motion.hpp).
#include "motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "cloud_queries.hpp"
#include "planning.hpp"

namespace collision_sensor {

void MotionWork::size_for(const Model& m) {
    if (sized) return;
    const int64_t J = m.n_joints, L = m.n_links, N = m.n_nodes, P = m.n_pairs;
    delta.assign(J, 0.0);
    var.assign(J, 0.0);
    quat0.assign(J, 0.0);
    q.assign(J, 0.0);
    q_prev.assign(J, 0.0);
    T.assign(16 * L, 0.0);
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
    front_cost.assign(P, 0);
    marched.reserve(P);
    prev_gap.assign(P, 0.0);
    prev_sums.assign(2 * P, 0.0);
    // A descent from at most MOTION_FRONT_MAX seeds (or a pair's root pairs) holds at most
    // one node pair per level of each tree on top of them.
    stack.assign(3 * (std::max(MOTION_FRONT_MAX, m.most_seeds) + 2 * m.depth + 2), 0);
    tag = 0;
    margin.tag = 0;
    sized = true;
}

namespace {

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
    }

    // The straight path q0 -> q1 prepared: each link's joint's speed per unit of the
    // parameter (constant along it).
    void straight_speeds() {
        for (int64_t k = 0; k < m_.n_links; ++k) {
            const int64_t kind = m_.kin.joint_type[k];
            const int64_t j = m_.kin.q_index[k];
            double trans = 0.0, rot = 0.0;
            if (kind == JOINT_REVOLUTE) {
                rot = std::fabs(m_.kin.multiplier[k]) * w_.var[j];
            } else if (kind == JOINT_PRISMATIC) {
                trans = std::fabs(m_.kin.multiplier[k]) * w_.var[j];
            } else if (kind == JOINT_PLANAR) {
                trans = std::hypot(w_.delta[j], w_.delta[j + 1]);
                rot = w_.var[j + 2];
            } else if (kind == JOINT_FLOATING) {
                trans = std::sqrt(w_.delta[j] * w_.delta[j] + w_.delta[j + 1] * w_.delta[j + 1] +
                                  w_.delta[j + 2] * w_.delta[j + 2]);
                rot = w_.var[j + 3];
            }
            w_.trans[k] = trans * (1.0 + MOTION_BOUND_REL);
            w_.rot[k] = rot * (1.0 + MOTION_BOUND_REL);
            w_.speed[k] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC)
                              ? m_.kin.multiplier[k] * w_.delta[j]
                              : 0.0;
            w_.accel[k] = 0.0;
            w_.moving[k] = (trans > 0.0 || rot > 0.0) ? 1 : 0;
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

    // Pairs list[:n] (null: all) marched along path; returns the pair of the first contact
    // (-1: none), its parameter in *best.
    template <class Path>
    int64_t march_pairs(const int64_t* list, int64_t n, const Path& path, const double* q0,
                        double* best);

    // pairs[p] = 1 for the pairs list[:n] in contact at path(t), or within the touching
    // tolerance: a margin of MOTION_TOUCH_TOLERANCE everywhere; 0 for every other pair.
    template <class Path>
    void contacts(const int64_t* list, int64_t n, const Path& path, double t, uint8_t* pairs);

    template <class Path>
    int64_t check(const int64_t* list, int64_t n, const Path& path, const double* q0, double* t,
                  uint8_t* pairs) {
        double best;
        const int64_t best_pair = march_pairs(list, n, path, q0, &best);
        if (best_pair < 0) return 0;
        contacts(list, n, path, best, pairs);
        pairs[best_pair] = 1;
        *t = best;
        return 1;
    }

   private:
    static constexpr int MARCH_ON = 0, MARCH_FREE = 1, MARCH_CONTACT = 2;

    void evaluate(const double* q);
    void link_pose(int64_t i);
    void pair_pose(int64_t a, int64_t b, double* pose);
    bool sides(int64_t p);
    void margin(int64_t p, double h2);
    WithinResult pair_within(int64_t p, const double* pose, double h, double extra = 0.0);
    double solid_gap(int64_t a, int64_t b, const double* pose) const;
    void path_speeds(const StraightPath&, double, double) {}  // constant (straight_speeds)
    void path_speeds(const SplinePath& path, double t, double h2);
    template <class Path>
    int march_step(MotionWork::March& s, const Path& path, double t_end);

    MotionContext& c_;
    const Model& m_;
    MotionWork& w_;
    int64_t* counters_;
};

// Evaluate the link poses at q from now on (computed on demand, link_pose).
void MotionQuery::evaluate(const double* q) {
    if (q != w_.q.data()) std::copy(q, q + m_.n_joints, w_.q.begin());
    ++w_.tag;
}

// Link i's world pose at the evaluated state: it and the ancestors not yet computed, top down.
void MotionQuery::link_pose(int64_t i) {
    int64_t n = 0;
    for (int64_t k = i; k >= 0 && w_.stamp[k] != w_.tag; k = m_.kin.parent[k]) w_.chain[n++] = k;
    for (int64_t t = n - 1; t >= 0; --t) {
        set_link_pose(m_.kin, w_.chain[t], w_.q.data(), w_.T.data());
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
        side.first_order = true;
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
    const double* tris = m_.forest.tris;
    for (int64_t ea = m_.elem_start[a]; ea < m_.elem_end[a]; ++ea) {
        for (int64_t eb = m_.elem_start[b]; eb < m_.elem_end[b]; ++eb) {
            if (m_.elem_tris[2 * ea] == m_.elem_tris[2 * ea + 1] ||
                m_.elem_tris[2 * eb] == m_.elem_tris[2 * eb + 1])
                continue;  // an element without triangles
            if (m_.elem_solid[SOLID_WIDTH * ea] != SOLID_NONE) {  // eb's vertex, in body a
                const double* v = tris + 9 * m_.elem_tris[2 * eb];
                double x[3];
                for (int i = 0; i < 3; ++i)
                    x[i] = P[3 * i] * v[0] + P[3 * i + 1] * v[1] + P[3 * i + 2] * v[2] + P[9 + i];
                best = std::min(best, solid_distance(m_.elem_solid + SOLID_WIDTH * ea, x));
            }
            if (m_.elem_solid[SOLID_WIDTH * eb] != SOLID_NONE) {  // ea's vertex, in body b
                const double* v = tris + 9 * m_.elem_tris[2 * ea];
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
WithinResult MotionQuery::pair_within(int64_t p, const double* pose, double h, double extra) {
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
    const bool from_front = !front.empty();
    int64_t* stack = w_.stack.data();
    int64_t n_seeds = 0;
    if (from_front) {
        for (size_t k = 0; k < front.size(); k += 2) {
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
    w_.recorded.clear();
    const int64_t before = counters_[COUNT_BOX_TESTS];
    WithinResult trees = trees_within(n_seeds, pose, m_.forest, box_test,
                                      c_.view.options.expansion, stack, counters_, h, extra,
                                      mm, m_.padding[a] + m_.padding[b], &w_.recorded);
    if (trees.within) return trees;  // an incomplete descent: the front stays as it was
    trees.reach = std::min(trees.reach, reach);
    const int64_t cost = counters_[COUNT_BOX_TESTS] - before;
    if (!from_front) w_.front_cost[p] = cost;
    if (int64_t(w_.recorded.size()) <= 2 * MOTION_FRONT_MAX && cost <= w_.front_cost[p])
        front.swap(w_.recorded);
    else
        front.clear();
    return trees;
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
    const double hi = std::min(s.t + s.length, t_end);
    const double m = 0.5 * (s.t + hi);
    const double h = 0.5 * (hi - s.t);
    path_speeds(path, m, 2.0 * h);
    sides(s.p);
    path.at(m, w_.q.data());
    evaluate(w_.q.data());
    pair_pose(a, b, pose);
    margin(s.p, 2.0 * h);
    const WithinResult w = pair_within(s.p, pose, h);
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
    for (int64_t i = 0; i < n; ++i) w_.front[list ? list[i] : i].clear();
    const auto later = [](const MotionWork::March& x, const MotionWork::March& y) {
        return x.t > y.t;
    };
    path_speeds(path, 0.5, 0.5);
    for (int64_t i = 0; i < n && *best > 0.0; ++i) {
        const int64_t p = list ? list[i] : i;
        if (sides(p)) {
            heap.push_back({p, 0.0, 1.0, 1.0});
        } else {  // nothing moves the pair: as it is at q0 all the way
            w_.side_n[0] = w_.side_n[1] = 0;
            evaluate(q0);
            pair_pose(m_.pair_a[p], m_.pair_b[p], pose);
            margin(p, 0.0);
            if (pair_within(p, pose, 0.0).within) {
                *best = 0.0;
                best_pair = p;
            }
        }
    }
    std::make_heap(heap.begin(), heap.end(), later);
    while (!heap.empty() && heap.front().t < *best) {
        std::pop_heap(heap.begin(), heap.end(), later);
        MotionWork::March& s = heap.back();
        const int state = march_step(s, path, std::min(*best, 1.0));
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
                           uint8_t* pairs) {
    double pose[POSE_WIDTH];
    std::fill(pairs, pairs + m_.n_pairs, uint8_t(0));
    path.at(t, w_.q.data());
    evaluate(w_.q.data());
    w_.side_n[0] = w_.side_n[1] = 0;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = list ? list[i] : i;
        pair_pose(m_.pair_a[p], m_.pair_b[p], pose);
        margin(p, 0.0);
        pairs[p] = pair_within(p, pose, 0.0, MOTION_TOUCH_TOLERANCE).within ? 1 : 0;
    }
}

}  // namespace

int64_t check_straight_motion(MotionContext& c, const double* q0, const double* q1,
                              const int64_t* list, int64_t n, double* t, uint8_t* pairs) {
    MotionQuery query(c);
    MotionWork& w = c.work;
    StraightPath path{q0, c.view.model.motion_kind, c.view.model.n_joints, w.delta.data(),
                      w.var.data(), w.quat0.data()};
    path.prepare(q1);
    query.straight_speeds();
    return query.check(list, list ? n : c.view.model.n_pairs, path, q0, t, pairs);
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
    StraightPath path{q0, m.motion_kind, m.n_joints, w.delta.data(), w.var.data(),
                      w.quat0.data()};
    path.prepare(q1);
    // The query's skipped pairs are apart along the straight motion in q, which is this one
    // unless a continuous joint goes the shorter way round the other way: then all march.
    for (int64_t j = 0; j < m.n_joints; ++j)
        if (m.motion_kind[j] == MOTION_WRAP && w.var[j] != std::fabs(q1[j] - q0[j]))
            return check_straight_motion(c, q0, q1, nullptr, m.n_pairs, t, pairs);
    const double e_max = std::max(extension_before, s.extension[0]);
    w.marched.clear();
    const int64_t J = m.n_joints;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = rechecked[i];
        if (s.status[p] == 0 && w.prev_gap[p] > -INF) {
            // The step's bound: sum_j |dq_j| (reach[p, j] + E_max reach_ext[p, j]).
            double r = 0.0;
            const double* reach = m.reach + J * p;
            const double* reach_ext = m.reach_ext + J * p;
            for (int64_t j = 0; j < J; ++j)
                if (w.var[j] > 0.0) r += w.var[j] * (reach[j] + e_max * reach_ext[j]);
            if (w.prev_gap[p] + s.clearance[p] > r * (1.0 + MOTION_BOUND_REL)) continue;
        }
        w.marched.push_back(p);
    }
    if (w.marched.empty()) return 0;
    return check_straight_motion(c, q0, q1, w.marched.data(), int64_t(w.marched.size()), t,
                                 pairs);
}

}  // namespace collision_sensor
