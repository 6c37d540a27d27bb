#pragma once
// White light (recover.h, docs/recovery.md "White light"): the RGB slices of a broadband
// source are fitted as non-negative colour coordinates. Linear sRGB of a speckled spectrum is
// often negative (out of gamut) where one wavelength dominates a pixel; the amplitude loss
// clamps negatives to 0 and so has no gradient there. The CIE XYZ coordinates
// X, Y, Z = Σ_l x̄, ȳ, z̄ (λ_l) f_l are never negative (the colour-matching functions are not),
// and are a fixed 3 × 3 map of the RGB values: the refinement compares those instead.
#include <array>
#include <vector>

namespace wavebrdf::detail {

// The 3 × 3 map A (row-major) from an RGB slice of wavelengths `lambdas_um` (spectral_mix_weights
// M, N ≥ 2 wavelengths) to non-negative colour coordinates: A·M = the CIE 1931 x̄, ȳ, z̄ at the
// wavelengths (least squares; exact for the renderer's mix, whose rows span these), each row
// scaled so that a constant spectrum maps to (1, 1, 1). Throws as spectral_mix_weights.
std::array<double, 9> xyz_from_rgb(const std::vector<double>& lambdas_um);

// values (3 per pixel, interleaved) ← A · values, pixel by pixel.
void apply_colour_map(const std::array<double, 9>& a, std::vector<double>& values);

// weights (3 per pixel) ← Aᵀ · weights: the adjoint of apply_colour_map.
void apply_colour_map_adjoint(const std::array<double, 9>& a, std::vector<double>& weights);

}  // namespace wavebrdf::detail

#include <functional>

namespace wavebrdf::detail {

// Isolated defects of a refined estimate (docs/recovery.md, White light): a texel left a
// wrap (≈ λ/2 of one wavelength) away from its neighbours is a local minimum of the spectral
// loss the refinement cannot leave. Candidates are the texels whose height h (texel units,
// rows × cols, periodic) differs from the median of its 8 neighbours by more than
// `threshold` robust deviations (1.4826 · the median absolute difference over all texels),
// largest first, at most `max_candidates`; each is set to that median and kept only when
// `loss` (of all heights, collective: the same value on every rank) decreases. Returns the
// number kept. Deterministic: the same heights give the same choices on every rank.
int repair_defects(std::vector<double>& heights, int rows, int cols, double threshold, int max_candidates,
                   const std::function<double(const std::vector<double>&)>& loss);

}  // namespace wavebrdf::detail
