#include "wavebrdf/render_options.h"

#include <stdexcept>
#include <string>

#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// At most 80 bytes of `text`, control characters (a newline) shown as '?': messages are one line.
std::string shown(const std::string& text) {
    std::string out = text.substr(0, 80);
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    return out;
}

}  // namespace

RenderPath parse_render_path(const std::string& text, const std::string& name) {
    if (text == "auto") return RenderPath::Auto;
    if (text == "separable") return RenderPath::Separable;
    if (text == "fft") return RenderPath::Fft;
    if (text == "direct") return RenderPath::Direct;
    throw std::invalid_argument(name + " '" + shown(text) + "' is unknown; expected auto, separable, fft or direct");
}

const char* to_string(RenderPath path) {
    switch (path) {
        case RenderPath::Auto: return "auto";
        case RenderPath::Separable: return "separable";
        case RenderPath::Fft: return "fft";
        case RenderPath::Direct: return "direct";
    }
    return "auto";
}

void validate_render_tolerance(double tolerance, const std::string& name) {
    if (!(tolerance >= k_min_render_tolerance && tolerance <= k_max_render_tolerance))
        throw std::domain_error(name + " " + format_shortest(tolerance) +
                                " is out of range; expected 1e-12 to 1e-2 (an error bound relative to the slice peak)");
}

}  // namespace wavebrdf
