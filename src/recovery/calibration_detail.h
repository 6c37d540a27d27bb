#pragma once
// Internal: the pieces of the self-calibration (calibration.h) that the recovery stages and
// the run directory call.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "core/golden_section.h"  // golden_section_minimum, the σ_p searches' line search
#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/loss.h"

namespace wavebrdf::detail {

// A slice's exposure a (reference ≈ a · model) as the ratio of its energies, a = Σ R / Σ f over
// the n values (negative ones clamped to 0; 1 when the model is all 0). The energy a window
// sends into the slice hardly depends on the heights (it is the window's, less what leaves the
// disk), so a is right from the first evaluation on, where the fits' closed forms (√a =
// Σ√f√R / Σf for the amplitude loss) are biased low while the model's detail is still wrong
// (measured: the blurred fit then ends at 8 % instead of 1.7 %). It is also the Poisson
// deviance's optimum in a.
double slice_exposure(const float* model, const float* reference, std::size_t n);

// The chain rule through a = Σ R / Σ f: given d = ∂L/∂e of a loss of e = a · f, replaces it by
// dL/df = a d − (a / Σ f) Σ_j d_j f_j (the loss's total derivative through a as well).
void exposure_gradient(double exposure, const float* model, std::size_t n, std::vector<double>& d);

// The σ_p self-calibration's schedule: k_sigma_rounds rounds, each a golden-section search on
// log s (at fixed heights; loss_at(s) is the loss with every σ_p scaled by s) over a bracket
// about the current s (±log 1.5 first, then narrower), then after_round(round, s, loss), which
// refines the heights with σ_p scaled by s and returns false to stop. The first bracket is
// about `initial` (the scale found before the field stage, sigma_search.h). Returns the last s
// (in [0.25, 4]).
constexpr int k_sigma_rounds = 3;
double refine_sigma_scale(const std::function<double(double)>& loss_at,
                          const std::function<bool(int, double, double)>& after_round, double initial = 1.0);

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
