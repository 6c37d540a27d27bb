#pragma once
// Measured surface topographies: the files of profilometers, interferometers, confocal and
// focus-variation microscopes and AFMs (docs/surfaces.md, "Formats"), read by their content and
// written by the target's extension.
//
// A measured surface is kept as the instrument gave it: heights in µm on a grid whose spacing
// may differ along x and y, with points the instrument did not measure as NaN. It becomes the
// model's Heightfield (square texels, finite values) only through to_heightfield, which refuses
// what needs conditioning first (`wavebrdf convert --resample-um W --fill METHOD`).
//
// Orientation: a MeasuredSurface is an image, row-major, rows along y and columns along x:
// heights_um[r * cols + c] is the height at x = c · dx_um, y = r · dy_um. This is how x3p, SDF,
// SUR, PLU, AL3D, MetroPro and Gwyddion store and show surfaces. The model's Heightfield runs its
// row index along x (docs/model.md §2), so to_heightfield and from_heightfield transpose: both
// describe the same surface z(x, y), with x and y where the instrument put them.
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// Heights as the instrument gave them.
struct MeasuredSurface {
    int rows = 0;                    // points along y
    int cols = 0;                    // points along x
    double dx_um = 0;                // spacing along x (between columns), µm, > 0
    double dy_um = 0;                // spacing along y (between rows), µm, > 0
    std::vector<double> heights_um;  // rows · cols heights in µm, row-major; NaN = not measured
    // The format it was read from or is meant for: "x3p", "sdf", "datx", "metropro", "sur",
    // "plu", "al3d", "npy", "text" or "exr".
    std::string format;
    // What the file says about itself (instrument, date, comment, ...) and, appended by the
    // conditioning, each step applied, as (key, value) pairs in file order.
    std::vector<std::pair<std::string, std::string>> metadata;

    // The number of NaN heights.
    std::size_t invalid_count() const;
    // The value of metadata `key` (the first one), or "" when there is none.
    std::string meta(const std::string& key) const;
};

// Bounds every reader checks before allocating: points per side and in all (the largest
// heightfield the project makes is 16384²), and the size of a file read whole.
constexpr long long k_max_surface_side = 65536;
constexpr long long k_max_surface_points = 16384LL * 16384LL;
constexpr long long k_max_surface_file_bytes = 4LL << 30;

// Reads a measured surface, recognising its format by content (magic bytes, not the
// extension; a plain text matrix is the one format recognised by being text):
//   x3p (ISO 25178-72), sdf (ISO 25178-71, ASCII and binary), metropro (Zygo .dat), sur
//   (Digital Surf), plu (Sensofar), al3d (Alicona), npy (NumPy 1.0–3.0:
//   float32/float64, either byte order, C or Fortran order), text (a matrix of numbers, one
//   line per row along y, NaN accepted), exr (a wavebrdf heightfield EXR, transposed as above).
//   datx (Zygo, HDF5: read by the HDF5 plugin; a build without HDF5 recognises it and says
//   so).
// spacing_um: the spacing (µm, both axes) for formats that carry none (npy, text); ignored
// with a file that states its own. Throws std::runtime_error with one line naming the file
// when it is missing, unreadable, of no known format, of an unsupported variant (which one is
// named), truncated, or declares more than it holds or than the bounds above; when a npy or
// text file has no spacing_um; std::domain_error when spacing_um is not finite and > 0.
MeasuredSurface read_surface(const std::string& path, std::optional<double> spacing_um = std::nullopt);

// The same from bytes already in memory (`name` is used in messages); the fuzz targets call it.
// EXR is read from a temporary file.
MeasuredSurface read_surface_bytes(const std::string& bytes, const std::string& name,
                                   std::optional<double> spacing_um = std::nullopt);

// The same, read as `format` ("x3p", "sdf", "datx", "metropro", "sur", "plu", "al3d", "npy",
// "text") whatever the bytes look like: for files whose format is known. The fuzz targets use it
// to aim at one reader. std::invalid_argument for an unknown format name.
MeasuredSurface read_surface_as(const std::string& bytes, const std::string& format, const std::string& name,
                                std::optional<double> spacing_um = std::nullopt);

// The format `bytes` look like ("x3p", ..., "text"), or "" when none: what read_surface uses.
std::string detect_surface_format(const std::string& bytes);

// True when the file at `path` starts with the OpenEXR magic number (an unreadable file: false).
bool is_exr_file(const std::string& path);

// Writes `surface` in the format of `path`'s extension (case-insensitive): .x3p (ISO 25178-72,
// float64, with main.xml's MD5 of the data), .sdf (ISO 25178-71 binary, float64), .npy
// (float64, little-endian, C order, shape (rows, cols), heights in µm; no spacing), .exr (a
// heightfield EXR: square spacing and no NaN required, as to_heightfield). Written to a
// temporary file and renamed (io.h). Throws std::invalid_argument for another extension (the
// message lists these four), for a surface whose size or spacing is invalid, or for NaN in a
// format that cannot hold it (exr); std::runtime_error when writing fails.
void write_surface(const std::string& path, const MeasuredSurface& surface);

// The model's heightfield of a measured surface: transposed (see the top), texel width
// texel_um (default: the spacing), vertical scale vscale (default 1), values
// heights_um / (vscale · texel_um) so that the heights in µm are kept. Throws
// std::invalid_argument with one line when the spacing is not square (relative difference over
// 1e-6) or there are NaN heights, naming their count and `wavebrdf convert IN OUT
// --resample-um W --fill METHOD`; `name` (a path) leads the message.
Heightfield to_heightfield(const MeasuredSurface& surface, const std::string& name,
                           std::optional<double> texel_um = std::nullopt, std::optional<double> vscale = std::nullopt);

// The measured surface of a heightfield: heights v · w · h in µm, spacing w on both axes,
// transposed (see the top); format `format`, metadata texel_um, vscale.
MeasuredSurface from_heightfield(const Heightfield& heightfield, const std::string& format = "exr");

}  // namespace wavebrdf
