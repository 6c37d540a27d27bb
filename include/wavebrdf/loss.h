#pragma once
// Losses between an estimated and a reference BRDF slice, with their gradients, and the
// reporting metrics of the thesis (its Figure 5.3). Slices are flat arrays of `channels`
// interleaved values per pixel (channels = 1 for a single-wavelength slice, 3 for RGB).
// Every loss is a mean over pixels of a sum over channels, as in the thesis's Definition 3.2:
//   CMSLE(I, R)     = 1/|P| Σ_p Σ_c (log(I + ε) − log(R + ε))²
//   MSE(I, R)       = 1/|P| Σ_p Σ_c (I − R)²
//   amplitude(I, R) = 1/|P| Σ_p Σ_c (√I − √R)²   (the Gaussian-noise loss on amplitudes)
//   poisson(I, R)   = 1/|P| Σ_p Σ_c 2 [k log(k / μ) − (k − μ)],  k = s·R, μ = s·I
//                     the Poisson deviance (negative log-likelihood up to a constant) of photon
//                     counts k for a slice measured with N photons: s = N / Σ R (noise.h)
#include <string>
#include <type_traits>
#include <vector>

namespace wavebrdf {

enum class LossKind { CMSLE, MSE, Amplitude, Poisson };

struct Loss {
    LossKind kind = LossKind::CMSLE;
    double epsilon = 1.0;  // CMSLE's ε (> 0); unused by the others
    double photons = 0.0;  // Poisson: expected photons per slice N (> 0); unused by the others
};

// Parses "cmsle:EPS" (e.g. "cmsle:0.01"; plain "cmsle" means ε = 1), "mse", "amplitude",
// "poisson:N" (N photons per slice, e.g. poisson:1e4) (exact, lower case, no blanks). Throws
// std::invalid_argument naming the text and the accepted forms; std::domain_error, also naming
// the text, for ε or N ≤ 0 or not finite.
Loss parse_loss(const std::string& text);
// The text parse_loss reads back to the same Loss: "cmsle:EPS" with the shortest EPS that
// round-trips (so "cmsle:1", "cmsle:0.01"), "mse", "amplitude", "poisson:N".
std::string to_string(const Loss& loss);

// The loss of `estimate` against `reference` (same size, a multiple of `channels`). When
// `gradient` is not null it receives ∂loss/∂estimate (resized to estimate.size()).
// Negative values (impossible for a BRDF, possible in float noise) are clamped to 0 for the
// log and square root; the amplitude loss uses √(I + 1e-30) so its gradient stays finite at 0.
// The gradient is that of the clamped function: 0 where estimate < 0 (CMSLE, amplitude), the
// one-sided derivative at estimate = 0, so finite differences and line searches see one
// consistent function. Non-finite inputs are not checked and propagate into the result.
// The Poisson loss takes its count scale s = N / Σ R from the reference (Σ R > 0 required) and
// adds 1e-9 counts to k and μ, so its gradient 2 s (1 − k/μ) stays finite where I = 0.
// Throws std::invalid_argument on a size mismatch, a size that is not a multiple of
// `channels`, channels < 1, empty slices (the mean over no pixels is undefined), or a Poisson
// reference that sums to 0; std::domain_error for a CMSLE ε or Poisson N ≤ 0 or not finite.
double loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<double>& reference,
                  int channels, std::vector<double>* gradient = nullptr);
// The same for a reference stored in float (Observation::reference): each value read as double.
// A template for float alone, so that a braced list as the reference ({1.0, 2.0}) selects the
// double overload above instead of being ambiguous between the two.
template <typename Ref, typename = std::enable_if_t<std::is_same_v<Ref, float>>>
double loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                  int channels, std::vector<double>* gradient = nullptr);

// The loss with a weight per pixel: Σ_p w_p Σ_c ℓ(I_pc, R_pc) / Σ_p w_p, the mean of
// loss_value weighted by `weights` (one per pixel: estimate.size() / channels values, each finite
// and ≥ 0, at least one > 0). A pixel of weight 0 (a dead, saturated or unmeasured detector
// pixel) is skipped: neither its estimate nor its reference (which may then be anything, even
// NaN) enters the loss or the gradient. With weights of 0 and 1 this is loss_value of the pixels
// of weight 1 alone; the Poisson loss's count scale is then N / Σ R over the pixels of weight
// > 0. Throws what loss_value throws, and std::invalid_argument for weights of the wrong count,
// a negative or non-finite weight, or all weights 0.
double weighted_loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<float>& reference,
                           int channels, const std::vector<float>& weights, std::vector<double>* gradient = nullptr);
double weighted_loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<double>& reference,
                           int channels, const std::vector<float>& weights, std::vector<double>* gradient = nullptr);

// Reporting metrics (no gradients). Mono slices (channels = 1) are treated as grey RGB, which
// makes both a plain mean over all values; negative values are clamped to 0 first (as above).
// Throws std::invalid_argument on a size mismatch, empty slices, or channels other than 1 or 3
// (spectral slices must be converted to RGB first).
//   rgb_mse        mean over pixels and channels of (T(I) − T(R))², T(x) = x / (1 + x)
//                  (Reinhard's global operator)
//   rgb_gamma_mse  the same with T(x) = (x / (1 + x))^(1/2.2)
double rgb_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels);
double rgb_gamma_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels);
// A float reference (templates for float alone, as loss_value's).
template <typename Ref, typename = std::enable_if_t<std::is_same_v<Ref, float>>>
double rgb_mse(const std::vector<double>& estimate, const std::vector<Ref>& reference, int channels);
template <typename Ref, typename = std::enable_if_t<std::is_same_v<Ref, float>>>
double rgb_gamma_mse(const std::vector<double>& estimate, const std::vector<Ref>& reference, int channels);

// Mean squared difference of two heightfields (same size) after removing each one's mean
// height, which no slice can see. In the squared units of the inputs. Throws
// std::invalid_argument on a size mismatch or empty inputs.
double height_mse(const std::vector<double>& estimate, const std::vector<double>& truth);

}  // namespace wavebrdf
