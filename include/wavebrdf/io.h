#pragma once
// File input and output: OpenEXR heightfields and images, PNG previews, text files.
// Every writer writes to a temporary file beside the target (named `<path>.tmp-<pid>-<n>`,
// unique per process and write) and renames it into place, so an interrupted or failed write
// never leaves a partial output file, and two writers of one path never mix their contents
// (the last rename wins). A writer replaces only a regular file: when `path` exists and is
// anything else (directory, symbolic link, FIFO, socket, device node such as /dev/null) it
// throws std::runtime_error "<path>: is a ..., not a regular file; refusing to replace it" and
// touches nothing. Symbolic links are refused too, even to a regular file (write to the link's
// target instead); links among the parent directories are followed as usual. (The check and
// the rename are two steps: a file another process puts at `path` in between is replaced.)
// Temporary files in progress are listed in a fixed-size table that a signal handler may empty
// with remove_temporary_files(), so a process killed by a handled signal leaves none behind.
#include <functional>
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
// Per side, channels and tile size: what OpenEXR allocates when it opens a file (line-offset
// tables, compressor and tile buffers) grows with these, so they are checked on the raw header
// before OpenEXR reads it. OpenEXR's own default tile is 64x64.
constexpr long long k_max_exr_side = 16384;
constexpr int k_max_exr_channels = 64;
constexpr long long k_max_exr_tile_pixels = 1024LL * 1024LL;

// Reads the R channel of an OpenEXR file (half or float pixels, any size) as a heightfield in
// the public release's convention (values in units of texel width; row i = image row).
// Throws std::runtime_error naming the file when it is missing, unreadable, corrupt or
// truncated, declares more than k_max_exr_pixels pixels, has no R channel (a single Y channel
// is accepted too), or is a multi-part file of two or more parts (refused rather than silently
// reading part 0; a one-part file written through the multi-part API is read);
// std::domain_error when a value is not finite.
Heightfield read_heightfield_exr(const std::string& path, double texel_um = 1.0, double vscale = 1.0);

// Writes the heightfield's raw values (texel units) as a single-channel float EXR (channel R).
void write_heightfield_exr(const std::string& path, const Heightfield& heightfield);

// Writes a grey PNG preview of a heightfield, min → black, max → white.
void write_heightfield_png(const std::string& path, const Heightfield& heightfield);

// An n × n slice of `channels` (1 or 3) values per pixel (row-major, interleaved, as
// render_observation returns it) as an RGB float image: one channel becomes grey (R = G = B).
RgbImage to_image(const std::vector<double>& slice, int n, int channels);

// Writes an RGB float EXR (channels R, G, B). With `with_alpha`, also an A channel set to 1
// (the layout of genBrdf's output).
void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha = false);

// Reads the R, G, B channels of an EXR (half or float) as linear float. Errors as
// read_heightfield_exr's (k_max_exr_pixels, multi-part files of two or more parts refused).
RgbImage read_rgb_exr(const std::string& path);

// Writes an 8-bit sRGB PNG preview: value · 2^exposure, Reinhard-free clamp to [0, 1], sRGB
// transfer curve. With `tonemap`, x/(1+x) (Reinhard) is applied before the transfer curve.
void write_rgb_png(const std::string& path, const RgbImage& image, double exposure = 0.0, bool tonemap = false);

// Writes a little-endian float64 NumPy .npy array of the given shape (C order), for the
// Python plotting scripts. Atomic like every writer here.
void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const std::vector<double>& data);

// Exposure (in stops) that maps the 99.9th percentile of `slice` to about 4 before Reinhard
// (write_rgb_png's previews of slices); 0 for an empty or non-positive slice.
double auto_exposure(const std::vector<double>& slice);

// Throws std::runtime_error when `path` cannot be created (missing directory, no permission)
// or exists and is not a regular file (see the top of this header), without leaving a file
// behind. Lets a command fail before long work, not after it.
void check_writable(const std::string& path);

// The atomic write every writer here uses: refuses a non-regular `path` (see the top of this
// header), calls `write(temporary_path)`, which must create and fill that file, and renames it
// onto `path`. On any failure the temporary is removed and std::runtime_error naming `path`
// (and the cause) is thrown; an existing `path` is then unchanged.
void write_file_atomically(const std::string& path,
                           const std::function<void(const std::string& temporary_path)>& write);

// Writes `text` (bytes as given, no newline added) to `path` through write_file_atomically.
void write_text_atomically(const std::string& path, const std::string& text);

// Removes (unlink) every temporary file of a write in progress in this process. Async-signal-
// safe: meant for a handler of SIGINT/SIGTERM that then ends the process. The table holds 64
// writes in progress at once with paths up to 4095 bytes; a write beyond that still works but
// its temporary is not removed by this call.
void remove_temporary_files() noexcept;

}  // namespace wavebrdf
