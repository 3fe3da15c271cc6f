// Certified motion checks (motion.hpp): Engine::motion, update_motion and path.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "motion.hpp"
#include "query.hpp"

namespace collision_sensor {

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

}  // namespace

void Engine::set_motion_kinds(const int64_t* kinds) {
    motion_.kind.assign(kinds, kinds + n_joints_);
}

// Size the work on the first call; take the joint offsets as they are now (an attached
// object's pose is its link's offset, and may have moved since the last call).
void Engine::motion_prepare() {
    MotionWork& w = motion_;
    const int64_t J = n_joints_, L = n_links_, N = n_nodes_;
    if (int64_t(w.q.size()) == J && int64_t(w.T.size()) == 16 * L &&
        int64_t(w.node_motion[0].size()) == N)
        return;
    if (int64_t(w.kind.size()) != J) w.kind.assign(J, MOTION_LINEAR);
    w.delta.assign(J, 0.0);
    w.var.assign(J, 0.0);
    w.quat0.assign(J, 0.0);
    w.q.assign(J, 0.0);
    w.q_prev.assign(J, 0.0);
    w.T.assign(16 * L, 0.0);
    w.stamp.assign(L, 0);
    w.chain.assign(L, 0);
    w.trans.assign(L, 0.0);
    w.rot.assign(L, 0.0);
    w.speed.assign(L, 0.0);
    w.accel.assign(L, 0.0);
    w.moving.assign(L, 0);
    w.depth.assign(L, 0);
    for (int64_t i = 1; i < L; ++i) w.depth[i] = w.depth[kin_.parent[i]] + 1;
    w.prev_gap.assign(n_pairs_, 0.0);
    w.prev_sums.assign(2 * n_pairs_, 0.0);
    for (int s = 0; s < 2; ++s) {
        w.side_link[s].assign(L, 0);
        w.side_trans[s].assign(L, 0.0);
        w.side_rot[s].assign(L, 0.0);
        w.side_origin[s].assign(3 * L, 0.0);
        w.side_axis[s].assign(3 * L, 0.0);
        w.side_speed[s].assign(L, 0.0);
        w.side_above[s].assign(L, 0.0);
        w.side_accel[s].assign(L, 0.0);
        w.node_motion[s].assign(N, BoxMotion{});
        w.node_stamp[s].assign(N, 0);
    }
    w.tag = 0;
    w.margin.tag = 0;
}

// Evaluate the link poses at q from now on (computed on demand, motion_link_pose).
void Engine::motion_evaluate(const double* q) {
    MotionWork& w = motion_;
    if (q != w.q.data()) std::copy(q, q + n_joints_, w.q.begin());
    ++w.tag;
}

// Link i's world pose at the evaluated state: it and the ancestors not yet computed, top down.
void Engine::motion_link_pose(int64_t i) {
    MotionWork& w = motion_;
    int64_t n = 0;
    for (int64_t k = i; k >= 0 && w.stamp[k] != w.tag; k = kin_.parent[k]) w.chain[n++] = k;
    for (int64_t t = n - 1; t >= 0; --t) {
        set_link_pose(kin_, w.chain[t], w.q.data(), w.T.data());
        w.stamp[w.chain[t]] = w.tag;
    }
}

// Body b's pose in body a's frame at the evaluated state (a is a link; b a link, or a world
// object, which no joint moves).
void Engine::motion_pair_pose(int64_t a, int64_t b, double* pose) {
    motion_link_pose(a);
    const double* Tb = T_world_body_ + 16 * b;
    if (b < n_links_) {
        motion_link_pose(b);
        Tb = motion_.T.data() + 16 * b;
    }
    relative_pose(motion_.T.data() + 16 * a, Tb, pose);
}

// Prepare pair p's two sides for path: the joints between each body and the pair's lowest
// common ancestor (none above a world object: it is the world's), lowest first, those moving
// at the evaluated part of the path, with their speeds per unit of the parameter. Returns
// whether any of those joints moves anywhere on the path.
bool Engine::motion_sides(int64_t p) {
    MotionWork& w = motion_;
    const int64_t a = pair_a_[p], b = pair_b_[p];
    int64_t common = -1;
    if (b < n_links_) {
        int64_t x = a, y = b;
        while (w.depth[x] > w.depth[y]) x = kin_.parent[x];
        while (w.depth[y] > w.depth[x]) y = kin_.parent[y];
        while (x != y) {
            x = kin_.parent[x];
            y = kin_.parent[y];
        }
        common = x;
    }
    bool moves = false;
    for (int s = 0; s < 2; ++s) {
        const int64_t x = s == 0 ? a : b;
        int64_t n = 0;
        if (s == 0 || b < n_links_) {
            for (int64_t k = x; k > 0 && k != common; k = kin_.parent[k]) {
                moves |= w.moving[k] != 0;
                if (w.trans[k] > 0.0 || w.rot[k] > 0.0) {
                    w.side_link[s][n] = k;
                    w.side_trans[s][n] = w.trans[k];
                    w.side_rot[s][n] = w.rot[k];
                    w.side_speed[s][n] = w.speed[k];
                    w.side_accel[s][n] = w.accel[k];
                    ++n;
                }
            }
        }
        w.side_n[s] = n;
        // How fast each joint's own frame turns: the turns of the joints above it, summed.
        double above = 0.0;
        for (int64_t i = n - 1; i >= 0; --i) {
            w.side_above[s][i] = above;
            above += w.side_rot[s][i];
        }
    }
    return moves;
}

// The motion margin of pair p at the evaluated state (motion_pair_pose computed its poses):
// each side's joints placed in the world (MotionMargin).
void Engine::motion_margin(int64_t p, double h2) {
    MotionWork& w = motion_;
    MotionMargin& m = w.margin;
    for (int s = 0; s < 2; ++s) {
        const int64_t x = s == 0 ? pair_a_[p] : pair_b_[p];
        SideMotion& side = m.side[s];
        side.first_order = true;
        side.omega[0] = side.omega[1] = side.omega[2] = 0.0;
        for (int64_t i = 0; i < w.side_n[s]; ++i) {
            const int64_t k = w.side_link[s][i];
            motion_link_pose(k);
            const double* T = w.T.data() + 16 * k;
            double* o = w.side_origin[s].data() + 3 * i;
            double* u = w.side_axis[s].data() + 3 * i;
            o[0] = T[3];
            o[1] = T[7];
            o[2] = T[11];
            // The axis in the world: the joint frame's (revolute, prismatic: axis[k]; planar:
            // z), which the child frame shares, turned by the child's world rotation.
            const int64_t kind = kin_.joint_type[k];
            double v[3] = {0.0, 0.0, 0.0};
            if (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC) {
                v[0] = kin_.axis[3 * k];
                v[1] = kin_.axis[3 * k + 1];
                v[2] = kin_.axis[3 * k + 2];
            } else if (kind == JOINT_PLANAR) {
                v[2] = 1.0;
            }
            for (int r = 0; r < 3; ++r)
                u[r] = T[4 * r] * v[0] + T[4 * r + 1] * v[1] + T[4 * r + 2] * v[2];
            if (kind == JOINT_REVOLUTE) {
                for (int r = 0; r < 3; ++r) side.omega[r] += w.side_speed[s][i] * u[r];
            } else if (kind != JOINT_PRISMATIC) {
                side.first_order = false;  // planar, floating: the zeroth order only
            }
        }
        side.n = w.side_n[s];
        side.origin = w.side_origin[s].data();
        side.axis = w.side_axis[s].data();
        side.trans = w.side_trans[s].data();
        side.rot = w.side_rot[s].data();
        side.speed = w.side_speed[s].data();
        side.accel = w.side_accel[s].data();
        side.above = w.side_above[s].data();
        side.T = x < n_links_ ? w.T.data() + 16 * x : T_world_body_ + 16 * x;
        m.cache[s] = w.node_motion[s].data();
        m.stamp[s] = w.node_stamp[s].data();
    }
    m.h2 = h2;
    ++m.tag;
}

// The smallest distance from a solid element of one body to the first vertex of an element
// of the other (contained()'s test vertex), INF if neither body has a solid element.
double Engine::solid_gap(int64_t a, int64_t b, const double* P) const {
    double best = INF;
    for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea) {
        for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb) {
            if (elem_tris_[2 * ea] == elem_tris_[2 * ea + 1] ||
                elem_tris_[2 * eb] == elem_tris_[2 * eb + 1])
                continue;  // an element without triangles
            if (elem_solid_[SOLID_WIDTH * ea] != SOLID_NONE) {  // eb's vertex, in body a
                const double* v = forest_.tris + 9 * elem_tris_[2 * eb];
                double x[3];
                for (int i = 0; i < 3; ++i)
                    x[i] = P[3 * i] * v[0] + P[3 * i + 1] * v[1] + P[3 * i + 2] * v[2] + P[9 + i];
                best = std::min(best, solid_distance(elem_solid_ + SOLID_WIDTH * ea, x));
            }
            if (elem_solid_[SOLID_WIDTH * eb] != SOLID_NONE) {  // ea's vertex, in body b
                const double* v = forest_.tris + 9 * elem_tris_[2 * ea];
                const double d0 = v[0] - P[9], d1 = v[1] - P[10], d2 = v[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                best = std::min(best, solid_distance(elem_solid_ + SOLID_WIDTH * eb, y));
            }
        }
    }
    return best;
}

// Is pair p (body b at pose in body a) within its motion margin of contact over the
// half-width h of the path (motion_margin: triangles within padding + margin, or a test
// vertex within its margin of a solid element)? Else over what half-width is it apart?
WithinResult Engine::pair_within(int64_t p, const double* pose, double h, double extra) {
    const int64_t a = pair_a_[p], b = pair_b_[p];
    MotionMargin& margin = motion_.margin;
    const double* A = body_boxes_ + BOX_WIDTH * a;
    const double* B = body_boxes_ + BOX_WIDTH * b;
    const int box_method = int(header_[H_BOX_METHOD]);
    const BoxMotion ma = margin.box_motion(A, 0), mb = margin.box_motion(B, 1);
    const double rate = ma.rate + mb.rate;
    const double r = h * rate + extra;
    double reach = margin.h2;
    if (node_pair_apart(A, B, pose, margin.side[0].T, ma, mb, h, extra, margin, box_method,
                        &reach))
        return {false, 0.0, reach};
    reach = margin.h2;
    if (body_solid_[a] || body_solid_[b]) {
        // A test vertex of one body moves no farther than the body's box allows.
        const double solid = solid_gap(a, b, pose);
        if (solid <= r) return {true, r, rate > 0.0 ? std::max((solid - extra) / rate, 0.0) : 0.0};
        if (rate > 0.0) reach = std::min(reach, (solid - extra) / rate);
    }
    int64_t n_seeds = 0;
    for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea) {
        for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb) {
            int64_t* row = stack_ + 3 * n_seeds++;
            row[0] = roots_[ea];
            row[1] = roots_[eb];
            row[2] = 0;
        }
    }
    WithinResult trees =
        trees_within(n_seeds, pose, forest_, box_method, int(header_[H_EXPANSION]), stack_,
                     counters_, h, extra, margin, padding_[a] + padding_[b]);
    if (!trees.within) trees.reach = std::min(trees.reach, reach);
    return trees;
}

// One step of pair s.p's march along the path (motion_sides(s.p) prepared): the pair is proven
// apart on [0, s.t). The interval [t, t + length] is tested at its midpoint m over its
// half-width h (pair_within): apart, the pair is proven apart on the whole interval and
// further, on [m, m + reach], and the next interval is sized from that reach (its half-width
// a factor of it, which grows while intervals pass and shrinks when one does not: near an
// obstacle the distance, and so the reach, shrinks from one interval to the next). Within its
// margin: the interval is halved, and once twice the margin is at most the touching tolerance,
// the state at t is within the tolerance of contact: the first contact. Returns MARCH_*.
template <class Path>
int Engine::march_step(PairMarch& s, const Path& path, double t_end) {
    const int64_t a = pair_a_[s.p], b = pair_b_[s.p];
    double pose[POSE_WIDTH];
    const double hi = std::min(s.t + s.length, t_end);
    const double m = 0.5 * (s.t + hi);
    const double h = 0.5 * (hi - s.t);
    path_speeds(path, m, 2.0 * h);
    motion_sides(s.p);
    path.at(m, motion_.q.data());
    motion_evaluate(motion_.q.data());
    motion_pair_pose(a, b, pose);
    motion_margin(s.p, 2.0 * h);
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

// The straight path q0 -> q1 in motion_ (path.prepare done): each link's joint's speeds per
// unit of the parameter.
void Engine::straight_speeds(const double* q0, const double* q1) {
    MotionWork& w = motion_;
    (void)q0;
    (void)q1;
    w.side_n[0] = w.side_n[1] = 0;
    for (int64_t k = 0; k < n_links_; ++k) {
        const int64_t kind = kin_.joint_type[k];
        const int64_t j = kin_.q_index[k];
        double trans = 0.0, rot = 0.0;
        if (kind == JOINT_REVOLUTE) {
            rot = std::fabs(kin_.multiplier[k]) * w.var[j];
        } else if (kind == JOINT_PRISMATIC) {
            trans = std::fabs(kin_.multiplier[k]) * w.var[j];
        } else if (kind == JOINT_PLANAR) {
            trans = std::hypot(w.delta[j], w.delta[j + 1]);
            rot = w.var[j + 2];
        } else if (kind == JOINT_FLOATING) {
            trans = std::sqrt(w.delta[j] * w.delta[j] + w.delta[j + 1] * w.delta[j + 1] +
                              w.delta[j + 2] * w.delta[j + 2]);
            rot = w.var[j + 3];
        }
        w.trans[k] = trans * (1.0 + MOTION_BOUND_REL);
        w.rot[k] = rot * (1.0 + MOTION_BOUND_REL);
        w.speed[k] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC)
                         ? kin_.multiplier[k] * w.delta[j]
                         : 0.0;
        w.accel[k] = 0.0;
        w.moving[k] = (trans > 0.0 || rot > 0.0) ? 1 : 0;
    }
}

// A spline's speeds around t (SplinePath::rates over [t - h2, t + h2]); the planar and
// floating joints stay (spline_motion refuses anything else).
void Engine::path_speeds(const SplinePath& path, double t, double h2) {
    MotionWork& w = motion_;
    for (int64_t k = 0; k < n_links_; ++k) {
        const int64_t kind = kin_.joint_type[k];
        w.trans[k] = w.rot[k] = w.speed[k] = w.accel[k] = 0.0;
        if (!w.moving[k]) continue;
        double speed, speed_max, accel_max;
        path.rates(kin_.q_index[k], t, h2, &speed, &speed_max, &accel_max);
        const double mult = kin_.multiplier[k], scale = std::fabs(mult) * (1.0 + MOTION_BOUND_REL);
        if (kind == JOINT_REVOLUTE)
            w.rot[k] = scale * speed_max;
        else
            w.trans[k] = scale * speed_max;
        w.speed[k] = mult * speed;
        w.accel[k] = scale * accel_max;
    }
}

// The links a spline moves (revolute and prismatic joints whose variable is not constant).
void Engine::spline_moving(const SplinePath& path) {
    MotionWork& w = motion_;
    for (int64_t k = 0; k < n_links_; ++k) {
        const int64_t kind = kin_.joint_type[k];
        w.moving[k] = (kind == JOINT_REVOLUTE || kind == JOINT_PRISMATIC) &&
                      path.moves(kin_.q_index[k]);
    }
}

// March the pairs list[:n] (all pairs when list is null) along the path, side by side, the
// one proven apart least far first (a heap on t): a contact found bounds every other march,
// so no later contact is ever localised. Returns the pair of the first contact (-1: none),
// its parameter in *best.
template <class Path>
int64_t Engine::march_pairs(const int64_t* list, int64_t n, const Path& path, const double* q0,
                            double* best) {
    MotionWork& w = motion_;
    *best = INF;
    int64_t best_pair = -1;
    double pose[POSE_WIDTH];
    std::vector<PairMarch>& heap = w.heap;
    heap.clear();
    const auto later = [](const PairMarch& x, const PairMarch& y) { return x.t > y.t; };
    path_speeds(path, 0.5, 0.5);
    for (int64_t i = 0; i < n && *best > 0.0; ++i) {
        const int64_t p = list ? list[i] : i;
        if (motion_sides(p)) {
            heap.push_back({p, 0.0, 1.0, 1.0});
        } else {  // nothing moves the pair: as it is at q0 all the way
            w.side_n[0] = w.side_n[1] = 0;
            motion_evaluate(q0);
            motion_pair_pose(pair_a_[p], pair_b_[p], pose);
            motion_margin(p, 0.0);
            if (pair_within(p, pose, 0.0).within) {
                *best = 0.0;
                best_pair = p;
            }
        }
    }
    std::make_heap(heap.begin(), heap.end(), later);
    while (!heap.empty() && heap.front().t < *best) {
        std::pop_heap(heap.begin(), heap.end(), later);
        PairMarch& s = heap.back();
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

// pairs[p] = 1 for the pairs list[:n] (all: list null) in contact at path(t), or within the
// touching tolerance: a margin of MOTION_TOUCH_TOLERANCE everywhere; 0 for every other.
template <class Path>
void Engine::motion_contacts(const int64_t* list, int64_t n, const Path& path, double t,
                             uint8_t* pairs) {
    MotionWork& w = motion_;
    double pose[POSE_WIDTH];
    std::fill(pairs, pairs + n_pairs_, uint8_t(0));
    path.at(t, w.q.data());
    motion_evaluate(w.q.data());
    w.side_n[0] = w.side_n[1] = 0;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = list ? list[i] : i;
        motion_pair_pose(pair_a_[p], pair_b_[p], pose);
        motion_margin(p, 0.0);
        pairs[p] = pair_within(p, pose, 0.0, MOTION_TOUCH_TOLERANCE).within ? 1 : 0;
    }
}

int64_t Engine::straight_motion(const double* q0, const double* q1, double* t_out,
                                uint8_t* pairs) {
    MotionWork& w = motion_;
    StraightPath path{q0, w.kind.data(), n_joints_, w.delta.data(), w.var.data(),
                      w.quat0.data()};
    path.prepare(q1);
    straight_speeds(q0, q1);
    return motion_marched(nullptr, n_pairs_, path, q0, t_out, pairs);
}

int64_t Engine::motion(const double* q0, const double* q1, double* t, uint8_t* pairs) {
    const int64_t bad0 = unusable_variable(kin_, q0, n_joints_);
    if (bad0 >= 0) return -1 - bad0;
    const int64_t bad1 = unusable_variable(kin_, q1, n_joints_);
    if (bad1 >= 0) return -1 - (n_joints_ + bad1);
    motion_prepare();
    return straight_motion(q0, q1, t, pairs);
}

// Pair p's gap at the last state, before plan_update moves its travel sums (extension: E
// there): its clearance less its travel since, which bounds its distance from below; 0 when
// the pair has no clearance (known apart, by how much unknown), -INF in contact. The sums are
// kept too (motion_skip).
void Engine::record_gap(int64_t p, double extension) {
    motion_.prev_sums[2 * p] = travel_[2 * p];
    motion_.prev_sums[2 * p + 1] = travel_[2 * p + 1];
    double gap = 0.0;
    if (status_[p] != 0) {
        gap = -INF;
    } else if (clearance_[p] > 0.0) {
        // The running sums' rounding is a few ulps of the clearance (plan_update).
        const double travel = travel_[2 * p] + extension * travel_[2 * p + 1];
        gap = std::max(clearance_[p] - travel - 1e-9 * clearance_[p], 0.0);
    }
    motion_.prev_gap[p] = gap;
}

// The incremental motion check (issue 25) on the incremental query:
//   - a pair in contact at the last state: the motion starts in contact (t = 0);
//   - a pair the query does not re-check is apart along the whole straight motion: no joint on
//     its path moved (its pose is the same all along), or its travel bound is below its
//     clearance at both ends, and the bound, sum_j |q_j - q_eval_j| reach[p, j] (+ E ...), is
//     convex in q: below the clearance on the whole segment between the two;
//   - a pair the query re-checks and finds apart with clearance c_now, whose gap at the last
//     state was c_prev (record_gap), is apart all along when c_prev + c_now exceeds the
//     step's bound r = sum_j |dq_j| (reach[p, j] + E_max reach_ext[p, j]) (the distance at t
//     is at least max(c_prev - t r, c_now - (1 - t) r));
//   - every other pair marches (march_pairs) along the step.
// A moved prismatic joint changes E: then the bound is max(f0, f1) + max(E0, E1) max(x0, x1)
// over the segment (its two sums, each convex, at the two ends), which plan_update checks too
// (motion_skip). A continuous joint that jumped by more than pi (the same pose, the other way
// round) makes the straight motion in q another path than the motion's: then every pair marches
// (straight_motion on all pairs).
int64_t Engine::update_motion(const double* q, double* t, uint8_t* pairs,
                              int64_t* query_code) {
    const int64_t bad = unusable_variable(kin_, q, n_joints_);
    if (bad >= 0) return -1 - bad;
    motion_prepare();
    MotionWork& w = motion_;
    if (!header_[H_CHECKED_ONCE]) {  // no state before: the instant q
        *query_code = run(q, false);
        bool any = false;
        for (int64_t p = 0; p < n_pairs_; ++p) {
            pairs[p] = uint8_t(status_[p]);
            any |= status_[p] != 0;
        }
        *t = 0.0;
        return any ? 1 : 0;
    }
    bool contact = false;
    for (int64_t p = 0; p < n_pairs_ && !contact; ++p) contact = status_[p] != 0;
    if (contact) {  // in contact already at the start
        for (int64_t p = 0; p < n_pairs_; ++p) pairs[p] = uint8_t(status_[p]);
        *query_code = run(q, false);
        *t = 0.0;
        return 1;
    }
    std::copy(q_last_, q_last_ + n_joints_, w.q_prev.begin());
    const double* q0 = w.q_prev.data();
    StraightPath path{q0, w.kind.data(), n_joints_, w.delta.data(), w.var.data(),
                      w.quat0.data()};
    path.prepare(q);
    // The query's skipped pairs are apart along the straight motion in q, which is this one
    // unless a continuous joint goes the shorter way round the other way.
    bool convex = true;
    for (int64_t j = 0; j < n_joints_; ++j)
        if (w.kind[j] == MOTION_WRAP && w.var[j] != std::fabs(q[j] - q0[j])) convex = false;
    const double e_before = scalars_[S_EXTENSION];
    motion_record_ = true;
    *query_code = run(q, false);
    motion_record_ = false;
    straight_speeds(q0, q);
    if (!convex) return motion_marched(nullptr, n_pairs_, path, q0, t, pairs);
    // The re-checked pairs are todo[:n] (run's incremental plan).
    const int64_t n = *query_code >> 1;
    const double e_max = std::max(e_before, scalars_[S_EXTENSION]);
    w.marched.clear();
    for (int64_t i = 0; i < n; ++i) {
        const int64_t p = todo_[i];
        if (status_[p] == 0 && w.prev_gap[p] > -INF) {
            double r = 0.0;
            const double* reach = reach_ + n_joints_ * p;
            const double* reach_ext = reach_ext_ + n_joints_ * p;
            for (int64_t j = 0; j < n_joints_; ++j)
                if (w.var[j] > 0.0) r += w.var[j] * (reach[j] + e_max * reach_ext[j]);
            if (w.prev_gap[p] + clearance_[p] > r * (1.0 + MOTION_BOUND_REL)) continue;
        }
        w.marched.push_back(p);
    }
    if (w.marched.empty()) return 0;
    return motion_marched(w.marched.data(), int64_t(w.marched.size()), path, q0, t,
                                   pairs);
}

// straight_motion on the pairs list[:n] (all: null) of the prepared path.
// True iff pair p, which plan_update skips at the new state (its travel below its clearance),
// is below its clearance on the whole segment from the last state too, E having changed from
// extension_before to extension (record_gap kept its sums at the last state).
bool Engine::motion_skip(int64_t p, double extension_before, double extension) const {
    const double f = std::max(motion_.prev_sums[2 * p], travel_[2 * p]);
    const double x = std::max(motion_.prev_sums[2 * p + 1], travel_[2 * p + 1]);
    return f + std::max(extension_before, extension) * x < TRAVEL_GUARD * clearance_[p];
}

template <class Path>
int64_t Engine::motion_marched(const int64_t* list, int64_t n, const Path& path,
                               const double* q0, double* t, uint8_t* pairs) {
    double best;
    const int64_t best_pair = march_pairs(list, n, path, q0, &best);
    if (best_pair < 0) return 0;
    motion_contacts(list, n, path, best, pairs);
    pairs[best_pair] = 1;
    *t = best;
    return 1;
}

int64_t Engine::path(const double* Q, int64_t n, int64_t* segment, double* t, uint8_t* pairs) {
    for (int64_t i = 0; i < n; ++i) {  // all rows first: a bad row answers before any work
        const int64_t bad = unusable_variable(kin_, Q + n_joints_ * i, n_joints_);
        if (bad >= 0) return -1 - (n_joints_ * i + bad);
    }
    motion_prepare();
    *segment = -1;
    if (n == 1 && straight_motion(Q, Q, t, pairs)) {  // one waypoint: its instant
        *segment = 0;
        return 1;
    }
    for (int64_t i = 0; i + 1 < n; ++i) {
        if (straight_motion(Q + n_joints_ * i, Q + n_joints_ * (i + 1), t, pairs)) {
            *segment = i;
            return 1;
        }
    }
    return 0;
}

int64_t Engine::spline(const double* coef, int64_t n, int64_t* segment, double* t,
                       uint8_t* pairs) {
    MotionWork& w = motion_;
    const int64_t J = n_joints_;
    std::vector<double>& q0 = w.q_prev;
    for (int64_t i = 0; i < n; ++i) {  // every segment first: a bad one answers before any work
        const double* c = coef + 6 * J * i;
        for (int64_t k = 0; k < 6 * J; ++k)
            if (!std::isfinite(c[k])) return -1 - i;
        const SplinePath path{c, J};
        for (int64_t l = 0; l < n_links_; ++l) {
            const int64_t kind = kin_.joint_type[l];
            if (kind != JOINT_PLANAR && kind != JOINT_FLOATING) continue;
            for (int64_t v = 0; v < joint_variable_count(kind); ++v)
                if (path.moves(kin_.q_index[l] + v)) return -1 - i;
        }
        if (q0.size() != size_t(J)) q0.assign(J, 0.0);
        for (double end : {0.0, 1.0}) {
            path.at(end, q0.data());
            if (unusable_variable(kin_, q0.data(), J) >= 0) return -1 - i;
        }
    }
    motion_prepare();
    *segment = -1;
    for (int64_t i = 0; i < n; ++i) {
        const SplinePath path{coef + 6 * J * i, J};
        path.at(0.0, w.q_prev.data());
        spline_moving(path);
        if (motion_marched(nullptr, n_pairs_, path, w.q_prev.data(), t, pairs)) {
            *segment = i;
            return 1;
        }
    }
    return 0;
}

}  // namespace collision_sensor
