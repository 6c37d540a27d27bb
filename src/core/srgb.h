#pragma once
// Internal: the sRGB transfer curve (IEC 61966-2-1) on [0, 1] and its inverse, shared by the PNG
// writers (io.cpp, preview.cpp) and wavebrdf::srgb_decode (design.h).
#include <cmath>

namespace wavebrdf::detail {

inline double srgb_encode(double linear) {
    return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}
inline double srgb_decode(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

}  // namespace wavebrdf::detail
