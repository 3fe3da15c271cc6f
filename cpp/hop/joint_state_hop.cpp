// The node's joint-state hop: joint_states taken from the middleware and answered by the sensor
// core on a thread of its own, with no Python on the way (collision_sensor.ros._joint_state_hop).
//
// The hop owns one rcl subscription on the node (made here, on the rcl node rclpy made, so
// rclpy's executor never sees it) and waits on it as a C program over rcl does: a wait set of
// the subscription, its message-lost and incompatible-QoS events and a guard condition that
// stops it. Each wake-up takes every message waiting, serialized, and hands them to the core
// in one call (sensor_api.h: take_batch; more than max_backlog waiting: only the newest is
// answered, the rest merged and counted); the core publishes each answer through the hop's
// publishers (rclpy's, by their rcl handles) while it holds its own mutex, so the answers of
// every thread leave in the order they were made.
//
// rcl is not linked: its functions are looked up in the librcl and librcutils that rclpy
// loaded into the process (one copy of rcl, the one whose node and context these are). Its
// headers are needed to build this file; setup.py builds it when it finds them (a ROS install
// or the ROS 2 wheels in the environment), and the node answers through rclpy without it.
#include <dlfcn.h>
#include <link.h>
#include <pybind11/pybind11.h>
#include <rcl/error_handling.h>
#include <rcl/event.h>
#include <rcl/guard_condition.h>
#include <rcl/publisher.h>
#include <rcl/rcl.h>
#include <rcl/subscription.h>
#include <rcl/wait.h>
#include <rcutils/allocator.h>
#include <rcutils/types/uint8_array.h>
#include <rmw/events_statuses/incompatible_qos.h>
#include <rmw/events_statuses/message_lost.h>
#include <rmw/qos_profiles.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "../sensor_api.h"

namespace py = pybind11;

namespace {

// The most messages taken in one wake-up (a reliable keep-all reader may hold many more; they
// wait for the next turn).
constexpr size_t MAX_TAKEN = 4096;
// A wait returns at least this often (ns): a stop never waits on the middleware.
constexpr int64_t WAIT_TIMEOUT_NS = 100'000'000;

// The rcl and rcutils functions the hop calls, found in the libraries rclpy loaded.
struct Rcl {
#define CS_RCL_FUNCTION(name) decltype(&::name) name = nullptr
    CS_RCL_FUNCTION(rcl_get_zero_initialized_subscription);
    CS_RCL_FUNCTION(rcl_subscription_get_default_options);
    CS_RCL_FUNCTION(rcl_subscription_init);
    CS_RCL_FUNCTION(rcl_subscription_fini);
    CS_RCL_FUNCTION(rcl_subscription_get_topic_name);
    CS_RCL_FUNCTION(rcl_take_serialized_message);
    CS_RCL_FUNCTION(rcl_publish_serialized_message);
    CS_RCL_FUNCTION(rcl_get_zero_initialized_guard_condition);
    CS_RCL_FUNCTION(rcl_guard_condition_get_default_options);
    CS_RCL_FUNCTION(rcl_guard_condition_init);
    CS_RCL_FUNCTION(rcl_guard_condition_fini);
    CS_RCL_FUNCTION(rcl_trigger_guard_condition);
    CS_RCL_FUNCTION(rcl_get_zero_initialized_wait_set);
    CS_RCL_FUNCTION(rcl_wait_set_init);
    CS_RCL_FUNCTION(rcl_wait_set_fini);
    CS_RCL_FUNCTION(rcl_wait_set_clear);
    CS_RCL_FUNCTION(rcl_wait_set_add_subscription);
    CS_RCL_FUNCTION(rcl_wait_set_add_guard_condition);
    CS_RCL_FUNCTION(rcl_wait_set_add_event);
    CS_RCL_FUNCTION(rcl_wait);
    CS_RCL_FUNCTION(rcl_get_zero_initialized_event);
    CS_RCL_FUNCTION(rcl_subscription_event_init);
    CS_RCL_FUNCTION(rcl_event_fini);
    CS_RCL_FUNCTION(rcl_take_event);
    CS_RCL_FUNCTION(rcutils_get_default_allocator);
    CS_RCL_FUNCTION(rcutils_uint8_array_init);
    CS_RCL_FUNCTION(rcutils_uint8_array_fini);
    CS_RCL_FUNCTION(rcutils_get_error_string);
    CS_RCL_FUNCTION(rcutils_reset_error);
#undef CS_RCL_FUNCTION
};

// The path of the loaded shared object whose file name starts with prefix ("librcl.so").
std::string loaded_library(const std::string& prefix) {
    struct Search {
        std::string prefix, found;
    } search{prefix, ""};
    dl_iterate_phdr(
        [](dl_phdr_info* info, size_t, void* data) {
            auto* s = static_cast<Search*>(data);
            const char* path = info->dlpi_name;
            if (!path || !*path) return 0;
            const char* base = std::strrchr(path, '/');
            base = base ? base + 1 : path;
            if (std::strncmp(base, s->prefix.c_str(), s->prefix.size()) == 0) {
                s->found = path;
                return 1;
            }
            return 0;
        },
        &search);
    return search.found;
}

void* open_loaded(const char* soname, const char* prefix) {
    void* handle = dlopen(soname, RTLD_NOLOAD | RTLD_LAZY);
    if (handle) return handle;
    const std::string path = loaded_library(prefix);
    if (!path.empty()) handle = dlopen(path.c_str(), RTLD_NOLOAD | RTLD_LAZY);
    if (!handle)
        throw std::runtime_error(std::string(soname) +
                                 " is not loaded in this process: import rclpy and make its "
                                 "node before the joint-state hop");
    return handle;
}

const Rcl& rcl() {
    static const Rcl functions = [] {
        Rcl r;
        void* librcl = open_loaded("librcl.so", "librcl.so");
        void* librcutils = open_loaded("librcutils.so", "librcutils.so");
        const auto find = [&](auto* slot, const char* name, void* library) {
            *slot = reinterpret_cast<std::remove_pointer_t<decltype(slot)>>(dlsym(library, name));
            if (!*slot)
                throw std::runtime_error(std::string("the joint-state hop needs ") + name +
                                         ", which the loaded rcl does not have");
        };
#define CS_FIND(name, library) find(&r.name, #name, library)
        CS_FIND(rcl_get_zero_initialized_subscription, librcl);
        CS_FIND(rcl_subscription_get_default_options, librcl);
        CS_FIND(rcl_subscription_init, librcl);
        CS_FIND(rcl_subscription_fini, librcl);
        CS_FIND(rcl_subscription_get_topic_name, librcl);
        CS_FIND(rcl_take_serialized_message, librcl);
        CS_FIND(rcl_publish_serialized_message, librcl);
        CS_FIND(rcl_get_zero_initialized_guard_condition, librcl);
        CS_FIND(rcl_guard_condition_get_default_options, librcl);
        CS_FIND(rcl_guard_condition_init, librcl);
        CS_FIND(rcl_guard_condition_fini, librcl);
        CS_FIND(rcl_trigger_guard_condition, librcl);
        CS_FIND(rcl_get_zero_initialized_wait_set, librcl);
        CS_FIND(rcl_wait_set_init, librcl);
        CS_FIND(rcl_wait_set_fini, librcl);
        CS_FIND(rcl_wait_set_clear, librcl);
        CS_FIND(rcl_wait_set_add_subscription, librcl);
        CS_FIND(rcl_wait_set_add_guard_condition, librcl);
        CS_FIND(rcl_wait_set_add_event, librcl);
        CS_FIND(rcl_wait, librcl);
        CS_FIND(rcl_get_zero_initialized_event, librcl);
        CS_FIND(rcl_subscription_event_init, librcl);
        CS_FIND(rcl_event_fini, librcl);
        CS_FIND(rcl_take_event, librcl);
        CS_FIND(rcutils_get_default_allocator, librcutils);
        CS_FIND(rcutils_uint8_array_init, librcutils);
        CS_FIND(rcutils_uint8_array_fini, librcutils);
        CS_FIND(rcutils_get_error_string, librcutils);
        CS_FIND(rcutils_reset_error, librcutils);
#undef CS_FIND
        return r;
    }();
    return functions;
}

// rcl's last error on this thread, then cleared.
std::string rcl_error() {
    const std::string text = rcl().rcutils_get_error_string().str;
    rcl().rcutils_reset_error();
    return text;
}

double steady_seconds() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

template <class T>
T* pointer_of(uintptr_t address, const char* what) {
    if (!address) throw std::invalid_argument(std::string(what) + ": a null handle");
    return reinterpret_cast<T*>(address);
}

class JointStateHop {
   public:
    // sensor: engine.SensorCore.api(); node, context: the rcl handles' addresses (rclpy's
    // Node.handle.pointer, Context.handle.pointer); type_support: JointState._TYPE_SUPPORT;
    // reliable: keep-all reliable, else the sensor-data profile; max_backlog: answer only the
    // newest beyond it (negative: answer every one).
    JointStateHop(py::capsule sensor, uintptr_t node, uintptr_t context, py::capsule type_support,
                  std::string topic, bool reliable, int64_t max_backlog)
        : sensor_capsule_(std::move(sensor)),
          type_support_capsule_(std::move(type_support)),
          node_(pointer_of<rcl_node_t>(node, "node")),
          context_(pointer_of<rcl_context_t>(context, "context")),
          topic_(std::move(topic)),
          reliable_(reliable),
          max_backlog_(max_backlog) {
        auto* handle = static_cast<cs_sensor_handle*>(
            PyCapsule_GetPointer(sensor_capsule_.ptr(), CS_SENSOR_API_CAPSULE));
        if (!handle) throw py::error_already_set();
        if (handle->api->version != CS_SENSOR_API_VERSION)
            throw std::runtime_error("the sensor core's C interface is version " +
                                     std::to_string(handle->api->version) + ", the hop's " +
                                     std::to_string(CS_SENSOR_API_VERSION) +
                                     ": rebuild the package (pip install -e . or colcon build)");
        api_ = handle->api;
        core_ = handle->core;
        type_support_ = static_cast<const rosidl_message_type_support_t*>(
            PyCapsule_GetPointer(type_support_capsule_.ptr(), nullptr));
        if (!type_support_) throw py::error_already_set();
        for (auto& p : publishers_) p.store(nullptr);
    }

    ~JointStateHop() { stop(); }

    // Make the subscription and start the thread; answers go to the publishers from now on.
    void start() {
        std::lock_guard<std::mutex> hold(life_);
        if (running_) return;
        const Rcl& r = rcl();
        subscription_ = r.rcl_get_zero_initialized_subscription();
        rcl_subscription_options_t options = r.rcl_subscription_get_default_options();
        if (reliable_) {
            options.qos = rmw_qos_profile_default;
            options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_ALL;
            options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
            options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
        } else {
            options.qos = rmw_qos_profile_sensor_data;
        }
        if (r.rcl_subscription_init(&subscription_, node_, type_support_, topic_.c_str(),
                                    &options) != RCL_RET_OK)
            throw std::runtime_error("joint_states subscription: " + rcl_error());
        subscribed_ = true;
        topic_name_ = r.rcl_subscription_get_topic_name(&subscription_);
        guard_ = r.rcl_get_zero_initialized_guard_condition();
        if (r.rcl_guard_condition_init(&guard_, context_,
                                       r.rcl_guard_condition_get_default_options()) != RCL_RET_OK) {
            const std::string error = rcl_error();
            release();
            throw std::runtime_error("joint-state hop guard condition: " + error);
        }
        guarded_ = true;
        events_ = 0;
        const rcl_subscription_event_type_t kinds[] = {RCL_SUBSCRIPTION_MESSAGE_LOST,
                                                       RCL_SUBSCRIPTION_REQUESTED_INCOMPATIBLE_QOS};
        for (const auto kind : kinds) {
            event_[events_] = r.rcl_get_zero_initialized_event();
            if (r.rcl_subscription_event_init(&event_[events_], &subscription_, kind) ==
                RCL_RET_OK) {
                event_kind_[events_] = kind;
                ++events_;
            } else {
                rcl_error();  // an rmw without this event: not counted
            }
        }
        wait_set_ = r.rcl_get_zero_initialized_wait_set();
        if (r.rcl_wait_set_init(&wait_set_, 1, 1, 0, 0, 0, events_, context_,
                                r.rcutils_get_default_allocator()) != RCL_RET_OK) {
            const std::string error = rcl_error();
            release();
            throw std::runtime_error("joint-state hop wait set: " + error);
        }
        waiting_ = true;
        {
            // The core's mutex is taken with the interpreter let go (bind_sensor.cpp).
            py::gil_scoped_release release_gil;
            api_->set_publisher(core_, &JointStateHop::publish, this);
        }
        stopping_ = false;
        running_ = true;
        thread_ = std::thread([this] { run(); });
    }

    // Stop the thread and withdraw the subscription; answers go to the core's outbox again.
    void stop() {
        std::lock_guard<std::mutex> hold(life_);
        if (!running_) return;
        stopping_ = true;
        if (rcl().rcl_trigger_guard_condition(&guard_) != RCL_RET_OK) rcl_error();
        {
            py::gil_scoped_release release_gil;
            thread_.join();
            api_->set_publisher(core_, nullptr, nullptr);
        }
        release();
        running_ = false;
    }

    // The publisher of topic (engine.TOPIC_*): an rcl handle's address, 0 for none.
    void set_publisher(int topic, uintptr_t publisher) {
        if (topic < 0 || topic >= int(publishers_.size()))
            throw std::invalid_argument("topic: not one of engine.TOPIC_*");
        publishers_[topic].store(reinterpret_cast<rcl_publisher_t*>(publisher));
    }

    py::dict counts() const {
        py::dict d;
        d["lost"] = lost_.load();
        d["incompatible_qos"] = incompatible_.load();
        d["last_policy_kind"] = last_policy_kind_.load();
        d["wake_ups"] = wake_ups_.load();
        d["taken"] = taken_.load();
        d["newest_only_batches"] = newest_only_.load();
        d["publish_errors"] = publish_errors_.load();
        d["take_errors"] = take_errors_.load();
        std::lock_guard<std::mutex> hold(error_lock_);
        d["last_error"] = last_error_;
        return d;
    }

    std::string topic_name() const { return topic_name_; }
    bool running() const { return running_; }

   private:
    static void publish(void* context, int topic, const uint8_t* data, size_t size) {
        auto* self = static_cast<JointStateHop*>(context);
        rcl_publisher_t* publisher = self->publishers_[topic].load();
        if (!publisher) return;  // the topic is not advertised (the warning zone off)
        rcl_serialized_message_t message;
        message.buffer = const_cast<uint8_t*>(data);  // read only by rcl
        message.buffer_length = size;
        message.buffer_capacity = size;
        message.allocator = rcl().rcutils_get_default_allocator();
        if (rcl().rcl_publish_serialized_message(publisher, &message, nullptr) != RCL_RET_OK) {
            ++self->publish_errors_;
            self->remember(rcl_error());
        }
    }

    void remember(std::string error) {
        std::lock_guard<std::mutex> hold(error_lock_);
        last_error_ = std::move(error);
    }

    void run() {
        const Rcl& r = rcl();
        std::vector<rcl_serialized_message_t> pool;
        std::vector<const uint8_t*> data;
        std::vector<size_t> sizes;
        rcutils_allocator_t allocator = r.rcutils_get_default_allocator();
        while (!stopping_) {
            // The set's sizes were made for these entries: adding them cannot fail.
            bool ready = r.rcl_wait_set_clear(&wait_set_) == RCL_RET_OK &&
                         r.rcl_wait_set_add_subscription(&wait_set_, &subscription_, nullptr) ==
                             RCL_RET_OK &&
                         r.rcl_wait_set_add_guard_condition(&wait_set_, &guard_, nullptr) ==
                             RCL_RET_OK;
            for (size_t k = 0; k < events_; ++k)
                ready &= r.rcl_wait_set_add_event(&wait_set_, &event_[k], nullptr) == RCL_RET_OK;
            if (!ready) {
                remember("wait set: " + rcl_error());
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
                continue;
            }
            const rcl_ret_t waited = r.rcl_wait(&wait_set_, WAIT_TIMEOUT_NS);
            if (waited == RCL_RET_TIMEOUT) continue;
            if (waited != RCL_RET_OK) {
                remember("wait: " + rcl_error());
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
                continue;
            }
            if (stopping_) break;
            ++wake_ups_;
            for (size_t k = 0; k < events_; ++k)
                if (wait_set_.events[k]) take_event(k);
            if (!wait_set_.subscriptions[0]) continue;
            size_t n = 0;
            while (n < MAX_TAKEN) {
                if (n == pool.size()) {
                    pool.emplace_back();
                    pool.back() = rcutils_uint8_array_t{nullptr, 0, 0, allocator};
                    if (r.rcutils_uint8_array_init(&pool.back(), 256, &allocator) != RCUTILS_RET_OK) {
                        pool.pop_back();
                        remember("out of memory for a joint state");
                        break;
                    }
                }
                rmw_message_info_t info;
                const rcl_ret_t took =
                    r.rcl_take_serialized_message(&subscription_, &pool[n], &info, nullptr);
                if (took == RCL_RET_SUBSCRIPTION_TAKE_FAILED) break;
                if (took != RCL_RET_OK) {
                    ++take_errors_;
                    remember("take: " + rcl_error());
                    break;
                }
                ++n;
            }
            if (n == 0) continue;
            taken_ += n;
            data.resize(n);
            sizes.resize(n);
            for (size_t k = 0; k < n; ++k) {
                data[k] = pool[k].buffer;
                sizes[k] = pool[k].buffer_length;
            }
            const bool newest_only = max_backlog_ >= 0 && int64_t(n) > max_backlog_;
            newest_only_ += newest_only;
            api_->take_batch(core_, data.data(), sizes.data(), n, newest_only, steady_seconds());
        }
        for (auto& message : pool)
            if (r.rcutils_uint8_array_fini(&message) != RCUTILS_RET_OK) rcl_error();
    }

    void take_event(size_t k) {
        const Rcl& r = rcl();
        if (event_kind_[k] == RCL_SUBSCRIPTION_MESSAGE_LOST) {
            rmw_message_lost_status_t status{};
            if (r.rcl_take_event(&event_[k], &status) == RCL_RET_OK)
                lost_ += int64_t(status.total_count_change);
            else
                rcl_error();
        } else {
            rmw_requested_qos_incompatible_event_status_t status{};
            if (r.rcl_take_event(&event_[k], &status) == RCL_RET_OK) {
                incompatible_ += int64_t(status.total_count_change);
                last_policy_kind_ = int64_t(status.last_policy_kind);
            } else {
                rcl_error();
            }
        }
    }

    void release() {
        const Rcl& r = rcl();
        bool clean = true;
        if (waiting_) clean &= r.rcl_wait_set_fini(&wait_set_) == RCL_RET_OK;
        for (size_t k = 0; k < events_; ++k) clean &= r.rcl_event_fini(&event_[k]) == RCL_RET_OK;
        events_ = 0;
        if (guarded_) clean &= r.rcl_guard_condition_fini(&guard_) == RCL_RET_OK;
        if (subscribed_) clean &= r.rcl_subscription_fini(&subscription_, node_) == RCL_RET_OK;
        waiting_ = guarded_ = subscribed_ = false;
        if (!clean) remember("releasing the subscription: " + rcl_error());
    }

    py::capsule sensor_capsule_, type_support_capsule_;  // keep the core and the type alive
    const cs_sensor_api* api_ = nullptr;
    void* core_ = nullptr;
    const rosidl_message_type_support_t* type_support_ = nullptr;
    rcl_node_t* node_;
    rcl_context_t* context_;
    std::string topic_, topic_name_;
    bool reliable_;
    int64_t max_backlog_;

    std::mutex life_;
    std::thread thread_;
    std::atomic<bool> stopping_{false};
    bool running_ = false, subscribed_ = false, guarded_ = false, waiting_ = false;
    rcl_subscription_t subscription_;
    rcl_guard_condition_t guard_;
    rcl_wait_set_t wait_set_;
    std::array<rcl_event_t, 2> event_;
    std::array<rcl_subscription_event_type_t, 2> event_kind_;
    size_t events_ = 0;
    std::array<std::atomic<rcl_publisher_t*>, 5> publishers_;

    std::atomic<int64_t> lost_{0}, incompatible_{0}, last_policy_kind_{0}, wake_ups_{0},
        taken_{0}, newest_only_{0}, publish_errors_{0}, take_errors_{0};
    mutable std::mutex error_lock_;
    std::string last_error_;
};

}  // namespace

PYBIND11_MODULE(_joint_state_hop, m) {
    m.doc() = "The node's compiled joint-state hop (cpp/hop/joint_state_hop.cpp).";
    py::class_<JointStateHop>(m, "JointStateHop")
        .def(py::init<py::capsule, uintptr_t, uintptr_t, py::capsule, std::string, bool,
                      int64_t>(),
             py::arg("sensor"), py::arg("node"), py::arg("context"), py::arg("type_support"),
             py::arg("topic"), py::arg("reliable"), py::arg("max_backlog"))
        .def("start", &JointStateHop::start)
        .def("stop", &JointStateHop::stop)
        .def("set_publisher", &JointStateHop::set_publisher, py::arg("topic"),
             py::arg("publisher"))
        .def("counts", &JointStateHop::counts)
        .def_property_readonly("topic_name", &JointStateHop::topic_name)
        .def_property_readonly("running", &JointStateHop::running);
}
