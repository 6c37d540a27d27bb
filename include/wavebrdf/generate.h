#pragma once
// Procedural heightfields, so that a user has inputs without downloading anything.
// All generators are deterministic in `seed` and produce periodic (tileable) surfaces.
#include <cstdint>
#include <string>

#include "wavebrdf/heightfield.h"

namespace wavebrdf {

enum class SurfaceType { Flat, Isotropic, Brushed, Scratched, Grating };

// Parameters of the generators; lengths in µm, heights in µm. Not every field applies to
// every type (see generate_heightfield).
// The most scratches a scratched surface takes: each is a full-period line, so 10000 of the
// default width already cover the largest tile (16384 texels) about once; more only cost time.
constexpr int k_max_scratches = 10000;

struct SurfaceParams {
    SurfaceType type = SurfaceType::Isotropic;
    int rows = 256;
    int cols = 256;
    double texel_um = 1.0;  // texel width w of the result
    std::uint64_t seed = 1;
    // Isotropic / brushed: Gaussian-correlated noise. Exactly one of rms_height_um or
    // rms_slope is used: rms_slope when it is > 0, else rms_height_um.
    double rms_height_um = 0.1;
    double rms_slope = 0.0;       // rms of the slope magnitude per axis (dimensionless)
    double correlation_um = 4.0;  // correlation length (Gaussian autocorrelation 1/e radius)
    double anisotropy = 8.0;      // brushed: correlation along y is this many times longer
    // Scratched: random straight scratches (periodic lines) on a smooth base.
    int scratch_count = 40;  // 0 … k_max_scratches
    double scratch_depth_um = 0.05;
    double scratch_width_um = 1.5;
    // Grating: H(x) = amplitude · sin(2π x / period), x along rows.
    double amplitude_um = 0.1;
    double period_um = 32.0;
};

// Parses "flat", "isotropic", "brushed", "scratched", "grating"; throws std::invalid_argument
// naming the value and the accepted names otherwise.
SurfaceType parse_surface_type(const std::string& name);
const char* to_string(SurfaceType type);

// The heightfield, stored in the public release's convention: values in units of texel width
// (value = height_um / texel_um) with vscale 1 and texel width params.texel_um. Deterministic in
// params.seed (std::mt19937_64 and our own Box–Muller, so one toolchain gives one result).
//   Flat       all zero.
//   Isotropic  Gaussian-correlated Gaussian noise: white noise filtered in the Fourier domain by
//              the square root of the power spectrum of C(r) = σ_h² exp(−r²/ℓ²), ℓ =
//              correlation_um, sampled exactly on the periodic grid (aliasing included). The mean
//              is removed and the field rescaled so that its realised rms height is exactly
//              rms_height_um or, when rms_slope > 0, so that the realised rms of the central-
//              difference slope, sqrt(mean(s_x² + s_y²) / 2), is exactly rms_slope.
//   Brushed    the same with correlation length ℓ along x (rows) and anisotropy · ℓ along y.
//   Scratched  a smooth isotropic base (rms height 0.1 · scratch_depth_um, correlation
//              8 · correlation_um) plus scratch_count straight scratches with the Gaussian
//              groove profile −depth · exp(−d² / (2 (width / 2)²)), d the periodic distance to
//              the scratch. Each scratch runs through a random point in a random direction and
//              is as long as one period along its dominant axis (rows/|cos θ| or cols/|sin θ|
//              texels, whichever is shorter), so axis-aligned (and, on square tiles, diagonal)
//              scratches close into infinite periodic lines; a straight line in a generic
//              direction cannot close on the torus, so those end in rounded caps instead of
//              jumping at the tile border. Where scratches cross, the deeper groove wins (a
//              tool cuts to a depth below the original surface), so the minimum is ≈ −depth.
//   Grating    H = amplitude_um · sin(2π x / period_um), x = (i + ½) · texel_um along rows,
//              constant along columns. Exactly periodic only when period_um divides the tile
//              period rows · texel_um; otherwise the tiling has a kink at the border.
// Every field is validated whatever the type (the defaults are all valid):
//   std::invalid_argument  rows or cols < 1 or > 16384; an unknown type; an isotropic or
//                          brushed request for a non-zero rms on a grid that admits no
//                          zero-mean variation (1×1; or, in rms-slope mode, a grid on which
//                          every central difference vanishes, such as 2×2 or 1×2);
//   std::domain_error      a non-finite value; texel_um, correlation_um, anisotropy,
//                          scratch_width_um or period_um ≤ 0; rms_height_um, rms_slope,
//                          scratch_depth_um or scratch_count < 0; scratch_count >
//                          k_max_scratches.
Heightfield generate_heightfield(const SurfaceParams& params);

// One line saying how generate_heightfield(params) was made, for a file's "made_by" attribute:
// the type, size, seed, texel width and the parameters the type uses, e.g.
// "generate_heightfield type=grating size=256x256 seed=1 texel_um=0.5 amplitude_um=0.1 period_um=32".
std::string describe_surface(const SurfaceParams& params);

// Summary statistics of a heightfield, in µm where dimensional (heights include vscale).
struct HeightStats {
    double mean_um = 0.0;        // mean height (added so the CLI can show the offset of
                                 // scratched surfaces, whose mean is below zero)
    double rms_height_um = 0.0;  // rms deviation from the mean height (R_q)
    double min_um = 0.0;
    double max_um = 0.0;
    double rms_slope = 0.0;  // sqrt(mean(s_x² + s_y²) / 2), s from Heightfield::slope()
};

// Statistics of `heightfield` as above; never throws (a Heightfield is never empty).
HeightStats height_stats(const Heightfield& heightfield);

// `heightfield` scaled about its mean so that its peak-to-valley height (max − min, µm) is
// `range_um`; texel width and vertical scale unchanged. For recovery studies ("heights up to
// ±1 µm"). Throws std::domain_error naming the value for range_um ≤ 0 or not finite, and for
// a flat heightfield (nothing to scale).
Heightfield with_height_range(const Heightfield& heightfield, double range_um);

}  // namespace wavebrdf
