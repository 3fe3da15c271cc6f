// The sensor core's state (sensor_core.hpp): its window of recent states, the state to check
// or start a trajectory from, its counters, log lines and outbox.
#include <algorithm>
#include <cmath>

#include "engine.hpp"
#include "motion.hpp"
#include "sensor_core.hpp"
#include "sensor_core_detail.hpp"
#include "sensor_text.hpp"

namespace collision_sensor {

using namespace sensor_detail;

void SensorCore::set_sink(Sink sink) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    sink_ = std::move(sink);
}

std::vector<std::pair<int, std::vector<uint8_t>>> SensorCore::take_outbox() {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    std::vector<std::pair<int, std::vector<uint8_t>>> out;
    out.swap(outbox_);
    return out;
}

std::vector<Note> SensorCore::take_notes() {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    std::vector<Note> out(notes_.begin(), notes_.end());
    notes_.clear();
    if (notes_dropped_) {
        out.push_back({1, "notes_dropped",
                       std::to_string(notes_dropped_) +
                           " log lines dropped: more came than the node writes (bad input "
                           "flooding joint_states?); /diagnostics counts every input"});
        notes_dropped_ = 0;
    }
    return out;
}

void SensorCore::note(int level, std::string kind, std::string line) {
    if (notes_.size() >= MAX_NOTES) {
        ++notes_dropped_;
        return;
    }
    notes_.push_back({level, std::move(kind), std::move(line)});
}

int SensorCore::positions_at(double stamp, std::vector<double>* q) const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (window_.empty()) return current_positions(q) == 0 ? 0 : 2;
    if (stamp < window_.front().stamp) return 1;
    if (stamp >= window_.back().stamp) {
        *q = window_.back().q;
        return 0;
    }
    // window_[k - 1].stamp <= stamp < window_[k].stamp
    const auto after = std::upper_bound(
        window_.begin(), window_.end(), stamp,
        [](double s, const WindowState& w) { return s < w.stamp; });
    const WindowState& b = *after;
    const WindowState& a = *(after - 1);
    const double s = (stamp - a.stamp) / (b.stamp - a.stamp);
    const int64_t J = int64_t(a.q.size());
    std::vector<double> delta(J), var(J), quat0(J);
    StraightPath path{a.q.data(), model_.motion_kinds.data(), J, delta.data(), var.data(),
                      quat0.data()};
    path.prepare(b.q.data());
    q->resize(J);
    path.at(s, q->data());
    return 0;
}

double SensorCore::window_oldest() const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    return window_.empty() ? std::nan("") : window_.front().stamp;
}

double SensorCore::window_newest() const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    return window_.empty() ? std::nan("") : window_.back().stamp;
}

int SensorCore::current_positions(std::vector<double>* q) const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (!merge_ || !accepted_any_) return 1;
    if (merge_->complete()) {
        *q = merge_->positions();
        return 0;
    }
    if (settings_.require_all_joints) return 1;
    *q = filled(merge_->positions());
    return 0;
}

std::string SensorCore::start_state(double now, std::vector<double>* q) const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (!merge_ || !accepted_any_)
        return "no joint state accepted yet: where the robot starts is unknown";
    const double timeout = settings_.stale_timeout;
    if (timeout > 0.0 && now - last_accepted_ > timeout)
        return "joint states stale: none accepted for " + fixed1(now - last_accepted_) +
               " s (stale_timeout " + text::general(timeout, 6) +
               " s): where the robot starts is unknown";
    if (settings_.require_all_joints && !merge_->complete()) {
        const std::vector<std::string> missing = merge_->missing();
        return "waiting for joints " + text::listing(missing, missing.size(), 20) +
               " (require_all_joints): where the robot starts is unknown";
    }
    std::lock_guard<std::mutex> engine_hold(model_.engine->lock());
    const double* engine_q = model_.engine->view().state.q_last;
    const std::vector<double>& merged = merge_->positions();
    q->resize(merged.size());
    for (size_t j = 0; j < merged.size(); ++j)
        (*q)[j] = merge_->heard(j) ? merged[j] : engine_q[j];
    return "";
}

std::vector<double> SensorCore::merged_positions() const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    return merge_ ? merge_->positions() : std::vector<double>();
}

SensorSnapshot SensorCore::snapshot(double now, bool reset_period) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    SensorSnapshot s;
    s.totals = totals_;
    s.period_received = period_received_;
    s.period_rejected = period_rejected_;
    s.period_checks = period_checks_;
    s.period_check_time_sum = period_time_sum_;
    s.period_check_time_max = period_time_max_;
    if (reset_period) {
        period_received_ = period_rejected_ = period_checks_ = 0;
        period_time_sum_ = period_time_max_ = 0.0;
    }
    s.has_model = merge_ != nullptr;
    if (merge_) {
        s.missing = merge_->missing();
        s.unknown = merge_->unknown_names();
        s.unknown_overflow = merge_->unknown_overflow();
    }
    for (const auto& [name, entry] : out_of_limits_) {
        const auto& [value, lo, hi] = entry;
        s.out_of_limits.emplace_back(name, value, lo, hi);
    }
    s.accepted_any = accepted_any_;
    s.seconds_since_accepted = accepted_any_ ? now - last_accepted_ : 0.0;
    s.held = held_;
    s.held_contact = held_ && held_verdict_.contact;
    if (held_) {
        s.held_now = held_verdict_.now;
        s.held_met = held_verdict_.met;
    }
    s.stale = stale_;
    s.stale_episodes = stale_episodes_;
    s.engine_error = engine_error_;
    if (!settings_.check_motion)
        s.motion_state = "off";
    else if (has_last_)
        s.motion_state = "sweeping";
    else
        s.motion_state = "new_motion: " + (motion_reason_.empty() ? std::string("first_state")
                                                                  : motion_reason_);
    s.motion_counts = motion_counts_;
    for (const auto& entry : failing_) s.failing.push_back(entry.first);
    return s;
}

}  // namespace collision_sensor
