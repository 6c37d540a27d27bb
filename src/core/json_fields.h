#pragma once
// Internal: integer fields of the JSON files we read (observations, checkpoints, run.json).
// nlohmann's get<int>() truncates 8.7 to 8 and wraps 2^40 + 8 to 8; these refuse both.
#include <cmath>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace wavebrdf::detail {

// The integer `value` (called `what` in messages) if it is a JSON integer, or a number with no
// fractional part, within [min, max]; otherwise throws std::runtime_error
// "<what> is <value>; expected an integer from <min> to <max>".
inline long long json_int_value(const nlohmann::json& value, const std::string& what, long long min, long long max) {
    const auto bad = [&] {
        return std::runtime_error(what + " is " + value.dump() + "; expected an integer from " + std::to_string(min) +
                                  " to " + std::to_string(max));
    };
    if (value.is_number_unsigned()) {
        const auto v = value.get<std::uint64_t>();
        if (v > static_cast<std::uint64_t>(max)) throw bad();
        const auto s = static_cast<long long>(v);
        if (s < min) throw bad();
        return s;
    }
    if (value.is_number_integer()) {
        const auto v = value.get<std::int64_t>();
        if (v < min || v > max) throw bad();
        return static_cast<long long>(v);
    }
    if (value.is_number_float()) {
        // 32.0 is an integer written by a tool that only has doubles; 8.7 is not.
        const double v = value.get<double>();
        if (!std::isfinite(v) || std::floor(v) != v || v < static_cast<double>(min) || v > static_cast<double>(max))
            throw bad();
        return static_cast<long long>(v);
    }
    throw bad();
}

// The integer field `key` of object `j` as json_int_value; `where` (e.g. "file: observation 2: ")
// prefixes the message, which also names a missing field.
inline long long json_int(const nlohmann::json& j, const char* key, long long min, long long max,
                          const std::string& where) {
    if (!j.is_object() || !j.contains(key)) throw std::runtime_error(where + "missing field '" + key + "'");
    return json_int_value(j.at(key), where + "field '" + key + "'", min, max);
}

// The same for an int-sized field (min and max within int).
inline int json_int32(const nlohmann::json& j, const char* key, int min, int max, const std::string& where) {
    return static_cast<int>(json_int(j, key, min, max, where));
}

}  // namespace wavebrdf::detail
