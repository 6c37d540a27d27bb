#pragma once
// Conditioning a measured surface for the model (docs/surfaces.md, "Conditioning"): a crop,
// form removal, invalid points filled, non-square spacing resampled to square texels and the
// tile made periodic, in that order. Every step applied is appended to the surface's metadata
// (key "conditioning", one entry per step, in order) and returned, so that files and runs say
// what was done.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "wavebrdf/surface_file.h"

namespace wavebrdf {

// How points the instrument did not measure (NaN) are filled.
enum class FillMethod {
    Refuse,    // no fill: a step that needs every point, or to_heightfield, refuses them
    Nearest,   // the value of the nearest measured point (Euclidean distance in µm)
    Harmonic,  // Laplace inpainting: the smoothest surface through the measured points
               // (∇²z = 0 on the holes, the measured points fixed, no flux across the grid's edges)
    Mean,      // the mean of the measured points
};

// How the tile is made periodic (the renderer tiles it: docs/model.md §7).
enum class PeriodicMethod {
    None,
    Smooth,  // periodic-plus-smooth decomposition (Moisan 2011): the periodic component, i.e.
             // the surface less the smooth one whose Laplacian is the seam's jumps
    Mirror,  // mirror tiling: the surface and its reflections, 2 rows × 2 cols the size
};

struct ConditioningOptions {
    // R0, C0, ROWS, COLS: keep rows R0 … R0+ROWS−1 and columns C0 … C0+COLS−1 of the file's
    // grid (ROWS, COLS ≥ 2, inside the grid).
    std::optional<std::array<int, 4>> crop;
    // Form removed by least squares over the measured points: a polynomial in x and y of total
    // degree ≤ detrend_order (1: a plane, 2: a quadric, … up to 10); 0 removes the mean; −1: none.
    int detrend_order = -1;
    FillMethod fill = FillMethod::Refuse;
    // Resample to square texels of this width (µm) by bilinear interpolation over the same
    // extent: (cols − 1) · dx / W + 1 columns (rounded down), likewise rows.
    std::optional<double> resample_um;
    PeriodicMethod periodic = PeriodicMethod::None;
};

// What condition() did.
struct ConditioningReport {
    std::vector<std::string> steps;  // one line each, as in the metadata
    // The periodic step's seam: the rms of the height step across the tile's wrap-around
    // (last row to first, last column to first) over the rms of neighbouring differences
    // inside the tile (1: the seam looks like the surface; a tilt gives far more). Negative
    // where there was no periodic step.
    double seam_ratio_before = -1.0;
    double seam_ratio_after = -1.0;
};

// `surface` conditioned by `options`, in the order crop, detrend, fill, resample, periodic.
// Throws std::invalid_argument naming the value for a crop outside the grid, a detrend order
// outside −1 … 10, a resample width not finite and > 0 or giving more than k_max_surface_points
// points or fewer than 2 a side, fewer measured points than the polynomial has terms, and
// unmeasured points left where resample or periodic need them all (their count named, with
// the --fill methods). `report` (optional) receives the steps and the seam ratios.
MeasuredSurface condition(const MeasuredSurface& surface, const ConditioningOptions& options,
                          ConditioningReport* report = nullptr);

// Parsers for the command line and Python, each throwing std::invalid_argument that names
// `option` and the text and lists what is accepted:
//   fill      "none" (refuse), "nearest", "harmonic", "mean"
//   detrend   "none", "mean", "plane", "poly:N" (N = 0 … 10)
//   crop      "R0,C0,ROWS,COLS" (integers)
//   periodic  "none", "smooth", "mirror"
FillMethod parse_fill_method(const std::string& text, const std::string& option);
int parse_detrend(const std::string& text, const std::string& option);
std::array<int, 4> parse_crop(const std::string& text, const std::string& option);
PeriodicMethod parse_periodic_method(const std::string& text, const std::string& option);
const char* to_string(FillMethod method);
const char* to_string(PeriodicMethod method);

// The seam ratio (as in ConditioningReport) of a complete surface (no NaN).
double seam_slope_ratio(const MeasuredSurface& surface);

}  // namespace wavebrdf
