#pragma once
// Numbers in messages and option texts, the same in the library, the CLI and the bindings.
#include <cstdio>
#include <cstdlib>
#include <string>

namespace wavebrdf {

// Shortest "%.{15,16,17}g" text that reads back as the same double, so that a parsed option
// prints as typed ("0.01", not "0.010000000000000000208") and round-trips exactly; "nan",
// "inf" and "-inf" for the non-finite values.
inline std::string format_shortest(double v) {
    char buf[40];
    for (int precision = 15; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) break;
    }
    return buf;
}

// `v` by one printf conversion for doubles ("%.3g", "%.2f", …): the numbers of notes, plan
// lines and warnings, which are read, not parsed back (those use format_shortest).
inline std::string format_number(double v, const char* format) {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

// `v` with `digits` digits after the point ("%.*f").
inline std::string format_fixed(double v, int digits) {
    char buf[352];  // DBL_MAX in %f is 309 digits before the point
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

}  // namespace wavebrdf
