#pragma once
// Internal: the refinement stage (recover.h, stage 3) with the footprint positions refined
// together with the heights (self-calibration of positions, calibration.h; docs/recovery.md,
// "Self-calibration").
//
// The L-BFGS variables are the heights (texel units) and one offset (dx, dy) per footprint
// position: observations at the same stated centre (x_um, y_um, equal bits) share it, as the
// stage put every wavelength there. Offsets are variables in texels (offset_um = texel_um · t).
// Gauge: a common shift of every position is a shift of the surface, which the slices cannot
// see; the offsets used are t − mean(t) per coordinate (the mean is removed, so the gradient
// with respect to t has zero mean too, and the returned offsets have mean 0).
// Under MPI the positions are gathered from every rank and sorted (x, then y), so the
// variables are the same on every rank and for any split; their gradients are summed exactly
// (core/exact_sum.h) with the heights', so 1, 2, 3 ranks give the same bits.
#include <array>
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "recovery/refinement.h"

namespace wavebrdf::detail {

// Distinct stated footprint centres of every rank's observations, sorted; index[i] is this
// rank's observation i's position (collective).
std::vector<std::array<double, 2>> gather_positions(const std::vector<Observation>& observations,
                                                    std::vector<std::size_t>& index, const Communicator& comm);

// The field stage's position correction: field_positions.h.

// What the position fits read of stage 3's settings: the loss and the exposure calibration
// (every function below); L-BFGS's iterations and history and σ_p's calibration
// (refine_heights_and_positions only). The defaults are RecoverSettings' refine_loss and
// refine_history; the schedule (PositionLoopSettings, stages.h) sets every field.
struct PositionFitSettings {
    Loss loss{LossKind::Amplitude, 1.0};
    bool calibrate_exposure = false;
    bool calibrate_sigma = false;
    int iterations = 0;
    int history = 20;
};

// Each of this rank's observations' closed-form exposure (calibration_detail.h, slice_exposure:
// Σ R / Σ f) at `heights`, its centre moved by its position's offset (offsets_um, 2 per gathered
// position, µm; index[i]: observation i's position) and σ_p × sigma_scale; 1 where the ratio is
// not a positive finite number. With positions and exposures both calibrated the field stage
// runs at these, held fixed: its object is complex, and an
// exposure found anew at every evaluation lets it trade its local amplitude for the exposures
// of the slices over it. Local (no collective); one observation per thread, the same bits for
// any thread count. Throws std::invalid_argument for an index without an offset.
std::vector<double> exposures_at(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                                 const Heightfield& heights, double sigma_scale, const std::vector<double>& offsets_um);

// Registration at fixed heights (the outer loop of stage 3 with positions): every gathered
// position's offset (offsets_um, 2 per position, µm, every rank's) moved where the sum of its
// observations' losses (all its wavelengths, the full slice model, settings.loss, each
// slice's exposure its energy ratio with settings.calibrate_exposure, every σ_p × sigma_scale)
// is smallest, coarse to fine: the best
// point of the grid {offset + 2·step·(a, b): |a|, |b| ≤ radius/(2·step)} (texels), then of the
// grid ± step in steps of step about it (radius ≤ step: one grid ± radius in steps of step);
// ties: the first, and the offset so far unless a smaller loss. The last grid is followed by a
// parabola through the best point and its grid neighbours, per coordinate (its vertex kept
// within half a step; none at the grid's edge). index[i]: observation i's position
// (gather_positions). The offsets' mean is left in. Collective: each position's losses are
// summed exactly over its observations on every rank (core/exact_sum.h), so 1, 2, 3 ranks and
// any thread count give the same bits. Returns the rms change (texels) over positions and
// coordinates. Throws std::invalid_argument for radius < 0, step ≤ 0, radius/(2·step) > 16 or
// offsets_um not 2 per position.
double register_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                          const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                          double radius_texels, double step_texels, std::vector<double>& offsets_um,
                          const Communicator& comm);

// The positions whose loss (the sum
// of their observations' losses at their offsets, as register_positions') exceeds factor × the
// median over the positions are registered again over ± radius_texels (register_positions with
// step_texels: a coarse grid of 2·step, then ± step; its throws): a position trapped beyond the
// outer loop's radius is brought back (its true basin can be narrower than a texel: the coarse
// grid must be fine enough to land in it). Returns how many positions were searched (the same
// on every rank: the losses are exact and collective); median_loss (if given) receives the
// median position's loss before the search (0 when no position has an observation; the outer
// loop's stall rule on the median position). Throws std::invalid_argument for factor ≤ 1 or radius ≤ 0.
int rescue_lost_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                          const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                          double factor, double radius_texels, double step_texels, std::vector<double>& offsets_um,
                          const Communicator& comm, double* median_loss = nullptr);

// A Newton step on every gathered
// position's offset after the registration's grid and parabola. Per position, the 2 × 2 Hessian
// and gradient of its loss (as register_positions') in its offset by central differences of
// ± step_texels (a 3 × 3 stencil about the offset, the cross term from its corners); where the
// Hessian is positive definite, the Newton point (its step capped at cap_texels in length) is
// taken if that position's loss there is lower than at its offset, else the step is halved (at
// most 3 times; then the offset is kept). The losses are register_positions' exact collective
// sums, so every rank takes the same decisions (1, 2, 3 ranks give the same bits). Returns how
// many positions moved. Throws std::invalid_argument for step ≤ 0, cap ≤ 0 or offsets_um not 2
// per position.
// The position loop's registration: a grid of ± k_register_radius_texels in half-texel steps,
// then a Newton step with a ± k_newton_step_texels stencil capped at k_newton_cap_texels.
inline constexpr double k_register_radius_texels = 2.0;
inline constexpr double k_newton_step_texels = 0.25;
inline constexpr double k_newton_cap_texels = 0.5;

int newton_register_positions(const std::vector<Observation>& observations, const std::vector<std::size_t>& index,
                              const Heightfield& heights, const PositionFitSettings& settings, double sigma_scale,
                              double step_texels, double cap_texels, std::vector<double>& offsets_um,
                              const Communicator& comm);

// The smooth part of a displacement field over the positions: values holds 2 per position
// (x, y; any unit) at centres_um; the least-squares fit of each coordinate by a smooth field is subtracted in place and
// returned (2 per position). nodes = 1: an affine field (1, x, y); nodes = k ≥ 2: bilinear on
// k × k nodes spanning the centres' bounding box (it holds the affine fields). Positions and
// heights moved together by such a warp change the slices little, so the outer loop can drift
// along it. Deterministic (the same bits on every rank). Throws std::invalid_argument for
// nodes < 1 or values not 2 per centre.
std::vector<double> remove_smooth_displacement(const std::vector<std::array<double, 2>>& centres_um,
                                               std::vector<double>& values, int nodes);

// The fitted smooth displacement itself, evaluable anywhere: nodes 0 (empty: zero
// everywhere), 1 (affine) or k (bilinear on k × k nodes over [lo_um, hi_um], clamped outside),
// coefficients per coordinate. remove_smooth_displacement subtracts it at the centres.
struct SmoothDisplacement {
    int nodes = 0;
    std::array<double, 2> lo_um{0.0, 0.0}, hi_um{0.0, 0.0};
    std::array<std::vector<double>, 2> coefficients;
    std::array<double, 2> at(double x_um, double y_um) const;  // (x, y) displacement at a point
};
// The least-squares fit of remove_smooth_displacement (the same checks, the same throws).
SmoothDisplacement fit_smooth_displacement(const std::vector<std::array<double, 2>>& centres_um,
                                           const std::vector<double>& values, int nodes);

// Stage 3 with positions: L-BFGS on the heights of `estimate` and the position offsets
// (settings.iterations, history, loss, k_refine_relative_tolerance) on all
// ranks' observations (observations_total of them), from initial_offsets_um (2 per gathered
// position; empty: 0). Returns the heights; offsets_um receives
// one offset (true − stated, µm, mean 0 over the positions) per observation of this rank.
// With settings.calibrate_exposure each slice's exposure is its energy ratio at every
// evaluation (calibration_detail.h), and exposures_out (when given) receives them at the end.
// sigma_scale (when given): every σ_p is used × *sigma_scale; with settings.calibrate_sigma the
// scale is refined as well, in the rounds of calibration_detail.h's refine_sigma_scale (a
// golden-section search from *sigma_scale at fixed heights and offsets, then L-BFGS on both),
// and *sigma_scale receives it. position_offsets_out (when given) receives the offsets per
// gathered position (2 each, µm, mean 0), as initial_offsets_um takes them. last_loss (when
// given) receives the last reported "refine" loss (unchanged where none was reported).
// The refinement's objective and rounds are refinement.h's, with the offsets as variables.
Heightfield refine_heights_and_positions(const std::vector<Observation>& observations, double observations_total,
                                         const Heightfield& flat, const Heightfield& estimate,
                                         const PositionFitSettings& settings, const StageReport& report,
                                         const Communicator& comm, std::vector<std::array<double, 2>>& offsets_um,
                                         const std::vector<double>& initial_offsets_um = {},
                                         std::vector<double>* exposures_out = nullptr, double* sigma_scale = nullptr,
                                         std::vector<double>* position_offsets_out = nullptr,
                                         double* last_loss = nullptr);

}  // namespace wavebrdf::detail
