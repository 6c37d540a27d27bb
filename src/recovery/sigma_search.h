#pragma once
// Internal: the σ_p self-calibration before the field stage (docs/recovery.md,
// "Self-calibration", "σ_p before the field stage"). The field stage needs σ_p close to the
// true one (σ_p 30 % off leaves its fields at ≈ 1 % and the refinement from there can settle in
// a local minimum), so recover_heights estimates the scale s (true σ_p = s · stated) at the
// blurred fit's heights, before the field stage, and hands the field stage, the refinement's σ
// rounds (which start from it) and the joint position refinement σ_p · s.
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

// The mean over every rank's observations (observations_total of them) of the full model's
// loss `loss` at the fixed `heights`, every σ_p scaled by s (> 0); with calibrate_exposure each
// slice scaled by its energy ratio (calibration_detail.h). Collective (summed exactly: the same
// bits for any thread count and split over ranks). Throws as SlicePlan does for a footprint that
// does not fit.
double scaled_sigma_loss(const std::vector<Observation>& observations, double observations_total,
                         const Heightfield& heights, double s, const Loss& loss, bool calibrate_exposure,
                         const Communicator& comm);

// The σ_p scale s in [1/2, 2] where scaled_sigma_loss at `heights` is smallest: a golden-section
// search on log s with k_presearch_evaluations loss evaluations (final bracket ≈ ±0.3 % in s).
// Collective.
constexpr int k_presearch_evaluations = 14;
double presearch_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                             const Heightfield& heights, const Loss& loss, bool calibrate_exposure,
                             const Communicator& comm);

}  // namespace wavebrdf::detail
