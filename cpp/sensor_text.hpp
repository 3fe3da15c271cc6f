// Text the sensor core writes into answers and log lines: names from the network escaped and
// bounded, numbers as the Python side formats them.
//
// The rules of collision_sensor/untrusted_text.py, for bytes from a message: printable ASCII is
// kept, the backslash doubled, everything else written as an escape (\n, \r, \t, \xNN for other
// ASCII controls and for bytes that are not UTF-8, \uNNNN or \UNNNNNNNN for every character
// beyond ASCII), so the result is one line whose escapes cannot be confused with the text. It
// is stricter than the Python side beyond ASCII (which keeps the characters Python calls
// printable): without Unicode tables here, no character beyond ASCII is shown as it is.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace collision_sensor::text {

// Longest text shown for one value from outside (characters, after escaping).
constexpr size_t MAX_SHOWN_CHARS = 120;

// value as one line of printable ASCII, escaped, cut to limit (>= 16) characters: longer text
// ends in "...(+N chars)", N counting the characters (code points) left out.
std::string printable(std::string_view value, size_t limit = MAX_SHOWN_CHARS);

// printable(value, limit) in double quotes, as log lines name joints and links.
std::string quoted(std::string_view value, size_t limit = MAX_SHOWN_CHARS);

// A bounded, comma-separated list of items: at most max_items shown, the text cut to limit
// characters, then " (+N more)" with N = total - shown. escape: pass each item through
// printable (max(16, min(MAX_SHOWN_CHARS, limit / 4)) each); false for items built from
// quoted parts already.
std::string listing(const std::vector<std::string>& items, size_t total, size_t max_items = 10,
                    size_t limit = 400, bool escape = true);

// Python's format(value, '.<precision>g').
std::string general(double value, int precision);
// Python's repr(value) for a float: the shortest text that reads back as value.
std::string repr(double value);

}  // namespace collision_sensor::text
