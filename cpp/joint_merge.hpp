// Partial joint states merged into one robot state, malformed messages rejected whole.
//
// The sensor core (sensor_core.hpp) hands over the name and position fields of each
// sensor_msgs/JointState and gets back a MergeOutcome that says what happened and why. The
// rules, in the order they are applied to one message:
//
// 1. no positions at all (a velocity- or effort-only message, or an empty one): nothing
//    changes (ignored);
// 2. name and position of different lengths: rejected whole;
// 3. a name given twice: rejected whole;
// 4. a position that is NaN or infinite (for any joint, known or not): rejected whole;
// 5. a known joint with limits whose value lies beyond them by more than the tolerance (rad
//    or m): by the policy, LIMITS_REJECT rejects the message whole, LIMITS_CLAMP stores the
//    nearest limit, LIMITS_ACCEPT stores the value as given. Values beyond a limit by at most
//    the tolerance (sensor noise, calibration) are stored as given; joints without limits
//    (continuous) take any finite value;
// 6. derived joints (mimic joints: they follow their source joint) are skipped silently; any
//    other name the robot does not move (unknown or fixed joints) is ignored and reported once,
//    the first time it is seen (MergeOutcome::new_unknown). At most max_unknown names are
//    remembered, later ones are only counted (unknown_overflow);
// 7. the positions of the known joints are stored; joints a message does not name keep the
//    value they had, so publishers that each name a subset (arm, gripper) merge into one state.
//
// A rejected message changes nothing: neither the positions nor the unknown names. Reasons
// quote names through sensor_text.hpp (escaped, bounded), so they are safe to log.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace collision_sensor {

// What a value beyond a joint's limits does (rule 5).
constexpr int LIMITS_REJECT = 0, LIMITS_CLAMP = 1, LIMITS_ACCEPT = 2;

enum class MergeVerdict { ACCEPTED, IGNORED, REJECTED };

// Why a message was rejected (the names are the counters' and log throttles' suffixes).
enum class MergeProblem { NONE, LENGTH_MISMATCH, DUPLICATE_NAMES, NOT_FINITE, OUT_OF_LIMITS };
const char* problem_name(MergeProblem problem);  // "length_mismatch", ...

struct MergeOutcome {
    MergeVerdict verdict = MergeVerdict::IGNORED;
    MergeProblem problem = MergeProblem::NONE;
    std::string reason;                    // one sentence, "" unless rejected
    std::vector<int64_t> updated;          // the variables this message set, in its order
    std::vector<std::string> unknown;      // its names the robot does not move
    std::vector<std::string> new_unknown;  // of those, never seen before and now remembered
    int64_t unremembered = 0;              // of those, not remembered (the memory is full)
    std::vector<int64_t> clamped;          // the variables replaced by a limit (LIMITS_CLAMP)
    // For undo(): each stored variable's value before (NaN: not heard before).
    std::vector<std::pair<int64_t, double>> previous;
    bool accepted() const { return verdict == MergeVerdict::ACCEPTED; }
};

class JointMerge {
   public:
    // names: the variables the robot moves, in the engine's order; derived: names published
    // but never used (mimic joints); lower, upper: each variable's limits (not finite: none on
    // that side).
    JointMerge(std::vector<std::string> names, const std::vector<std::string>& derived,
               std::vector<double> lower, std::vector<double> upper, int policy,
               double tolerance, int64_t max_unknown);
    // Its lookups view its own names: neither copied nor moved.
    JointMerge(const JointMerge&) = delete;
    JointMerge& operator=(const JointMerge&) = delete;

    // Merge one message (rules above).
    MergeOutcome merge(const std::vector<std::string_view>& names,
                       const std::vector<double>& positions);
    // Restore what a merged message replaced (the engine refused its state).
    void undo(const MergeOutcome& outcome);
    // Give variable j the value unless it has one (a planar or floating joint's variables).
    void set_default(int64_t j, double value);
    // Keep the values of the variables other has of the same name (a new robot model).
    void carry_from(const JointMerge& other);

    bool complete() const { return heard_count_ == int64_t(names_.size()); }
    bool heard(int64_t j) const { return heard_[j] != 0; }
    // (J,) the values, NaN where not heard yet.
    const std::vector<double>& positions() const { return q_; }
    std::vector<std::string> missing() const;
    const std::vector<std::string>& names() const { return names_; }
    const std::vector<std::string>& unknown_names() const { return unknown_order_; }
    int64_t unknown_overflow() const { return unknown_overflow_; }
    double lower(int64_t j) const { return lower_[j]; }
    double upper(int64_t j) const { return upper_[j]; }
    int policy() const { return policy_; }
    void set_policy(int policy) { policy_ = policy; }
    double tolerance() const { return tolerance_; }
    int64_t max_unknown() const { return max_unknown_; }

   private:
    int64_t index_of(std::string_view name) const;
    bool is_derived(std::string_view name) const;

    std::vector<std::string> names_;
    std::vector<std::string> derived_names_;
    // Views of names_ and derived_names_ (never resized after construction): lookups by the
    // message's own bytes, no string made per name.
    std::unordered_map<std::string_view, int64_t> index_;
    std::unordered_set<std::string_view> derived_;
    std::vector<double> lower_, upper_;
    int policy_;
    double tolerance_;
    int64_t max_unknown_;
    std::vector<double> q_;
    std::vector<uint8_t> heard_;
    int64_t heard_count_ = 0;
    std::unordered_set<std::string> unknown_;
    std::vector<std::string> unknown_order_;
    int64_t unknown_overflow_ = 0;
    // Scratch of merge(): the message's variables, by position.
    std::vector<int64_t> slots_;
    std::vector<double> values_;
};

}  // namespace collision_sensor
