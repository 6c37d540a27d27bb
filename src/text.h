#pragma once
// Internal: numbers in option texts such as "cmsle:0.01" or "poisson:1e4".
#include <cctype>
#include <cstdlib>
#include <string>

#include "wavebrdf/text.h"

namespace wavebrdf::detail {

using wavebrdf::format_shortest;  // wavebrdf/text.h

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
