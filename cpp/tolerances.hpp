// Every tolerance of the engine, as collision_sensor/tolerances.py states and explains them;
// test_compiled.py checks that the two agree.
#pragma once

namespace collision_sensor {

constexpr double BOX_EPS_REL = 1e-9;
constexpr double BOX_EPS_PARALLEL = 1e-3;
constexpr double TRIANGLE_EPS_REL = 1e-12;
constexpr double SPHERE_EPS_REL = 1e-9;

}  // namespace collision_sensor
