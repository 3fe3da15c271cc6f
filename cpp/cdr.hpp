// The few ROS 2 messages the sensor core reads and writes, in their serialized form (CDR, as
// rmw hands them over and takes them): no ROS library needed, nothing trusted.
//
// A serialized message is 4 bytes of encapsulation (0x00 0x01: little-endian CDR, 0x00 0x00:
// big-endian), then the fields in order, each primitive aligned to its size counted from the
// byte after the encapsulation; a string is a uint32 length (its bytes plus a NUL), the bytes
// and the NUL; a sequence a uint32 count, then its elements.
//
// Read: sensor_msgs/JointState (header, name[], position[]; velocity[] and effort[] must be
// whole, their values are not kept). Written:
// std_msgs/Bool, std_msgs/Float64, diagnostic_msgs/DiagnosticArray, little-endian.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace collision_sensor::cdr {

struct Stamp {
    int32_t sec = 0;
    uint32_t nanosec = 0;
    bool zero() const { return sec == 0 && nanosec == 0; }
    double seconds() const { return sec + 1e-9 * nanosec; }
};

// A std_msgs/Header: its stamp and frame (bytes as received; escaped where shown).
struct Header {
    Stamp stamp;
    std::string frame_id;
};

// A sensor_msgs/JointState read from its bytes: views into them (valid while they are).
struct JointStateView {
    Header header;
    std::vector<std::string_view> names;
    std::vector<double> positions;
    std::vector<double> rest;  // scratch: velocity, then effort (read to check them)
};

// Read a JointState from data[:size]. Returns "" and fills out, or what is wrong with the
// bytes (one phrase, no text from them: "the name sequence runs past the message's end").
std::string read_joint_state(const uint8_t* data, size_t size, JointStateView* out);

// The header of any serialized message that starts with a std_msgs/Header (stamp, and a frame
// of at most 256 bytes), as far as it can be read; an empty header else.
Header read_header(const uint8_t* data, size_t size);

// A KeyValue and a DiagnosticStatus of diagnostic_msgs (levels as its constants).
constexpr uint8_t LEVEL_OK = 0, LEVEL_WARN = 1, LEVEL_ERROR = 2;
struct KeyValue {
    std::string key, value;
};
struct Status {
    uint8_t level = LEVEL_OK;
    std::string name, message, hardware_id;
    std::vector<KeyValue> values;
};

// Little-endian CDR writers, into out (replaced).
void write_bool(bool value, std::vector<uint8_t>* out);
void write_float64(double value, std::vector<uint8_t>* out);
void write_diagnostic_array(const Header& header, const std::vector<Status>& statuses,
                            std::vector<uint8_t>* out);
// Overwrite the stamp of a serialized message that starts with a header (written by
// write_diagnostic_array): the same array answers many inputs.
void write_stamp(std::vector<uint8_t>* message, Stamp stamp);

}  // namespace collision_sensor::cdr
