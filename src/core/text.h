#pragma once
// Internal: numbers in option texts such as "cmsle:0.01" or "poisson:1e4".
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace wavebrdf::detail {

// Shortest "%.{15,16,17}g" text that reads back as the same double, so that a parsed option
// prints as typed ("0.01", not "0.010000000000000000208") and round-trips exactly.
inline std::string format_shortest(double v) {
    char buf[40];
    for (int precision = 15; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) break;
    }
    return buf;
}

// The number that fills `text` from position `start` on, or throws bad(). strtod accepts
// leading blanks; we do not, so that "cmsle: 1" is not half-accepted.
template <typename Bad>
double parse_number_from(const std::string& text, std::size_t start, Bad bad) {
    const std::string number = text.substr(start);
    if (number.empty() || std::isspace(static_cast<unsigned char>(number[0]))) throw bad();
    char* end = nullptr;
    const double value = std::strtod(number.c_str(), &end);
    if (end != number.c_str() + number.size()) throw bad();
    return value;
}

}  // namespace wavebrdf::detail
