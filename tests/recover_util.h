#pragma once
// Fixtures shared by the recovery tests: the small isotropic test surface and the distance of two
// fields up to a global phase.
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <vector>

#include "wavebrdf/generate.h"
#include "wavebrdf/heightfield.h"

namespace wavebrdf::test {

// A rows × rows isotropic surface of 2 µm texels (Gaussian correlation `correlation_um`, seeded),
// scaled so that max |H| = peak_um (texel units, vscale 1).
inline Heightfield peak_scaled_surface(int rows, double correlation_um, double peak_um, std::uint64_t seed) {
    SurfaceParams p;
    p.rows = p.cols = rows;
    p.texel_um = 2.0;
    p.correlation_um = correlation_um;
    p.rms_height_um = 1.0;
    p.seed = seed;
    const Heightfield raw = generate_heightfield(p);
    double peak = 0.0;
    for (double v : raw.values()) peak = std::max(peak, std::abs(v));
    std::vector<double> v = raw.values();
    for (double& x : v) x *= peak_um / (peak * p.texel_um);
    return raw.with_values(v);
}

// RMS of a − e^{iφ}b over RMS of a, for the best single phase φ.
inline double distance_up_to_phase(const std::vector<std::complex<double>>& a,
                                   const std::vector<std::complex<double>>& b) {
    std::complex<double> overlap = 0.0;
    double norm = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        overlap += std::conj(b[k]) * a[k];
        norm += std::norm(a[k]);
    }
    const std::complex<double> phase = std::polar(1.0, std::arg(overlap));
    double d = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) d += std::norm(a[k] - phase * b[k]);
    return std::sqrt(d / norm);
}

}  // namespace wavebrdf::test
