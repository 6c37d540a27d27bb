#pragma once
// Vectors and pixel lookups the camera-image tests compute their geometry with by hand.
#include <array>
#include <cmath>
#include <cstddef>

#include "wavebrdf/image.h"

namespace wavebrdf::test {

using Vec3 = std::array<double, 3>;

inline double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross3(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline Vec3 unit(const Vec3& v) {
    const double n = std::sqrt(dot3(v, v));
    return {v[0] / n, v[1] / n, v[2] / n};
}

// Channel `ch` of pixel (r, c).
inline double value_at(const RgbImage& image, int r, int c, int ch = 0) {
    return static_cast<double>(image.data[(std::size_t(r) * image.cols + std::size_t(c)) * 3 + std::size_t(ch)]);
}

// The brightest pixel of channel 0 (the first of equals).
struct Brightest {
    int row = 0, col = 0;
    double value = 0.0;
};
inline Brightest brightest(const RgbImage& image) {
    Brightest b;
    for (int r = 0; r < image.rows; ++r)
        for (int c = 0; c < image.cols; ++c)
            if (value_at(image, r, c) > b.value) b = {r, c, value_at(image, r, c)};
    return b;
}

}  // namespace wavebrdf::test
