#pragma once
// Internal: the σ_p self-calibration before the field stage (docs/recovery.md,
// "Self-calibration"; experiments/2026-11-23-self-calibration-exposure-sigma.md). The field
// stage needs σ_p close to the true one (σ_p 30 % off leaves its fields at ≈ 1 % and the
// refinement from there can settle in a local minimum), so recover_heights estimates the scale s
// (true σ_p = s · stated) at the blurred fit's heights, before the field stage, and hands the
// field stage, the refinement's σ rounds (which start from it) and the joint position refinement
// σ_p · s.
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

// The mean over every rank's observations (observations_total of them) of the full model's
// loss `loss` at the fixed `heights`, every σ_p scaled by s (> 0); with calibrate_exposure each
// slice scaled by its energy ratio (observation_loss.h observation_misfit). Collective (summed exactly: the same
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

// The second σ_p search, at the field stage's unwrapped heights (≈ 0.4–1 % off, where the
// blurred fit's 5 % bias the first search towards 1: 1.20 for a true 1.30 on seed 9003): the
// scale in [around / k_research_span, around · k_research_span] (around > 0, the first search's
// answer) where scaled_sigma_loss at `heights` is smallest; a golden-section search on log s
// with k_research_evaluations loss evaluations (final bracket ≈ ±0.2 % in s). Collective.
constexpr double k_research_span = 1.25;
constexpr int k_research_evaluations = 12;
double research_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                            const Heightfield& heights, double around, const Loss& loss, bool calibrate_exposure,
                            const Communicator& comm);

// The σ search at the unwrapped heights when there was none before the field stage (exposure
// calibration on): presearch_sigma_scale's wide search at `heights`, kept only where its loss is
// below the stated σ_p's (scale 1) by more than k_guard_margin relative; else 1. Collective.
constexpr double k_guard_margin = 1e-6;
double guarded_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                           const Heightfield& heights, const Loss& loss, bool calibrate_exposure,
                           const Communicator& comm);

// Whether the second search moved the scale from `before` to `after` (both > 0) by more than
// k_research_tolerance (relative, on log s): then the field stage runs again at the new σ_p.
constexpr double k_research_tolerance = 0.02;
bool sigma_scale_moved(double before, double after);

}  // namespace wavebrdf::detail
