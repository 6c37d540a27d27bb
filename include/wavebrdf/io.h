#pragma once
// File input and output: OpenEXR heightfields and images, PNG previews.
// Every writer writes to a temporary file beside the target and renames it into place,
// so an interrupted or failed write never leaves a partial output file.
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// An RGB image in linear float, row-major, channel-interleaved: data[(i * cols + j) * 3 + c].
struct RgbImage {
    int rows = 0;
    int cols = 0;
    std::vector<float> data;
};

// The most pixels an EXR file read here may declare (16384², the largest heightfield
// `wavebrdf heightfield --size` makes): checked on the header, before any pixel is allocated,
// so a small file declaring a huge data window fails with its size, not std::bad_alloc.
// Not tied to the file size: compressed constant images are legitimately tiny.
constexpr long long k_max_exr_pixels = 16384LL * 16384LL;

// Reads the R channel of an OpenEXR file (half or float pixels, any size) as a heightfield in
// the public release's convention (values in units of texel width; row i = image row).
// Throws std::runtime_error naming the file when it is missing, unreadable, corrupt or
// truncated, declares more than k_max_exr_pixels pixels, or has no R channel (a single Y
// channel is accepted too); std::domain_error when a value is not finite.
Heightfield read_heightfield_exr(const std::string& path, double texel_um = 1.0,
                                 double vscale = 1.0);

// Writes the heightfield's raw values (texel units) as a single-channel float EXR (channel R).
void write_heightfield_exr(const std::string& path, const Heightfield& heightfield);

// Writes a grey PNG preview of a heightfield, min → black, max → white.
void write_heightfield_png(const std::string& path, const Heightfield& heightfield);

// Writes an RGB float EXR (channels R, G, B). With `with_alpha`, also an A channel set to 1
// (the layout of genBrdf's output).
void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha = false);

// Reads the R, G, B channels of an EXR (half or float) as linear float. Throws
// std::runtime_error naming the file as read_heightfield_exr does (k_max_exr_pixels included).
RgbImage read_rgb_exr(const std::string& path);

// Writes an 8-bit sRGB PNG preview: value · 2^exposure, Reinhard-free clamp to [0, 1], sRGB
// transfer curve. With `tonemap`, x/(1+x) (Reinhard) is applied before the transfer curve.
void write_rgb_png(const std::string& path, const RgbImage& image, double exposure = 0.0,
                   bool tonemap = false);

// Writes a little-endian float64 NumPy .npy array of the given shape (C order), for the
// Python plotting scripts. Atomic like every writer here.
void write_npy(const std::string& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data);

// Throws std::runtime_error when `path` cannot be created (missing directory, no permission),
// without leaving a file behind. Lets a command fail before long work, not after it.
void check_writable(const std::string& path);

}  // namespace wavebrdf
