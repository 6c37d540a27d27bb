#pragma once
// How the library's messages name a front end's option, so that options are checked once, in
// the library, and each front end's user reads the name they typed.
#include <algorithm>
#include <string>

namespace wavebrdf {

// How messages name an option: Cli "--lambda-um", Python "lambda_um".
enum class OptionStyle { Cli, Python };

// `key` (an option's Python name, e.g. "lambda_um") in `style`: "--lambda-um" or "lambda_um".
inline std::string option_name(OptionStyle style, const std::string& key) {
    if (style == OptionStyle::Python) return key;
    std::string name = "--" + key;
    std::replace(name.begin(), name.end(), '_', '-');
    return name;
}

}  // namespace wavebrdf
