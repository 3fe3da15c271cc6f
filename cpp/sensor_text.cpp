// Text of the sensor core's answers (sensor_text.hpp).
#include "sensor_text.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace collision_sensor::text {

namespace {

// The next character of s from i: its code point, or -1 - byte for a byte that does not start
// a well-formed UTF-8 sequence; *size the bytes it takes.
int64_t next_character(std::string_view s, size_t i, size_t* size) {
    const auto byte = [&](size_t k) { return static_cast<uint8_t>(s[k]); };
    const uint8_t b0 = byte(i);
    *size = 1;
    if (b0 < 0x80) return b0;
    size_t n;
    int64_t cp;
    if (b0 >= 0xC2 && b0 <= 0xDF) {
        n = 2;
        cp = b0 & 0x1F;
    } else if (b0 >= 0xE0 && b0 <= 0xEF) {
        n = 3;
        cp = b0 & 0x0F;
    } else if (b0 >= 0xF0 && b0 <= 0xF4) {
        n = 4;
        cp = b0 & 0x07;
    } else {
        return -1 - int64_t(b0);
    }
    if (i + n > s.size()) return -1 - int64_t(b0);
    for (size_t k = 1; k < n; ++k) {
        const uint8_t b = byte(i + k);
        if ((b & 0xC0) != 0x80) return -1 - int64_t(b0);
        cp = (cp << 6) | (b & 0x3F);
    }
    // Overlong forms, surrogates and values beyond Unicode are not UTF-8.
    if ((n == 3 && cp < 0x800) || (n == 4 && (cp < 0x10000 || cp > 0x10FFFF)) ||
        (cp >= 0xD800 && cp <= 0xDFFF))
        return -1 - int64_t(b0);
    *size = n;
    return cp;
}

std::string escape(int64_t c) {
    char buffer[16];
    if (c < 0) {  // a byte that is not UTF-8, as Python's backslashreplace writes it
        std::snprintf(buffer, sizeof buffer, "\\x%02x", unsigned(-1 - c));
        return buffer;
    }
    switch (c) {
        case '\n': return "\\n";
        case '\r': return "\\r";
        case '\t': return "\\t";
        case '\\': return "\\\\";
        default: break;
    }
    if (c >= 0x20 && c < 0x7F) return std::string(1, char(c));
    if (c < 0x100)
        std::snprintf(buffer, sizeof buffer, "\\x%02x", unsigned(c));
    else if (c < 0x10000)
        std::snprintf(buffer, sizeof buffer, "\\u%04x", unsigned(c));
    else
        std::snprintf(buffer, sizeof buffer, "\\U%08x", unsigned(c));
    return buffer;
}

size_t count_characters(std::string_view s, size_t from) {
    size_t count = 0, size;
    for (size_t i = from; i < s.size(); i += size) {
        next_character(s, i, &size);
        ++count;
    }
    return count;
}

}  // namespace

std::string printable(std::string_view value, size_t limit) {
    if (limit < 16) limit = 16;
    std::vector<std::string> pieces;
    std::vector<size_t> starts;  // the byte where each piece's character starts
    size_t length = 0, size;
    for (size_t i = 0; i < value.size(); i += size) {
        std::string piece = escape(next_character(value, i, &size));
        if (length + piece.size() > limit) {
            // Cut: drop pieces until the tail fits, the tail counting what was left out.
            size_t cut = i;
            auto tail = [&] { return "...(+" + std::to_string(count_characters(value, cut)) +
                                     " chars)"; };
            std::string end = tail();
            while (!pieces.empty() && length + end.size() > limit) {
                length -= pieces.back().size();
                cut = starts.back();
                pieces.pop_back();
                starts.pop_back();
                end = tail();
            }
            std::string out;
            for (const std::string& p : pieces) out += p;
            return out + end;
        }
        length += piece.size();
        pieces.push_back(std::move(piece));
        starts.push_back(i);
    }
    std::string out;
    out.reserve(length);
    for (const std::string& p : pieces) out += p;
    return out;
}

std::string quoted(std::string_view value, size_t limit) {
    return "\"" + printable(value, limit) + "\"";
}

std::string listing(const std::vector<std::string>& items, size_t total, size_t max_items,
                    size_t limit, bool escape_items) {
    const size_t each =
        escape_items ? std::max<size_t>(16, std::min<size_t>(MAX_SHOWN_CHARS, limit / 4)) : limit;
    std::string out;
    size_t shown = 0;
    for (const std::string& item : items) {
        if (shown >= max_items) break;
        if (shown) out += ", ";
        out += escape_items ? printable(item, each) : item;
        ++shown;
    }
    if (out.size() > limit) out = out.substr(0, limit - 3) + "...";
    total = std::max(total, shown);
    if (total > shown) out += " (+" + std::to_string(total - shown) + " more)";
    return out;
}

std::string general(double value, int precision) {
    if (std::isnan(value)) return "nan";
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*g", precision, value);
    return buffer;
}

std::string repr(double value) {
    if (std::isnan(value)) return "nan";
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    char buffer[64];
    const auto done = std::to_chars(buffer, buffer + sizeof buffer, value);
    std::string out(buffer, done.ptr);
    // Python writes exponents from 1e16 up and below 1e-4, and a float that is a whole number
    // with ".0"; to_chars picks the shorter of the two forms.
    const double magnitude = std::fabs(value);
    if (magnitude != 0.0 && (magnitude >= 1e16 || magnitude < 1e-4)) {
        if (out.find('e') == std::string::npos) {
            const auto sci = std::to_chars(buffer, buffer + sizeof buffer, value,
                                           std::chars_format::scientific);
            out.assign(buffer, sci.ptr);
        }
    } else if (out.find('e') != std::string::npos) {
        const auto fixed = std::to_chars(buffer, buffer + sizeof buffer, value,
                                         std::chars_format::fixed);
        out.assign(buffer, fixed.ptr);
    }
    const size_t e = out.find('e');
    if (e != std::string::npos) {
        // Python: at least two exponent digits, always a sign ("1e-05", "1e+16").
        std::string mantissa = out.substr(0, e), exponent = out.substr(e + 1);
        char sign = '+';
        if (!exponent.empty() && (exponent[0] == '-' || exponent[0] == '+')) {
            sign = exponent[0];
            exponent = exponent.substr(1);
        }
        if (exponent.size() < 2) exponent = "0" + exponent;
        return mantissa + "e" + sign + exponent;
    }
    if (out.find('.') == std::string::npos) out += ".0";
    return out;
}

}  // namespace collision_sensor::text
