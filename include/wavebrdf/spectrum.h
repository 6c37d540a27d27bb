#pragma once
// Wavelength sampling and the conversion of spectral BRDF values to linear sRGB.
#include <array>
#include <cstddef>
#include <vector>

namespace wavebrdf {

// CIE 1931 2° colour-matching functions (x̄, ȳ, z̄) at a wavelength in µm, linearly
// interpolated in the tabulated CIE data (360–830 nm); zero outside.
std::array<double, 3> cie1931_xyz(double lambda_um);

// N wavelengths spread over the visible range the reference program uses,
// λ_k = 0.36 + (k + ½) · 0.47 / N µm (N = 8 gives genBrdf's samples), 1 ≤ N ≤
// k_max_spectral_samples (256: 1.8 nm steps, as the CLI's --spectral allows); throws
// std::invalid_argument otherwise.
constexpr int k_max_spectral_samples = 256;
std::vector<double> spectral_wavelengths_um(int count);

// Per-wavelength weights (a 3 × N matrix, row-major: weights[c * N + k]) that map the
// values f(λ_k) at the given wavelengths to linear sRGB (Rec. 709 primaries, D65 white):
// CIE 1931 at the sampled wavelengths (Riemann sum, Y normalised so that a constant
// spectrum has Y = 1), then a Bradford adaptation of that sampled equal-energy white to D65,
// then XYZ → linear sRGB. So a constant spectrum c maps exactly (to rounding) to (c, c, c).
// Wavelengths in µm, any order; each sample's Δλ is half the distance to each neighbour (the
// end ones: the full distance to their neighbour, so an equally spaced grid gets equal Δλ;
// equal wavelengths share one Δλ). Samples outside 360–830 nm get zero weight.
// Throws std::invalid_argument on an empty list, std::domain_error on a non-positive or
// non-finite wavelength and when the sampled white has Y ≤ 0 (no sample inside 360–830 nm).
std::vector<double> spectral_to_srgb_weights(const std::vector<double>& lambdas_um);

// The spectral mix of the renderer (render_rgb, SlicePlan, observation_loss and the Python
// bindings all use these three): the 3 × N matrix M (row-major, M[c * N + l]) that maps the
// slices f_l of N wavelengths to RGB, rgb_c = Σ_l M[c, l] f_l. N ≥ 2: spectral_to_srgb_weights;
// one wavelength: (1, 1, 1), its slice in R, G and B. Throws as spectral_to_srgb_weights.
std::vector<double> spectral_mix_weights(const std::vector<double>& lambdas_um);

// Forward: adds wavelength `wavelength`'s slice (pixels values) into `rgb` (3 · pixels,
// channel-interleaved): rgb[3p + c] += Float(mix[c · N + wavelength]) · slice[p], N =
// mix.size() / 3. Called once per wavelength on a zeroed `rgb`, it is the whole mix. Throws
// std::invalid_argument on a size mismatch or a wavelength ≥ N. Float: float or double.
template <typename Float>
void mix_spectral_to_rgb(const std::vector<double>& mix, std::size_t wavelength, const std::vector<Float>& slice,
                         std::vector<Float>& rgb);

// Adjoint: the weights of wavelength `wavelength`'s slice for RGB weights `rgb_weights`
// (3 · pixels): weights[p] = Float(scale · Σ_c mix[c · N + wavelength] · rgb_weights[3p + c]),
// overwritten (resized to pixels). So Σ_l weights_l · f_l = scale · Σ rgb_weights · rgb.
// Throws std::invalid_argument on a size mismatch or a wavelength ≥ N.
template <typename Float>
void mix_spectral_to_rgb_adjoint(const std::vector<double>& mix, std::size_t wavelength,
                                 const std::vector<double>& rgb_weights, std::vector<Float>& weights,
                                 double scale = 1.0);

// XYZ (D65-relative) → linear sRGB matrix (row-major), derived from the Rec. 709 primaries
// and the D65 chromaticity (0.3127, 0.3290): D65 with Y = 1 maps to (1, 1, 1).
std::array<double, 9> xyz_to_linear_srgb();

}  // namespace wavebrdf
