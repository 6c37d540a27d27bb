#pragma once
// Internal: numbers in option texts such as "cmsle:0.01" or "poisson:1e4".
#include <cctype>
#include <cstdlib>
#include <string>
#include <utility>

#include "wavebrdf/text.h"

namespace wavebrdf::detail {

using wavebrdf::format_shortest;  // wavebrdf/text.h

// One enum's names, as a table of {value, name}: the value named `name` (false when none is),
// and the name of `value` (nullptr when it has none). The one list that both parse_* and
// to_string read, so a new value is named once.
template <typename Enum, std::size_t N>
bool value_named(const std::pair<Enum, const char*> (&table)[N], const std::string& name, Enum& value) {
    for (const auto& entry : table)
        if (name == entry.second) {
            value = entry.first;
            return true;
        }
    return false;
}
template <typename Enum, std::size_t N>
const char* name_of(const std::pair<Enum, const char*> (&table)[N], Enum value) {
    for (const auto& entry : table)
        if (entry.first == value) return entry.second;
    return nullptr;
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
