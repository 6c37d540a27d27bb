#pragma once
// Internal: recover_heights' stages and the Schedule that runs them (recover.h; the order and
// what each stage does: docs/recovery.md, "How it works"; the files: docs/architecture.md).
//
// A stage is a small type holding its own settings (resolved from RecoverSettings by
// make_schedule, the one place where the run's defaults and conditions are decided) with
// run(context, state): it reads the StageContext (what is fixed for the whole run) and reads and
// writes the RecoveryState fields its comment names. run returns false when a report asked to
// stop; the Schedule then ends the run with the state so far.
#include <array>
#include <chrono>
#include <complex>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "recovery/field_proxy.h"
#include "recovery/field_tiles.h"
#include "recovery/recover_field_model.h"
#include "recovery/recover_positions.h"
#include "recovery/refinement.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// The metrics stream (StageMetrics to on_step, with the height errors when a truth is known),
// agreed over the ranks: one rank's stop stops all, at the same step. Once stopped, stopped()
// stays true.
class StageReporter {
public:
    // `resolved`: the run's settings (scheduled_settings), for each step's planned total.
    StageReporter(const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth,
                  const Communicator& comm, const RecoverSettings& resolved);
    bool operator()(const StageId& stage, int iteration, double loss, const Heightfield* heights);
    bool stopped() const { return m_stopped; }

private:
    const std::function<bool(const StageMetrics&)>& m_on_step;
    const Heightfield* m_truth;
    const Communicator& m_comm;
    std::chrono::steady_clock::time_point m_start;
    bool m_stopped = false;
    std::array<int, k_stage_kinds> m_totals{};
};

// What every stage reads and none changes.
struct StageContext {
    // This rank's share, with their weights: the full-model stages' (observation_loss.h).
    const std::vector<Observation>& observations;
    // This rank's single-wavelength separable observations by wavelength, with a key (maybe
    // empty) for every rank's wavelengths, so that all ranks run the same wavelengths.
    const std::map<double, std::vector<const Observation*>>& by_lambda;
    double observations_total;  // every rank's observations
    const Heightfield& flat;    // the grid: rows × cols texels of texel_um, vscale; heights 0
    int rows, cols;
    double texel_um, vscale;
    const Communicator& comm;
    StageReporter& reporter;
    StageReport report;  // reporter as a StageReport
    // White light: no single-wavelength observation on any rank (no field stage).
    bool white = false;
    // GHS/RGHS slices: the field stage and the blurred fit run on the separable proxy for the
    // heights s·H (field_proxy.h), s = cos θ_i; 1 for OHS/ROHS.
    FieldProxy proxy;
    int refine = 1;  // the object grid's samples per texel (odd)
    // With positions calibrated: each observation's gathered position (gather_positions).
    std::vector<std::size_t> position_of;
    // What the stages with their own slice models read (the blurred fit, the field stage, the
    // model check; by_lambda points into it): filled_observations' copies (observation_loss.h)
    // where this rank's observations carry weights; null: `observations` themselves. Index i
    // is observation i in both.
    const std::vector<Observation>* filled = nullptr;
    const std::vector<Observation>& field_observations() const { return filled ? *filled : observations; }

    bool stopped() const { return reporter.stopped(); }
};

// The fields of the field stage: each wavelength's object on the refined grid.
struct FieldSet {
    std::vector<double> lambdas_um;
    std::vector<std::vector<std::complex<double>>> objects;
};

// What the stages hand on.
struct RecoveryState {
    explicit RecoveryState(const Heightfield& start) : estimate(start), unwrapped(start) {}
    Heightfield estimate;      // the heights so far (texel units)
    double sigma_scale = 1.0;  // every σ_p is used × this
    // With positions calibrated: one offset per gathered position (2 each, µm).
    std::vector<double> offsets_um;
    FieldSet fields;  // the unwrapping's input only
    // The smallest final loss of the field retrievals (the model check's shortcut; ∞: none).
    double field_floor = std::numeric_limits<double>::infinity();
    // Each observation's exposure held fixed through the field stage (empty: found there).
    std::vector<double> field_exposures;
    Heightfield unwrapped;  // the last unwrapped heights (the model check's start)
    std::vector<std::array<double, 2>> refined_offsets;  // stage 3's, per observation
    double refined_sigma_scale = 1.0;                    // stage 3's σ_p scale
    Calibration calibration;                             // the acquisition as refined so far
};

class Stage {
public:
    virtual ~Stage() = default;
    // false: a report asked to stop (the run ends with the state so far).
    virtual bool run(const StageContext& context, RecoveryState& state) const = 0;
};

// Stage 0: the surface's shape from blurred slices (recover_blur.cpp), from state.estimate.
// Writes estimate.
struct BlurredFitStage : Stage {
    BlurredFitSettings fit;
    int wavelengths = 1;  // the slices of this many longest wavelengths (0: all)
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// σ_p's scale at the blurred heights, before the field stage (sigma_search.h). Writes
// sigma_scale and the calibration's σ_p scales.
struct SigmaPresearchStage : Stage {
    Loss loss;
    bool calibrate_exposure = false;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// Each observation's exposure at the current heights and offsets, held through the field stage
// (recover_positions.h, exposures_at). Writes field_exposures.
struct HeldExposuresStage : Stage {
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// Stage 1: the field at every wavelength ≥ lambda_min_um on the refined grid (recover_field.cpp,
// field_tiles.h, field_positions.h), longest first, the first started from state.estimate and
// each later one from the heights of the fields before it. Writes fields, field_floor,
// offsets_um (positions calibrated) and, with more than one wavelength, estimate.
struct FieldStage : Stage {
    FieldRetrievalSettings field;  // refine and the exposure calibration resolved
    bool calibrate_exposure = false;
    double lambda_min_um = 0.0;
    FieldTiling tiling;
    bool positions = false;
    double height_range_um = 4.0;  // the unwrapping's bound
    bool run(const StageContext& context, RecoveryState& state) const override;
    // The same with `settings` for every retrieval (the position loop's later passes).
    bool retrieve(const StageContext& context, RecoveryState& state, const FieldRetrievalSettings& settings) const;
    // Stage 2: heights from the fields so far (recover_unwrap.cpp), at the texel centres. Writes estimate.
    void unwrap(const StageContext& context, RecoveryState& state) const;
};

// Stage 2 after the field stage: "unwrap" reported with `pass`. Writes estimate.
struct UnwrapStage : Stage {
    std::shared_ptr<const FieldStage> field;
    int pass = 0;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// σ_p searched again at the unwrapped heights (sigma_search.h); where it moved, the field stage
// and the unwrapping run again. Writes sigma_scale, the calibration's σ_p scales, and (moved)
// what the field stage writes.
struct SigmaResearchStage : Stage {
    Loss loss;
    bool calibrate_exposure = false;
    bool presearched = false;  // SigmaPresearchStage ran (else: the guarded wide search)
    bool hold_exposures = false;
    std::shared_ptr<const FieldStage> field;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// The fields released (16 bytes a sample, the unwrapping's input only), the unwrapped heights
// kept for the model check. Writes fields, unwrapped.
struct ReleaseFieldsStage : Stage {
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// Stage 3's settings (RecoverSettings' refine_*, outlier_repair_rounds, white_smoothness*, the
// calibration's exposure and σ_p; the ladder's as wavelengths, resolved by make_schedule).
struct RefineSettings {
    int iterations = 0;  // on every slice (refine_iterations)
    int history = 20;
    Loss loss{LossKind::Amplitude, 1.0};
    bool calibrate_exposure = false;
    bool calibrate_sigma = false;  // σ_p's calibration rounds instead of the plain refinement
    // The coarse space (refine_coarse_*).
    double coarse_spacing = 0.0;
    double coarse_weight = 1.0;
    int coarse_iterations = 0;
    // The wavelength ladder (refine_ladder_*): rungs at wavelengths ≥ ladder_min_um (0: none).
    double ladder_min_um = 0.0;
    int ladder_iterations = 40;
    double ladder_relative_tolerance = 0.0;
    int ladder_stall_window = 0;
    double ladder_stall_tolerance = 0.01;
    int outlier_repair_rounds = 0;
    // White light's smoothness continuation (white_smoothness*).
    std::vector<double> white_smoothness;
    int white_smoothness_iterations = 0;
};

// Stage 3 on the heights: L-BFGS in the full model (refinement.h) with the wavelength ladder
// and its outlier repairs, σ_p's calibration rounds, white light's smoothness continuation, the
// outlier repair and white light's defect repair. Writes estimate, sigma_scale's calibration,
// refined_sigma_scale and the calibration's exposures.
struct RefineStage : Stage {
    RefineSettings settings;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// The position loop's settings (PositionLoopStage; make_schedule sets every field: passes from
// RecoverSettings::position_outer_passes, the rescue's radius from
// position_rescue_radius_texels, the rest the loop's measured constants in schedule.cpp). Tests
// and experiments/recover_study.cpp vary them through recover_heights_edited.
struct PositionLoopSettings {
    PositionFitSettings fit;  // stage 3 with positions (its first run's iterations)
    int passes = 0;           // outer passes at most (0: one recovery)
    // The loop ends when a registration moves the offsets by less than this (rms, texels; 0: never).
    double tolerance_texels = 0.0;
    // A later pass's L-BFGS iterations: each field's and stage 3's (0: the first pass's).
    int field_iterations = 0;
    int refine_iterations = 0;
    // The rescue: positions whose loss exceeds rescue_factor × the median position's (> 1; 0:
    // off) registered again over ± rescue_radius_texels on a grid of 2 × rescue_step_texels,
    // then ± the step.
    double rescue_factor = 0.0;
    double rescue_radius_texels = 0.0;
    double rescue_step_texels = 0.0;
    // A later pass skips the field stage when the registration moved the offsets by less than
    // this (rms, texels; 0: the field stage in every pass).
    double field_below_texels = 0.0;
    // The stall rule (core/stall_rule.h) over stall_passes passes (0: off) with stall_tolerance;
    // stall_median: on the median position's loss at the start of a pass (with the rescue on),
    // else on stage 3's loss after it.
    int stall_passes = 0;
    double stall_tolerance = 0.0;
    bool stall_median = false;
    bool hold_exposures = false;  // each field stage at stage 3's exposures, held
};

// Throws std::invalid_argument naming the first out-of-range field of `settings`.
void check_position_loop(const PositionLoopSettings& settings);

// Stage 3 with the positions as variables (recover_positions.h), then the position loop:
// registration, rescue, the field stage and stage 3 again until the offsets stop moving or the
// loss stalls. Writes estimate, offsets_um, sigma_scale, unwrapped, refined_offsets,
// refined_sigma_scale and the calibration.
struct PositionLoopStage : Stage {
    PositionLoopSettings settings;
    FieldStage field;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// The model check (recover_field_model.h): the unwrapped heights refined in the field model
// against stage 3's, the better-fitting kept. Writes estimate.
struct ModelCheckStage : Stage {
    ModelCheckSettings settings;
    bool run(const StageContext& context, RecoveryState& state) const override;
};

// The stages in their order.
struct Schedule {
    std::vector<std::shared_ptr<const Stage>> stages;
};

// The schedule of a run with `settings` (RecoverSettings' −1 defaults resolved here) for the
// context's observations: which stages run, in which order, with which settings.
Schedule make_schedule(const RecoverSettings& settings, const StageContext& context);

// Runs the stages in order from state (estimate: flat), stopping at the first that returns false.
void run_schedule(const Schedule& schedule, const StageContext& context, RecoveryState& state);

// Each stage of type S in `schedule` replaced by a copy with change(S&) applied: how
// recover_heights_edited's callers vary one stage's own settings.
template <typename S, typename Change>
void edit_stages(Schedule& schedule, const Change& change) {
    for (auto& stage : schedule.stages)
        if (const S* s = dynamic_cast<const S*>(stage.get())) {
            auto copy = std::make_shared<S>(*s);
            change(*copy);
            stage = std::move(copy);
        }
}

// recover_heights with edit(schedule) applied to its schedule before the run (null: none, as
// recover_heights): tests and experiments/recover_study.cpp vary the settings that stages hold
// but RecoverSettings does not (e.g. the position loop's) this way.
Heightfield recover_heights_edited(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                                   double vscale, const RecoverSettings& settings,
                                   const std::function<void(Schedule&)>& edit,
                                   const std::function<bool(const StageMetrics&)>& on_step = {},
                                   const Heightfield* truth = nullptr,
                                   const Communicator& comm = serial_communicator(),
                                   Calibration* calibration = nullptr);

}  // namespace wavebrdf::detail
