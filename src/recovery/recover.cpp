// The recovery pipeline: field retrieval per wavelength → unwrapping → refinement in the full
// Gabor model (recover.h).
#include "wavebrdf/recover.h"

#include <algorithm>
#include <chrono>
#include <iterator>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "recovery/field_proxy.h"
#include "recovery/observation_loss.h"
#include "recovery/recover_field_model.h"
#include "recovery/recover_positions.h"
#include "recovery/stages.h"
#include "recovery/white_light.h"

namespace wavebrdf {

double height_rel_rmse(const Heightfield& estimate, const Heightfield& truth) {
    if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols())
        throw std::invalid_argument("height_rel_rmse: estimate is " + std::to_string(estimate.rows()) + " x " +
                                    std::to_string(estimate.cols()) + " but truth is " + std::to_string(truth.rows()) +
                                    " x " + std::to_string(truth.cols()));
    const double n = double(truth.values().size());
    double mean_e = 0.0, mean_t = 0.0, lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j) {
            mean_e += estimate.height_um(i, j);
            const double t = truth.height_um(i, j);
            mean_t += t;
            lo = std::min(lo, t);
            hi = std::max(hi, t);
        }
    if (!(hi > lo)) throw std::domain_error("height_rel_rmse: the truth is flat; its height range is 0");
    mean_e /= n;
    mean_t /= n;
    double sum = 0.0;
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j) {
            const double d = (estimate.height_um(i, j) - mean_e) - (truth.height_um(i, j) - mean_t);
            sum += d * d;
        }
    return std::sqrt(sum / n) / (hi - lo);
}

int auto_refine(double texel_um, double lambda_min_um, double max_omega_i) {
    // The object grid must hold the slice's band and the field's: 1/d > 2(1 + |ω_i|)/λ.
    int q = int(std::floor(2.0 * texel_um * (1.0 + max_omega_i) / lambda_min_um)) + 1;
    if (q % 2 == 0) ++q;
    return std::max(q, 1);
}

namespace {

// recover_heights' stages, after its checks: `filled` the copies the stages with their own
// models read (null: `observations`), `by_lambda` this rank's single-wavelength separable
// ones among them, with an entry (maybe empty) for every rank's wavelengths;
// `observations_total` counts all ranks' observations. The context every stage reads, then the
// schedule (stages.h).
Heightfield recover_stages(const std::vector<Observation>& observations, const std::vector<Observation>* filled,
                           const std::map<double, std::vector<const Observation*>>& by_lambda,
                           double observations_total, const Heightfield& flat, int rows, int cols, double texel_um,
                           double vscale, const RecoverSettings& settings,
                           const std::function<void(detail::Schedule&)>& edit,
                           const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                           const Communicator& comm, Calibration* calibration) {
    detail::StageReporter reporter(on_step, truth, comm, settings);
    // White light: no single-wavelength observation on any rank.
    const bool white = by_lambda.empty();
    const detail::FieldProxy proxy = detail::common_field_proxy(by_lambda, comm);
    detail::RecoveryState state(flat);
    std::vector<std::size_t> position_of;
    if (settings.calibrate.positions)
        state.offsets_um.assign(2 * detail::gather_positions(observations, position_of, comm).size(), 0.0);
    // The object grid: fine enough for every rank's light directions.
    double max_omega_i = 0.0;
    for (const auto& [lambda, group] : by_lambda)
        for (const Observation* o : group)
            max_omega_i = std::max(max_omega_i, std::hypot(o->query.omega_i[0], o->query.omega_i[1]));
    for (double w : all_gather(comm, {max_omega_i})) max_omega_i = std::max(max_omega_i, w);
    const int q = settings.refine > 0 ? settings.refine
                : white        ? 1
                               : auto_refine(texel_um, by_lambda.begin()->first, max_omega_i);
    if (q % 2 == 0 || q > 63)
        throw std::invalid_argument("recover_heights: refine " + std::to_string(q) +
                                    " is invalid; expected an odd value up to 63 (texel centres must be samples)");
    const detail::StageContext context{observations, by_lambda, observations_total, flat, rows, cols, texel_um,
                                       vscale, comm, reporter, std::ref(reporter), white, proxy, q,
                                       std::move(position_of), filled};
    detail::Schedule schedule = detail::make_schedule(settings, context);
    if (edit) edit(schedule);
    detail::run_schedule(schedule, context, state);
    if (calibration) *calibration = std::move(state.calibration);
    return std::move(state.estimate);
}

}  // namespace

Heightfield recover_heights(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                            double vscale, const RecoverSettings& given,
                            const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                            const Communicator& comm, Calibration* calibration) {
    return detail::recover_heights_edited(observations, rows, cols, texel_um, vscale, given, {}, on_step, truth, comm,
                                          calibration);
}

Heightfield detail::recover_heights_edited(const std::vector<Observation>& observations, int rows, int cols,
                                           double texel_um, double vscale, const RecoverSettings& given,
                                           const std::function<void(Schedule&)>& edit,
                                           const std::function<bool(const StageMetrics&)>& on_step,
                                           const Heightfield* truth, const Communicator& comm,
                                           Calibration* calibration) {
    if (calibration) *calibration = Calibration{};
    // Checks of what every rank is given alike first, then of each rank's share, agreed.
    const Heightfield flat(rows, cols, std::vector<double>(std::size_t(rows) * std::size_t(cols), 0.0), texel_um,
                           vscale);
    // The unset settings resolved (the schedule's defaults), so that the checks see what runs.
    const RecoverSettings settings = scheduled_settings(given, texel_um);
    if (truth && (truth->rows() != rows || truth->cols() != cols))
        throw std::invalid_argument("recover_heights: truth is " + std::to_string(truth->rows()) + " x " +
                                    std::to_string(truth->cols()) + "; expected " + std::to_string(rows) + " x " +
                                    std::to_string(cols));
    if (vscale == 0.0) throw std::domain_error("recover_heights: vscale 0 maps every height to 0; expected != 0");
    validate_iterations(settings.blurred.iterations, "recover_heights: blur iterations");
    validate_iterations(settings.field.iterations, "recover_heights: field iterations");
    validate_iterations(settings.refine_iterations, "recover_heights: refine iterations");
    if (settings.position_outer_passes < -1 || settings.position_outer_passes > 100)
        throw std::invalid_argument("recover_heights: position outer passes " +
                                    std::to_string(settings.position_outer_passes) +
                                    " is invalid; expected 0 ... 100 (-1: the default)");
    if (!(settings.position_rescue_radius_texels > 0.0 && settings.position_rescue_radius_texels <= 16.0))
        throw std::invalid_argument("recover_heights: position rescue radius " +
                                    std::to_string(settings.position_rescue_radius_texels) +
                                    " texels is invalid; expected > 0 ... 16");
    validate_iterations(settings.refine_coarse_iterations, "recover_heights: refine coarse iterations");
    if (!(std::isfinite(settings.refine_coarse_spacing) &&
          (settings.refine_coarse_spacing == 0.0 || settings.refine_coarse_spacing >= 1.0)))
        throw std::domain_error("recover_heights: refine_coarse_spacing " +
                                std::to_string(settings.refine_coarse_spacing) + "; expected 0 (off) or >= 1 texel");
    if (!(std::isfinite(settings.refine_coarse_weight) && settings.refine_coarse_weight >= 0.0))
        throw std::domain_error("recover_heights: refine_coarse_weight " +
                                std::to_string(settings.refine_coarse_weight) + "; expected finite and >= 0");
    if (!(std::isfinite(settings.field_lambda_min_um) && settings.field_lambda_min_um >= 0.0))
        throw std::domain_error("recover_heights: field_lambda_min_um " + std::to_string(settings.field_lambda_min_um) +
                                " is invalid; expected a finite wavelength >= 0 um (0: every wavelength)");
    if (settings.field_wavelengths < 0)
        throw std::invalid_argument("recover_heights: field_wavelengths " + std::to_string(settings.field_wavelengths) +
                                    " is invalid; expected >= 0 (0: every wavelength)");
    if (settings.refine_ladder_wavelengths < 0)
        throw std::invalid_argument("recover_heights: refine_ladder_wavelengths " +
                                    std::to_string(settings.refine_ladder_wavelengths) +
                                    " is invalid; expected >= 0 (0: no ladder)");
    if (!(std::isfinite(settings.refine_ladder_min_um) && settings.refine_ladder_min_um >= 0.0))
        throw std::domain_error("recover_heights: refine_ladder_min_um " +
                                std::to_string(settings.refine_ladder_min_um) +
                                " is invalid; expected a finite wavelength >= 0 um (0: no ladder)");
    validate_iterations(settings.refine_ladder_iterations, "recover_heights: refine ladder iterations");
    if (!(std::isfinite(settings.refine_ladder_relative_tolerance) && settings.refine_ladder_relative_tolerance >= 0.0 &&
          settings.refine_ladder_relative_tolerance < 1.0))
        throw std::domain_error("recover_heights: refine_ladder_relative_tolerance " +
                                std::to_string(settings.refine_ladder_relative_tolerance) +
                                " is invalid; expected 0 (off) to below 1");
    if (settings.refine_ladder_stall_window < 0 ||
        !(std::isfinite(settings.refine_ladder_stall_tolerance) && settings.refine_ladder_stall_tolerance >= 0.0))
        throw std::invalid_argument("recover_heights: refine ladder stall window " +
                                    std::to_string(settings.refine_ladder_stall_window) + " / tolerance " +
                                    std::to_string(settings.refine_ladder_stall_tolerance) +
                                    " is invalid; expected >= 0 (0: off) / a finite value >= 0");
    if (settings.outlier_repair_rounds < 0 || settings.outlier_repair_rounds > 100)
        throw std::invalid_argument("recover_heights: outlier repair rounds " +
                                    std::to_string(settings.outlier_repair_rounds) +
                                    " is invalid; expected 0 ... 100 (-1: the schedule's)");
    validate_iterations(settings.white_smoothness_iterations, "recover_heights: white smoothness iterations");
    detail::check_white_smoothness(settings.white_smoothness, "recover_heights: white_smoothness");
    detail::skip_field_refinement(0.0, 0.0, settings.model_check_skip_ratio);  // throws when out of [0, 1]
    // Single-wavelength separable observations, grouped by wavelength, feed the field stage.
    // (Pointers, not copies: the references are most of the memory a run holds.)
    std::map<double, std::vector<const Observation*>> by_lambda;
    std::vector<Observation> filled;  // with weights: what the stages with their own models read
    run_agreed(comm, [&] {
        for (std::size_t i = 0; i < observations.size(); ++i) {
            validate(observations[i], i);
        }
        // Here, not only in the renderer: the stages render inside parallel regions.
        for (const Observation& o : observations)
            validate_footprint(o.query.sigma_p_um, flat.period_x_um(), flat.period_y_um());
        if (detail::any_weights(observations)) filled = detail::filled_observations(observations);
        for (const Observation& o : filled.empty() ? observations : filled)
            if (o.lambdas_um.size() == 1 && detail::has_field_stage(o.query.model))
                by_lambda[o.lambdas_um[0]].push_back(&o);
    });
    // Every rank runs every rank's wavelengths (its share of one may be empty).
    std::vector<double> lambdas_here;
    for (const auto& entry : by_lambda) lambdas_here.push_back(entry.first);
    for (double lambda : all_gather(comm, lambdas_here)) by_lambda[lambda];
    std::vector<double> total{double(observations.size())};
    comm.allreduce_sum(total);
    if (total[0] == 0.0) throw std::invalid_argument("recover_heights: no observations given");
    // From here on the ranks meet in collective calls: one rank's failure ends them all.
    return run_or_abort(comm, [&] {
        return recover_stages(observations, filled.empty() ? nullptr : &filled, by_lambda, total[0], flat, rows, cols,
                              texel_um, vscale, settings, edit, on_step, truth, comm, calibration);
    });
}

}  // namespace wavebrdf
