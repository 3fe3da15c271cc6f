// The sensor core's answers (sensor_core.hpp): verdicts, the held one, failures by policy,
// staleness and failing sources.
#include <algorithm>

#include "sensor_core.hpp"
#include "sensor_core_detail.hpp"
#include "sensor_text.hpp"

namespace collision_sensor {

using namespace sensor_detail;

// -- answers ------------------------------------------------------------------------------------

void SensorCore::emit(const Answer& answer) {
    writer_.write(answer, &topics_, &messages_);
    for (size_t k = 0; k < topics_.size(); ++k) {
        if (sink_)
            sink_(topics_[k], messages_[k].data(), messages_[k].size());
        else
            outbox_.emplace_back(topics_[k], messages_[k]);
    }
    last_answer_ = answer;
}

void SensorCore::publish_verdict(const cdr::Header& header, const Verdict& verdict,
                                 const Zone* zone) {
    Answer a;
    a.header = header;
    a.contact = verdict.contact;
    a.verdict = verdict;
    held_ = true;
    held_verdict_ = verdict;
    held_stamp_ = header.stamp;
    if (zone) {
        a.zoned = true;
        a.zone = *zone;
        held_zone_ = true;
        held_zone_value_ = *zone;
    }
    emit(a);
    ++verdict_serial_;
}

bool SensorCore::publish_held(const cdr::Header& header) {
    if (!held_) return false;
    Answer a;
    a.header = header;
    a.contact = held_verdict_.contact;
    a.verdict = held_verdict_;
    if (settings_.warning_distance > 0.0 && held_zone_) {
        a.zoned = true;
        a.zone = held_zone_value_;
    }
    emit(a);
    return true;
}

void SensorCore::publish_failure(const cdr::Header& header, const Failure& failure) {
    Answer a;
    a.header = header;
    a.failed = true;
    a.failure = failure;
    const bool hold = failure.policy == POLICY_HOLD;
    if (hold && held_) {
        a.contact = held_verdict_.contact;
        a.verdict = held_verdict_;
    } else {
        a.contact = true;
    }
    if (settings_.warning_distance > 0.0) {
        a.zoned = a.zone_failed = true;
        if (hold && held_zone_) {
            a.zone = held_zone_value_;
        } else {
            a.zone.near = true;
            a.zone.min_distance = -INFINITE;  // not a distance: no comparison says "far"
        }
    }
    emit(a);
    ++totals_["failure_answers"];
}

void SensorCore::fail(const cdr::Header& header, const std::string& error, bool internal) {
    ++totals_["engine_errors"];
    const std::string shown = text::printable(error, 500);
    engine_error_ = shown;
    resync_ = true;
    restart_motion("engine_error");
    const int policy = settings_.on_engine_error;
    note(2, internal ? "internal" : "engine",
         "collision check failed: " + shown +
             "; the state stays the last one checked, answered by on_engine_error " +
             policy_name(policy));
    publish_failure(header, {ENGINE_ERROR, "engine error: " + shown, policy});
}

bool SensorCore::answer_current(cdr::Stamp stamp) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    std::vector<double> q;
    if (current_positions(&q) != 0) return false;
    const cdr::Header header = root_header(stamp);
    Zone zone;
    const bool zoned = settings_.warning_distance > 0.0;
    try {
        const Verdict verdict = check(q, last_accepted_, zoned ? &zone : nullptr);
        if (!failing_.empty())
            publish_failure(header, failing_.front().second);
        else
            publish_verdict(header, verdict, zoned ? &zone : nullptr);
    } catch (const EngineRefused& refused) {
        fail(header, unusable_message(refused.variable, q), false);
    } catch (const EngineError& e) {
        fail(header, e.what(), false);
    } catch (const std::exception& e) {
        fail(header, e.what(), true);
    }
    return true;
}

void SensorCore::answer_failure(cdr::Stamp stamp, const Failure& failure) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    publish_failure(root_header(stamp), failure);
}

void SensorCore::set_failing(const std::string& source, const Failure& failure) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    for (auto& entry : failing_)
        if (entry.first == source) {
            entry.second = failure;
            return;
        }
    failing_.emplace_back(source, failure);
}

void SensorCore::clear_failing(const std::string& source) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    failing_.erase(std::remove_if(failing_.begin(), failing_.end(),
                                  [&](const auto& entry) { return entry.first == source; }),
                   failing_.end());
}

bool SensorCore::stale_due(double now) const {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    return !stale_ && settings_.stale_timeout > 0.0 && accepted_any_ &&
           now - last_accepted_ > settings_.stale_timeout;
}

bool SensorCore::poll_stale(double now, cdr::Stamp stamp) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (!stale_due(now)) return false;
    stale_ = true;
    stale_since_ = last_accepted_;
    ++stale_episodes_;
    const std::string reason = "joint states stale: none accepted for " +
                               fixed1(now - last_accepted_) + " s (stale_timeout " +
                               text::general(settings_.stale_timeout, 6) + " s)";
    note(1, "stale", reason + "; stale episode " + std::to_string(stale_episodes_));
    if (settings_.stale_policy == POLICY_CONTACT)
        publish_failure(root_header(stamp), {STALE, reason, POLICY_CONTACT});
    return true;
}

void SensorCore::resume(double now) {
    stale_ = false;
    note(0, "resumed",
         "joint states resumed after " + fixed1(now - stale_since_) +
             " s without (stale episode " + std::to_string(stale_episodes_) + ")");
}

}  // namespace collision_sensor
