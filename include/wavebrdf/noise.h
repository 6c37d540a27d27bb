#pragma once
// Simulated measurement noise on BRDF slices, for recovery studies and tests:
//   poisson:N    photon noise: the slice is a photon-count image with N photons expected in
//                all (k_p ~ Poisson(N · R_p / Σ R)), returned in the slice's units (k_p · Σ R / N)
//   gaussian:REL additive read noise: R_p + REL · max(R) · z_p, z_p standard normal, clamped
//                at 0 (a detector reports no negative light)
// The loss matched to each (loss.h): poisson:N for photon noise, mse for Gaussian noise.
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/loss.h"

namespace wavebrdf {

struct Observation;

enum class NoiseKind { None, Poisson, Gaussian };

struct Noise {
    NoiseKind kind = NoiseKind::None;
    double level = 0.0;  // Poisson: photons per slice N (> 0); Gaussian: σ relative to the peak (≥ 0)
};

// Parses "none", "poisson:N" (e.g. poisson:1e4) or "gaussian:REL" (e.g. gaussian:0.01).
// Throws std::invalid_argument naming the text and the accepted forms; std::domain_error,
// naming the text, for N ≤ 0, REL < 0 or values that are not finite.
Noise parse_noise(const std::string& text);
// The text parse_noise reads back to the same Noise.
std::string to_string(const Noise& noise);

// `slice` (non-negative values, any number of channels) with noise drawn from `seed` (the same
// seed gives the same noise). A slice that sums to 0 has no photons to count and is returned
// unchanged under Poisson noise.
std::vector<double> add_noise(const std::vector<double>& slice, const Noise& noise, std::uint64_t seed);

// Adds noise to every observation's reference, observation i with a seed derived from
// (seed, i), so that adding an observation does not change the noise of the others.
void add_noise(std::vector<Observation>& observations, const Noise& noise, std::uint64_t seed);

// The loss whose minimum is the maximum-likelihood estimate under `noise`: poisson:N for
// Poisson noise, mse for Gaussian noise; `fallback` for none.
Loss matched_loss(const Noise& noise, const Loss& fallback);

}  // namespace wavebrdf
