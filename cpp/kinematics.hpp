// Forward kinematics over flat arrays (collision_sensor/kinematics.py builds them).
//
// Per link i (L links, root first, every parent before its children), reached through the
// joint above it:
//     value = multiplier[i] q[q_index[i]] + offset[i]            (mimic chains composed)
//     T_world_link[i] = T_world_link[parent[i]] T_parent_joint[i] M(joint_type[i], value)
//     M(FIXED) = I;  M(REVOLUTE) = [Rodrigues(axis[i], value), 0; 0, 1];
//     M(PRISMATIC) = [I, value axis[i]; 0, 1]
// "world" is the root link's frame. Poses are (4, 4) row-major blocks of 16 doubles.
#pragma once

#include <cmath>
#include <cstdint>

#include "tolerances.hpp"

namespace collision_sensor {

constexpr int64_t JOINT_FIXED = 0, JOINT_REVOLUTE = 1, JOINT_PRISMATIC = 2;

// The largest |value| of a prismatic joint (m) the engine takes. Every coordinate, box and
// gap it computes then stays far from overflow (their squares included), so its answers keep
// their meaning; beyond it a link would sit 1000 km away. A revolute joint takes any finite
// value (it enters through cos and sin only).
constexpr double PRISMATIC_VALUE_MAX = 1e6;

struct KinematicTree {
    int64_t n_links;
    const int64_t* parent;          // (L,) parent link, -1 for the root
    const int64_t* joint_type;      // (L,) JOINT_*
    const double* T_parent_joint;   // (L, 4, 4) joint origins
    const double* axis;             // (L, 3) unit joint axes, in the joint frame
    const int64_t* q_index;         // (L,) index into q of the driving value, -1 if fixed
    const double* multiplier;       // (L,)
    const double* offset;           // (L,)
};

// -1 if every joint value that q gives is usable (finite; prismatic ones within
// PRISMATIC_VALUE_MAX), else the index into q of the first variable that gives one that is not.
inline int64_t unusable_variable(const KinematicTree& kin, const double* q, int64_t n_joints) {
    for (int64_t j = 0; j < n_joints; ++j)
        if (!std::isfinite(q[j])) return j;
    for (int64_t i = 0; i < kin.n_links; ++i) {
        const int64_t kind = kin.joint_type[i];
        if (kind == JOINT_FIXED) continue;
        const double value = kin.multiplier[i] * q[kin.q_index[i]] + kin.offset[i];
        if (!std::isfinite(value) ||
            (kind == JOINT_PRISMATIC && !(std::fabs(value) <= PRISMATIC_VALUE_MAX)))
            return kin.q_index[i];
    }
    return -1;
}

// Write link i's world pose into T_world_link from its parent's (already current) pose.
CS_ALWAYS_INLINE void set_link_pose(const KinematicTree& kin, int64_t i, const double* q,
                          double* T_world_link) {
    const double* J = kin.T_parent_joint + 16 * i;
    // M = T_parent_joint motion, as 12 scalars (rotation m.., translation t.).
    double m00 = J[0], m01 = J[1], m02 = J[2], t0 = J[3];
    double m10 = J[4], m11 = J[5], m12 = J[6], t1 = J[7];
    double m20 = J[8], m21 = J[9], m22 = J[10], t2 = J[11];
    const int64_t kind = kin.joint_type[i];
    if (kind != JOINT_FIXED) {
        const double value = kin.multiplier[i] * q[kin.q_index[i]] + kin.offset[i];
        const double x = kin.axis[3 * i], y = kin.axis[3 * i + 1], z = kin.axis[3 * i + 2];
        if (kind == JOINT_REVOLUTE) {
            // Rodrigues: R = c I + s [a]x + (1 - c) a a'; then M.R <- J.R R.
            const double c = std::cos(value);
            const double s = std::sin(value);
            const double v = 1.0 - c;
            const double r00 = c + v * x * x, r01 = v * x * y - s * z, r02 = v * x * z + s * y;
            const double r10 = v * x * y + s * z, r11 = c + v * y * y, r12 = v * y * z - s * x;
            const double r20 = v * x * z - s * y, r21 = v * y * z + s * x, r22 = c + v * z * z;
            const double a00 = m00 * r00 + m01 * r10 + m02 * r20;
            const double a01 = m00 * r01 + m01 * r11 + m02 * r21;
            const double a02 = m00 * r02 + m01 * r12 + m02 * r22;
            const double a10 = m10 * r00 + m11 * r10 + m12 * r20;
            const double a11 = m10 * r01 + m11 * r11 + m12 * r21;
            const double a12 = m10 * r02 + m11 * r12 + m12 * r22;
            const double a20 = m20 * r00 + m21 * r10 + m22 * r20;
            const double a21 = m20 * r01 + m21 * r11 + m22 * r21;
            const double a22 = m20 * r02 + m21 * r12 + m22 * r22;
            m00 = a00; m01 = a01; m02 = a02;
            m10 = a10; m11 = a11; m12 = a12;
            m20 = a20; m21 = a21; m22 = a22;
        } else {
            // Prismatic: the child frame slides by value axis, in the joint frame.
            t0 += value * (m00 * x + m01 * y + m02 * z);
            t1 += value * (m10 * x + m11 * y + m12 * z);
            t2 += value * (m20 * x + m21 * y + m22 * z);
        }
    }
    double* T = T_world_link + 16 * i;
    const int64_t p = kin.parent[i];
    if (p < 0) {
        T[0] = m00; T[1] = m01; T[2] = m02; T[3] = t0;
        T[4] = m10; T[5] = m11; T[6] = m12; T[7] = t1;
        T[8] = m20; T[9] = m21; T[10] = m22; T[11] = t2;
    } else {
        const double* Tp = T_world_link + 16 * p;
        for (int r = 0; r < 3; ++r) {
            const double p0 = Tp[4 * r], p1 = Tp[4 * r + 1], p2 = Tp[4 * r + 2];
            T[4 * r] = p0 * m00 + p1 * m10 + p2 * m20;
            T[4 * r + 1] = p0 * m01 + p1 * m11 + p2 * m21;
            T[4 * r + 2] = p0 * m02 + p1 * m12 + p2 * m22;
            T[4 * r + 3] = p0 * t0 + p1 * t1 + p2 * t2 + Tp[4 * r + 3];
        }
    }
    T[12] = 0.0;
    T[13] = 0.0;
    T[14] = 0.0;
    T[15] = 1.0;
}

// Fill T_world_link (L, 4, 4) with every link's pose for configuration q.
inline void forward_kinematics(const KinematicTree& kin, const double* q, double* T_world_link) {
    for (int64_t i = 0; i < kin.n_links; ++i) set_link_pose(kin, i, q, T_world_link);
}

}  // namespace collision_sensor
