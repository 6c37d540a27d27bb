#pragma once
// An independent scalar-diffraction simulator: slices of a heightfield computed from the exact
// reflected field e^{−i(4π/λ)H(x)} of a smooth surface through the heights, not from the Gabor
// expansion (docs/model.md §3), to test the recovery against data the model does not explain
// exactly (experiments/2026-11-23-scalar-diffraction-model-check.md).
//
// What it computes, for one observation (query, one wavelength λ, resolution n):
//   I(u) = ∫ W(x − μ_p) e^{−i(4π/λ)H̃(x)} e^{−i2π u·(x − μ_p)} dx,   f_r = c1(ω_i, ω_o, λ) |I(u)|²
// on the slice's grid u = (ω_i + ω_o)/λ (docs/model.md §5, §6), with
//  - H̃ the periodic cubic-convolution interpolant of the heights (Keys 1981, a = −½): through
//    every texel centre, C¹, local (4 × 4 texels), third-order accurate, exact for polynomials of
//    degree ≤ 2 (a tilted plane stays a plane away from the tile's seam);
//  - the OHS vertical wavenumber 4π/λ at every angle (as the model's OHS and ROHS: S = 1;
//    oblique light enters through u only), c1 of the query's model (OHS or ROHS);
//  - W the footprint window: by default as the Gabor model applies it (ScalarWindow::Gabor),
//    W(δ) = Σ_k c_k w² G(δ; δ_k, w/2) over the model's kernels within 3σ_p (gabor.h
//    footprint_kernels: the same weights c_k w², offsets δ_k and cut), so that the simulator
//    and render_slice differ only in the field: they agree exactly for a plane (every tangent
//    plane is the plane), and their distance elsewhere is the Gabor expansion's own error. Or
//    the continuous Gaussian c(δ) = e^{−|δ|²/(2σ_p²)}/(√π σ_p) (ScalarWindow::Gaussian, ∫c² = 1),
//    uncut;
//  - the integral by the midpoint rule on a fine grid of spacing w/m aligned with the texels
//    (m samples per texel; within each texel the interpolant is a polynomial, so the rule
//    converges fast), evaluated at the slice's u exactly as a separable matrix product
//    E_x · F · E_yᵀ (no FFT, no interpolation in u). m starts from ≥ 2 samples per cycle of the
//    highest local frequency |u| + 2 max|∇H̃|/λ and is doubled until the slice changes by less
//    than `tolerance` (relative L2), so the result is converged to that tolerance.
// Conventions of docs/model.md: heights H = v·w·h (µm), e^{−ix} phase, f_r in 1/sr, pixels
// outside the unit disk 0, non-finite c1 written as 0.
#include <complex>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf {


enum class ScalarWindow {
    Gabor,     // the model's window: sampled Gaussian within 3σ_p, each sample spread by G(·, w/2)
    Gaussian,  // the continuous footprint Gaussian, L2-normalised, uncut
};

struct ScalarDiffractionSettings {
    double tolerance = 1e-4;  // relative L2 change of the slice at which the fine grid is converged, 1e-12 … 0.1
    int min_samples_per_texel = 2;    // m starts at least here, 1 … max_samples_per_texel
    int max_samples_per_texel = 256;  // refuse (std::runtime_error) when not converged by this m
    ScalarWindow window = ScalarWindow::Gabor;
    // Largest fine grid, samples per side (bounds memory before allocating: the field and
    // the phase matrices are ~ 16·(P² + 2nP) bytes).
    long long max_grid_side = 16384;
};

// What scalar_field / scalar_slice did: the fine grid they converged on.
struct ScalarDiffractionInfo {
    int samples_per_texel = 0;     // m: fine spacing w/m
    int grid_side = 0;             // fine samples per side P (the window's support)
    double relative_change = 0.0;  // relative L2 change between m/2 and m (0 when m was not doubled)
};

// The complex far field I(u) (µm² · field units, the Gabor model's normalisation: render_slice's
// I) on the whole n × n grid u = (ω_i + ω_o)/λ, row-major, pixels outside the disk included.
// With settings.tolerance ≤ 0 the grid is not refined: m = min_samples_per_texel exactly (for
// convergence studies). Throws std::invalid_argument / std::domain_error naming the bad value
// (query, λ, resolution as render_slice; a model other than OHS / ROHS; settings out of range),
// std::runtime_error when the grid does not converge within max_samples_per_texel, OutOfMemory
// (memory.h) before allocating a grid above max_grid_side or that does not fit.
std::vector<std::complex<double>> scalar_field(const Heightfield& heightfield, const Query& query, double lambda_um,
                                               int resolution, const ScalarDiffractionSettings& settings = {},
                                               ScalarDiffractionInfo* info = nullptr);

// The slice f_r = c1 |I|² (1/sr, n² values row-major, 0 outside the unit disk) of scalar_field;
// comparable value for value with render_slice<double>(heightfield, query, λ, n). Throws as
// scalar_field.
std::vector<double> scalar_slice(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                 const ScalarDiffractionSettings& settings = {}, ScalarDiffractionInfo* info = nullptr);

// ∫ |W|² dx of the window scalar_field uses for `query` on `heightfield`'s tile (µm⁰: W is
// normalised like the model's c_k): for ScalarWindow::Gabor in closed form,
// Σ_k Σ_l c_k c_l w⁴ e^{−|δ_k − δ_l|²/(4σ²)} / (4πσ²), σ = w/2; for Gaussian 1. By Parseval it
// equals ∫|I(u)|² du, whatever the heights.
double scalar_window_energy(const Heightfield& heightfield, const Query& query,
                            ScalarWindow window = ScalarWindow::Gabor);

}  // namespace wavebrdf
