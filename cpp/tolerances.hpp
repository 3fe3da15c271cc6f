// Every tolerance and limit of the engine, in one place. bindings.cpp exports each under its
// name; collision_sensor/engine/tolerances.py reads them from the extension and explains the
// geometric ones, and the rest of the Python side reads the limits from there or from the
// extension, never a copy.
//
// Every tolerance errs toward "contact" or toward "re-check": it only ever turns a near miss
// into a reported contact, or a pair skipped into a pair re-checked, never the other way.
#pragma once

#include <cstdint>

namespace collision_sensor {

// ---- The geometric tests (dimensionless: each multiplies a length scale of its test).

// Box tests (box_test.hpp): boxes are separated along an axis L only if their projections'
// gap exceeds BOX_EPS_REL * (the sum of the six half extents) * (1 + BOX_EPS_PARALLEL / |L|),
// |L| the unnormalised axis' length (sin of the angle of two edges for an edge-edge axis): a
// floor that keeps an axis made of two almost parallel edges from separating on rounding.
constexpr double BOX_EPS_REL = 1e-9;
constexpr double BOX_EPS_PARALLEL = 1e-3;
// Triangle test (triangle_test.hpp): two triangles meet iff their distance is at most this
// fraction of their largest absolute coordinate.
constexpr double TRIANGLE_EPS_REL = 1e-12;
// The traversal's sphere pre-test (traversal.hpp): spheres apart only by more than this
// fraction of their radii's sum.
constexpr double SPHERE_EPS_REL = 1e-9;
// A closed mesh is a hull (model.cpp: element_hull) when no vertex lies beyond a face plane by
// more than this fraction of the mesh's extent (rounding of coplanar vertices).
constexpr double HULL_FLAT_REL = 1e-9;

// A bound computed in a few float64 operations (a box's extent along the world axes, a gap
// less a running sum) is widened by this fraction of its terms: far above their rounding, far
// below any gap that matters.
constexpr double BOUND_ROUNDING_REL = 1e-9;

// ---- The incremental query's bounds (planning.hpp, recheck.cpp).

// A pair's clearance is rounded down by this fraction of the pair's coordinate scale (its
// body boxes' reach plus their distance): it covers the triangle test's contact tolerance,
// boxes that hold their triangles only up to rounding, and the rounding of the gaps and FK.
constexpr double CLEARANCE_EPS_REL = 1e-9;
// A skipped pair's running travel sum is replaced by the exact sum once it reaches this
// fraction of the pair's clearance (the running sum's rounding stays far below the rest).
constexpr double TRAVEL_GUARD = 1.0 - 1e-6;
// A front's node pair is kept untested while its until exceeds the pair's travel by more than
// this fraction of itself: the travel is a running sum, and this covers its rounding.
constexpr double FRONT_GUARD_REL = 1e-9;
// A pair keeps a front only while its clearance is at most this fraction of its size.
constexpr double FRONT_GAP_REL = 1e-3;

// ---- Motion checks (motion.hpp).

// A reported first contact's state is in contact, or its padded distance is at most this (m).
constexpr double MOTION_TOUCH_TOLERANCE = 1e-6;
// Every bound of the motion is widened by this fraction (the reach bounds' own rounding).
constexpr double MOTION_BOUND_REL = 1e-9;
// A ray-cast sweep (convex_sweep.hpp) stops within this distance (m) of contact: a tenth of
// the touching tolerance.
constexpr double SWEEP_EPS = 0.1 * MOTION_TOUCH_TOLERANCE;
// Slerp between unit quaternions half an angle below this (rad) apart is their chord
// (kinematics.hpp: MOTION_QUATERNION): the chord is the arc there to rounding, and kinematics
// normalises the quaternion; the same rule in every interpolation (motion.hpp: StraightPath,
// and the interpolate binding).
constexpr double SLERP_HALF_ANGLE_MIN = 1e-6;

// ---- The values the engine takes.

// The largest |value| of a prismatic joint (m) the engine takes. Every coordinate, box and
// gap it computes then stays far from overflow (their squares included), so its answers keep
// their meaning; beyond it a link would sit 1000 km away. A revolute joint takes any finite
// value (it enters through cos and sin only). The translation variables of planar and floating
// joints are held to the same bound.
constexpr double PRISMATIC_VALUE_MAX = 1e6;
// The smallest norm of a quaternion the package takes, a floating joint's and a scene pose's
// alike: below it, its direction is rounding noise (its components are scaled by the largest
// before the norm is taken, kinematics.hpp: scaled_quaternion, so any larger norm has a
// direction to full precision). It also keeps the checker's bound on how far a quaternion
// component moves a point (pair_reach.py: QUATERNION_REACH, 1e300 per unit) valid: changing
// the quaternion by dq turns the rotation by at most about pi |dq| / |quaternion| <= pi 1e100
// |dq|, which times any lever arm under 1e199 m stays below it.
constexpr double QUATERNION_NORM_MIN = 1e-100;
// The rigid transforms the scene methods take (engine.hpp: is_rigid_transform): the position
// within MAX_COORDINATE (m) of the origin on each axis (as PRISMATIC_VALUE_MAX bounds the
// joints), |R^T R - I| <= ROTATION_TOLERANCE entrywise.
constexpr double MAX_COORDINATE = 1e6;
constexpr double ROTATION_TOLERANCE = 1e-6;
// A pair of a body and a cloud keeps at most this clearance (m): an empty cloud is infinitely
// far, and its pairs are forced when its next cloud arrives.
constexpr double MAX_CLOUD_CLEARANCE = 1e6;
// The most threads a setting may ask for (a bound on the workers' memory, far beyond any
// machine this runs on).
constexpr int64_t MAX_THREADS = 256;

}  // namespace collision_sensor
