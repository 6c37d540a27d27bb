#pragma once
// The Gabor kernels of a heightfield that fall inside one coherence window (docs/model.md,
// §3 and §4). Everything here is independent of the wavelength
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
    std::vector<int> row, col;             // texel (i, j), for scattering gradients back
    std::vector<double> dx_um, dy_um;      // δ_k = μ_k − μ_p (nearest periodic image), µm
    std::vector<double> weight;            // c_k · w²: window weight times kernel area, µm
    std::vector<double> height_um;         // H_k = v · w · h[i][j]
    std::vector<double> slope_x, slope_y;  // s_k (dimensionless)
    double sigma_um = 0.0;                 // kernel σ = w / 2
    std::size_t size() const { return weight.size(); }
};

// The largest footprint a tile supports, in tile periods. Each texel enters the window once,
// at its nearest periodic image, so the window is cut to one tile: at σ_p = P it keeps
// erf(1/2)² ≈ 27 % of its energy, at 10 P erf(1/20)² ≈ 0.3 %, and beyond that the slice is
// mostly the cut (it fades like (P/σ_p)² towards all-zero). Every texel is inside 3σ_p long
// before that (from σ_p ≈ P/4), so a larger footprint adds nothing but the fade.
constexpr double k_max_sigma_p_periods = 10.0;

// Throws std::domain_error naming σ_p, the tile and the allowed range unless
// 0 < sigma_p_um ≤ k_max_sigma_p_periods · max(period_x_um, period_y_um) (all in µm).
void validate_footprint(double sigma_p_um, double period_x_um, double period_y_um);

// The kernels of `heightfield` within 3σ_p of (x_um, y_um). The centre may be any finite
// value: it is reduced modulo the tile period in floating point first (exactly, std::fmod),
// so x_um and x_um + k · period_x_um give the same kernels. σ_p > 0 (validate the Query
// first); throws std::domain_error when σ_p is too large for the tile (validate_footprint).
FootprintKernels footprint_kernels(const Heightfield& heightfield, double x_um, double y_um, double sigma_p_um);

// The Gabor representation of a heightfield within one footprint: its kernels with the
// geometry needed to map them back to texels (the Python GaborRep).
struct GaborRepresentation {
    // The kernels of `heightfield` within 3σ_p of (x_um, y_um), as footprint_kernels (which
    // validates σ_p against the tile).
    GaborRepresentation(const Heightfield& heightfield, double x_um, double y_um, double sigma_p_um);

    // The inverse transform: heightfield values (rows·cols, texel units) with
    // h = H_k / (vscale · texel_um) at each kernel's texel and `fill` (rows·cols values)
    // elsewhere. `height_um`: one kernel height per kernel (µm). Throws std::invalid_argument
    // on a size mismatch and std::domain_error when vscale = 0 (the heights cannot be recovered).
    std::vector<double> heights_from_kernels(const std::vector<double>& height_um, std::vector<double> fill) const;

    FootprintKernels kernels;
    int rows, cols;
    double texel_um, vscale;
    double x_um, y_um, sigma_p_um;  // the footprint the kernels were gathered for
};

// Footprint window weight c(d) = exp(−d² / (2σ_p²)) / (√π σ_p) (L2-normalised, ∫c² = 1).
double window_weight(double distance_sq_um2, double sigma_p_um);

}  // namespace wavebrdf
