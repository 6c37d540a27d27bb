// The Schedule of recover_heights' stages: the run's defaults (scheduled_settings), which stages
// run, in which order, with which settings (stages.h); the metrics stream; the model check.
#include <algorithm>
#include <cmath>

#include "recovery/recover_field_model.h"
#include "recovery/stages.h"

namespace wavebrdf {

namespace {

// The smooth schedule (smooth surfaces without self-calibration;
// experiments/2026-11-23-recovery-speed.md, experiments/2026-11-24-time-per-texel.md): the
// same final heights as the longer schedule at about half the CPU time, at every size (above the
// tile threshold the field's iterations are each tile's, and the refinement's coarse space takes
// the undulation that made capped large runs worse).
// The field stage's cap: from the blurred fit the longest field is near its loss floor after
// ~20 iterations (0.5 % of the range off, against 0.36 % after the ~46 of the stall rule), and
// the refinement's first iterations on its slices close that gap at a sixth of a field
// iteration's cost each.
constexpr int k_smooth_field_iterations = 25;
// Refinement iterations on every slice after the rung on the longest wavelength's slices.
constexpr int k_smooth_refine_iterations = 8;
// The rung stops once loss / loss(flat) < this: on exact data a loss of ~3e-9 (loss(flat) ≈ 0.27
// at 64²) is ~0.005 % of the range off, reached after ~24 of its 40 iterations (seed 10421);
// with noise the loss stays far above and the rung runs its 40.
constexpr double k_smooth_ladder_relative_tolerance = 1e-8;
// The rung's stall rule: stopped where its loss fell by < 1 % (refine_ladder_stall_tolerance)
// over 5 iterations (a rung trapped by a single-texel outlier levels off at ≈ 1e-5 from its
// ~17th iteration; untrapped rungs fall by 25–50 % every 5), so the outlier repair comes early.
constexpr int k_smooth_ladder_stall_window = 5;
// Rounds of the outlier repair (after the rung and after every slice): a second trapped texel may
// stand out only once the first is repaired and the rung has run again (64², seed 9346: one round
// left it, and the rung ran on to its cap at a flat loss; 18 → 14 s with 3). A round that keeps
// nothing ends the repair, so an untrapped run computes the same bits.
constexpr int k_smooth_outlier_repair_rounds = 3;
// Elsewhere (rough surfaces, calibrated runs): the longer schedule.
constexpr int k_refine_iterations = 40;
constexpr int k_outlier_repair_rounds = 1;
// Unwrapping's bound on the height range when no range is stated (only the per-sample
// unwrapping without a grid reads it).
constexpr double k_height_range_um = 4.0;

}  // namespace

namespace {

// Each kind's metrics text (stage_kind_name), in StageKind's order.
constexpr const char* k_stage_kind_names[k_stage_kinds] = {
    "blur:",      "blur",    "exposures:held", "field:",          "unwrap",          "sigma:",
    "refine",     "refine:", "refine:coarse",  "calibrate:sigma", "repair:outliers", "repair",
    "positions:", "misfit:", "refine:field",   "select:",         "thesis",          "other"};

}  // namespace

const char* stage_kind_name(StageKind kind) {
    const int k = int(kind);
    return k >= 0 && k < k_stage_kinds ? k_stage_kind_names[k] : "other";
}

StageKind stage_kind(const std::string& stage) {
    // Whole names first, then the longest prefix (none of the prefixes is another's prefix but
    // "refine:", which the whole names "refine:coarse" and "refine:field" precede).
    for (int k = 0; k + 1 < k_stage_kinds; ++k) {
        const std::string name = k_stage_kind_names[k];
        if (name.back() != ':' && stage == name) return StageKind(k);
    }
    for (int k = 0; k + 1 < k_stage_kinds; ++k) {
        const std::string name = k_stage_kind_names[k];
        if (name.back() == ':' && stage.size() > name.size() && stage.compare(0, name.size(), name) == 0)
            return StageKind(k);
    }
    return StageKind::Other;
}

int planned_iterations(const RecoverSettings& s, StageKind kind) {
    int total = 0;
    switch (kind) {
        case StageKind::BlurredFit:
            total = s.blurred.iterations;
            for (int n : s.blurred.width_iterations) total = std::max(total, n);
            break;
        case StageKind::Field: total = s.field.iterations; break;
        case StageKind::Refine: total = s.refine_iterations; break;
        case StageKind::RefineRung: total = s.refine_ladder_iterations; break;
        case StageKind::RefineCoarse: total = s.refine_coarse_iterations; break;
        case StageKind::ModelRefine: total = s.model_check_iterations; break;
        default: return 0;  // reported once per result
    }
    return std::max(total, 1);
}

RecoverSettings scheduled_settings(const RecoverSettings& settings, double texel_um) {
    RecoverSettings s = settings;
    const SurfaceClass& surface = settings.surface;
    // The surface class: the rough-surface plan where a stated surface is rough, else smooth.
    RoughnessPlan plan;
    if (surface.height_range_um && surface.correlation_um && *surface.height_range_um > 0.0 &&
        *surface.correlation_um > 0.0)
        plan = surface.measured ? plan_for_measured_roughness(*surface.measured, texel_um)
                                : plan_for_roughness(*surface.height_range_um, *surface.correlation_um, texel_um);
    // The calibrated runs' loops keep the longer schedule.
    const bool smooth = !plan.rough && !settings.calibrate.any();
    if (s.field.iterations == -1) {
        const int library = FieldRetrievalSettings{}.iterations;
        s.field.iterations = plan.rough  ? std::max(library, plan.field_iterations)
                             : smooth    ? std::min(library, k_smooth_field_iterations)
                                         : library;
    }
    if (s.field_lambda_min_um == -1.0)
        s.field_lambda_min_um =
            plan.long_lambdas_um.empty() ? 0.0 : *std::min_element(plan.long_lambdas_um.begin(), plan.long_lambdas_um.end());
    if (s.refine_ladder_min_um == -1.0) s.refine_ladder_min_um = plan.refine_ladder_min_um;
    if (s.field_wavelengths == -1) s.field_wavelengths = smooth ? 1 : 0;
    if (s.refine_iterations == -1) {
        s.refine_iterations = smooth ? k_smooth_refine_iterations : k_refine_iterations;
        if (settings.error_bars) s.refine_iterations = std::max(s.refine_iterations, k_uncertainty_refine_iterations);
    }
    // A stated refinement count is the whole refinement: no ladder before it.
    if (s.refine_ladder_wavelengths == -1) s.refine_ladder_wavelengths = smooth && settings.refine_iterations == -1 ? 1 : 0;
    if (s.refine_ladder_relative_tolerance == -1.0)
        s.refine_ladder_relative_tolerance = smooth ? k_smooth_ladder_relative_tolerance : 0.0;
    if (s.refine_ladder_stall_window == -1) s.refine_ladder_stall_window = smooth ? k_smooth_ladder_stall_window : 0;
    if (s.outlier_repair_rounds == -1)
        s.outlier_repair_rounds = smooth ? k_smooth_outlier_repair_rounds : k_outlier_repair_rounds;
    if (s.height_range_um == -1.0)
        s.height_range_um = surface.height_range_um ? std::max(*surface.height_range_um, 1e-3) : k_height_range_um;
    return s;
}

}  // namespace wavebrdf

namespace wavebrdf::detail {

namespace {

// RecoverSettings::position_outer_passes = −1 (the default): outer passes of position
// self-calibration. Converging runs still gain after 12 passes, a cluster the rescue brings back
// late needs 20, and 3 texels rms with the footprint sized for it converges in 12–19 passes, the
// slowest seed's last passes doing the most (3.1 % → 0.36 % → 0.04 %): so the cap is 40, and
// converged or stalled runs end earlier by the stall rule
// (experiments/2026-11-23-position-calibration.md).
constexpr int k_position_outer_passes = 40;
// The position loop's constants (PositionLoopSettings; measured in
// experiments/2026-11-23-position-calibration.md).
// The loop's stop on the registration's moves: at the loop's end the registration jitters the
// offsets by ~0.004 texel a pass, so 0.001 leaves the stopping to the stall rule.
constexpr double k_position_outer_tolerance_texels = 0.001;
// Later passes warm-start from the pass before (its heights, hence its objects): 20 field
// iterations suffice there; stage 3 keeps the first pass's count.
constexpr int k_position_outer_field_iterations = 20;
constexpr int k_position_outer_refine_iterations = 0;
// The rescue: a position trapped beyond the registration's ± 2 texels had a loss 100–700 × the
// median; 20 × finds those and leaves the rest. Its coarse grid reaches radius / (2 step) = 16
// points each side, the most register_positions allows, so the step follows the radius (0.125
// texel at the default ± 4: the true basin can be narrower than a texel).
constexpr double k_position_rescue_factor = 20.0;
constexpr double k_position_rescue_points = 32.0;  // radius / step
// A later pass skips the field stage once the registration moves the offsets by less than this
// (rms, texels): near the end the field stage's own position steps undo the registration's last
// 0.02 texel.
constexpr double k_position_outer_field_below_texels = 0.05;
// The stall rule over passes: 2 passes, 2 % (converging runs lower stage 3's loss by ≥ 14 % a
// pass to their 12th, a stalled one by ≤ 1 %; 0.1 stopped a run whose lost cluster the rescue
// brought back later, 0.05 nearly did). On the median position's loss: a few positions lost for
// good dominate stage 3's loss and stop the loop while the heights elsewhere still improve by a
// quarter a pass.
constexpr int k_position_outer_stall_passes = 2;
constexpr double k_position_outer_stall_tolerance = 0.02;
constexpr bool k_position_outer_stall_median = true;

}  // namespace

StageReporter::StageReporter(const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                             const Communicator& comm, const RecoverSettings& resolved)
    : m_on_step(on_step), m_truth(truth), m_comm(comm), m_start(std::chrono::steady_clock::now()) {
    for (int k = 0; k < k_stage_kinds; ++k) m_totals[std::size_t(k)] = planned_iterations(resolved, StageKind(k));
}

bool StageReporter::operator()(const StageId& stage, int iteration, double loss, const Heightfield* heights) {
    bool go_on = true;
    if (m_on_step) {
        StageMetrics m;
        m.stage = stage.name;
        m.kind = stage.kind;
        m.total = m_totals[std::size_t(m.kind)];
        m.iteration = iteration;
        m.loss = loss;
        m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
        if (m_truth && heights) {
            m.height_rel_rmse = height_rel_rmse(*heights, *m_truth);
            m.height_rel_rmse_plane_removed = height_rel_rmse_plane_removed(*heights, *m_truth);
        }
        go_on = m_on_step(m);
    }
    go_on = !m_comm.any(!go_on);  // one rank's stop stops all, at the same step
    if (!go_on) m_stopped = true;
    return go_on;
}

bool ReleaseFieldsStage::run(const StageContext&, RecoveryState& state) const {
    // The position loop's field stages start from empty fields again.
    state.fields = FieldSet{};
    state.unwrapped = state.estimate;
    return true;
}

bool ModelCheckStage::run(const StageContext& context, RecoveryState& state) const {
    std::vector<const Observation*> separable;
    std::vector<std::size_t> index;
    for (const auto& entry : context.by_lambda)
        for (const Observation* o : entry.second) {
            separable.push_back(o);
            index.push_back(std::size_t(o - context.field_observations().data()));
        }
    state.estimate = check_model(separable, index, state.refined_offsets, state.refined_sigma_scale, state.unwrapped,
                                 state.estimate, context.refine, settings, context.report, context.comm,
                                 std::isfinite(state.field_floor) ? state.field_floor : 0.0);
    return !context.stopped();
}

namespace {

// Stage 3's own settings from the run's (scheduled, the ladder's wavelengths resolved).
RefineSettings refine_settings(const RecoverSettings& s) {
    RefineSettings r;
    r.iterations = s.refine_iterations;
    r.history = s.refine_history;
    r.loss = s.refine_loss;
    r.calibrate_exposure = s.calibrate.exposure;
    r.calibrate_sigma = s.calibrate.sigma;
    r.coarse_spacing = s.refine_coarse_spacing;
    r.coarse_weight = s.refine_coarse_weight;
    r.coarse_iterations = s.refine_coarse_iterations;
    r.ladder_min_um = s.refine_ladder_min_um;
    r.ladder_iterations = s.refine_ladder_iterations;
    r.ladder_relative_tolerance = s.refine_ladder_relative_tolerance;
    r.ladder_stall_window = s.refine_ladder_stall_window;
    r.ladder_stall_tolerance = s.refine_ladder_stall_tolerance;
    r.outlier_repair_rounds = s.outlier_repair_rounds;
    r.white_smoothness = s.white_smoothness;
    r.white_smoothness_iterations = s.white_smoothness_iterations;
    return r;
}

// The position loop's own settings from the run's (scheduled): stage 3's fit, the user's passes
// and rescue radius, the loop's constants.
PositionLoopSettings position_loop_settings(const RecoverSettings& s, bool hold_exposures) {
    PositionLoopSettings p;
    p.fit.loss = s.refine_loss;
    p.fit.calibrate_exposure = s.calibrate.exposure;
    p.fit.calibrate_sigma = s.calibrate.sigma;
    p.fit.iterations = s.refine_iterations;
    p.fit.history = s.refine_history;
    p.passes = s.position_outer_passes >= 0 ? s.position_outer_passes : k_position_outer_passes;
    p.tolerance_texels = k_position_outer_tolerance_texels;
    p.field_iterations = k_position_outer_field_iterations;
    p.refine_iterations = k_position_outer_refine_iterations;
    p.rescue_factor = k_position_rescue_factor;
    p.rescue_radius_texels = s.position_rescue_radius_texels;
    p.rescue_step_texels = s.position_rescue_radius_texels / k_position_rescue_points;
    p.field_below_texels = k_position_outer_field_below_texels;
    p.stall_passes = k_position_outer_stall_passes;
    p.stall_tolerance = k_position_outer_stall_tolerance;
    p.stall_median = k_position_outer_stall_median;
    p.hold_exposures = hold_exposures;
    return p;
}

// The model check's own settings: its iterations and shortcut, the field stage's L-BFGS rule.
ModelCheckSettings model_check_settings(const RecoverSettings& s) {
    ModelCheckSettings m;
    m.iterations = s.model_check_iterations;
    m.skip_ratio = s.model_check_skip_ratio;
    m.history = s.field.history;
    m.stall_window = s.field.stall_window;
    m.stall_tolerance = s.field.stall_tolerance;
    m.calibrate_exposure = s.calibrate.exposure;
    m.loss = s.refine_loss;
    return m;
}

}  // namespace

Schedule make_schedule(const RecoverSettings& settings_in, const StageContext& context) {
    RecoverSettings settings = scheduled_settings(settings_in, context.texel_um);
    const auto& by_lambda = context.by_lambda;
    const CalibrationSettings& calibrate = settings.calibrate;
    const bool white = context.white;
    // field_wavelengths / refine_ladder_wavelengths as wavelengths (every rank holds every
    // wavelength's key, so all ranks agree): the n-th longest.
    const auto nth_longest = [&](int n) {
        double l = 0.0;
        for (auto it = by_lambda.rbegin(); it != by_lambda.rend() && n > 0; ++it, --n) l = it->first;
        return l;
    };
    if (settings.field_lambda_min_um == 0.0 && settings.field_wavelengths > 0)
        settings.field_lambda_min_um = nth_longest(settings.field_wavelengths);
    if (settings.refine_ladder_min_um == 0.0 && settings.refine_ladder_wavelengths > 0)
        settings.refine_ladder_min_um = nth_longest(settings.refine_ladder_wavelengths);

    Schedule schedule;
    const auto add = [&](std::shared_ptr<const Stage> stage) { schedule.stages.push_back(std::move(stage)); };

    const BlurredFitSettings& blur = white ? settings.white_blurred : settings.blurred;
    if (!blur.blur_widths.empty() && blur.iterations > 0) {
        auto stage = std::make_shared<BlurredFitStage>();
        stage->fit = blur;
        stage->fit.calibrate_exposure = blur.calibrate_exposure || calibrate.exposure;
        stage->wavelengths = settings.blur_wavelengths;
        add(stage);
    }
    // σ_p before the field stage (which then sees the refined σ_p: measured 5.4 % against 6.8 %
    // with the stated one on a 12² tile 30 % off), not with exposure calibration as well: the energy ratio then
    // absorbs σ_p's energy and the search at the blurred heights can run off (measured: 1.68 for a
    // true 1.0 on an 8² tile of 0.1 µm range, where the refinement from there stayed at 1.45).
    const bool presearched = calibrate.sigma && !calibrate.exposure;
    if (presearched) {
        auto stage = std::make_shared<SigmaPresearchStage>();
        stage->loss = settings.refine_loss;
        stage->calibrate_exposure = calibrate.exposure;
        add(stage);
    }

    auto field = std::make_shared<FieldStage>();
    field->field = settings.field;
    field->field.refine = context.refine;
    field->calibrate_exposure = settings.field.calibrate_exposure || calibrate.exposure;
    field->field.calibrate_exposure = field->calibrate_exposure;
    // When no wavelength reaches the bound, every wavelength runs the field stage.
    field->lambda_min_um = !by_lambda.empty() && by_lambda.rbegin()->first >= settings.field_lambda_min_um
                               ? settings.field_lambda_min_um
                               : 0.0;
    field->tiling = FieldTiling{settings.field_tile_threshold, settings.field_tile_core};
    field->positions = calibrate.positions;
    field->height_range_um = settings.height_range_um;
    // With positions and exposures both calibrated the field stage holds each slice's exposure
    // (found before it: the blurred fit's heights, then each pass's stage 3) fixed: its object is
    // complex, and free exposures let it trade the object's local amplitude for the exposures of
    // the slices over it once the positions are off (measured: 18.5 % with free exposures where
    // the positions alone give 5.5 %).
    const bool hold_exposures = calibrate.positions && calibrate.exposure && !white;
    if (hold_exposures) add(std::make_shared<HeldExposuresStage>());
    if (!white) {
        add(field);
        auto unwrap = std::make_shared<UnwrapStage>();
        unwrap->field = field;
        add(unwrap);
    }
    if (!white && calibrate.sigma && (presearched || calibrate.exposure)) {
        auto stage = std::make_shared<SigmaResearchStage>();
        stage->loss = settings.refine_loss;
        stage->calibrate_exposure = calibrate.exposure;
        stage->presearched = presearched;
        stage->hold_exposures = hold_exposures;
        stage->field = field;
        add(stage);
    }
    add(std::make_shared<ReleaseFieldsStage>());

    if (settings.refine_iterations > 0 && calibrate.positions) {
        auto stage = std::make_shared<PositionLoopStage>();
        stage->settings = position_loop_settings(settings, hold_exposures);
        stage->field = *field;
        add(stage);
    } else if (settings.refine_iterations > 0) {
        auto stage = std::make_shared<RefineStage>();
        stage->settings = refine_settings(settings);
        add(stage);
    }
    // Not for white light (no single-wavelength slice, no field model, no unwrapped heights),
    // nor for GHS/RGHS slices (the field model is their separable proxy's, not theirs).
    if (!white && !context.proxy.proxied && settings.refine_iterations > 0 && settings.model_check_iterations > 0) {
        auto stage = std::make_shared<ModelCheckStage>();
        stage->settings = model_check_settings(settings);
        add(stage);
    }
    return schedule;
}

void run_schedule(const Schedule& schedule, const StageContext& context, RecoveryState& state) {
    for (const auto& stage : schedule.stages)
        if (!stage->run(context, state)) return;
}

}  // namespace wavebrdf::detail
