// Every tolerance of the engine. collision_sensor/engine/tolerances.py reads them from the
// extension (bindings.cpp exports them) and states and explains them.
#pragma once

// Small functions of the inner loops: the compiler's own inlining budget leaves some of them
// out of line at -O2 (box_in_frame, the edge-axis test), which cost a third of a query.
#if defined(__GNUC__) || defined(__clang__)
#define CS_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define CS_ALWAYS_INLINE inline
#endif

namespace collision_sensor {

constexpr double BOX_EPS_REL = 1e-9;
constexpr double BOX_EPS_PARALLEL = 1e-3;
constexpr double TRIANGLE_EPS_REL = 1e-12;
constexpr double SPHERE_EPS_REL = 1e-9;

// The rigid transforms the scene methods take (engine.hpp: is_rigid_transform): the position
// within MAX_COORDINATE (m) of the origin on each axis, |R^T R - I| <= ROTATION_TOLERANCE
// entrywise.
constexpr double MAX_COORDINATE = 1e6;
constexpr double ROTATION_TOLERANCE = 1e-6;

}  // namespace collision_sensor
