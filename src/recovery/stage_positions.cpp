// Stage 3 with the footprint positions calibrated, and the position loop around it (stages.h).
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/stall_rule.h"
#include "recovery/recover_positions.h"
#include "recovery/stages.h"

namespace wavebrdf::detail {

namespace {

// The rms (texels) of the change from `before` to `after` (2 values per position).
double rms_move(const std::vector<double>& before, const std::vector<double>& after, double texel_um) {
    double s2 = 0.0;
    for (std::size_t i = 0; i < before.size(); ++i) s2 += (after[i] - before[i]) * (after[i] - before[i]);
    return before.empty() ? 0.0 : std::sqrt(s2 / double(before.size())) / texel_um;
}

}  // namespace

void check_position_loop(const PositionLoopSettings& s) {
    const auto refuse = [](const std::string& what, double value, const char* expected) {
        throw std::invalid_argument("position loop: " + what + " " + std::to_string(value) + " is invalid; expected " +
                                    expected);
    };
    if (s.passes < 0 || s.passes > 100) refuse("passes", s.passes, "0 ... 100");
    if (!(s.tolerance_texels >= 0.0 && std::isfinite(s.tolerance_texels)))
        refuse("tolerance_texels", s.tolerance_texels, "a finite value >= 0");
    if (s.field_iterations < 0) refuse("field_iterations", s.field_iterations, ">= 0 (0: the first pass's)");
    if (s.refine_iterations < 0) refuse("refine_iterations", s.refine_iterations, ">= 0 (0: the first pass's)");
    if (!(s.rescue_factor == 0.0 || (s.rescue_factor > 1.0 && s.rescue_factor <= 1e6)))
        refuse("rescue_factor", s.rescue_factor, "0 (off) or > 1 ... 1e6");
    if (!(s.rescue_radius_texels > 0.0 && s.rescue_radius_texels <= 16.0))
        refuse("rescue_radius_texels", s.rescue_radius_texels, "> 0 ... 16");
    if (!(s.rescue_step_texels > 0.0 && s.rescue_radius_texels / (2.0 * s.rescue_step_texels) <= 16.0))
        refuse("rescue_step_texels", s.rescue_step_texels, "> 0 with radius / (2 step) <= 16");
    if (!(s.field_below_texels >= 0.0 && std::isfinite(s.field_below_texels)))
        refuse("field_below_texels", s.field_below_texels, "a finite value >= 0");
    if (s.stall_passes < 0 || s.stall_passes > 100) refuse("stall_passes", s.stall_passes, "0 ... 100 (0: off)");
    if (!(s.stall_tolerance >= 0.0 && s.stall_tolerance <= 1.0))
        refuse("stall_tolerance", s.stall_tolerance, "0 ... 1");
}

bool PositionLoopStage::run(const StageContext& context, RecoveryState& state) const {
    const auto& observations = context.observations;
    const Communicator& comm = context.comm;
    const auto& report = context.report;
    check_position_loop(settings);
    std::vector<std::array<double, 2>> offsets;
    std::vector<double> exposures;
    std::vector<double> position_offsets;  // per gathered position (2 each, µm)
    double last_refine_loss = 0.0;         // stage 3's last reported loss (the stall rule's)
    state.estimate = refine_heights_and_positions(observations, context.observations_total, context.flat,
                                                  state.estimate, settings.fit, report, comm, offsets, state.offsets_um,
                                                  &exposures, &state.sigma_scale, &position_offsets, &last_refine_loss);
    if (context.stopped()) return false;
    // The outer loop: every position registered on its own at the final heights (a grid search
    // of its full-model loss, then Newton steps), then the field stage (from the final heights,
    // while the registration moves) and stage 3 again at the registered positions, until the
    // registration moves the offsets by less than tolerance_texels rms or stage 3's loss stalls.
    // Later passes warm-start from the pass before (its heights, hence its objects) and may run
    // fewer iterations (field_iterations, refine_iterations).
    PositionFitSettings later = settings.fit;
    if (settings.refine_iterations > 0) later.iterations = settings.refine_iterations;
    FieldRetrievalSettings later_field = field.field;
    if (settings.field_iterations > 0) later_field.iterations = settings.field_iterations;
    // The affine part of each registration's update removed: positions and heights moved
    // together by a smooth warp change the slices little, so without it the loop drifts along one
    // (recover_positions.h, remove_smooth_displacement).
    std::vector<std::array<double, 2>> centres;
    if (settings.passes > 0) {
        std::vector<std::size_t> unused;
        centres = gather_positions(observations, unused, comm);
    }
    // The stall rule (core/stall_rule.h) over passes, on stage 3's loss after each pass or, with
    // stall_median, on the median position's loss at the start of each pass (for
    // the heights of the pass before). Heights from the field stage are a new start: the rule
    // starts again from their loss.
    StallRule stall(settings.stall_passes, settings.stall_tolerance);
    const bool judge_median = settings.stall_median && settings.rescue_factor > 0.0;
    if (!judge_median) stall.stalled_at(last_refine_loss);  // the first recovery ran the field stage
    bool after_field = true;
    for (int outer = 0; outer < settings.passes; ++outer) {
        const std::vector<double> before = position_offsets;
        double moved = register_positions(observations, context.position_of, state.estimate, settings.fit,
                                          state.sigma_scale, k_register_radius_texels, 0.5, position_offsets, comm);
        // A Newton step on each position's offset after the grid and parabola
        // (recover_positions.h); moved counts it.
        {
            const int stepped = newton_register_positions(observations, context.position_of, state.estimate,
                                                          settings.fit, state.sigma_scale, k_newton_step_texels,
                                                          k_newton_cap_texels, position_offsets, comm);
            moved = rms_move(before, position_offsets, state.estimate.texel_um());
            if (!report({StageKind::Positions, "newton"}, stepped, moved, &state.estimate)) return false;
        }
        {
            std::vector<double> update(position_offsets.size());
            for (std::size_t i = 0; i < update.size(); ++i) update[i] = position_offsets[i] - before[i];
            remove_smooth_displacement(centres, update, 1);
            double s2 = 0.0;
            for (std::size_t i = 0; i < update.size(); ++i) {
                position_offsets[i] = before[i] + update[i];
                s2 += update[i] * update[i];
            }
            moved = update.empty() ? 0.0 : std::sqrt(s2 / double(update.size())) / state.estimate.texel_um();
        }
        if (!report({StageKind::Positions, "register"}, outer + 1, moved, &state.estimate)) return false;
        // The lost positions searched wide.
        if (settings.rescue_factor > 0.0) {
            const std::vector<double> kept = position_offsets;
            double median = 0.0;
            const int rescued = rescue_lost_positions(
                observations, context.position_of, state.estimate, settings.fit, state.sigma_scale,
                settings.rescue_factor, settings.rescue_radius_texels, settings.rescue_step_texels, position_offsets,
                comm, &median);
            const double jump = rms_move(kept, position_offsets, state.estimate.texel_um());
            if (!report({StageKind::Positions, "rescue"}, rescued, jump, &state.estimate)) return false;
            if (jump > 0.0) moved = std::max(moved, settings.tolerance_texels);
            // The stall rule on the median position's loss at the heights of the pass before
            // (stage 3's loss is dominated by positions lost for good). A stalled loop ends here,
            // with the pass before's heights and offsets.
            if (judge_median && settings.stall_passes > 0) {
                if (after_field) stall.restart();
                const bool stalled = stall.stalled_at(median);
                if (!report({StageKind::Positions, "stall"}, stall.quiet(), median, &state.estimate)) return false;
                if (stalled) break;
            }
        }
        if (moved < settings.tolerance_texels) break;
        state.offsets_um = position_offsets;
        const bool field_pass =
            !context.white && !(settings.field_below_texels > 0.0 && moved < settings.field_below_texels);
        if (field_pass) {
            state.fields = FieldSet{};
            if (settings.hold_exposures)  // stage 3's, at the heights and offsets it ended with
                state.field_exposures = exposures.size() == observations.size()
                                            ? exposures
                                            : exposures_at(observations, context.position_of, state.estimate,
                                                           state.sigma_scale, state.offsets_um);
            if (!field.retrieve(context, state, later_field)) return false;
            field.unwrap(context, state);
            if (!report(StageKind::Unwrap, outer + 1, 0.0, &state.estimate)) return false;
            state.unwrapped = state.estimate;
        }
        state.estimate = refine_heights_and_positions(observations, context.observations_total, context.flat,
                                                      state.estimate, later, report, comm, offsets, state.offsets_um,
                                                      &exposures, &state.sigma_scale, &position_offsets,
                                                      &last_refine_loss);
        if (context.stopped()) return false;
        after_field = field_pass;
        if (!judge_median) {
            if (field_pass) stall.restart();
            const bool stalled = stall.stalled_at(last_refine_loss);
            if (!field_pass && settings.stall_passes > 0) {
                if (!report({StageKind::Positions, "stall"}, stall.quiet(), last_refine_loss, &state.estimate))
                    return false;
                if (stalled) break;
            }
        }
    }
    state.refined_offsets = offsets;
    state.refined_sigma_scale = state.sigma_scale;
    state.calibration.position_offsets_um = std::move(offsets);
    state.calibration.exposures = std::move(exposures);
    state.calibration.sigma_p_scale = state.sigma_scale;
    return true;
}

}  // namespace wavebrdf::detail
