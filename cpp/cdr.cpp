// Serialized ROS 2 messages (cdr.hpp).
#include "cdr.hpp"

#include <cstring>

namespace collision_sensor::cdr {

namespace {

constexpr size_t ENCAPSULATION = 4;
// The longest frame_id read_header takes (bytes, with its NUL).
constexpr uint32_t HEADER_FRAME_MAX = 257;

// True on a little-endian machine (CDR's byte order flag is compared with it).
bool little_endian() {
    const uint16_t one = 1;
    uint8_t first;
    std::memcpy(&first, &one, 1);
    return first == 1;
}

// Reads primitives from data[:size] in the message's byte order, aligned from ENCAPSULATION.
class Reader {
   public:
    Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}

    // The encapsulation: false when it is not plain CDR.
    bool start() {
        if (size_ < ENCAPSULATION || data_[0] != 0 || data_[1] > 1) return false;
        swap_ = (data_[1] == 1) != little_endian();
        at_ = ENCAPSULATION;
        return true;
    }

    template <class T>
    bool read(T* value) {
        if (!align(sizeof(T)) || size_ - at_ < sizeof(T)) return false;
        uint8_t bytes[sizeof(T)];
        std::memcpy(bytes, data_ + at_, sizeof(T));
        if (swap_)
            for (size_t k = 0; k < sizeof(T) / 2; ++k) std::swap(bytes[k], bytes[sizeof(T) - 1 - k]);
        std::memcpy(value, bytes, sizeof(T));
        at_ += sizeof(T);
        return true;
    }

    // A string: its bytes without the NUL (which must be there).
    bool read_string(std::string_view* value, uint32_t max_length = UINT32_MAX) {
        uint32_t length;
        if (!read(&length) || length == 0 || length > max_length || size_ - at_ < length ||
            data_[at_ + length - 1] != 0)
            return false;
        *value = std::string_view(reinterpret_cast<const char*>(data_ + at_), length - 1);
        at_ += length;
        return true;
    }

    // A sequence's count, when count elements of at least `each` bytes can still follow.
    bool read_count(uint32_t* count, size_t each) {
        return read(count) && size_t(*count) <= (size_ - at_) / each;
    }

    // n doubles (the count read already).
    bool read_doubles(uint32_t n, std::vector<double>* out) {
        out->resize(n);
        if (n == 0) return true;
        if (!align(8) || (size_ - at_) / 8 < n) return false;
        std::memcpy(out->data(), data_ + at_, 8 * size_t(n));
        if (swap_)
            for (double& v : *out) {
                uint8_t b[8];
                std::memcpy(b, &v, 8);
                for (int k = 0; k < 4; ++k) std::swap(b[k], b[7 - k]);
                std::memcpy(&v, b, 8);
            }
        at_ += 8 * size_t(n);
        return true;
    }

   private:
    bool align(size_t n) {
        const size_t offset = (at_ - ENCAPSULATION) % n;
        if (offset) {
            if (size_ - at_ < n - offset) return false;
            at_ += n - offset;
        }
        return true;
    }

    const uint8_t* data_;
    size_t size_, at_ = 0;
    bool swap_ = false;
};

bool read_header_fields(Reader& r, Header* header, uint32_t max_frame) {
    std::string_view frame;
    if (!r.read(&header->stamp.sec) || !r.read(&header->stamp.nanosec) ||
        !r.read_string(&frame, max_frame))
        return false;
    header->frame_id.assign(frame);
    return true;
}

// Writes little-endian CDR.
class Writer {
   public:
    explicit Writer(std::vector<uint8_t>* out) : out_(out) {
        out_->assign({0x00, 0x01, 0x00, 0x00});
    }
    template <class T>
    void write(T value) {
        align(sizeof(T));
        uint8_t bytes[sizeof(T)];
        std::memcpy(bytes, &value, sizeof(T));
        if (!little_endian())
            for (size_t k = 0; k < sizeof(T) / 2; ++k) std::swap(bytes[k], bytes[sizeof(T) - 1 - k]);
        out_->insert(out_->end(), bytes, bytes + sizeof(T));
    }
    void write_string(const std::string& s) {
        write(uint32_t(s.size() + 1));
        out_->insert(out_->end(), s.begin(), s.end());
        out_->push_back(0);
    }
    void write_header(const Header& h) {
        write(h.stamp.sec);
        write(h.stamp.nanosec);
        write_string(h.frame_id);
    }

   private:
    void align(size_t n) {
        while ((out_->size() - ENCAPSULATION) % n) out_->push_back(0);
    }
    std::vector<uint8_t>* out_;
};

}  // namespace

std::string read_joint_state(const uint8_t* data, size_t size, JointStateView* out) {
    Reader r(data, size);
    if (!r.start()) return "its encapsulation is not CDR";
    if (!read_header_fields(r, &out->header, UINT32_MAX)) return "its header cannot be read";
    uint32_t n;
    if (!r.read_count(&n, 5)) return "the name sequence runs past the message's end";
    out->names.resize(n);
    for (uint32_t k = 0; k < n; ++k)
        if (!r.read_string(&out->names[k])) return "a name runs past the message's end";
    if (!r.read_count(&n, 8) || !r.read_doubles(n, &out->positions))
        return "the position sequence runs past the message's end";
    // velocity and effort: not used, but a message must hold them whole.
    std::vector<double>& rest = out->rest;
    if (!r.read_count(&n, 8) || !r.read_doubles(n, &rest))
        return "the velocity sequence runs past the message's end";
    if (!r.read_count(&n, 8) || !r.read_doubles(n, &rest))
        return "the effort sequence runs past the message's end";
    return "";
}

Header read_header(const uint8_t* data, size_t size) {
    Header header;
    Reader r(data, size);
    if (r.start() && !read_header_fields(r, &header, HEADER_FRAME_MAX)) {
        // The stamp alone, when the frame cannot be read.
        Reader again(data, size);
        Header stamp_only;
        if (again.start() && again.read(&stamp_only.stamp.sec) &&
            again.read(&stamp_only.stamp.nanosec))
            return stamp_only;
        return Header();
    }
    return header;
}

void write_bool(bool value, std::vector<uint8_t>* out) {
    Writer w(out);
    w.write(uint8_t(value ? 1 : 0));
}

void write_float64(double value, std::vector<uint8_t>* out) {
    Writer w(out);
    w.write(value);
}

void write_diagnostic_array(const Header& header, const std::vector<Status>& statuses,
                            std::vector<uint8_t>* out) {
    Writer w(out);
    w.write_header(header);
    w.write(uint32_t(statuses.size()));
    for (const Status& s : statuses) {
        w.write(s.level);
        w.write_string(s.name);
        w.write_string(s.message);
        w.write_string(s.hardware_id);
        w.write(uint32_t(s.values.size()));
        for (const KeyValue& kv : s.values) {
            w.write_string(kv.key);
            w.write_string(kv.value);
        }
    }
}

void write_stamp(std::vector<uint8_t>* message, Stamp stamp) {
    // Little-endian, as written: sec at 4, nanosec at 8.
    uint8_t* at = message->data() + ENCAPSULATION;
    const uint32_t sec = uint32_t(stamp.sec);
    for (int k = 0; k < 4; ++k) {
        at[k] = uint8_t(sec >> (8 * k));
        at[4 + k] = uint8_t(stamp.nanosec >> (8 * k));
    }
}

}  // namespace collision_sensor::cdr
