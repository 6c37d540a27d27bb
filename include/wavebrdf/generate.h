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
struct SurfaceParams {
    SurfaceType type = SurfaceType::Isotropic;
    int rows = 256;
    int cols = 256;
    double texel_um = 1.0;          // texel width w of the result
    std::uint64_t seed = 1;
    // Isotropic / brushed: Gaussian-correlated noise. Exactly one of rms_height_um or
    // rms_slope is used: rms_slope when it is > 0, else rms_height_um.
    double rms_height_um = 0.1;
    double rms_slope = 0.0;         // rms of the slope magnitude per axis (dimensionless)
    double correlation_um = 4.0;    // correlation length (Gaussian autocorrelation 1/e radius)
    double anisotropy = 8.0;        // brushed: correlation along y is this many times longer
    // Scratched: random straight scratches (periodic lines) on a smooth base.
    int scratch_count = 40;
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
// (value = height_um / texel_um) with vscale 1. Throws std::invalid_argument /
// std::domain_error on a size < 1, a non-positive length, or a non-finite parameter.
Heightfield generate_heightfield(const SurfaceParams& params);

}  // namespace wavebrdf
