/* The sensor core's C interface, for compiled callers in other extension modules (the node's
 * joint-state hop, collision_sensor/ros/joint_state_hop.cpp): what engine.SensorCore.api()
 * returns, a PyCapsule named CS_SENSOR_API_CAPSULE holding a cs_sensor_handle. Plain C types
 * only, so that the two modules share no C++ ABI; the version changes with any change here. */
#ifndef COLLISION_SENSOR_SENSOR_API_H
#define COLLISION_SENSOR_SENSOR_API_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define CS_SENSOR_API_VERSION 1
#define CS_SENSOR_API_CAPSULE "collision_sensor.SensorCore.api"

/* Publish one message of an answer: topic is one of engine.TOPIC_*; the bytes are serialized
 * (CDR) and valid during the call. Called with the core's mutex held. */
typedef void (*cs_publish_fn)(void* context, int topic, const uint8_t* data, size_t size);

typedef struct cs_sensor_api {
    int version;
    /* Answers go to publish(context, ...) from now on; NULL: to the core's outbox. */
    void (*set_publisher)(void* core, cs_publish_fn publish, void* context);
    /* Answer serialized sensor_msgs/JointState messages data[k][:sizes[k]] in order, or with
     * newest_only merge them all and answer only the newest accepted; now: the steady clock
     * (CLOCK_MONOTONIC) in s. */
    void (*take_batch)(void* core, const uint8_t* const* data, const size_t* sizes, size_t n,
                       int newest_only, double now);
} cs_sensor_api;

typedef struct cs_sensor_handle {
    const cs_sensor_api* api;
    void* core;  /* the first argument of every api function */
    void* owner; /* keeps the core alive while the capsule lives (the module's own) */
} cs_sensor_handle;

#ifdef __cplusplus
}
#endif

#endif
