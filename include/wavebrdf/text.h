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

}  // namespace wavebrdf
