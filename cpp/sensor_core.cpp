// The sensor core (sensor_core.hpp): the model, joint states merged and checked. Its answers
// and failures: sensor_answers.cpp; its window, state and counters: sensor_state.cpp.
#include "sensor_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "engine.hpp"
#include "proximity.hpp"
#include "sensor_core_detail.hpp"
#include "sensor_text.hpp"

namespace collision_sensor {

using namespace sensor_detail;

namespace {

std::string upper(std::string s) {
    for (char& c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

// The wall clock (ROS time without simulated time), s: a zero stamp's time.
double wall_seconds() {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
        .count();
}

double stamp_seconds(const cdr::Stamp& stamp) {
    return stamp.zero() ? wall_seconds() : stamp.seconds();
}

}  // namespace

SensorCore::SensorCore(const SensorSettings& settings) : settings_(settings) {}

// -- the model ----------------------------------------------------------------------------------

void SensorCore::use_model(SensorModel model) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    const size_t J = model.joint_names.size();
    if (model.engine == nullptr || model.lower.size() != J || model.upper.size() != J ||
        model.motion_kinds.size() != J ||
        model.swapped.size() != model.names.pairs.size())
        throw std::invalid_argument("use_model: an engine, and limits and kinds per variable");
    auto merge = std::make_unique<JointMerge>(model.joint_names, model.derived, model.lower,
                                              model.upper, settings_.limit_policy,
                                              settings_.limit_tolerance, settings_.max_unknown);
    if (merge_) merge->carry_from(*merge_);
    for (const auto& [j, value] : model.defaults) merge->set_default(j, value);
    const bool same_joints = has_last_ && model.joint_names == model_.joint_names;
    const bool first = model_.engine == nullptr;
    std::vector<double> last = last_;
    merge_ = std::move(merge);
    model_ = std::move(model);
    writer_.set_names(model_.names);
    out_of_limits_.clear();
    for (size_t j = 0; j < J; ++j) {
        if (!merge_->heard(j)) continue;
        const double v = merge_->positions()[j], lo = model_.lower[j], hi = model_.upper[j];
        if ((std::isfinite(lo) && v < lo) || (std::isfinite(hi) && v > hi))
            out_of_limits_[model_.joint_names[j]] = {v, lo, hi};
    }
    window_.clear();
    unchecked_.clear();
    announced_waiting_ = false;
    restart_motion(first ? "first_state" : "new_checker");
    if (same_joints) {
        last_ = std::move(last);
        has_last_ = true;
    }
    held_ = held_zone_ = false;
    configure(settings_);  // the spans and the ignored pairs, for this model
}

void SensorCore::set_engine(Engine* engine, AnswerNames names, std::vector<uint8_t> swapped) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (engine == nullptr || swapped.size() != names.pairs.size())
        throw std::invalid_argument("set_engine: an engine, and swapped per pair");
    // The held verdict names its pairs by their index: carry it over by name.
    std::map<std::pair<std::string, std::string>, int64_t> index;
    for (size_t p = 0; p < names.pairs.size(); ++p) index[names.pairs[p]] = int64_t(p);
    const auto remap = [&](std::vector<int64_t>* pairs) {
        std::vector<int64_t> out;
        for (const int64_t p : *pairs) {
            const auto found = index.find(model_.names.pairs[p]);
            if (found != index.end()) out.push_back(found->second);
        }
        std::sort(out.begin(), out.end());
        *pairs = std::move(out);
    };
    remap(&held_verdict_.now);
    remap(&held_verdict_.met);
    std::vector<ZoneRecord> records;
    for (ZoneRecord r : held_zone_value_.records) {
        const auto found = index.find(model_.names.pairs[r.pair]);
        if (found == index.end()) continue;
        r.pair = found->second;
        records.push_back(r);
    }
    held_zone_value_.records = std::move(records);
    model_.engine = engine;
    model_.names = std::move(names);
    model_.swapped = std::move(swapped);
    writer_.set_names(model_.names);
    configure(settings_);
}

void SensorCore::configure(const SensorSettings& settings) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (settings.warning_distance != settings_.warning_distance ||
        settings.warning_ignore != settings_.warning_ignore)
        held_zone_ = false;
    settings_ = settings;
    if (merge_) merge_->set_policy(settings.limit_policy);
    const size_t J = model_.joint_names.size();
    spans_.assign(J, INFINITE);
    for (size_t j = 0; j < J; ++j) {
        const double span = model_.upper[j] - model_.lower[j] + 2.0 * settings.limit_tolerance;
        if (std::isfinite(span)) spans_[j] = span;
    }
    step_.motion.pairs.assign(model_.names.pairs.size(), 0);
}

void SensorCore::restart_motion(const char* reason) {
    motion_reason_ = reason;
    has_last_ = carried_ = false;
}

cdr::Header SensorCore::root_header(cdr::Stamp stamp) const {
    cdr::Header h;
    h.stamp = stamp;
    h.frame_id = model_.names.root_frame;
    return h;
}

// -- joint states -------------------------------------------------------------------------------

void SensorCore::take(const uint8_t* data, size_t size, bool answer, double now) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    ++period_received_;
    ++totals_["received"];
    if (!merge_) {
        ++totals_["no_model"];
        if (answer)
            publish_failure(cdr::read_header(data, size),
                            {WAITING, "no robot model yet: nothing can be checked",
                             settings_.on_rejected_input});
        return;
    }
    if (int64_t(size) > settings_.max_joint_state_bytes) {
        reject("oversized", cdr::read_header(data, size),
               std::to_string(size) + " bytes, above max_joint_state_bytes (" +
                   std::to_string(settings_.max_joint_state_bytes) +
                   "); raise the parameter if the robot's joint states are really that large",
               answer, "OVERSIZED", "joint state rejected before decoding, state unchanged: ");
        return;
    }
    const std::string error = cdr::read_joint_state(data, size, &scratch_message_);
    if (!error.empty()) {
        reject("malformed", cdr::read_header(data, size),
               "not a sensor_msgs/JointState: " + error, answer, "MALFORMED");
        return;
    }
    take_locked(scratch_message_, answer, now);
}

void SensorCore::take_view(const cdr::JointStateView& message, bool answer, double now) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    ++period_received_;
    ++totals_["received"];
    if (!merge_) {
        ++totals_["no_model"];
        if (answer)
            publish_failure(message.header, {WAITING, "no robot model yet: nothing can be checked",
                                             settings_.on_rejected_input});
        return;
    }
    take_locked(message, answer, now);
}

void SensorCore::take_batch(const std::vector<std::pair<const uint8_t*, size_t>>& batch,
                            bool newest_only, double now) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    for (size_t k = 0; k < batch.size(); ++k) {
        const bool last = k + 1 == batch.size();
        try {
            take(batch[k].first, batch[k].second, !newest_only || last, now);
            if (last && !unchecked_.empty()) {
                // The newest message was not accepted: answer the newest that was.
                --totals_["superseded"];
                Unchecked newest = std::move(unchecked_.back());
                unchecked_.pop_back();
                check_and_answer(newest.header, newest.outcome);
            }
        } catch (const std::exception& e) {
            // One message must never stop the sensor: answered as an internal error.
            fail(cdr::read_header(batch[k].first, batch[k].second), e.what(), true);
        }
    }
}

void SensorCore::take_locked(const cdr::JointStateView& message, bool answer, double now) {
    const cdr::Header& header = message.header;
    MergeOutcome outcome = merge_->merge(message.names, message.positions);
    if (outcome.verdict == MergeVerdict::REJECTED) {
        const std::string problem = problem_name(outcome.problem);
        reject(problem.c_str(), header, outcome.reason, answer, upper(problem));
        return;
    }
    if (!outcome.new_unknown.empty() || outcome.unremembered) {
        note(1, "unknown",
             "ignoring " + std::to_string(outcome.unknown.size()) +
                 " joint name(s) in joint_states that the robot model does not move: " +
                 text::listing(outcome.unknown, outcome.unknown.size(), 5, 300) + "; " +
                 std::to_string(merge_->unknown_names().size()) +
                 " distinct unknown names remembered (at most " +
                 std::to_string(merge_->max_unknown()) + "), " +
                 std::to_string(merge_->unknown_overflow()) +
                 " not remembered; /diagnostics lists them");
    }
    if (!outcome.clamped.empty()) {
        ++totals_["clamped"];
        std::vector<std::string> clamped;
        for (const int64_t j : outcome.clamped) clamped.push_back(model_.joint_names[j]);
        note(1, "clamped",
             "joints beyond their limits clamped to them (joint_limit_policy clamp): " +
                 text::listing(clamped, clamped.size(), 5));
    }
    if (!outcome.accepted()) {
        ++totals_["ignored"];
        if (answer && unchecked_.empty() && !publish_held(header)) answer_waiting(header);
        return;
    }
    ++totals_["accepted"];
    last_accepted_ = now;
    accepted_any_ = true;
    if (stale_) resume(now);
    update_limits(outcome);
    if (settings_.require_all_joints && !merge_->complete()) {
        ++totals_["waiting_for_joints"];
        if (!announced_waiting_) {
            announced_waiting_ = true;
            note(0, "", "waiting for joints " +
                            text::listing(merge_->missing(), merge_->missing().size(), 20) +
                            " before the first verdict (require_all_joints)");
        }
        if (answer && unchecked_.empty()) answer_waiting(header);
        return;
    }
    if (merge_->complete()) record_window(stamp_seconds(header.stamp), merge_->positions());
    if (!answer) {
        // Overloaded: a newer state waits; this one is merged but not checked.
        unchecked_.push_back({header, std::move(outcome)});
        ++totals_["superseded"];
        return;
    }
    check_and_answer(header, outcome);
}

void SensorCore::reject(const char* problem, const cdr::Header& header, const std::string& reason,
                        bool answer, const std::string& kind, const char* prefix) {
    ++period_rejected_;
    ++totals_["rejected"];
    ++totals_[std::string("rejected_") + problem];
    note(1, kind, prefix + reason);
    if (answer && unchecked_.empty())
        publish_failure(header, {REJECTED, "joint state rejected: " + reason,
                                 settings_.on_rejected_input});
}

void SensorCore::answer_waiting(const cdr::Header& header) {
    const std::vector<std::string> missing = merge_->missing();
    const std::string reason =
        !missing.empty() && settings_.require_all_joints
            ? "waiting for joints " + text::listing(missing, missing.size(), 20) +
                  " before the first verdict (require_all_joints)"
            : "no joint state has named a joint of the robot yet";
    publish_failure(header, {WAITING, reason, settings_.on_rejected_input});
}

void SensorCore::update_limits(const MergeOutcome& outcome) {
    const std::vector<double>& q = merge_->positions();
    for (const int64_t j : outcome.updated) {
        const std::string& name = model_.joint_names[j];
        out_of_limits_.erase(name);
        const double v = q[j], lo = model_.lower[j], hi = model_.upper[j];
        if ((std::isfinite(lo) && v < lo) || (std::isfinite(hi) && v > hi)) {
            out_of_limits_[name] = {v, lo, hi};
            note(1, "limits",
                 "joint " + text::quoted(name) + " at " + text::general(v, 6) +
                     " is outside its limits [" + bound(lo) + ", " + bound(hi) +
                     "]; checked as given (joint_limit_policy " +
                     limit_policy_name(settings_.limit_policy) + ")");
        }
    }
}

void SensorCore::record_window(double stamp, const std::vector<double>& q) {
    if (!window_.empty() && stamp < window_.back().stamp) {
        window_.clear();  // time went back (a bag restarted, simulated time reset)
    } else if (!window_.empty() && stamp == window_.back().stamp) {
        window_.back().q = q;
        return;
    }
    window_.push_back({stamp, q});
    const double horizon = stamp - settings_.state_window;
    // Keep one state at or before the horizon, so that a stamp there can still be placed.
    while (window_.size() > WINDOW_CAPACITY ||
           (window_.size() > 1 && window_[1].stamp <= horizon))
        window_.pop_front();
}

std::vector<double> SensorCore::filled(const std::vector<double>& q) const {
    std::vector<double> out = q;
    std::lock_guard<std::mutex> hold(model_.engine->lock());
    const double* base = has_last_ ? last_.data() : model_.engine->view().state.q_last;
    for (size_t j = 0; j < out.size(); ++j)
        if (!merge_->heard(j)) out[j] = base[j];
    return out;
}

void SensorCore::check_and_answer(const cdr::Header& header, const MergeOutcome& outcome) {
    const std::vector<double> q =
        merge_->complete() ? merge_->positions() : filled(merge_->positions());
    const auto undo_all = [&] {
        merge_->undo(outcome);
        for (auto it = unchecked_.rbegin(); it != unchecked_.rend(); ++it) merge_->undo(it->outcome);
        const int64_t undone = 1 + int64_t(unchecked_.size());
        totals_["superseded"] -= int64_t(unchecked_.size());
        unchecked_.clear();
        return undone;
    };
    Zone zone;
    Verdict verdict;
    try {
        verdict = check(q, last_accepted_, settings_.warning_distance > 0.0 ? &zone : nullptr);
    } catch (const EngineRefused& refused) {
        // The engine refuses a value it cannot honour (a slider beyond its range, a zero
        // quaternion): the message is rejected after all, with the superseded states merged
        // since (counted as rejected instead).
        const int64_t undone = undo_all();
        period_rejected_ += undone - 1;
        totals_["rejected"] += undone - 1;
        totals_["rejected_engine_range"] += undone - 1;
        reject("engine_range", header, text::printable(unusable_message(refused.variable, q), 500),
               true, "ENGINE_RANGE");
        return;
    } catch (const EngineError& e) {
        undo_all();
        fail(header, e.what(), false);
        return;
    } catch (const std::exception& e) {
        undo_all();
        fail(header, e.what(), true);
        return;
    }
    unchecked_.clear();
    ++totals_["verdicts"];
    if (!failing_.empty()) {
        publish_failure(header, failing_.front().second);
        return;
    }
    publish_verdict(header, verdict, settings_.warning_distance > 0.0 ? &zone : nullptr);
}

void SensorCore::inject_fault(InjectedFault fault) {
    std::lock_guard<std::recursive_mutex> hold(mutex_);
    if (fault.variable < 0)
        faults_.clear();
    else
        faults_.push_back(std::move(fault));
}

Verdict SensorCore::check(const std::vector<double>& q, double accepted_at, Zone* zone) {
    for (const InjectedFault& fault : faults_) {
        if (fault.variable >= int64_t(q.size()) || q[fault.variable] != fault.value) continue;
        if (fault.corrupt) {
            std::lock_guard<std::mutex> hold(model_.engine->lock());
            int64_t* status = model_.engine->view().state.status;
            std::fill(status, status + model_.names.pairs.size(), int64_t(1));
        }
        if (fault.internal) throw std::runtime_error(fault.message);
        throw EngineError(fault.message);
    }
    const auto started = std::chrono::steady_clock::now();
    const bool motion = settings_.check_motion, from_scratch = resync_;
    std::string reason;
    if (motion && from_scratch) {
        reason = motion_reason_.empty() ? "engine_error" : motion_reason_;
    } else if (motion) {
        const double timeout = settings_.stale_timeout;
        if (!has_last_) {
            reason = motion_reason_.empty() ? "first_state" : motion_reason_;
        } else if (timeout > 0.0 && accepted_at - last_accepted_at_ > timeout) {
            reason = "stale_gap";
        } else {
            for (size_t j = 0; j < q.size(); ++j)
                if (std::fabs(q[j] - last_[j]) > spans_[j]) {
                    reason = "jump";
                    break;
                }
        }
    }
    Engine& engine = *model_.engine;
    bool hit = false;
    double t = 0.0;
    Verdict v;
    {
        std::lock_guard<std::mutex> hold(engine.lock());
        if (!motion || from_scratch || !reason.empty()) {
            const QueryResult query = engine.query(q.data(), from_scratch);
            if (query.refused()) throw EngineRefused{query.bad_variable};
        } else if (carried_) {
            engine.update_motion(q.data(), step_);
            if (step_.query.refused()) throw EngineRefused{step_.query.bad_variable};
            hit = step_.motion.contact;
            t = step_.motion.t;
        } else {  // a new model with the same joints: from the state the one before checked
            engine.motion(last_.data(), q.data(), step_.motion);
            if (step_.motion.refused()) throw EngineRefused{step_.motion.bad.variable};
            hit = step_.motion.contact;
            t = step_.motion.t;
            const QueryResult query = engine.query(q.data(), false);
            if (query.refused()) throw EngineRefused{query.bad_variable};
        }
        const int64_t* status = engine.view().state.status;
        const int64_t P = int64_t(model_.names.pairs.size());
        for (int64_t p = 0; p < P; ++p)
            if (status[p]) v.now.push_back(p);
        if (hit)
            for (int64_t p = 0; p < P; ++p)
                if (step_.motion.pairs[p] && !status[p]) v.met.push_back(p);
        if (zone) measure_zone(q, zone);
    }
    if (motion) ++motion_counts_[reason.empty() ? "swept" : reason];
    motion_reason_.clear();
    carried_ = has_last_ = true;
    last_accepted_at_ = accepted_at;
    last_ = q;
    v.contact = hit || !v.now.empty();
    if (hit) {
        v.first_contact = t;
        if (!v.met.empty() && v.now.empty()) ++motion_counts_["met_on_the_way"];
    }
    if (resync_) {
        resync_ = false;
        engine_error_.clear();
    }
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    ++period_checks_;
    period_time_sum_ += elapsed;
    period_time_max_ = std::max(period_time_max_, elapsed);
    return v;
}

void SensorCore::measure_zone(const std::vector<double>& q, Zone* zone) {
    Engine& engine = *model_.engine;
    const int64_t P = int64_t(model_.names.pairs.size());
    std::vector<double> distance(P), points(6 * P);
    const ProximityRequest request = {settings_.warning_distance};
    const ProximityResult result = {distance.data(), points.data()};
    const QueryResult query = engine.proximity(q.data(), request, result);
    if (query.refused()) throw EngineRefused{query.bad_variable};
    zone->records.clear();
    for (int64_t p = 0; p < P; ++p) {
        if (!std::isfinite(distance[p])) continue;
        const auto& names = model_.names.pairs[p];
        if (settings_.warning_ignore.count(names)) continue;
        ZoneRecord r;
        r.pair = p;
        r.distance = distance[p];
        const double* row = points.data() + 6 * p;
        const bool swap = model_.swapped[p] != 0;  // the engine keeps a scene object second
        for (int k = 0; k < 3; ++k) {
            r.point_a[k] = swap ? row[3 + k] : row[k];
            r.point_b[k] = swap ? row[k] : row[3 + k];
        }
        zone->records.push_back(r);
    }
    const auto& pairs = model_.names.pairs;
    std::sort(zone->records.begin(), zone->records.end(),
              [&](const ZoneRecord& a, const ZoneRecord& b) {
                  if (a.distance != b.distance) return a.distance < b.distance;
                  return pairs[a.pair] < pairs[b.pair];
              });
    zone->near = !zone->records.empty();
    zone->min_distance = zone->near ? zone->records.front().distance : INFINITE;
}

std::string SensorCore::unusable_message(int64_t j, const std::vector<double>& q) const {
    const std::string& name = model_.joint_names[j];
    const double value = q[j];
    const std::string rot = "/rot_x";
    if (std::isfinite(value) && name.size() > rot.size() &&
        name.compare(name.size() - rot.size(), rot.size(), rot) == 0 && j + 3 < int64_t(q.size())) {
        const std::string joint = name.substr(0, name.size() - rot.size());
        std::string values;
        for (int k = 0; k < 4; ++k)
            values += (k ? ", " : "") + text::general(q[j + k], 6);
        return "floating joint \"" + joint + "\": quaternion (rot_x, rot_y, rot_z, rot_w) = (" +
               values + ") is zero (norm below " + text::general(QUATERNION_NORM_MIN, 6) +
               "); send a unit quaternion, (0, 0, 0, 1) for no rotation (nothing was changed)";
    }
    const std::string why =
        std::isfinite(value)
            ? "moves a joint out of the engine's range (a prismatic joint, or a planar or "
              "floating joint's translation, by more than " +
                  text::general(PRISMATIC_VALUE_MAX, 6) +
                  " m, or a value that overflows); send a value within the joint's limits"
            : std::string("is not finite; send a finite value");
    return "joint \"" + name + "\": position " + text::repr(value) + " " + why +
           " (nothing was changed)";
}

}  // namespace collision_sensor
