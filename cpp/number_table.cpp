// Decimal number tables read from text (number_table.hpp).
#include "number_table.hpp"

#include <charconv>
#include <system_error>

namespace collision_sensor {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// True iff s is [+-] digits [. digits] [(e|E) [+-] digits], with a digit before or after the
// point: the decimal numbers from_chars and Python's float read alike.
bool plain_decimal(std::string_view s) {
    size_t i = 0;
    const size_t n = s.size();
    if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
    size_t digits = 0;
    while (i < n && is_digit(s[i])) ++i, ++digits;
    if (i < n && s[i] == '.') {
        ++i;
        while (i < n && is_digit(s[i])) ++i, ++digits;
    }
    if (digits == 0) return false;
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        ++i;
        if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
        size_t exponent = 0;
        while (i < n && is_digit(s[i])) ++i, ++exponent;
        if (exponent == 0) return false;
    }
    return i == n;
}

// One field, blanks around it allowed: its value, or false.
bool parse_field(std::string_view field, double* value) {
    size_t begin = 0, end = field.size();
    while (begin < end && is_blank(field[begin])) ++begin;
    while (end > begin && is_blank(field[end - 1])) --end;
    std::string_view s = field.substr(begin, end - begin);
    if (!plain_decimal(s)) return false;
    if (s[0] == '+') s.remove_prefix(1);  // from_chars takes no '+'
    const auto [ptr, error] = std::from_chars(s.data(), s.data() + s.size(), *value);
    // Out of range (1e999, 1e-999): Python's float gives inf or 0; the caller's slow path
    // then decides, so such a field is "anything else" here.
    return error == std::errc() && ptr == s.data() + s.size();
}

}  // namespace

int64_t parse_number_table(std::string_view text, int64_t columns, std::vector<double>& values) {
    values.clear();
    if (columns < 1) return -1;
    int64_t rows = 0;
    size_t at = 0;
    while (at < text.size()) {
        size_t eol = text.find('\n', at);
        if (eol == std::string_view::npos) eol = text.size();
        std::string_view line = text.substr(at, eol - at);
        at = eol + 1;
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        size_t k = 0;
        while (k < line.size() && is_blank(line[k])) ++k;
        if (k == line.size()) continue;  // blank
        int64_t fields = 0;
        size_t start = 0;
        while (true) {
            const size_t comma = line.find(',', start);
            const size_t stop = comma == std::string_view::npos ? line.size() : comma;
            if (++fields > columns) return -1;
            double v;
            if (!parse_field(line.substr(start, stop - start), &v)) return -1;
            values.push_back(v);
            if (comma == std::string_view::npos) break;
            start = comma + 1;
        }
        if (fields != columns) return -1;
        ++rows;
    }
    return rows;
}

}  // namespace collision_sensor
