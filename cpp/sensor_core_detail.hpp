// What the sensor core's sources share (sensor_core.cpp, sensor_answers.cpp,
// sensor_state.cpp): its constants, the failures' kinds, and how it tells an engine's refusal
// and an engine error from an internal one. Not for other callers.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "joint_merge.hpp"
#include "sensor_text.hpp"

namespace collision_sensor {
namespace sensor_detail {

constexpr double INFINITE = std::numeric_limits<double>::infinity();
// The most log lines waiting for the caller (a flood of bad input drops the rest, counted).
constexpr size_t MAX_NOTES = 1000;
// The most complete states kept for positions_at, whatever the window (1 s at 4 kHz).
constexpr size_t WINDOW_CAPACITY = 4096;

// Failure kinds (colliding_pairs status names).
constexpr const char* REJECTED = "joint_state_rejected";
constexpr const char* WAITING = "waiting_for_joints";
constexpr const char* ENGINE_ERROR = "engine_error";
constexpr const char* STALE = "joint_states_stale";

// The engine refused a state: variable j is not usable (kinematics.hpp: unusable_variable).
struct EngineRefused {
    int64_t variable;
};
// An engine error (not an internal one): the engine, or a test's injected fault, said what.
struct EngineError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

inline std::string fixed1(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.1f", value);
    return buffer;
}

inline std::string bound(double value) {
    return std::isfinite(value) ? text::general(value, 6) : "none";
}

inline const char* limit_policy_name(int policy) {
    return policy == LIMITS_CLAMP ? "clamp" : policy == LIMITS_ACCEPT ? "accept" : "reject";
}

}  // namespace sensor_detail
}  // namespace collision_sensor
