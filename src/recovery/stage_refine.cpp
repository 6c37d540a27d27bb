// Stage 3 on the heights alone: the refinement in the full model with its ladder, σ_p rounds,
// continuation and repairs (stages.h).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "recovery/outlier_repair.h"
#include "recovery/stages.h"
#include "recovery/white_light.h"

namespace wavebrdf::detail {

namespace {

// White light's defect repair: texels farther than this many robust deviations from their
// neighbours' median are flagged, and connected regions of them up to k_white_repair_region_texels
// are shifted by whole wraps or filled (white_light.h, repair_defect_regions).
constexpr double k_white_repair_threshold = 3.0;
constexpr int k_white_repair_region_texels = 64;
// … up to this many rounds of it, each followed by the refinement again (a round that keeps no
// region ends them).
constexpr int k_white_repair_rounds = 2;
// The outlier repair (outlier_repair.h): texels farther than this many robust deviations from
// the quadratic through their neighbours are flagged; after a round that kept one, the
// refinement on every slice runs this many iterations (stopped early at the ladder's relative
// tolerance: a repaired texel's neighbours had bent towards it, and 8 iterations left seed 4 at
// 0.05 %).
constexpr double k_outlier_repair_threshold = 6.0;
constexpr int k_outlier_repair_iterations = 30;
// A rung with a stall rule that reaches its cap while its loss still falls by more than the
// rule's tolerance over its window runs on, in one more round, until the rule holds, its
// tolerance is met or it has run this many times its cap in all. Noiseless sur-2 on 64² slices
// (experiments/2026-11-30-refinement-budget.md): where the truth holds a texel-scale texture the
// loss still falls 2–3 % an iteration at 40, the 64² patch 1.36 % off, and running on it meets
// its tolerance at 96 (0.002 %). A converged rung stops at its tolerance before the cap and a
// noisy one stalls on its noise floor, so neither runs on (the same bits as before).
constexpr int k_rung_extension_caps = 4;

// The refinement's objective: the observations' loss plus, during white light's continuation,
// weight · the smoothness penalty (white_light.h).
struct SmoothedObjective {
    ObservationObjective* data;
    int rows, cols;
    const double* weight;
    double operator()(const std::vector<double>& x, std::vector<double>& g) const {
        const double value = (*data)(x, g);
        return *weight > 0.0 ? value + add_smoothness_penalty(x, rows, cols, *weight, g) : value;
    }
};

// Single-texel outliers (outlier_repair.h): each flagged texel of h judged on the slices that
// see it (its gradient box) among `within` (a ladder rung's; empty: every slice), through the
// objective restricted to them (a local loss, collective); the objective sums over `within`
// after. Reports "repair:outliers" where a texel was flagged.
OutlierRepairCounts repair_outliers(const StageContext& context, ObservationObjective& data, RefinementRounds& rounds,
                                    std::vector<double>& h, const std::vector<char>& within) {
    OutlierRepairCounts counts;
    std::vector<double> wraps;  // λ/2 of every rank's wavelengths, value units
    for (const auto& entry : context.by_lambda)
        wraps.push_back(0.5 * entry.first / std::abs(context.vscale * context.texel_um));
    if (wraps.empty()) return counts;
    const std::size_t n = context.observations.size();
    std::vector<double> no_g;
    const auto local_loss = [&](const std::vector<double>& x, std::size_t texel) {
        const int r = int(texel / std::size_t(context.cols)), c = int(texel % std::size_t(context.cols));
        std::vector<char> active(n, 0);
        for (std::size_t i = 0; i < n; ++i) active[i] = (within.empty() || within[i]) && data.sees(i, r, c);
        data.set_active(std::move(active));
        return rounds.objective()(x, no_g);
    };
    const double min_residual = 0.25 * *std::min_element(wraps.begin(), wraps.end());
    counts = repair_outlier_texels(h, context.rows, context.cols, k_outlier_repair_threshold, min_residual,
                                   std::max(16, context.rows * context.cols / 256), wraps, local_loss);
    data.set_active(within);
    if (counts.flagged > 0) {
        const Heightfield current = context.flat.with_values(h);
        if (!context.report(StageKind::RepairOutliers, counts.kept, double(counts.flagged), &current)) rounds.stop();
    }
    return counts;
}

// The wavelength ladder (rough surfaces): a round on the slices at wavelengths ≥ each rung,
// longest first, each from the last ("refine:λ" in the metrics), each followed by the outlier
// repair on its slices. False: stopped.
bool run_ladder(const StageContext& context, const RefineSettings& settings, ObservationObjective& data,
                RefinementRounds& rounds, std::vector<double>& h) {
    const auto going = [&] { return rounds.go_on() && !context.stopped(); };
    const std::size_t n = context.observations.size();
    for (auto it = context.by_lambda.rbegin();
         it != context.by_lambda.rend() && it->first >= settings.ladder_min_um && going(); ++it) {
        std::vector<char> active(n, 0);
        for (std::size_t i = 0; i < n; ++i) {
            const std::vector<double>& l = context.observations[i].lambdas_um;
            active[i] = !l.empty() && *std::min_element(l.begin(), l.end()) >= it->first;
        }
        data.set_active(active);
        const StageId name(StageKind::RefineRung, stage_part(it->first));
        rounds.set_done(0);
        int rung_start = 0;  // the iteration count where the last round of the rung began
        const auto rung = [&](int iterations, int stall_window) {
            rung_start = rounds.done();
            return rounds.run(h, iterations, name, settings.ladder_relative_tolerance, stall_window,
                              settings.ladder_stall_tolerance);
        };
        bool stalled = rung(settings.ladder_iterations, settings.ladder_stall_window);
        // The outlier repair on the rung's slices, then the rung again where a texel was kept.
        for (int round = 0; going() && round < settings.outlier_repair_rounds; ++round) {
            const std::vector<char> within = data.active();
            if (repair_outliers(context, data, rounds, h, within).kept == 0 || !going()) break;
            stalled = rung(settings.ladder_iterations, settings.ladder_stall_window);
        }
        // A stall that no repair answered: the rung runs on to its cap, without the rule (the
        // stall was the loss's own pace, not a trapped texel).
        const int left = settings.ladder_iterations - (rounds.done() - rung_start);
        if (stalled && left > 0 && going()) rung(left, 0);
        // A rung still falling at its cap runs on under its stall rule (k_rung_extension_caps).
        const double stop_below = std::max(k_refine_relative_tolerance, settings.ladder_relative_tolerance);
        if (!stalled && settings.ladder_stall_window > 0 && settings.ladder_stall_tolerance > 0.0 &&
            rounds.done() - rung_start >= settings.ladder_iterations &&
            rounds.last_loss() > stop_below * rounds.reference_loss() && going())
            rung((k_rung_extension_caps - 1) * settings.ladder_iterations, settings.ladder_stall_window);
    }
    data.set_active({});
    rounds.set_done(0);
    return !context.stopped();
}

// White light's wrap: half the shortest mean wavelength of any rank's observations, in value
// units (every rank agrees).
double white_wrap_height(const StageContext& context) {
    std::vector<double> mine;
    for (const Observation& o : context.observations)
        if (!o.lambdas_um.empty()) mine.push_back(white_light_lambda_um(o.lambdas_um));
    const std::vector<double> all = all_gather(context.comm, mine);
    if (all.empty()) return 0.0;
    return 0.5 * *std::min_element(all.begin(), all.end()) / std::abs(context.vscale * context.texel_um);
}

}  // namespace

bool RefineStage::run(const StageContext& context, RecoveryState& state) const {
    const bool white = context.white;
    const int rows = context.rows, cols = context.cols;
    std::vector<double> h = state.estimate.values();
    ObservationObjective data(context.observations, context.observations_total, context.flat, settings.loss,
                              settings.calibrate_exposure, state.sigma_scale, context.comm);
    double smooth_weight = 0.0;  // white light: the smoothness continuation's weight
    const SmoothedObjective objective{&data, rows, cols, &smooth_weight};
    const double reference_loss = mean_observation_loss(context.observations, context.observations_total, context.flat,
                                                        settings.loss, context.comm);
    // The coarse space (coarse_correction.h): none when off or the surface is too small.
    const CoarseBasis coarse(rows, cols,
                             settings.coarse_spacing > 0.0 ? settings.coarse_spacing : double(std::max(rows, cols)),
                             settings.coarse_weight > 0.0 ? settings.coarse_weight : 1.0);
    const bool coarse_on = settings.coarse_spacing > 0.0 && coarse.size() > 0;
    RefinementRounds rounds(objective, context.flat, settings.history, reference_loss, context.report,
                            coarse_on ? &coarse : nullptr, settings.coarse_weight > 0.0, settings.coarse_iterations);
    const auto going = [&] { return rounds.go_on() && !context.stopped(); };
    if (!white && !settings.calibrate_sigma && settings.ladder_min_um > 0.0 && settings.ladder_iterations > 0 &&
        !run_ladder(context, settings, data, rounds, h)) {
        state.estimate = context.flat.with_values(h);
        return false;
    }
    if (settings.calibrate_sigma) {
        state.sigma_scale = calibrate_sigma_rounds(data, rounds, h, settings.iterations, context.report);
    } else {
        // White light: the smoothness continuation (white_light.h), then the loss alone.
        for (std::size_t k = 0; white && k < settings.white_smoothness.size() && going(); ++k) {
            smooth_weight = settings.white_smoothness[k];
            if (settings.white_smoothness_iterations > 0) rounds.run(h, settings.white_smoothness_iterations);
        }
        smooth_weight = 0.0;
        rounds.run(h, settings.iterations);
    }
    // Single-texel outliers after stage 3 (every slice), then stage 3's last iterations again.
    for (int round = 0; !white && going() && round < settings.outlier_repair_rounds; ++round) {
        const OutlierRepairCounts counts = repair_outliers(context, data, rounds, h, {});
        if (counts.flagged == 0 || counts.kept == 0 || !going()) break;
        rounds.run(h, k_outlier_repair_iterations, StageKind::Refine, settings.ladder_relative_tolerance);
    }
    // White light: isolated texels (or connected regions) left a wrap from their neighbours,
    // repaired where the loss agrees, then refined again (white_light.h).
    for (int round = 0; white && going() && round < k_white_repair_rounds; ++round) {
        std::vector<double> no_g;
        const auto loss_of = [&](const std::vector<double>& x) { return objective(x, no_g); };
        const int budget = std::max(16, rows * cols / 64);
        const int kept = repair_defect_regions(h, rows, cols, white_wrap_height(context), k_white_repair_threshold,
                                               budget, k_white_repair_region_texels, loss_of);
        const Heightfield current = context.flat.with_values(h);
        if (!context.report(StageKind::RepairWhite, kept, 0.0, &current)) break;
        if (kept == 0) break;
        rounds.run(h, settings.iterations);
    }
    state.estimate = context.flat.with_values(h);
    if (context.stopped()) return false;
    // The exposures at the final heights (collective: on every rank, whatever it asked).
    if (settings.calibrate_exposure) {
        std::vector<double> g;
        objective(h, g);
        state.calibration.exposures = data.exposures();
    }
    state.calibration.sigma_p_scale = state.sigma_scale;
    state.refined_sigma_scale = state.sigma_scale;
    return true;
}

}  // namespace wavebrdf::detail
