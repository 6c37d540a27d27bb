#include "wavebrdf/recovery_run.h"

#include <algorithm>
#include <stdexcept>

#include "wavebrdf/generate.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/plan.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

RecoveryMethod parse_recovery_method(const std::string& text, const std::string& name) {
    if (text == "pipeline") return RecoveryMethod::Pipeline;
    if (text == "thesis") return RecoveryMethod::Thesis;
    throw std::invalid_argument(name + " '" + text + "' is unknown; expected pipeline or thesis");
}

const char* to_string(RecoveryMethod method) {
    return method == RecoveryMethod::Thesis ? "thesis" : "pipeline";
}

Loss recovery_loss(const RecoveryOptions& options) {
    if (options.loss) return *options.loss;
    // The thesis's method is the baseline as the thesis ran it: its own loss on any data.
    if (options.method == RecoveryMethod::Thesis) return Loss{LossKind::CMSLE, 1.0};
    return matched_loss(options.noise, Loss{LossKind::Amplitude, 1.0});
}

Heightfield generated_recovery_truth(const RecoveryOptions& options) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = options.rows;
    p.cols = options.cols;
    p.texel_um = options.texel_um;
    p.correlation_um = options.correlation_texels * options.texel_um;
    p.seed = options.seed;
    return with_height_range(generate_heightfield(p).with_scale(options.texel_um, options.vscale),
                             options.height_range_um);
}

PreparedRecovery prepare_recovery(const RecoveryOptions& options, const Heightfield* truth,
                                  std::vector<Observation> observations, bool show_progress) {
    if (truth != nullptr && !observations.empty())
        throw std::invalid_argument("a truth and observations exclude each other; expected one of them (or neither)");
    if (options.noise.kind != NoiseKind::None && !observations.empty())
        throw std::invalid_argument("noise '" + to_string(options.noise) +
                                    "' is simulated on rendered observations; it needs a truth, not given observations");
    // Counts first, before the observations are planned and rendered (negative iteration counts: the library's default).
    validate_iterations(options.epochs, "epochs");
    if (options.field_iterations >= 0) validate_iterations(options.field_iterations, "field iterations");
    if (options.refine_iterations >= 0) validate_iterations(options.refine_iterations, "refine iterations");

    PreparedRecovery r;
    r.method = options.method;
    r.noise = options.noise;
    r.loss = recovery_loss(options);
    r.range_um = options.height_range_um;
    r.texel_um = options.texel_um;
    r.vscale = options.vscale;
    // The pipeline's field retrieval needs single-wavelength separable slices: checked here,
    // before the observations are simulated, not after.
    if (options.method == RecoveryMethod::Pipeline) {
        if (observations.empty() && !is_separable(options.model))
            throw std::invalid_argument(std::string("model ") + to_string(options.model) +
                                        " is not separable; the pipeline's field retrieval expects OHS or ROHS "
                                        "(or the thesis's method)");
        if (!observations.empty() &&
            std::none_of(observations.begin(), observations.end(), [](const Observation& o) {
                return o.lambdas_um.size() == 1 && is_separable(o.query.model);
            }))
            throw std::invalid_argument(
                "no single-wavelength OHS or ROHS observation given; the pipeline's field retrieval needs some "
                "(or the thesis's method)");
    }
    if (!observations.empty()) {
        r.observations = std::move(observations);
        r.rows = options.rows;
        r.cols = options.cols;
    } else {
        r.truth = truth != nullptr ? *truth : generated_recovery_truth(options);
        r.rows = r.truth->rows();
        r.cols = r.truth->cols();
        r.texel_um = r.truth->texel_um();
        r.vscale = r.truth->vscale();
        const HeightStats stats = height_stats(*r.truth);
        r.range_um = stats.max_um - stats.min_um;
        PlanRequest request;
        request.rows = r.rows;
        request.cols = r.cols;
        request.texel_um = r.texel_um;
        request.height_range_um = r.range_um;
        request.sigma_p_um = options.sigma_p_um;
        request.overlap = options.overlap;
        request.jitter = options.jitter;
        request.light = options.light;
        request.model = options.model;
        request.seed = options.seed;
        request.lambdas_um = options.lambdas_um;
        request.resolution = options.resolution;
        const AcquisitionPlan plan = plan_acquisition(request);
        r.notes = plan.notes;
        Progress progress("simulate", static_cast<long long>(plan.positions_um.size() * plan.lambdas_um.size()),
                          show_progress);
        r.observations = simulate_observations(*r.truth, plan, options.noise, options.seed, &progress);
        progress.finish();
    }
    if (r.truth) {
        const HeightStats stats = height_stats(*r.truth);
        if (!(stats.max_um > stats.min_um)) r.metric_note = "undefined: the truth is flat";
    }
    r.warnings = check_acquisition(r.observations, r.rows, r.cols, r.texel_um, r.truth ? &*r.truth : nullptr);
    if (!r.metric_note.empty())
        r.warnings.push_back("height_rel_rmse is " + r.metric_note + " (its height range is 0); the metrics give nan");

    r.pipeline.refine_loss = r.loss;
    r.pipeline.max_range_um = std::max(r.range_um, 1e-3);
    if (options.field_iterations >= 0) r.pipeline.field.iterations = options.field_iterations;
    if (options.refine_iterations >= 0) r.pipeline.refine_iterations = options.refine_iterations;
    r.thesis.epochs = options.epochs;
    r.thesis.loss = r.loss;
    r.thesis.seed = options.seed;
    return r;
}

Heightfield run_recovery(const PreparedRecovery& r, const std::function<bool(const StageMetrics&)>& on_step) {
    // A flat truth has no relative height error (its range is 0): the recovery runs without it.
    const Heightfield* truth = r.truth && r.metric_note.empty() ? &*r.truth : nullptr;
    if (r.method == RecoveryMethod::Pipeline)
        return recover_heights(r.observations, r.rows, r.cols, r.texel_um, r.vscale, r.pipeline, on_step, truth);
    return recover_heights_thesis(r.observations, r.rows, r.cols, r.texel_um, r.vscale, r.thesis, on_step, truth);
}

}  // namespace wavebrdf
