#pragma once
// Catmull-Rom cubic interpolation (Keys' cubic convolution with a = −½: interpolating, C¹), the
// one the position calibration's warps, the stitching's patches and the study programs sample
// heights with.
#include <cmath>

namespace wavebrdf::detail {

// The weights of the samples at −1, 0, 1, 2 for a point t ∈ [0, 1) past sample 0.
inline void catmull_rom_weights(double t, double w[4]) {
    const double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2 * t2 - t);
    w[1] = 0.5 * (3 * t3 - 5 * t2 + 2);
    w[2] = 0.5 * (-3 * t3 + 4 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
}

// The bicubic at (r, c) of samples value(i, j) at integer points: the 4 × 4 samples around it,
// summed row by row. `value` decides what the grid's edges are (clamped, periodic, refused).
template <typename Value>
double catmull_rom_bicubic(double r, double c, const Value& value) {
    const int i0 = int(std::floor(r)), j0 = int(std::floor(c));
    double wr[4], wc[4];
    catmull_rom_weights(r - i0, wr);
    catmull_rom_weights(c - j0, wc);
    double s = 0.0;
    for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) s += wr[a] * wc[b] * value(i0 - 1 + a, j0 - 1 + b);
    return s;
}

}  // namespace wavebrdf::detail
