// The sensor core: joint states in, answers out, with no ROS library and no Python on the way.
//
// One object per node (collision_sensor/sensor/ wraps it for Python; the node's compiled
// joint-state hop calls it straight from the middleware's thread). It owns what a joint state
// is answered from:
//
// - the merge of partial joint states (joint_merge.hpp) and what each message's answer is:
//   accepted and the state complete: the verdict of the merged state; rejected (malformed,
//   beyond its limits, above max_joint_state_bytes, refused by the engine): a
//   joint_state_rejected failure by on_rejected_input, the state unchanged; accepted while
//   joints are still missing (require_all_joints), or ignored before any state was checked:
//   a waiting_for_joints failure by on_rejected_input; ignored once a state was checked (no
//   positions, no joint of the robot named): the held verdict again; the engine fails: an
//   engine_error failure by on_engine_error, the merge undone and the next state checked from
//   scratch;
// - the motion stream (check_motion): each verdict covers the straight motion from the state
//   checked last, except for a new motion, checked as an instant and counted by reason:
//   first_state, stale_gap (more than stale_timeout since the state accepted before),
//   engine_error, new_checker (a new model whose joints are not the old one's), jump (a
//   variable moved farther than its joint's range widened by joint_limit_tolerance at both
//   ends: joint_limit_policy accept lets such values in). A new model with the same joints
//   sweeps its first state from the last state checked (Engine::motion, then a query); a
//   scene change keeps the motion's start;
// - the fail-safe policies: contact answers true with the failure alone; hold repeats the
//   held verdict (the last one published) after the failure, or answers as contact when none
//   is held;
// - staleness (no accepted joint state for stale_timeout after the first: poll()), failing
//   sources (set_failing: every verdict answered with their failure until cleared);
// - the warning zone (warning_distance > 0): the pairs nearer than it, measured at the state
//   (measure_proximity), without warning_ignore's pairs;
// - the recent complete states by stamp (positions_at: a cloud is placed with the robot's pose
//   at its stamp), counters, and log lines (notes) for the caller to write.
//
// Every method takes the core's mutex; the Engine is called with its own lock taken after it
// (never the other way round). Its implementation: sensor_core.cpp (the model, joint states
// merged and checked), sensor_answers.cpp (answers, failures, staleness), sensor_state.cpp (the
// window, the state, counters and log lines). Answers go to the sink (the hop publishes them straight away,
// under the mutex, so they leave in the order they were made) or, without a sink, to the
// outbox for the caller to take.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cdr.hpp"
#include "engine.hpp"
#include "joint_merge.hpp"
#include "sensor_answer.hpp"

namespace collision_sensor {

struct SensorSettings {
    bool check_motion = true;
    bool require_all_joints = true;
    int limit_policy = LIMITS_REJECT;
    double limit_tolerance = 0.01;
    int64_t max_unknown = 100;
    int64_t max_joint_state_bytes = 64 * 1024;
    double stale_timeout = 1.0;  // s; 0: no stale check
    int stale_policy = POLICY_CONTACT, on_rejected_input = POLICY_CONTACT,
        on_engine_error = POLICY_CONTACT;
    double warning_distance = 0.0;  // m; 0: no zone
    std::set<std::pair<std::string, std::string>> warning_ignore;  // each pair sorted
    double state_window = 1.0;  // s of complete states kept for positions_at
};

// A model the core answers with: the checker's engine and its names.
struct SensorModel {
    Engine* engine = nullptr;
    std::vector<std::string> joint_names;  // (J,) the engine's variables
    std::vector<std::string> derived;      // mimic joints (published, never used)
    std::vector<double> lower, upper;      // (J,) limits, not finite: none on that side
    std::vector<std::pair<int64_t, double>> defaults;  // planar/floating variables' neutral values
    std::vector<int64_t> motion_kinds;     // (J,) MOTION_* (kinematics.hpp)
    AnswerNames names;                     // the checked pairs' names, the root frame
    std::vector<uint8_t> swapped;          // (P,) 1: the engine's first body is the pair's second name
};

// A log line for the caller to write (level 0 info, 1 warning, 2 error); kind: its throttle
// ("" none).
struct Note {
    int level;
    std::string kind, text;
};

// Why a state was checked as an instant (counted on /diagnostics).
constexpr const char* NEW_MOTION_REASONS[] = {"first_state", "stale_gap", "engine_error",
                                              "new_checker", "jump"};

// The counters and state /diagnostics shows.
struct SensorSnapshot {
    std::map<std::string, int64_t> totals;
    int64_t period_received = 0, period_rejected = 0, period_checks = 0;
    double period_check_time_sum = 0.0, period_check_time_max = 0.0;  // s
    std::vector<std::string> missing, unknown;
    int64_t unknown_overflow = 0;
    // (name, value, lower, upper) of the joints out of their limits
    std::vector<std::tuple<std::string, double, double, double>> out_of_limits;
    bool has_model = false, accepted_any = false, held = false, held_contact = false;
    std::vector<int64_t> held_now, held_met;
    double seconds_since_accepted = 0.0;
    bool stale = false;
    int64_t stale_episodes = 0;
    std::string engine_error;
    std::string motion_state;
    std::map<std::string, int64_t> motion_counts;
    std::vector<std::string> failing;  // the failing sources' names
};

// A test's fault (inject_fault): the engine call for a state whose variable j is value fails
// with message, as an internal error (internal) or an engine error; with corrupt, after
// marking every pair in contact in the carried state, as a fault half-way through a query
// would leave it.
struct InjectedFault {
    int64_t variable = -1;
    double value = 0.0;
    std::string message;
    bool internal = true;
    bool corrupt = false;
};

class SensorCore {
   public:
    using Sink = std::function<void(int topic, const uint8_t* data, size_t size)>;

    explicit SensorCore(const SensorSettings& settings);

    std::recursive_mutex& mutex() { return mutex_; }

    // Answers go to sink from now on (empty: to the outbox).
    void set_sink(Sink sink);
    // The answers made since the last call (topic, message), in order.
    std::vector<std::pair<int, std::vector<uint8_t>>> take_outbox();

    // A new model (a new checker): the merged state carries over the joints of the same name;
    // the motion goes on from the last state checked when the joints are the old model's.
    void use_model(SensorModel model);
    bool has_model() const { return model_.engine != nullptr; }
    // The checker laid a scene change out in a new engine (the same joints and pairs' state).
    void set_engine(Engine* engine, AnswerNames names, std::vector<uint8_t> swapped);
    void configure(const SensorSettings& settings);
    const SensorSettings& settings() const { return settings_; }

    // Answer one serialized sensor_msgs/JointState (see the top of this file). answer false:
    // merge it without answering (a newer one waits: overload); then a later answer() of the
    // newest accepted state answers it. now: steady clock, s.
    void take(const uint8_t* data, size_t size, bool answer, double now);
    // The same for a message already read (names, positions, header).
    void take_view(const cdr::JointStateView& message, bool answer, double now);
    // Merge a batch, answering each, or only the newest (newest_only: under overload).
    void take_batch(const std::vector<std::pair<const uint8_t*, size_t>>& batch,
                    bool newest_only, double now);

    // Check the current state again and answer it, its header the stamp given and the root
    // frame: the scene or a parameter changed. False when there is no state to check yet.
    bool answer_current(cdr::Stamp stamp);
    // Answer with a failure by policy (a source's timeout), header the stamp given.
    void answer_failure(cdr::Stamp stamp, const Failure& failure);
    // Mark a source failing (its failure answers every verdict until clear_failing).
    void set_failing(const std::string& source, const Failure& failure);
    void clear_failing(const std::string& source);
    // Joint states stale (see the top): the first poll after stale_timeout without an
    // accepted state marks the episode and, with stale_policy contact, answers a
    // joint_states_stale failure. Returns true on the poll that started an episode.
    bool poll_stale(double now, cdr::Stamp stamp);
    // True when poll_stale could start an episode now (a cheap look).
    bool stale_due(double now) const;

    // The state at stamp (s): interpolated in the window of recent complete states, the newest
    // for a later stamp. Returns 0 and fills q; 1: older than the window; 2: no state yet.
    int positions_at(double stamp, std::vector<double>* q) const;
    double window_oldest() const;
    double window_newest() const;
    // Where a planned trajectory starts: the merged state (joints not heard: the engine's
    // last values) and "", or why it is not known.
    std::string start_state(double now, std::vector<double>* q) const;
    // The state to check now: 0 complete (or, without require_all_joints, what is known
    // filled with the engine's last values), 1 none yet.
    int current_positions(std::vector<double>* q) const;

    // (J,) the merged state, NaN for the variables not heard yet (empty before a model).
    std::vector<double> merged_positions() const;
    std::vector<Note> take_notes();
    SensorSnapshot snapshot(double now, bool reset_period);
    // The last answer made (for the structured answers of the Python side).
    const Answer& last_answer() const { return last_answer_; }
    const AnswerWriter& writer() const { return writer_; }
    // The last verdict published, for markers: a counter that grows with each one.
    int64_t verdict_serial() const { return verdict_serial_; }
    const Verdict* held() const { return held_ ? &held_verdict_ : nullptr; }
    // The stamp of the held verdict's answer.
    cdr::Stamp held_stamp() const { return held_stamp_; }
    const Zone* held_zone() const { return held_zone_ ? &held_zone_value_ : nullptr; }

    // Add a test's fault (variable -1: clear every one).
    void inject_fault(InjectedFault fault);

   private:
    struct Unchecked {
        cdr::Header header;
        MergeOutcome outcome;
    };
    struct WindowState {
        double stamp;
        std::vector<double> q;
    };

    void take_locked(const cdr::JointStateView& message, bool answer, double now);
    void reject(const char* problem, const cdr::Header& header, const std::string& reason,
                bool answer, const std::string& kind,
                const char* prefix = "joint state rejected, state unchanged: ");
    void answer_waiting(const cdr::Header& header);
    void check_and_answer(const cdr::Header& header, const MergeOutcome& outcome);
    // The verdict at q (the engine state moved there): motion stream, zone. Throws what the
    // engine throws; an unusable variable as EngineRefused.
    Verdict check(const std::vector<double>& q, double accepted_at, Zone* zone);
    void measure_zone(const std::vector<double>& q, Zone* zone);
    void fail(const cdr::Header& header, const std::string& text, bool internal);
    void publish_failure(const cdr::Header& header, const Failure& failure);
    void publish_verdict(const cdr::Header& header, const Verdict& verdict, const Zone* zone);
    bool publish_held(const cdr::Header& header);
    void emit(const Answer& answer);
    void note(int level, std::string kind, std::string text);
    std::string unusable_message(int64_t j, const std::vector<double>& q) const;
    void update_limits(const MergeOutcome& outcome);
    void record_window(double stamp, const std::vector<double>& q);
    void resume(double now);
    std::vector<double> filled(const std::vector<double>& q) const;
    void restart_motion(const char* reason);
    cdr::Header root_header(cdr::Stamp stamp) const;

    mutable std::recursive_mutex mutex_;
    SensorSettings settings_;
    SensorModel model_;
    std::unique_ptr<JointMerge> merge_;
    AnswerWriter writer_;
    Sink sink_;
    std::vector<std::pair<int, std::vector<uint8_t>>> outbox_;
    std::vector<int> topics_;
    std::vector<std::vector<uint8_t>> messages_;
    Answer last_answer_;
    int64_t verdict_serial_ = 0;

    // The held verdict (the last one published) and the zone's held values.
    bool held_ = false, held_zone_ = false;
    Verdict held_verdict_;
    cdr::Stamp held_stamp_;
    Zone held_zone_value_;

    // Joint states.
    bool accepted_any_ = false;
    double last_accepted_ = 0.0;  // steady clock, s
    bool stale_ = false;
    double stale_since_ = 0.0;
    int64_t stale_episodes_ = 0;
    bool announced_waiting_ = false;
    std::vector<Unchecked> unchecked_;  // merged, superseded since the last check
    std::map<std::string, std::tuple<double, double, double>> out_of_limits_;
    std::deque<WindowState> window_;

    // The motion stream.
    std::string motion_reason_ = "first_state";  // "" while the next state can be swept
    bool has_last_ = false, carried_ = false;
    std::vector<double> last_;
    double last_accepted_at_ = 0.0;
    std::vector<double> spans_;
    StepResult step_;  // the engine's motion answers, kept between calls (no allocation)
    std::map<std::string, int64_t> motion_counts_;

    // Failures.
    bool resync_ = false;  // check the next state from scratch (after an engine error)
    std::string engine_error_;
    std::vector<std::pair<std::string, Failure>> failing_;
    std::vector<InjectedFault> faults_;

    // Counters.
    std::map<std::string, int64_t> totals_;
    int64_t period_received_ = 0, period_rejected_ = 0, period_checks_ = 0;
    double period_time_sum_ = 0.0, period_time_max_ = 0.0;
    std::deque<Note> notes_;
    int64_t notes_dropped_ = 0;

    std::vector<std::string> ignored_names_;  // scratch of take(): nothing
    cdr::JointStateView scratch_message_;
};

}  // namespace collision_sensor
