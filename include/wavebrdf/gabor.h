#pragma once
// The Gabor kernels of a heightfield that fall inside one coherence window (MODEL.md,
// "Gabor kernels" and "Coherence area"). Everything here is independent of the wavelength
// and of the outgoing direction; the renderers combine it with λ and u.
#include <cstddef>
#include <vector>

#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// Structure-of-arrays list of the kernels k with periodic distance d_k ≤ 3σ_p from the
// footprint centre (the cut of the model). Each texel appears once, at its nearest periodic
// image; positions are stored relative to the footprint centre, which changes every slice
// only by a global phase per direction (so |I|² is unchanged) and keeps phases small.
struct FootprintKernels {
    std::vector<int> row, col;          // texel (i, j), for scattering gradients back
    std::vector<double> dx_um, dy_um;   // δ_k = μ_k − μ_p (nearest periodic image), µm
    std::vector<double> weight;         // c_k · w²: window weight times kernel area, µm
    std::vector<double> height_um;      // H_k = v · w · h[i][j]
    std::vector<double> slope_x, slope_y;  // s_k (dimensionless)
    double sigma_um = 0.0;              // kernel σ = w / 2
    std::size_t size() const { return weight.size(); }
};

// The kernels of `heightfield` within 3σ_p of (x_um, y_um). σ_p > 0 (not checked here;
// validate the Query first).
FootprintKernels footprint_kernels(const Heightfield& heightfield, double x_um, double y_um,
                                   double sigma_p_um);

// Footprint window weight c(d) = exp(−d² / (2σ_p²)) / (√π σ_p) (L2-normalised, ∫c² = 1).
double window_weight(double distance_sq_um2, double sigma_p_um);

}  // namespace wavebrdf
