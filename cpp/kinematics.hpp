// Forward kinematics over flat arrays (collision_sensor/engine/kinematics.py builds them).
//
// Per link i (L links, root first, every parent before its children), reached through the
// joint above it:
//     value = multiplier[i] q[q_index[i]] + offset[i]            (mimic chains composed)
//     T_world_link[i] = T_world_link[parent[i]] T_parent_joint[i] M(joint_type[i], value)
//     M(FIXED) = I;  M(REVOLUTE) = [Rodrigues(axis[i], value), 0; 0, 1];
//     M(PRISMATIC) = [I, value axis[i]; 0, 1]
// Multi-DOF joints read several consecutive variables v = q[q_index[i]], q[q_index[i] + 1], ...
// (MoveIt's order; a multi-DOF joint is never a mimic, so multiplier and offset are unused):
//     M(PLANAR)   = [Rz(v2), (v0, v1, 0); 0, 1]      x, y, theta: the joint frame's x-y plane
//     M(FLOATING) = [R(v3..v6 / |v3..v6|), (v0, v1, v2); 0, 1]    translation, then quaternion
//                                                                 (x, y, z, w), normalised
// Both translate first, then rotate about the translated origin (the child frame's origin).
// The planar joint's URDF <axis> is not used: its plane is the joint frame's x-y plane, as
// MoveIt's PlanarJointModel has it (robot_model.py warns about another axis).
// "world" is the root link's frame. Poses are (4, 4) row-major blocks of 16 doubles.
#pragma once

#include <cmath>
#include <cstdint>

#include "inlining.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

constexpr int64_t JOINT_FIXED = 0, JOINT_REVOLUTE = 1, JOINT_PRISMATIC = 2, JOINT_PLANAR = 3,
                  JOINT_FLOATING = 4;

// How variable j moves along a motion between two states (motion.hpp; the checker sets each
// variable's kind from its joint, MoveIt's interpolation):
constexpr int64_t MOTION_LINEAR = 0;      // revolute with limits, prismatic, translations
constexpr int64_t MOTION_WRAP = 1;        // continuous joint, planar theta: the shorter way
constexpr int64_t MOTION_QUATERNION = 2;  // a floating joint's rot_x; with rot_y, rot_z, rot_w
constexpr int64_t MOTION_QUATERNION_REST = 3;  // (kind 3) slerp along the shorter arc

// How many consecutive variables of q a joint of each type reads (JOINT_VARIABLES[kind]).
constexpr int64_t JOINT_VARIABLES[5] = {0, 1, 1, 3, 7};
inline int64_t joint_variable_count(int64_t kind) { return JOINT_VARIABLES[kind]; }

// A joint's values the engine takes: PRISMATIC_VALUE_MAX, QUATERNION_NORM_MIN (tolerances.hpp).

// Quaternion (x, y, z, w) scaled by 1 / its largest |component| (no overflow in the squares);
// false if it is zero or its norm is below QUATERNION_NORM_MIN. q must be finite.
CS_ALWAYS_INLINE bool scaled_quaternion(const double* v, double* x, double* y, double* z,
                                        double* w, double* n2) {
    const double s = std::fmax(std::fmax(std::fabs(v[0]), std::fabs(v[1])),
                               std::fmax(std::fabs(v[2]), std::fabs(v[3])));
    if (!(s > 0.0)) return false;
    *x = v[0] / s; *y = v[1] / s; *z = v[2] / s; *w = v[3] / s;
    *n2 = *x * *x + *y * *y + *z * *z + *w * *w;   // in [1, 4]
    return s * std::sqrt(*n2) >= QUATERNION_NORM_MIN;
}

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

// -1 if every joint value that q gives is usable (finite; prismatic ones and the translations of
// planar and floating joints within PRISMATIC_VALUE_MAX; a floating joint's quaternion not zero,
// see QUATERNION_NORM_MIN), else the index into q of the first variable that gives one that is
// not (for a quaternion, its first variable, rot_x).
inline int64_t unusable_variable(const KinematicTree& kin, const double* q, int64_t n_joints) {
    for (int64_t j = 0; j < n_joints; ++j)
        if (!std::isfinite(q[j])) return j;
    for (int64_t i = 0; i < kin.n_links; ++i) {
        const int64_t kind = kin.joint_type[i];
        if (kind == JOINT_FIXED) continue;
        const double* v = q + kin.q_index[i];
        if (kind == JOINT_PLANAR || kind == JOINT_FLOATING) {   // finite: checked above
            const int64_t n_translations = kind == JOINT_PLANAR ? 2 : 3;
            for (int64_t k = 0; k < n_translations; ++k)
                if (!(std::fabs(v[k]) <= PRISMATIC_VALUE_MAX)) return kin.q_index[i] + k;
            double x, y, z, w, n2;
            if (kind == JOINT_FLOATING && !scaled_quaternion(v + 3, &x, &y, &z, &w, &n2))
                return kin.q_index[i] + 3;
            continue;
        }
        const double value = kin.multiplier[i] * q[kin.q_index[i]] + kin.offset[i];
        if (!std::isfinite(value) ||
            (kind == JOINT_PRISMATIC && !(std::fabs(value) <= PRISMATIC_VALUE_MAX)))
            return kin.q_index[i];
    }
    return -1;
}

// Write link i's world pose into T_world_link from its parent's (already current) pose.
// turn, if given, (L, 3): each revolute joint's last angle and its cosine and sine, reused
// while the angle stays (a motion's two ends often turn a joint alike).
CS_ALWAYS_INLINE void set_link_pose(const KinematicTree& kin, int64_t i, const double* q,
                                    double* T_world_link, double* turn = nullptr) {
    const double* J = kin.T_parent_joint + 16 * i;
    // M = T_parent_joint motion, as 12 scalars (rotation m.., translation t.).
    double m00 = J[0], m01 = J[1], m02 = J[2], t0 = J[3];
    double m10 = J[4], m11 = J[5], m12 = J[6], t1 = J[7];
    double m20 = J[8], m21 = J[9], m22 = J[10], t2 = J[11];
    const int64_t kind = kin.joint_type[i];
    // An origin that does not turn (a rotation whose diagonal is all 1 is the identity): the
    // products with its rotation are skipped; they would give the same numbers.
    const bool plain = J[0] == 1.0 && J[5] == 1.0 && J[10] == 1.0;
    bool turned = !plain;  // M's rotation is not the identity
    if (kind != JOINT_FIXED) {
        const double value = kin.multiplier[i] * q[kin.q_index[i]] + kin.offset[i];
        const double x = kin.axis[3 * i], y = kin.axis[3 * i + 1], z = kin.axis[3 * i + 2];
        // The joint's rotation R (revolute, planar, floating), applied once below: M.R <- J.R R.
        double r00 = 1.0, r01 = 0.0, r02 = 0.0, r10 = 0.0, r11 = 1.0, r12 = 0.0, r20 = 0.0,
               r21 = 0.0, r22 = 1.0;
        bool rotates = true;
        if (kind == JOINT_REVOLUTE) {
            // Rodrigues: R = c I + s [a]x + (1 - c) a a'.
            double c, s;
            if (turn && turn[3 * i] == value) {
                c = turn[3 * i + 1];
                s = turn[3 * i + 2];
            } else {
                c = std::cos(value);
                s = std::sin(value);
                if (turn) {
                    turn[3 * i] = value;
                    turn[3 * i + 1] = c;
                    turn[3 * i + 2] = s;
                }
            }
            const double v = 1.0 - c;
            r00 = c + v * x * x; r01 = v * x * y - s * z; r02 = v * x * z + s * y;
            r10 = v * x * y + s * z; r11 = c + v * y * y; r12 = v * y * z - s * x;
            r20 = v * x * z - s * y; r21 = v * y * z + s * x; r22 = c + v * z * z;
        } else if (kind == JOINT_PLANAR || kind == JOINT_FLOATING) {
            // M = [Rm, tm]: t <- t + J.R tm, then J.R <- J.R Rm (translate, then rotate).
            const double* v = q + kin.q_index[i];
            const double tz = kind == JOINT_FLOATING ? v[2] : 0.0;
            t0 += m00 * v[0] + m01 * v[1] + m02 * tz;
            t1 += m10 * v[0] + m11 * v[1] + m12 * tz;
            t2 += m20 * v[0] + m21 * v[1] + m22 * tz;
            if (kind == JOINT_PLANAR) {
                const double c = std::cos(v[2]), s = std::sin(v[2]);
                r00 = c; r01 = -s; r02 = 0.0;
                r10 = s; r11 = c; r12 = 0.0;
                r20 = 0.0; r21 = 0.0; r22 = 1.0;
            } else {
                // Unit quaternion u = (x, y, z, w) / sqrt(n2): R = I + 2 w [u]x + 2 [u]x^2,
                // written with k = 2 / n2 so that no square root is taken.
                double x = 0.0, y = 0.0, z = 0.0, w = 1.0, n2 = 1.0;
                scaled_quaternion(v + 3, &x, &y, &z, &w, &n2);   // usable: validated first
                const double k = 2.0 / n2;
                const double xx = k * x * x, yy = k * y * y, zz = k * z * z;
                const double xy = k * x * y, xz = k * x * z, yz = k * y * z;
                const double wx = k * w * x, wy = k * w * y, wz = k * w * z;
                r00 = 1.0 - yy - zz; r01 = xy - wz; r02 = xz + wy;
                r10 = xy + wz; r11 = 1.0 - xx - zz; r12 = yz - wx;
                r20 = xz - wy; r21 = yz + wx; r22 = 1.0 - xx - yy;
            }
        } else {
            // Prismatic: the child frame slides by value axis, in the joint frame.
            t0 += value * (m00 * x + m01 * y + m02 * z);
            t1 += value * (m10 * x + m11 * y + m12 * z);
            t2 += value * (m20 * x + m21 * y + m22 * z);
            rotates = false;
        }
        if (rotates && plain) {
            m00 = r00; m01 = r01; m02 = r02;
            m10 = r10; m11 = r11; m12 = r12;
            m20 = r20; m21 = r21; m22 = r22;
            turned = true;
        } else if (rotates) {
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
        }
    }
    double* T = T_world_link + 16 * i;
    const int64_t p = kin.parent[i];
    if (p < 0) {
        T[0] = m00; T[1] = m01; T[2] = m02; T[3] = t0;
        T[4] = m10; T[5] = m11; T[6] = m12; T[7] = t1;
        T[8] = m20; T[9] = m21; T[10] = m22; T[11] = t2;
    } else if (!turned) {
        const double* Tp = T_world_link + 16 * p;
        for (int r = 0; r < 3; ++r) {
            const double p0 = Tp[4 * r], p1 = Tp[4 * r + 1], p2 = Tp[4 * r + 2];
            T[4 * r] = p0;
            T[4 * r + 1] = p1;
            T[4 * r + 2] = p2;
            T[4 * r + 3] = p0 * t0 + p1 * t1 + p2 * t2 + Tp[4 * r + 3];
        }
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
