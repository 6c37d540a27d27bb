#pragma once
// Internal: the pieces of the self-calibration (calibration.h) that the recovery stages and
// the run directory call.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/loss.h"

namespace wavebrdf::detail {

// The exposure a ≥ 0 that minimises loss(a · f, R) over one slice (n values, negative ones
// clamped to 0 as the losses do), in closed form:
//   amplitude  √a = Σ √f √R / Σ f
//   mse        a = Σ f R / Σ f²
//   poisson    a = Σ R / Σ f   (the deviance's minimum in a)
//   cmsle      the amplitude one (no closed form).
// At that a the loss's gradient with respect to f (at fixed a) is the gradient of the
// minimised loss (variable projection). 1 when the model slice is all 0.
double optimal_exposure(const Loss& loss, const float* model, const double* reference, std::size_t n);

// The x in [lo, hi] where f is smallest, by golden-section search with `evaluations` (≥ 3)
// calls of f; *value (when given) receives f there.
double golden_section_minimum(const std::function<double(double)>& f, double lo, double hi, int evaluations,
                              double* value = nullptr);

// The σ_p self-calibration's schedule: k_sigma_rounds rounds, each a golden-section search on
// log s (at fixed heights; loss_at(s) is the loss with every σ_p scaled by s) over a bracket
// about the current s (±log 1.5 first, then narrower), then after_round(round, s, loss), which
// refines the heights with σ_p scaled by s and returns false to stop. Returns the last s
// (in [0.25, 4]).
constexpr int k_sigma_rounds = 3;
double refine_sigma_scale(const std::function<double(double)>& loss_at,
                          const std::function<bool(int, double, double)>& after_round);

// Every rank's per-observation entries of `mine` (this rank's share: `share` holds their
// indices among all `total` observations) on rank 0, in the run's order (empty vectors stay
// empty; sigma_p_scale is rank 0's). Collective; the others get an empty Calibration.
Calibration gathered_calibration(const Calibration& mine, const std::vector<std::size_t>& share, std::size_t total,
                                 const Communicator& comm);

// calibration.json: what was refined (`refined`), the estimate's values and, with `truth`
// (the simulated acquisition errors), the true values and the estimate's errors: rms and
// maximum of a_est / a_true − 1, rms of the position offset's error (µm), σ_p scale error.
std::string calibration_json(const CalibrationSettings& refined, const Calibration& estimate, const Calibration* truth);

}  // namespace wavebrdf::detail
