// Decimal number tables read from text (the body of a recorded joint-state CSV file): the
// fast path of collision_sensor/model/sequences.py, which reads anything else, and reports
// every fault, with Python's own parser.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

namespace collision_sensor {

// Parse text of lines of `columns` comma-separated decimal numbers into values (row-major),
// and return the number of rows; or -1 when the text is anything else (a field that is not a
// plain decimal number: empty, "nan", hexadecimal, quoted; a line with another number of
// fields), leaving values unspecified. Lines end in "\n" or "\r\n"; blank lines (spaces and
// tabs only) are skipped, as are spaces and tabs around a field. A number is an optional
// sign, digits with at most one '.', and an optional exponent; each is the double nearest to
// it (std::from_chars: correctly rounded, as Python's float).
int64_t parse_number_table(std::string_view text, int64_t columns, std::vector<double>& values);

}  // namespace collision_sensor
