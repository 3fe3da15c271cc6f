// pybind11 bindings of the sensor core (sensor_core.hpp): engine.SensorCore, which
// collision_sensor/sensor/ wraps, and the C interface the node's compiled joint-state hop calls
// (sensor_api.h) without Python in between.
//
// Every method releases the interpreter before it takes the core's mutex: the hop's thread
// holds that mutex without ever wanting the interpreter, and a Python thread that held the
// interpreter while waiting for the mutex would stall every other Python thread meanwhile.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "binding.hpp"
#include "engine.hpp"
#include "sensor_api.h"
#include "sensor_core.hpp"

namespace cs = collision_sensor;

namespace collision_sensor {
namespace binding {

namespace {

int policy_code(const std::string& name, const char* parameter) {
    if (name == "contact") return cs::POLICY_CONTACT;
    if (name == "hold") return cs::POLICY_HOLD;
    throw std::invalid_argument(std::string(parameter) + ": \"" + name +
                                "\" is not contact or hold");
}

int limit_code(const std::string& name) {
    if (name == "reject") return cs::LIMITS_REJECT;
    if (name == "clamp") return cs::LIMITS_CLAMP;
    if (name == "accept") return cs::LIMITS_ACCEPT;
    throw std::invalid_argument("joint_limit_policy: \"" + name +
                                "\" is not reject, clamp or accept");
}

// SensorSettings from a mapping of the node's parameter names (missing ones: the defaults).
cs::SensorSettings settings_from(const py::dict& d) {
    cs::SensorSettings s;
    auto get = [&](const char* key, auto* out) {
        if (d.contains(key)) *out = d[key].cast<std::remove_pointer_t<decltype(out)>>();
    };
    get("check_motion", &s.check_motion);
    get("require_all_joints", &s.require_all_joints);
    if (d.contains("joint_limit_policy"))
        s.limit_policy = limit_code(d["joint_limit_policy"].cast<std::string>());
    get("joint_limit_tolerance", &s.limit_tolerance);
    get("max_unknown_joints", &s.max_unknown);
    get("max_joint_state_bytes", &s.max_joint_state_bytes);
    get("stale_timeout", &s.stale_timeout);
    const char* policies[] = {"stale_policy", "on_rejected_input", "on_engine_error"};
    int* slots[] = {&s.stale_policy, &s.on_rejected_input, &s.on_engine_error};
    for (int k = 0; k < 3; ++k)
        if (d.contains(policies[k]))
            *slots[k] = policy_code(d[policies[k]].cast<std::string>(), policies[k]);
    get("warning_distance", &s.warning_distance);
    if (d.contains("warning_ignore"))
        for (const auto& pair : d["warning_ignore"].cast<std::vector<std::vector<std::string>>>()) {
            if (pair.size() != 2) throw std::invalid_argument("warning_ignore: pairs of names");
            s.warning_ignore.insert(pair[0] < pair[1] ? std::make_pair(pair[0], pair[1])
                                                      : std::make_pair(pair[1], pair[0]));
        }
    get("point_cloud_state_window", &s.state_window);
    return s;
}

cs::AnswerNames names_of(const std::vector<std::pair<std::string, std::string>>& pairs,
                         const std::string& root_frame) {
    cs::AnswerNames names;
    names.pairs = pairs;
    names.root_frame = root_frame;
    return names;
}

py::bytes bytes_of(const std::vector<uint8_t>& v) {
    return py::bytes(reinterpret_cast<const char*>(v.data()), v.size());
}

py::list pair_list(const cs::AnswerNames& names, const std::vector<int64_t>& pairs) {
    py::list out;
    for (const int64_t p : pairs) out.append(py::make_tuple(names.pairs[p].first, names.pairs[p].second));
    return out;
}

py::dict zone_dict(const cs::AnswerNames& names, const cs::Zone& zone) {
    py::list records;
    for (const cs::ZoneRecord& r : zone.records)
        records.append(py::make_tuple(
            names.pairs[r.pair].first, names.pairs[r.pair].second, r.distance,
            py::make_tuple(r.point_a[0], r.point_a[1], r.point_a[2]),
            py::make_tuple(r.point_b[0], r.point_b[1], r.point_b[2])));
    py::dict d;
    d["near"] = zone.near;
    d["min_distance"] = zone.min_distance;
    d["records"] = records;
    return d;
}

py::dict verdict_dict(const cs::AnswerNames& names, const cs::Verdict& v) {
    py::dict d;
    d["contact"] = v.contact;
    d["now"] = pair_list(names, v.now);
    d["met"] = pair_list(names, v.met);
    d["first_contact"] = v.met.empty() ? py::object(py::none()) : py::object(py::float_(v.first_contact));
    return d;
}

// The C interface of sensor_api.h, over a SensorCore.
void api_set_publisher(void* core, cs_publish_fn publish, void* context) {
    auto* c = static_cast<cs::SensorCore*>(core);
    if (publish == nullptr) {
        c->set_sink(nullptr);
        return;
    }
    c->set_sink([publish, context](int topic, const uint8_t* data, size_t size) {
        publish(context, topic, data, size);
    });
}

void api_take_batch(void* core, const uint8_t* const* data, const size_t* sizes, size_t n,
                    int newest_only, double now) {
    std::vector<std::pair<const uint8_t*, size_t>> batch(n);
    for (size_t k = 0; k < n; ++k) batch[k] = {data[k], sizes[k]};
    static_cast<cs::SensorCore*>(core)->take_batch(batch, newest_only != 0, now);
}

const cs_sensor_api API = {CS_SENSOR_API_VERSION, api_set_publisher, api_take_batch};

}  // namespace

void bind_sensor(py::module_& m) {
    m.attr("TOPIC_CONTACT") = cs::TOPIC_CONTACT;
    m.attr("TOPIC_COLLIDING_PAIRS") = cs::TOPIC_COLLIDING_PAIRS;
    m.attr("TOPIC_NEAR") = cs::TOPIC_NEAR;
    m.attr("TOPIC_MIN_DISTANCE") = cs::TOPIC_MIN_DISTANCE;
    m.attr("TOPIC_NEAR_PAIRS") = cs::TOPIC_NEAR_PAIRS;
    m.attr("SENSOR_API_CAPSULE") = CS_SENSOR_API_CAPSULE;
    py::list reasons;
    for (const char* r : cs::NEW_MOTION_REASONS) reasons.append(r);
    m.attr("NEW_MOTION_REASONS") = py::tuple(reasons);

    py::class_<cs::SensorCore, std::shared_ptr<cs::SensorCore>>(
        m, "SensorCore",
        "The sensor core (cpp/sensor_core.hpp): joint states in, answers out. "
        "collision_sensor.sensor.Sensor wraps it.")
        .def(py::init([](const py::dict& settings) {
                 return std::make_shared<cs::SensorCore>(settings_from(settings));
             }),
             py::arg("settings"))
        .def("configure",
             [](cs::SensorCore& c, const py::dict& settings) {
                 const cs::SensorSettings s = settings_from(settings);
                 py::gil_scoped_release release;
                 c.configure(s);
             },
             py::arg("settings"))
        .def("use_model",
             [](cs::SensorCore& c, py::handle engine, std::vector<std::string> joints,
                std::vector<std::string> derived, std::vector<double> lower,
                std::vector<double> upper, std::vector<std::pair<int64_t, double>> defaults,
                std::vector<int64_t> kinds,
                std::vector<std::pair<std::string, std::string>> pairs, std::string root_frame,
                std::vector<uint8_t> swapped) {
                 cs::SensorModel model;
                 model.engine = &engine_of(engine);
                 model.joint_names = std::move(joints);
                 model.derived = std::move(derived);
                 model.lower = std::move(lower);
                 model.upper = std::move(upper);
                 model.defaults = std::move(defaults);
                 model.motion_kinds = std::move(kinds);
                 model.names = names_of(pairs, root_frame);
                 model.swapped = std::move(swapped);
                 py::gil_scoped_release release;
                 c.use_model(std::move(model));
             },
             py::arg("engine"), py::arg("joint_names"), py::arg("derived"), py::arg("lower"),
             py::arg("upper"), py::arg("defaults"), py::arg("motion_kinds"), py::arg("pairs"),
             py::arg("root_frame"), py::arg("swapped"))
        .def("set_engine",
             [](cs::SensorCore& c, py::handle engine,
                std::vector<std::pair<std::string, std::string>> pairs, std::string root_frame,
                std::vector<uint8_t> swapped) {
                 cs::Engine* e = &engine_of(engine);
                 py::gil_scoped_release release;
                 c.set_engine(e, names_of(pairs, root_frame), std::move(swapped));
             },
             py::arg("engine"), py::arg("pairs"), py::arg("root_frame"), py::arg("swapped"))
        .def("take",
             [](cs::SensorCore& c, const py::bytes& data, bool answer, double now) {
                 char* buffer;
                 py::ssize_t size;
                 PYBIND11_BYTES_AS_STRING_AND_SIZE(data.ptr(), &buffer, &size);
                 py::gil_scoped_release release;
                 c.take(reinterpret_cast<const uint8_t*>(buffer), size_t(size), answer, now);
             },
             py::arg("data"), py::arg("answer") = true, py::arg("now"),
             "Answer one serialized sensor_msgs/JointState (now: time.monotonic()).")
        .def("take_message",
             [](cs::SensorCore& c, int32_t sec, uint32_t nanosec, std::string frame,
                std::vector<std::string> names, std::vector<double> positions, double now) {
                 cs::cdr::JointStateView view;
                 view.header.stamp = {sec, nanosec};
                 view.header.frame_id = std::move(frame);
                 view.names.assign(names.begin(), names.end());
                 view.positions = std::move(positions);
                 py::gil_scoped_release release;
                 c.take_view(view, true, now);
             },
             py::arg("sec"), py::arg("nanosec"), py::arg("frame_id"), py::arg("names"),
             py::arg("positions"), py::arg("now"),
             "Answer one joint state given by its fields.")
        .def("take_batch",
             [](cs::SensorCore& c, const py::list& batch, bool newest_only, double now) {
                 std::vector<std::pair<const uint8_t*, size_t>> items;
                 for (const py::handle item : batch) {
                     char* buffer;
                     py::ssize_t size;
                     if (PYBIND11_BYTES_AS_STRING_AND_SIZE(item.ptr(), &buffer, &size) != 0)
                         throw py::error_already_set();
                     items.emplace_back(reinterpret_cast<const uint8_t*>(buffer), size_t(size));
                 }
                 py::gil_scoped_release release;
                 c.take_batch(items, newest_only, now);
             },
             py::arg("batch"), py::arg("newest_only"), py::arg("now"))
        .def("answer_current",
             [](cs::SensorCore& c, int32_t sec, uint32_t nanosec) {
                 py::gil_scoped_release release;
                 return c.answer_current({sec, nanosec});
             },
             py::arg("sec"), py::arg("nanosec"))
        .def("answer_failure",
             [](cs::SensorCore& c, int32_t sec, uint32_t nanosec, std::string kind,
                std::string reason, const std::string& policy) {
                 const cs::Failure f{std::move(kind), std::move(reason), policy_code(policy, "policy")};
                 py::gil_scoped_release release;
                 c.answer_failure({sec, nanosec}, f);
             },
             py::arg("sec"), py::arg("nanosec"), py::arg("kind"), py::arg("reason"),
             py::arg("policy"))
        .def("set_failing",
             [](cs::SensorCore& c, const std::string& source, std::string kind,
                std::string reason, const std::string& policy) {
                 const cs::Failure f{std::move(kind), std::move(reason), policy_code(policy, "policy")};
                 py::gil_scoped_release release;
                 c.set_failing(source, f);
             },
             py::arg("source"), py::arg("kind"), py::arg("reason"), py::arg("policy"))
        .def("clear_failing",
             [](cs::SensorCore& c, const std::string& source) {
                 py::gil_scoped_release release;
                 c.clear_failing(source);
             },
             py::arg("source"))
        .def("stale_due",
             [](cs::SensorCore& c, double now) {
                 py::gil_scoped_release release;
                 return c.stale_due(now);
             },
             py::arg("now"))
        .def("poll_stale",
             [](cs::SensorCore& c, double now, int32_t sec, uint32_t nanosec) {
                 py::gil_scoped_release release;
                 return c.poll_stale(now, {sec, nanosec});
             },
             py::arg("now"), py::arg("sec"), py::arg("nanosec"))
        .def("positions_at",
             [](cs::SensorCore& c, double stamp) -> py::object {
                 std::vector<double> q;
                 int code;
                 {
                     py::gil_scoped_release release;
                     code = c.positions_at(stamp, &q);
                 }
                 if (code == 1) return py::str("old");
                 if (code == 2) return py::none();
                 return py::array_t<double>(q.size(), q.data());
             },
             py::arg("stamp"),
             "The state at stamp (s): an array, 'old' (before the window), or None.")
        .def("window_bounds",
             [](cs::SensorCore& c) {
                 py::gil_scoped_release release;
                 return std::make_pair(c.window_oldest(), c.window_newest());
             })
        .def("start_state",
             [](cs::SensorCore& c, double now) -> py::tuple {
                 std::vector<double> q;
                 std::string reason;
                 {
                     py::gil_scoped_release release;
                     reason = c.start_state(now, &q);
                 }
                 if (!reason.empty()) return py::make_tuple(py::none(), reason);
                 return py::make_tuple(py::array_t<double>(q.size(), q.data()), "");
             },
             py::arg("now"))
        .def("current_positions",
             [](cs::SensorCore& c) -> py::object {
                 std::vector<double> q;
                 int code;
                 {
                     py::gil_scoped_release release;
                     code = c.current_positions(&q);
                 }
                 if (code) return py::none();
                 return py::array_t<double>(q.size(), q.data());
             })
        .def("merged_positions",
             [](cs::SensorCore& c) {
                 std::vector<double> q;
                 {
                     py::gil_scoped_release release;
                     q = c.merged_positions();
                 }
                 return py::array_t<double>(q.size(), q.data());
             },
             "(J,) the merged joint state, NaN for the variables not heard yet.")
        .def("take_outbox",
             [](cs::SensorCore& c) {
                 std::vector<std::pair<int, std::vector<uint8_t>>> out;
                 {
                     py::gil_scoped_release release;
                     out = c.take_outbox();
                 }
                 py::list items;
                 for (const auto& [topic, message] : out)
                     items.append(py::make_tuple(topic, bytes_of(message)));
                 return items;
             },
             "The answers' messages made since the last call, [(topic, bytes)], in order "
             "(without a publisher set).")
        .def("take_notes",
             [](cs::SensorCore& c) {
                 std::vector<cs::Note> notes;
                 {
                     py::gil_scoped_release release;
                     notes = c.take_notes();
                 }
                 static const char* levels[] = {"info", "warning", "error"};
                 py::list out;
                 for (const cs::Note& n : notes)
                     out.append(py::make_tuple(levels[n.level],
                                               n.kind.empty() ? py::object(py::none())
                                                              : py::object(py::str(n.kind)),
                                               py::str(n.text)));
                 return out;
             },
             "Log lines made since the last call: [(level, throttle kind or None, text)].")
        .def("snapshot",
             [](cs::SensorCore& c, double now, bool reset_period) {
                 cs::SensorSnapshot s;
                 std::vector<std::pair<std::string, std::string>> pairs;
                 {
                     py::gil_scoped_release release;
                     std::lock_guard<std::recursive_mutex> hold(c.mutex());
                     s = c.snapshot(now, reset_period);
                     pairs = c.writer().names().pairs;
                 }
                 py::dict d;
                 d["totals"] = s.totals;
                 d["period_received"] = s.period_received;
                 d["period_rejected"] = s.period_rejected;
                 d["period_checks"] = s.period_checks;
                 d["period_check_time_sum"] = s.period_check_time_sum;
                 d["period_check_time_max"] = s.period_check_time_max;
                 d["missing"] = s.missing;
                 d["unknown"] = s.unknown;
                 d["unknown_overflow"] = s.unknown_overflow;
                 d["out_of_limits"] = s.out_of_limits;
                 d["has_model"] = s.has_model;
                 d["accepted_any"] = s.accepted_any;
                 d["seconds_since_accepted"] = s.seconds_since_accepted;
                 d["held"] = s.held;
                 d["held_contact"] = s.held_contact;
                 cs::AnswerNames names;
                 names.pairs = pairs;
                 d["held_now"] = pair_list(names, s.held_now);
                 d["held_met"] = pair_list(names, s.held_met);
                 d["stale"] = s.stale;
                 d["stale_episodes"] = s.stale_episodes;
                 d["engine_error"] = s.engine_error;
                 d["motion_state"] = s.motion_state;
                 d["motion_counts"] = s.motion_counts;
                 d["failing"] = s.failing;
                 return d;
             },
             py::arg("now"), py::arg("reset_period") = false)
        .def("last_answer",
             [](cs::SensorCore& c) {
                 cs::Answer a;
                 cs::AnswerNames names;
                 {
                     py::gil_scoped_release release;
                     std::lock_guard<std::recursive_mutex> hold(c.mutex());
                     a = c.last_answer();
                     names = c.writer().names();
                 }
                 py::dict d;
                 d["sec"] = a.header.stamp.sec;
                 d["nanosec"] = a.header.stamp.nanosec;
                 d["frame_id"] = py::bytes(a.header.frame_id);
                 d["contact"] = a.contact;
                 d["failure"] = a.failed ? py::object(py::make_tuple(
                                               a.failure.kind, a.failure.reason,
                                               cs::policy_name(a.failure.policy)))
                                         : py::object(py::none());
                 d["verdict"] = verdict_dict(names, a.verdict);
                 d["zone"] = a.zoned ? py::object(zone_dict(names, a.zone)) : py::object(py::none());
                 return d;
             },
             "The last answer made, as fields: contact, failure (kind, reason, policy) or None, "
             "verdict (contact, now, met, first_contact), zone or None.")
        .def("held",
             [](cs::SensorCore& c) -> py::object {
                 cs::Verdict v;
                 cs::Zone zone;
                 bool held, zoned;
                 cs::AnswerNames names;
                 int64_t serial;
                 cs::cdr::Stamp stamp;
                 {
                     py::gil_scoped_release release;
                     std::lock_guard<std::recursive_mutex> hold(c.mutex());
                     held = c.held() != nullptr;
                     stamp = c.held_stamp();
                     zoned = c.held_zone() != nullptr;
                     if (held) v = *c.held();
                     if (zoned) zone = *c.held_zone();
                     names = c.writer().names();
                     serial = c.verdict_serial();
                 }
                 if (!held) return py::none();
                 py::dict d = verdict_dict(names, v);
                 d["zone"] = zoned ? py::object(zone_dict(names, zone)) : py::object(py::none());
                 d["serial"] = serial;
                 d["stamp"] = py::make_tuple(stamp.sec, stamp.nanosec);
                 return d;
             },
             "The verdict held (the last one published) with its zone, serial and stamp "
             "(sec, nanosec), or None.")
        .def("inject_fault",
             [](cs::SensorCore& c, int64_t variable, double value, std::string message,
                bool internal, bool corrupt) {
                 cs::InjectedFault f{variable, value, std::move(message), internal, corrupt};
                 py::gil_scoped_release release;
                 c.inject_fault(std::move(f));
             },
             py::arg("variable"), py::arg("value"), py::arg("message"), py::arg("internal"),
             py::arg("corrupt") = false,
             "For tests of the fail-safe path: the check of a state whose variable is value "
             "raises message, as an internal error or an engine error (variable -1: clears every "
             "fault); "
             "corrupt: after marking every pair in contact in the carried state.")
        .def("set_publish",
             [](cs::SensorCore& c, py::object publish) {
                 if (publish.is_none()) {
                     py::gil_scoped_release release;
                     c.set_sink(nullptr);
                     return;
                 }
                 // The core calls it holding its mutex, from whichever thread answers: the
                 // interpreter is taken for the call (every Python caller of the core let it go
                 // before taking the mutex, so none waits for the other).
                 // Dropped with the interpreter taken, whichever thread replaces the sink.
                 std::shared_ptr<py::object> shared(new py::object(std::move(publish)),
                                                    [](py::object* o) {
                                                        py::gil_scoped_acquire acquire;
                                                        delete o;
                                                    });
                 cs::SensorCore::Sink sink = [shared](int topic, const uint8_t* data,
                                                      size_t size) {
                     py::gil_scoped_acquire acquire;
                     try {
                         (*shared)(topic, py::bytes(reinterpret_cast<const char*>(data), size));
                     } catch (py::error_already_set& error) {
                         error.discard_as_unraisable("collision_sensor: publishing an answer");
                     }
                 };
                 py::gil_scoped_release release;
                 c.set_sink(std::move(sink));
             },
             py::arg("publish"),
             "Publish answers with publish(topic, bytes) from now on (None: to the outbox).")
        .def("lock",
             [](cs::SensorCore& c) {
                 py::gil_scoped_release release;
                 c.mutex().lock();
             },
             "Hold the core's mutex (the caller then changes the checker; unlock() after).")
        .def("unlock", [](cs::SensorCore& c) { c.mutex().unlock(); })
        .def("api",
             [](std::shared_ptr<cs::SensorCore> c) {
                 // The capsule holds the core alive: its destructor drops a shared_ptr copy.
                 auto* holder = new std::shared_ptr<cs::SensorCore>(std::move(c));
                 auto* handle = new cs_sensor_handle{&API, holder->get(), holder};
                 return py::capsule(handle, CS_SENSOR_API_CAPSULE, [](PyObject* o) {
                     auto* h = static_cast<cs_sensor_handle*>(
                         PyCapsule_GetPointer(o, CS_SENSOR_API_CAPSULE));
                     delete static_cast<std::shared_ptr<cs::SensorCore>*>(h->owner);
                     delete h;
                 });
             },
             "A capsule of the C interface (cpp/sensor_api.h) for compiled callers.");
}

}  // namespace binding
}  // namespace collision_sensor
