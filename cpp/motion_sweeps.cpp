// The pairs of a straight motion swept by ray casts (motion_query.hpp; convex_sweep.hpp):
// bodies of convex elements that only translate relative to each other.
#include <algorithm>
#include <cmath>

#include "convex_sweep.hpp"
#include "motion_query.hpp"
#include "poses.hpp"
#include "tolerances.hpp"

namespace collision_sensor {
namespace motion_detail {

bool MotionQuery::sweepable_bodies(int64_t p) {
    const int64_t a = m_.pair_a[p], b = m_.pair_b[p];
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

}  // namespace motion_detail
}  // namespace collision_sensor
