// Partial joint states merged into one state (joint_merge.hpp).
#include "joint_merge.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "sensor_text.hpp"

namespace collision_sensor {

namespace {

constexpr double NaN = std::numeric_limits<double>::quiet_NaN();
// Most names listed in one rejection reason.
constexpr size_t MAX_LISTED = 5;

std::string bound(double value) {
    return std::isfinite(value) ? text::general(value, 6) : "none";
}

MergeOutcome rejected(MergeProblem problem, std::string reason) {
    MergeOutcome out;
    out.verdict = MergeVerdict::REJECTED;
    out.problem = problem;
    out.reason = std::move(reason);
    return out;
}

}  // namespace

const char* problem_name(MergeProblem problem) {
    switch (problem) {
        case MergeProblem::LENGTH_MISMATCH: return "length_mismatch";
        case MergeProblem::DUPLICATE_NAMES: return "duplicate_names";
        case MergeProblem::NOT_FINITE: return "not_finite";
        case MergeProblem::OUT_OF_LIMITS: return "out_of_limits";
        case MergeProblem::NONE: break;
    }
    return "none";
}

JointMerge::JointMerge(std::vector<std::string> names, const std::vector<std::string>& derived,
                       std::vector<double> lower, std::vector<double> upper, int policy,
                       double tolerance, int64_t max_unknown)
    : names_(std::move(names)), lower_(std::move(lower)), upper_(std::move(upper)),
      policy_(policy), tolerance_(tolerance), max_unknown_(max_unknown) {
    const size_t J = names_.size();
    if (lower_.size() != J || upper_.size() != J)
        throw std::invalid_argument("limits: one lower and one upper per variable");
    if (policy < LIMITS_REJECT || policy > LIMITS_ACCEPT)
        throw std::invalid_argument("limit policy: not one of reject, clamp, accept");
    if (!(std::isfinite(tolerance) && tolerance >= 0.0))
        throw std::invalid_argument("limit tolerance: not a finite number >= 0");
    if (max_unknown < 0) throw std::invalid_argument("max_unknown: below 0");
    index_.reserve(J);
    for (size_t j = 0; j < J; ++j) index_.emplace(names_[j], int64_t(j));
    for (const std::string& name : derived)
        if (!index_.count(name)) derived_names_.push_back(name);
    for (const std::string& name : derived_names_) derived_.insert(name);
    q_.assign(J, NaN);
    heard_.assign(J, 0);
}

int64_t JointMerge::index_of(std::string_view name) const {
    const auto found = index_.find(name);
    return found == index_.end() ? -1 : found->second;
}

bool JointMerge::is_derived(std::string_view name) const { return derived_.count(name) != 0; }

MergeOutcome JointMerge::merge(const std::vector<std::string_view>& names,
                               const std::vector<double>& positions) {
    if (positions.empty()) return MergeOutcome();
    if (names.size() != positions.size())
        return rejected(MergeProblem::LENGTH_MISMATCH,
                        std::to_string(names.size()) + " names but " +
                            std::to_string(positions.size()) +
                            " positions; every named joint needs exactly one position");
    // Duplicates: sorted views side by side (a message of 10^4 names costs n log n, no more).
    if (names.size() > 1) {
        std::vector<std::string_view> sorted(names.begin(), names.end());
        std::sort(sorted.begin(), sorted.end());
        if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
            std::vector<std::string> duplicates;
            std::unordered_set<std::string_view> seen, listed;
            for (std::string_view name : names) {
                if (!seen.insert(name).second && listed.insert(name).second)
                    duplicates.push_back(text::quoted(name));
            }
            return rejected(MergeProblem::DUPLICATE_NAMES,
                            "joint names given more than once: " +
                                text::listing(duplicates, duplicates.size(), MAX_LISTED, 400,
                                              false));
        }
    }
    std::vector<std::string> bad;
    size_t bad_count = 0;
    for (size_t k = 0; k < names.size(); ++k) {
        if (std::isfinite(positions[k])) continue;
        if (bad.size() < MAX_LISTED + 1)
            bad.push_back(text::quoted(names[k]) + "=" + text::repr(positions[k]));
        ++bad_count;
    }
    if (bad_count)
        return rejected(MergeProblem::NOT_FINITE,
                        "positions that are not finite: " +
                            text::listing(bad, bad_count, MAX_LISTED, 400, false));

    slots_.assign(names.size(), -1);
    values_.assign(names.size(), 0.0);
    MergeOutcome out;
    std::vector<std::string> beyond;
    size_t beyond_count = 0;
    for (size_t k = 0; k < names.size(); ++k) {
        const int64_t j = index_of(names[k]);
        if (j < 0) continue;
        double value = positions[k];
        const double lo = lower_[j], hi = upper_[j];
        if ((std::isfinite(lo) && value < lo - tolerance_) ||
            (std::isfinite(hi) && value > hi + tolerance_)) {
            if (beyond.size() < MAX_LISTED + 1)
                beyond.push_back("joint " + text::quoted(names[k]) + " at " +
                                 text::general(value, 6) + " outside its limits [" + bound(lo) +
                                 ", " + bound(hi) + "]");
            ++beyond_count;
            if (policy_ == LIMITS_CLAMP) {
                if (std::isfinite(lo)) value = std::max(value, lo);
                if (std::isfinite(hi)) value = std::min(value, hi);
                out.clamped.push_back(j);
            }
        }
        slots_[k] = j;
        values_[k] = value;
    }
    if (beyond_count && policy_ == LIMITS_REJECT)
        return rejected(MergeProblem::OUT_OF_LIMITS,
                        text::listing(beyond, beyond_count, MAX_LISTED, 600, false) +
                            " by more than joint_limit_tolerance " + text::general(tolerance_, 6) +
                            "; fix the publisher (units, joint order, calibration), or set the "
                            "parameter joint_limit_policy to \"clamp\" or \"accept\"");

    for (size_t k = 0; k < names.size(); ++k) {
        const int64_t j = slots_[k];
        if (j >= 0) {
            out.updated.push_back(j);
        } else if (!is_derived(names[k])) {
            out.unknown.emplace_back(names[k]);
        }
    }
    for (const std::string& name : out.unknown) {
        if (unknown_.count(name)) continue;
        if (int64_t(unknown_order_.size()) < max_unknown_) {
            unknown_order_.push_back(name);
            unknown_.insert(unknown_order_.back());
            out.new_unknown.push_back(name);
        } else {
            ++out.unremembered;
        }
    }
    unknown_overflow_ += out.unremembered;
    out.previous.reserve(out.updated.size());
    for (size_t k = 0; k < names.size(); ++k) {
        const int64_t j = slots_[k];
        if (j < 0) continue;
        out.previous.emplace_back(j, heard_[j] ? q_[j] : NaN);
        if (!heard_[j]) {
            heard_[j] = 1;
            ++heard_count_;
        }
        q_[j] = values_[k];
    }
    out.verdict = out.updated.empty() ? MergeVerdict::IGNORED : MergeVerdict::ACCEPTED;
    return out;
}

void JointMerge::undo(const MergeOutcome& outcome) {
    // In reverse: a variable set twice by one message cannot happen (duplicates are rejected),
    // but outcomes undone in turn restore the oldest value last.
    for (auto it = outcome.previous.rbegin(); it != outcome.previous.rend(); ++it) {
        const auto [j, value] = *it;
        if (std::isnan(value)) {
            if (heard_[j]) {
                heard_[j] = 0;
                --heard_count_;
            }
            q_[j] = NaN;
        } else {
            q_[j] = value;
        }
    }
}

void JointMerge::set_default(int64_t j, double value) {
    if (heard_[j]) return;
    heard_[j] = 1;
    ++heard_count_;
    q_[j] = value;
}

void JointMerge::carry_from(const JointMerge& other) {
    for (size_t k = 0; k < other.names_.size(); ++k) {
        if (!other.heard_[k]) continue;
        const int64_t j = index_of(other.names_[k]);
        if (j < 0) continue;
        if (!heard_[j]) ++heard_count_;
        heard_[j] = 1;
        q_[j] = other.q_[k];
    }
}

std::vector<std::string> JointMerge::missing() const {
    std::vector<std::string> out;
    for (size_t j = 0; j < names_.size(); ++j)
        if (!heard_[j]) out.push_back(names_[j]);
    return out;
}

}  // namespace collision_sensor
