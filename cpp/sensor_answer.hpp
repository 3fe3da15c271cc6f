// What the sensor answers to one input, and that answer as the messages the node publishes.
//
// An answer is, in order: contact (std_msgs/Bool), colliding_pairs
// (diagnostic_msgs/DiagnosticArray, the input's header), and with the warning zone on, near
// (std_msgs/Bool), min_distance (std_msgs/Float64) and near_pairs (DiagnosticArray).
//
// colliding_pairs holds, for a verdict: one status per pair in contact at the state (level
// ERROR, name "a:b" with a < b as the checker names its pairs, message "a collides with b",
// values link_a, link_b), then one per pair met on the way and not in contact at the state
// (message "a met b on the way, at 0.42 of the motion", values link_a, link_b, first_contact);
// for an input the sensor cannot check, a failure status first (name: the failure's kind,
// message and value reason: why, values kind, reason, policy), then, with policy hold, the
// held verdict's pairs.
//
// near_pairs: one status per pair nearer than warning_distance, nearest first (level ERROR in
// contact, else WARN; name "a:b"; message "a is 0.0123 m from b" or "a is in contact with b
// (-0.0010 m)"; values link_a, link_b, distance (Python's repr of the float), point_a, point_b
// (the nearest points, "x y z" in the root link's frame)). After a failure: with policy contact
// near true, min_distance -inf and the failure status alone; with hold the held values, the
// failure status first.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "cdr.hpp"

namespace collision_sensor {

// The topics of an answer, in the order they are published.
constexpr int TOPIC_CONTACT = 0, TOPIC_COLLIDING_PAIRS = 1, TOPIC_NEAR = 2,
              TOPIC_MIN_DISTANCE = 3, TOPIC_NEAR_PAIRS = 4, N_TOPICS = 5;
// The fail-safe policies (on_rejected_input, on_engine_error, stale_policy).
constexpr int POLICY_CONTACT = 0, POLICY_HOLD = 1;
const char* policy_name(int policy);

// Longest reason in a failure status (characters).
constexpr size_t MAX_REASON_CHARS = 1000;

// A checked state's verdict (also what the sensor holds for policy hold).
struct Verdict {
    bool contact = false;       // at the state, or on the way to it
    std::vector<int64_t> now;   // the pairs in contact at the state, in the checker's order
    std::vector<int64_t> met;   // the pairs met on the way and not in contact now
    double first_contact = 0.0; // the fraction of the motion at the first contact (met only)
    bool operator==(const Verdict& o) const {
        return contact == o.contact && now == o.now && met == o.met &&
               (met.empty() || first_contact == o.first_contact);
    }
};

// A pair nearer than warning_distance: its padded distance and nearest points (world frame;
// point_a on the pair's first name).
struct ZoneRecord {
    int64_t pair = 0;
    double distance = 0.0;
    double point_a[3] = {0, 0, 0}, point_b[3] = {0, 0, 0};
};

struct Zone {
    bool near = false;
    double min_distance = 0.0;
    std::vector<ZoneRecord> records;  // nearest first
};

struct Failure {
    std::string kind, reason;
    int policy = POLICY_CONTACT;
};

struct Answer {
    cdr::Header header;
    bool contact = false;
    bool failed = false;
    Failure failure;  // when failed
    Verdict verdict;  // the pairs listed (a failure's: the held verdict's with hold, else none)
    bool zoned = false;
    Zone zone;        // when zoned; a failure's: see the top of this file
    bool zone_failed = false;  // the zone's failure status comes first (policy contact or hold)
};

// The names answers are written with: each checked pair's two names (a < b), the root frame.
struct AnswerNames {
    std::vector<std::pair<std::string, std::string>> pairs;
    std::string root_frame;
};

// Serializes answers; keeps the last colliding_pairs message and rewrites only its stamp while
// the pairs, the motion and the frame stay the same (the usual case: nothing changed).
class AnswerWriter {
   public:
    void set_names(AnswerNames names);
    const AnswerNames& names() const { return names_; }
    // The messages of answer a, in topic order: topics[k] is published as messages[k].
    void write(const Answer& a, std::vector<int>* topics,
               std::vector<std::vector<uint8_t>>* messages);
    // The statuses (for tests, and the Python side's structured answers).
    std::vector<cdr::Status> pair_statuses(const Answer& a) const;
    std::vector<cdr::Status> zone_statuses(const Answer& a) const;

   private:
    cdr::Status failure_status(const Failure& f) const;

    AnswerNames names_;
    std::vector<uint8_t> contact_[2];
    bool cached_ = false;
    Verdict cached_verdict_;
    std::string cached_frame_;
    std::vector<uint8_t> cached_pairs_;
};

}  // namespace collision_sensor
