#pragma once
// Losses between an estimated and a reference BRDF slice, with their gradients, and the
// reporting metrics of the thesis (its Figure 5.3). Slices are flat arrays of `channels`
// interleaved values per pixel (channels = 1 for a single-wavelength slice, 3 for RGB).
// Every loss is a mean over pixels of a sum over channels, as in the thesis's Definition 3.2:
//   CMSLE(I, R)     = 1/|P| Σ_p Σ_c (log(I + ε) − log(R + ε))²
//   MSE(I, R)       = 1/|P| Σ_p Σ_c (I − R)²
//   amplitude(I, R) = 1/|P| Σ_p Σ_c (√I − √R)²   (the Gaussian-noise loss on amplitudes)
#include <string>
#include <vector>

namespace wavebrdf {

enum class LossKind { CMSLE, MSE, Amplitude };

struct Loss {
    LossKind kind = LossKind::CMSLE;
    double epsilon = 1.0;  // CMSLE's ε (> 0); unused by the others
};

// Parses "cmsle:EPS" (e.g. "cmsle:0.01"; plain "cmsle" means ε = 1), "mse", "amplitude".
// Throws std::invalid_argument naming the text and the accepted forms; std::domain_error for
// ε ≤ 0 or not finite.
Loss parse_loss(const std::string& text);
std::string to_string(const Loss& loss);

// The loss of `estimate` against `reference` (same size, a multiple of `channels`). When
// `gradient` is not null it receives ∂loss/∂estimate (resized to estimate.size()).
// Negative values (impossible for a BRDF, possible in float noise) are clamped to 0 for the
// log and square root; the amplitude loss uses √(I + 1e-30) so its gradient stays finite at 0.
// Throws std::invalid_argument on a size mismatch or channels < 1.
double loss_value(const Loss& loss, const std::vector<double>& estimate,
                  const std::vector<double>& reference, int channels,
                  std::vector<double>* gradient = nullptr);

// Reporting metrics (no gradients). Mono slices (channels = 1) are treated as grey RGB.
//   rgb_mse        mean over pixels and channels of (T(I) − T(R))², T(x) = x / (1 + x)
//                  (Reinhard's global operator)
//   rgb_gamma_mse  the same with T(x) = (x / (1 + x))^(1/2.2)
double rgb_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels);
double rgb_gamma_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels);

// Mean squared difference of two heightfields (same size) after removing each one's mean
// height, which no slice can see. In the units of the inputs.
double height_mse(const std::vector<double>& estimate, const std::vector<double>& truth);

}  // namespace wavebrdf
