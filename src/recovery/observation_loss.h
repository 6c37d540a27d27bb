#pragma once
// Internal: the recovery's observation loss, written once. Every stage that compares the full
// slice model with the observations (the refinement and its σ rounds, the position loop's
// registration and exposures, the σ searches, the convergence check, the error bars) takes
// from here the query of an observation under the run's calibration, the pixels its misfit
// counts and their weights, the exposure, and the loss with its derivative in the slice.
//
// Per-pixel weights (Observation::weights): a pixel of weight 0 (dead, saturated, unmeasured)
// enters nothing here (its reference is never read: it may hold NaN); otherwise each pixel
// counts with its weight. The stages with their own slice models (the blurred fit, the field
// stage, the model check) read filled_observations' copies instead: the field stage's and the
// model check's amplitude losses honour the weights too (amplitude_loss.h); the blurred fit,
// whose blurred images mix neighbouring pixels, reads the filled values.
#include <algorithm>
#include <array>
#include <cstddef>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

// Observation o's query as the run's calibration has it: σ_p × sigma_scale, and the centre
// moved by *offset_um (µm; none when null).
Query calibrated_query(const Observation& o, double sigma_scale, const std::array<double, 2>* offset_um = nullptr);

// The weight of slice value k (pixel k / channels) of o: its pixel's weight, 1 without weights.
inline double value_weight(const Observation& o, std::size_t k) {
    return o.weights.empty() ? 1.0 : double(o.weights[k / std::size_t(o.channels())]);
}

// Σ w·max(0, R) over o's slice values, a value of weight 0 not read (it may be anything).
inline double weighted_reference_total(const Observation& o) {
    double total = 0.0;
    for (std::size_t k = 0; k < o.reference.size(); ++k) {
        const double w = value_weight(o, k);
        if (w != 0.0) total += w * std::max(0.0, double(o.reference[k]));
    }
    return total;
}

// o's exposure a (reference ≈ a · model) for the model slice f: the ratio of energies
// (calibration_detail.h slice_exposure) over the values of weight > 0, each weighted,
// a = Σ w R / Σ w f (negative values clamped to 0; 1 when the model is 0 there).
double observation_exposure(const std::vector<float>& f, const Observation& o);

// The chain rule through that exposure (calibration_detail.h exposure_gradient, weighted):
// d = ∂L/∂e of a loss of e = a · f becomes dL/df.
void observation_exposure_gradient(double exposure, const std::vector<float>& f, const Observation& o,
                                   std::vector<double>& d);

// The misfit of o's model slice f (its full slice model at its calibrated query): `loss` of
// f × exposure against o.reference (observation_slice_loss: the weighted mean over the pixels
// of weight > 0 when o has weights). With calibrate_exposure the exposure is the closed form
// above (*exposure_out receives it), else 1. d_f (when given) receives ∂/∂f, the exposure's
// chain rule included.
double slice_misfit(const Loss& loss, const std::vector<float>& f, const Observation& o, bool calibrate_exposure,
                    std::vector<double>* d_f = nullptr, double* exposure_out = nullptr);

// The misfit of o at `heights` under the calibration (σ_p scale, offset): builds its plan
// (forward-only unless `differentiable`), renders, slice_misfit without a gradient.
double observation_misfit(const Heightfield& heights, const Observation& o, const Loss& loss, double sigma_scale,
                          const std::array<double, 2>* offset_um, bool calibrate_exposure, bool differentiable = true);

// observation_loss (observation.h, weights included) of each observation alone at `heights`,
// their mean over every rank's observations (observations_total of them), summed exactly
// (core/exact_sum.h): the same on every rank for any split.
double mean_observation_loss(const std::vector<Observation>& observations, double observations_total,
                             const Heightfield& heights, const Loss& loss, const Communicator& comm);

// Whether any of `observations` (this rank's) has weights.
bool any_weights(const std::vector<Observation>& observations);

// Copies for the stages whose models read whole slices (the blurred fit's blurred images, the
// field stage's amplitudes, the model check): each value of a pixel of weight 0 replaced by the
// mean of the same channel over the pixels of weight > 0 in the smallest square window about it
// that holds any (finite values where the given ones may be NaN), the weights kept. Only the
// blurred fit reads the filled values; the amplitude losses leave pixels of weight 0 out. (With
// the model check reading the filled values unweighted, a masked specular peak, filled with
// its dim neighbours' mean, made it pick the field model's heights 3 % off over the refined ones
// at 4e-6: experiments/2026-11-30-masked-pixels-model-check.md.)
std::vector<Observation> filled_observations(const std::vector<Observation>& observations);

}  // namespace wavebrdf::detail
