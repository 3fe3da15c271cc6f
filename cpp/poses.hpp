// Body poses, kept lazily (paper sec. 4.2): a moved joint marks the links below it stale
// (planning.hpp), and a link's world pose is recomputed only when a pair being re-checked
// needs it, or when every pose is asked for. World objects are never stale: their poses are
// set between queries (engine.hpp: move_world_body).
//
// Header only: a re-check calls these for every pair.
#pragma once

#include <cmath>
#include <cstdint>

#include "context.hpp"
#include "inlining.hpp"
#include "kinematics.hpp"
#include "model.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

// Bring body i's pose up to date with q: it and its stale ancestors, top down (chain: (L,)
// work).
CS_ALWAYS_INLINE void refresh_pose(const Model& m, const double* q, const Poses& poses,
                                   int64_t* chain, int64_t i) {
    int64_t n = 0;
    for (int64_t k = i; k >= 0 && poses.stale[k]; k = m.kin.parent[k]) chain[n++] = k;
    for (int64_t t = n - 1; t >= 0; --t) {
        set_link_pose(m.kin, chain[t], q, poses.T_world_body);
        poses.stale[chain[t]] = 0;
    }
}

// Bring every link's pose up to date with q.
inline void refresh_all_poses(const Model& m, const double* q, const Poses& poses) {
    for (int64_t i = 0; i < m.n_links; ++i) {
        if (poses.stale[i]) {
            set_link_pose(m.kin, i, q, poses.T_world_body);
            poses.stale[i] = 0;
        }
    }
}

// Body b's pose in body a's frame (R_ab row-major, then t_ab: POSE_WIDTH numbers):
// [R_ab, t_ab] = T_world_a^-1 T_world_b = [Ra' Rb, Ra' (tb - ta)].
CS_ALWAYS_INLINE void write_pair_pose(const double* T_world_body, int64_t a, int64_t b,
                                      double* pose) {
    const double* Ta = T_world_body + 16 * a;
    const double* Tb = T_world_body + 16 * b;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            pose[3 * i + j] = Ta[i] * Tb[j] + Ta[4 + i] * Tb[4 + j] + Ta[8 + i] * Tb[8 + j];
        pose[9 + i] = Ta[i] * (Tb[3] - Ta[3]) + Ta[4 + i] * (Tb[7] - Ta[7]) +
                      Ta[8 + i] * (Tb[11] - Ta[11]);
    }
}


// CLEARANCE_EPS_REL times a bound of every coordinate pair (a, b)'s tests see at pose.
CS_ALWAYS_INLINE double clearance_margin(const Model& m, int64_t a, int64_t b,
                                         const double* pose) {
    const double t = std::sqrt(pose[9] * pose[9] + pose[10] * pose[10] + pose[11] * pose[11]);
    return CLEARANCE_EPS_REL * (t + m.body_reach[a] + m.body_reach[b]);
}

}  // namespace collision_sensor
