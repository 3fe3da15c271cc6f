// Answers and their messages (sensor_answer.hpp).
#include "sensor_answer.hpp"

#include <cmath>
#include <cstdio>

#include "sensor_text.hpp"

namespace collision_sensor {

namespace {

std::string pair_name(const std::pair<std::string, std::string>& p) {
    return p.first + ":" + p.second;
}

std::string fixed4(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.4f", value);
    return buffer;
}

std::string xyz(const double* p) {
    return text::general(p[0], 9) + " " + text::general(p[1], 9) + " " + text::general(p[2], 9);
}

}  // namespace

const char* policy_name(int policy) { return policy == POLICY_HOLD ? "hold" : "contact"; }

void AnswerWriter::set_names(AnswerNames names) {
    names_ = std::move(names);
    cached_ = false;
}

cdr::Status AnswerWriter::failure_status(const Failure& f) const {
    std::string reason = f.reason;
    if (reason.size() > MAX_REASON_CHARS) reason = reason.substr(0, MAX_REASON_CHARS - 3) + "...";
    cdr::Status s;
    s.level = cdr::LEVEL_ERROR;
    s.name = f.kind;
    s.message = reason;
    s.hardware_id = names_.root_frame;
    s.values = {{"kind", f.kind}, {"reason", reason}, {"policy", policy_name(f.policy)}};
    return s;
}

std::vector<cdr::Status> AnswerWriter::pair_statuses(const Answer& a) const {
    std::vector<cdr::Status> out;
    if (a.failed) out.push_back(failure_status(a.failure));
    const Verdict& v = a.verdict;
    for (const int64_t p : v.now) {
        const auto& [first, second] = names_.pairs[p];
        cdr::Status s;
        s.level = cdr::LEVEL_ERROR;
        s.name = pair_name(names_.pairs[p]);
        s.message = first + " collides with " + second;
        s.hardware_id = names_.root_frame;
        s.values = {{"link_a", first}, {"link_b", second}};
        out.push_back(std::move(s));
    }
    if (!v.met.empty()) {
        const std::string at = text::general(v.first_contact, 6);
        for (const int64_t p : v.met) {
            const auto& [first, second] = names_.pairs[p];
            cdr::Status s;
            s.level = cdr::LEVEL_ERROR;
            s.name = pair_name(names_.pairs[p]);
            s.message = first + " met " + second + " on the way, at " + at + " of the motion";
            s.hardware_id = names_.root_frame;
            s.values = {{"link_a", first}, {"link_b", second}, {"first_contact", at}};
            out.push_back(std::move(s));
        }
    }
    return out;
}

std::vector<cdr::Status> AnswerWriter::zone_statuses(const Answer& a) const {
    std::vector<cdr::Status> out;
    if (a.zone_failed) out.push_back(failure_status(a.failure));
    for (const ZoneRecord& r : a.zone.records) {
        const auto& [first, second] = names_.pairs[r.pair];
        const double d = r.distance;
        cdr::Status s;
        s.level = d <= 0.0 ? cdr::LEVEL_ERROR : cdr::LEVEL_WARN;
        s.name = pair_name(names_.pairs[r.pair]);
        s.message = d <= 0.0 ? first + " is in contact with " + second + " (" + fixed4(d) + " m)"
                             : first + " is " + fixed4(d) + " m from " + second;
        s.hardware_id = names_.root_frame;
        s.values = {{"link_a", first},
                    {"link_b", second},
                    {"distance", text::repr(d)},
                    {"point_a", xyz(r.point_a)},
                    {"point_b", xyz(r.point_b)}};
        out.push_back(std::move(s));
    }
    return out;
}

void AnswerWriter::write(const Answer& a, std::vector<int>* topics,
                         std::vector<std::vector<uint8_t>>* messages) {
    topics->clear();
    const size_t count = a.zoned ? N_TOPICS : 2;
    messages->resize(count);
    if (contact_[0].empty()) {
        cdr::write_bool(false, &contact_[0]);
        cdr::write_bool(true, &contact_[1]);
    }
    topics->push_back(TOPIC_CONTACT);
    (*messages)[0] = contact_[a.contact ? 1 : 0];
    topics->push_back(TOPIC_COLLIDING_PAIRS);
    if (a.failed) {
        cdr::write_diagnostic_array(a.header, pair_statuses(a), &(*messages)[1]);
    } else {
        // A verdict: the same pairs as the last one need only their stamp written.
        if (!cached_ || !(a.verdict == cached_verdict_) || a.header.frame_id != cached_frame_) {
            cdr::write_diagnostic_array(a.header, pair_statuses(a), &cached_pairs_);
            cached_verdict_ = a.verdict;
            cached_frame_ = a.header.frame_id;
            cached_ = true;
        } else {
            cdr::write_stamp(&cached_pairs_, a.header.stamp);
        }
        (*messages)[1] = cached_pairs_;
    }
    if (!a.zoned) return;
    topics->push_back(TOPIC_NEAR);
    (*messages)[2] = contact_[a.zone.near ? 1 : 0];
    topics->push_back(TOPIC_MIN_DISTANCE);
    cdr::write_float64(a.zone.min_distance, &(*messages)[3]);
    topics->push_back(TOPIC_NEAR_PAIRS);
    cdr::write_diagnostic_array(a.header, zone_statuses(a), &(*messages)[4]);
}

}  // namespace collision_sensor
