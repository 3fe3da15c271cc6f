// The floor of a joint-state -> verdict hop with a depth camera beside it: the floor folder's C
// echo over rcl (take JointState serialized, publish a DiagnosticArray carrying its header), which
// also takes every PointCloud2 on "points" (sensor-data QoS, serialized) and drops it. What a
// receiver of the camera pays at the bottom of ROS 2, with no Python and no checking.
#include <rcl/rcl.h>
#include <rmw/qos_profiles.h>
#include <rmw/rmw.h>
#include <rcutils/allocator.h>
#include <rosidl_runtime_c/message_type_support_struct.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

const rosidl_message_type_support_t *
rosidl_typesupport_c__get_message_type_support_handle__sensor_msgs__msg__JointState(void);
const rosidl_message_type_support_t *
rosidl_typesupport_c__get_message_type_support_handle__sensor_msgs__msg__PointCloud2(void);
const rosidl_message_type_support_t *
rosidl_typesupport_c__get_message_type_support_handle__diagnostic_msgs__msg__DiagnosticArray(void);

static volatile int run = 1;
static void stop(int s) { (void)s; run = 0; }

// Subscribe `topic` with `qos` (depth 100 when reliable); false on failure.
static int subscribe(rcl_subscription_t *sub, rcl_node_t *node,
                     const rosidl_message_type_support_t *type, const char *topic,
                     rmw_qos_profile_t qos) {
    rcl_subscription_options_t options = rcl_subscription_get_default_options();
    options.qos = qos;
    if (qos.reliability == RMW_QOS_POLICY_RELIABILITY_RELIABLE) options.qos.depth = 100;
    *sub = rcl_get_zero_initialized_subscription();
    return rcl_subscription_init(sub, node, type, topic, &options) == RCL_RET_OK;
}

int main(int argc, char **argv) {
    signal(SIGINT, stop);
    signal(SIGTERM, stop);
    const char *ns = argc > 1 ? argv[1] : "/floor";
    rcl_allocator_t al = rcl_get_default_allocator();
    rcl_init_options_t io = rcl_get_zero_initialized_init_options();
    rcl_init_options_init(&io, al);
    rcl_context_t ctx = rcl_get_zero_initialized_context();
    if (rcl_init(argc, (const char *const *)argv, &io, &ctx) != RCL_RET_OK) return 1;
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_node_options_t no = rcl_node_get_default_options();
    if (rcl_node_init(&node, "echo_rcl_camera", ns, &ctx, &no) != RCL_RET_OK) return 1;

    rcl_subscription_t states, clouds;
    if (!subscribe(&states, &node,
                   rosidl_typesupport_c__get_message_type_support_handle__sensor_msgs__msg__JointState(),
                   "joint_states", rmw_qos_profile_default) ||
        !subscribe(&clouds, &node,
                   rosidl_typesupport_c__get_message_type_support_handle__sensor_msgs__msg__PointCloud2(),
                   "points", rmw_qos_profile_sensor_data))
        return 1;
    rcl_publisher_t pub = rcl_get_zero_initialized_publisher();
    rcl_publisher_options_t po = rcl_publisher_get_default_options();
    po.qos = rmw_qos_profile_default;
    po.qos.depth = 100;
    if (rcl_publisher_init(
            &pub, &node,
            rosidl_typesupport_c__get_message_type_support_handle__diagnostic_msgs__msg__DiagnosticArray(),
            "colliding_pairs", &po) != RCL_RET_OK) return 1;

    rcl_wait_set_t ws = rcl_get_zero_initialized_wait_set();
    rcl_wait_set_init(&ws, 2, 0, 0, 0, 0, 0, &ctx, al);
    rmw_serialized_message_t in = rmw_get_zero_initialized_serialized_message();
    rmw_serialized_message_init(&in, 4096, &al);
    rmw_serialized_message_t cloud = rmw_get_zero_initialized_serialized_message();
    rmw_serialized_message_init(&cloud, 8u << 20, &al);
    rmw_serialized_message_t out = rmw_get_zero_initialized_serialized_message();
    rmw_serialized_message_init(&out, 64, &al);
    unsigned long clouds_taken = 0;
    fprintf(stderr, "ready\n");
    while (run) {
        rcl_wait_set_clear(&ws);
        rcl_wait_set_add_subscription(&ws, &states, NULL);
        rcl_wait_set_add_subscription(&ws, &clouds, NULL);
        if (rcl_wait(&ws, RCL_MS_TO_NS(100)) != RCL_RET_OK) continue;
        for (;;) {   // joint states first, as the floor's echo answers them
            rmw_message_info_t info;
            if (rcl_take_serialized_message(&states, &in, &info, NULL) != RCL_RET_OK) break;
            unsigned char *o = out.buffer;
            memcpy(o, in.buffer, 12);   // encapsulation and stamp; frame_id empty, no status
            unsigned int one = 1, zero = 0;
            memcpy(o + 12, &one, 4);
            o[16] = o[17] = o[18] = o[19] = 0;
            memcpy(o + 20, &zero, 4);
            out.buffer_length = 24;
            rcl_publish_serialized_message(&pub, &out, NULL);
        }
        for (;;) {
            rmw_message_info_t info;
            if (rcl_take_serialized_message(&clouds, &cloud, &info, NULL) != RCL_RET_OK) break;
            clouds_taken++;
        }
    }
    fprintf(stderr, "clouds taken: %lu\n", clouds_taken);
    return 0;
}
