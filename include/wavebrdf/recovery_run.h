#pragma once
// One heightfield recovery as `wavebrdf recover` and the Python module's recover() run it, so
// that both share one implementation: the truth (given, or generated for a study), the
// acquisition planned for it and its observations simulated with noise (acquisition.h, noise.h) or
// observations as given, the warnings of check_acquisition, the loss (given or matched to
// the noise), and the recovery with the pipeline (recover.h) or the thesis's method
// (baseline.h), both reporting through one StageMetrics stream. Writing files is the caller's.
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "wavebrdf/baseline.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/model.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/option_style.h"
#include "wavebrdf/photon_plan.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/scalar_observations.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {

enum class RecoveryMethod {
    Pipeline,  // recover_heights: blurred fit, field retrieval, unwrapping, refinement
    Thesis,    // recover_heights_thesis: Adam, one observation per epoch
};

// Parses "pipeline" or "thesis"; throws std::invalid_argument "NAME 'TEXT' is unknown;
// expected pipeline or thesis" (`name` is the option or argument, e.g. "--method").
RecoveryMethod parse_recovery_method(const std::string& text, const std::string& name = "method");
const char* to_string(RecoveryMethod method);

// The planner's overlap when the positions are calibrated (RecoveryOptions::overlap 0): the
// position loop (recover.h) ends with a cluster of positions lost together with the heights
// between them on 4 of 9 seeds at 0.6 and 1 of 3 fresh seeds at 0.7; at 0.8 no cluster is lost
// on 9 development seeds, only single positions far in the tail of the errors, which the loop's
// rescue about the stated centre brings back (experiments/2026-11-23-position-calibration.md).
// About 2.5 × the slices of 0.6, ≈ 1.5–2 × the CPU.
constexpr double k_position_calibration_overlap = 0.8;

// The position loop's rescue radius per unit of the stated position uncertainty
// (RecoveryOptions::position_uncertainty_um; at least RecoverSettings' default 4 texels, at most
// 16): at 3 texels rms the default ± 4 texels left positions 9–13 texels from their stated
// centres lost for good (experiments/2026-11-23-position-calibration.md).
constexpr double k_rescue_radius_per_position_uncertainty = 4.0;

// The options of `wavebrdf recover` (its defaults), as values.
struct RecoveryOptions {
    // Grid of the generated truth, and of the estimate with given observations (≥ 1 each).
    int rows = 32, cols = 32;
    double texel_um = 2.0;  // texel width w, µm (> 0); a given truth brings its own
    double vscale = 1.0;    // vertical scale v; a given truth brings its own
    // Generated truth: peak-to-valley height, µm (> 0). With given observations: the bound on
    // the height range for unwrapping. (With a given truth its own range is used.)
    double height_range_um = 2.0;
    double correlation_texels = 4.0;  // generated truth: correlation length, texels (> 0)
    // With a given truth: the rough-surface plan (roughness_plan.h) from the truth's measured
    // roughness (measure_roughness: range, slopes, Sal, Str) instead of height_range_um and
    // correlation_texels. false: the stated ones (a study that plans as a user without the
    // truth would).
    bool plan_from_truth = false;
    // Acquisition, planned for a truth (PlanRequest's fields of the same names).
    Model model = Model::OHS;
    std::array<double, 2> omega_i{{0.0, 0.0}};  // projected light direction ω_i (|ω_i| < 1)
    // Steep surfaces (the stated range and correlation, roughness_plan.h): every position is
    // observed under oblique lights as well (add_oblique_lights). false: under omega_i alone
    // (an instrument with one source).
    bool oblique_lights = true;
    double sigma_p_um = 0.0;                    // 0: the planner's (1.5 texels, or below)
    // The stage's position uncertainty, µm rms per coordinate (PlanRequest's: the planner sizes
    // σ_p for it; with calibrate.positions the loop's rescue searches ± k × it,
    // k_rescue_radius_per_position_uncertainty, where that exceeds its default). Unset: the
    // simulated error's rms (errors.position_rms_texels × texel_um), as a stage's datasheet would
    // state it; 0 without simulated errors.
    std::optional<double> position_uncertainty_um;
    int resolution = 0;                         // 0: the planner's (acquisition.h)
    std::vector<double> lambdas_um;             // empty: the planner's ladder
    // White light: N ≥ 2 makes every planned observation one RGB slice of a broadband source
    // sampled at spectral_wavelengths_um(N) (spectrum.h; the renderer's --spectral N), one per
    // position, its resolution planned for the shortest of them; 0: laser (lambdas_um).
    int spectral = 0;
    // Worst-case linear overlap of neighbouring windows for the planner (0.6 … 0.95,
    // check_recovery_options); unset: the planner's default (PlanRequest's, 0.6), or
    // k_position_calibration_overlap with calibrate.positions.
    std::optional<double> overlap;
    double jitter = 0.2;
    Noise noise;  // simulated on the rendered observations (a truth only)
    // Photon-aware planning (photon_plan.h), with Poisson noise and the loss matched to it: the
    // target rms height error, a fraction of the truth's peak to valley (0 … 1; 0: off), and the
    // most exposures of N photons (noise's N, per exposure) summed into a slice (1 … 10^4).
    double target_error = k_default_target_error;
    int max_exposures = k_default_max_exposures;
    // How the observations of a truth are simulated: the Gabor model (render_observation) or
    // the independent scalar-diffraction simulator (scalar_diffraction.h, OHS / ROHS only).
    Simulator simulator = Simulator::Gabor;
    std::optional<Loss> loss;  // none: recovery_loss's choice
    RecoveryMethod method = RecoveryMethod::Pipeline;
    int field_iterations = -1;   // pipeline: per wavelength, ≤ 10^7; < 0: RecoverSettings' default
    int refine_iterations = -1;  // pipeline: L-BFGS on the heights, ≤ 10^7; < 0: the default
    // Field tiles (RecoverSettings::field_tile_*): threshold 0 … 10^6 (0: never tiled), core 8 …
    // 4096 texels; < 0: the default.
    int field_tile_threshold = -1, field_tile_core = -1;
    // Stage 3's coarse space (RecoverSettings::refine_coarse_*): node spacing in texels (0: off),
    // the joint variables' weight (0: none) and coarse-only iterations per round; < 0: the default.
    double refine_coarse_spacing = -1.0, refine_coarse_weight = -1.0;
    int refine_coarse_iterations = -1;
    // White light's smoothness continuation (RecoverSettings::white_smoothness, largest first;
    // at most 64 weights, each 0 … 10^12; an empty list: none; unset: the default) and its
    // iterations per weight (≤ 10^7; < 0: the default).
    std::optional<std::vector<double>> white_smoothness;
    int white_smoothness_iterations = -1;
    int epochs = 1000;           // thesis: Adam epochs, 0 … 10^7 (k_max_iterations)
    std::uint64_t seed = 1;      // generated truth, jitter, noise, the thesis's draws
    // Refuse (OutOfMemory, before simulating or recovering) a run whose estimated peak memory
    // (estimate_recovery_bytes) exceeds this many GB; 0: the physical memory.
    double max_memory_gb = 0.0;
    // Self-calibration (calibration.h): the parts of the acquisition the pipeline refines.
    CalibrationSettings calibrate;
    // With calibrate.positions: at most this many passes of the position loop after the first
    // recovery (RecoverSettings::position_outer_passes, 0 … 100; 0: off, one recovery; < 0: the
    // library's default, 40, stopped earlier by its stall rule).
    int position_passes = -1;
    // A study's acquisition errors (a truth only): the observations are rendered for the
    // perturbed acquisition (positions offset per footprint position, σ_p scaled, each slice
    // scaled by its exposure after the noise, which is relative to the slice) and the recovery
    // is given the nominal one. Seeded per position / observation (calibration.h), so the same
    // on any number of ranks.
    AcquisitionErrors errors;
    // Error bars (uncertainty.h): run_recovery_in_directory also writes uncertainty.exr (σ of
    // every height, µm) and the summary, at the cost of a few refinements (docs/recovery.md).
    bool uncertainty = false;
    // Whether the convergence check computes error bars of its own where it needs them
    // (convergence.h: auto, by the cost rule; always; off).
    CheckErrorBars check_error_bars = CheckErrorBars::Auto;
    // Plan only (a truth, given or generated): prepare_recovery plans the acquisition and the
    // photons (plan_photons with its pilot) as the run would, then stops before simulating:
    // `observations` holds the planned slices without references, for write_recovery_plan.
    bool plan_only = false;
    // How prepare_recovery's messages name the options (the front end's spelling).
    OptionStyle names = OptionStyle::Cli;
};

// The loss the recovery fits: options.loss when given; else, for the pipeline, the one
// matched to the noise (matched_loss: poisson:N for Poisson noise, mse for Gaussian noise,
// amplitude without noise), and for the thesis's method its own cmsle:1 whatever the noise.
Loss recovery_loss(const RecoveryOptions& options);

// The study's default truth: an isotropic Gaussian-correlated surface (generate.h) of
// rows × cols texels of texel_um, correlation length correlation_texels texels, seeded, with
// vscale and scaled to the peak-to-valley height_range_um (with_height_range). Throws as
// generate_heightfield and with_height_range do.
Heightfield generated_recovery_truth(const RecoveryOptions& options);

// Everything a recovery needs, resolved: what run_recovery runs and what a caller reports.
struct PreparedRecovery {
    std::optional<Heightfield> truth;  // given or generated; none with given observations
    std::vector<Observation> observations;
    int rows = 0, cols = 0;               // of the estimate
    double texel_um = 0.0, vscale = 1.0;  // of the estimate
    double range_um = 0.0;                // the truth's peak-to-valley, else options.height_range_um
    RecoveryMethod method = RecoveryMethod::Pipeline;
    Noise noise;  // of the slices as recovered: with photon_plan, its exposures summed (k·N photons)
    Loss loss;
    // The photon-aware plan (options.target_error), where it was evaluated.
    std::optional<PhotonPlan> photon_plan;
    RecoverSettings pipeline;           // used when method is Pipeline
    BaselineSettings thesis;            // used when method is Thesis
    std::vector<std::string> notes;     // the plan's (none with given observations)
    std::vector<std::string> warnings;  // check_acquisition's
    // Why height_rel_rmse is undefined although a truth is known ("undefined: the truth is
    // flat", e.g. a 1×1 truth: its height range is 0); empty when it is defined or no truth.
    // The recovery runs all the same, with height_rel_rmse −1 (as without a truth).
    std::string metric_note;
    // Under MPI (prepared for a communicator of several ranks, docs/scale.md): `observations`
    // is this rank's share (observation_share: a block of footprint positions, all their
    // wavelengths); `share` holds their indices among all the run's observations (ascending;
    // 0 … N − 1 on one rank), total_observations is N and `ranks` the communicator's size.
    // `catalogue`: every observation of the run without its reference (metadata, for saving
    // them on rank 0); kept only on several ranks.
    std::vector<std::size_t> share;
    std::size_t total_observations = 0;
    bool plan_only = false;  // options.plan_only: observations are the planned slices, not rendered
    int ranks = 1;
    std::vector<Observation> catalogue;
    // With a truth and options.errors: the true acquisition errors of `observations` (this
    // rank's share; calibration.h's meaning), what a calibrated recovery should find.
    std::optional<Calibration> true_calibration;
    bool uncertainty = false;  // options.uncertainty
    CheckErrorBars check_error_bars = CheckErrorBars::Auto;  // options.check_error_bars
    // The memory limit the run was held to (options.max_memory_gb; 0: the physical memory) and
    // how the front end names it in messages: the check's own error bars are held to it too.
    double max_memory_gb = 0.0;
    std::string memory_hint = "--max-memory-gb";
};

// Estimated peak memory (bytes) of recovering a rows × cols heightfield of texel_um from
// `observations` (their references counted at full size even when still empty, as
// planned_observations leaves them) by `method` with `settings` (the pipeline's): the
// references and a fixed base, plus the largest of the stages' working sets, which do not
// overlap: the field stage (its per-slice operators of one wavelength, the object grid's
// L-BFGS history, with tiles the fields of every wavelength), the refinement (its plans and
// the heights' L-BFGS history) and the model check (one wavelength's object and the exact
// sums on the fine grid). Within a factor of ~2 of the measured peak
// (RecoveryRun.EstimateIsWithinAFactorOfTwoOfTheMeasuredPeak).
double estimate_recovery_bytes(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                               RecoveryMethod method, const RecoverSettings& settings = {});

// What a front end was given besides the options: a truth, observations, a stated
// correlation length (the library cannot tell a stated one from the default).
struct RecoveryInputs {
    bool truth = false;
    bool observations = false;
    bool correlation = false;
};

// Every check of `options` that needs no file, each written here once and named as
// options.names spells the option: the ranges of the counts, weights, wavelengths, tiles,
// white light's smoothness list, the position uncertainty, the simulated acquisition errors
// and max_memory_gb; which inputs exclude each other (a truth and observations; noise, a
// simulator, simulated errors or plan_from_truth without a truth to render;
// plan_from_truth with a stated correlation length); a pipeline without a field stage. The
// front ends call it before reading any file; prepare_recovery calls it again (without
// `given.correlation`). Throws std::invalid_argument (one line).
void check_recovery_options(const RecoveryOptions& options, const RecoveryInputs& given);

// For the pipeline, a model that is not separable (planned laser observations) is refused
// (std::invalid_argument) before any work; RGB observations alone take the white-light path
// (recover_heights).
// The set-up: with `observations` (non-empty) they are used as given on an
// options.rows × options.cols grid; else the truth is `truth` (its size, texel width and
// vscale) or, when null, generated_recovery_truth(options), the acquisition is planned for its
// size and height range (plan_acquisition) and the observations are simulated from it with
// options.noise (simulate_observations, seed options.seed). `show_progress` draws a
// "simulate" progress bar on a terminal. Throws std::invalid_argument when both a truth and
// observations are given, when noise is asked for with given observations, or for epochs or
// iteration counts above k_max_iterations (optim.h) or epochs < 0 (before any work); the
// planner's, the generator's and the loss's exceptions otherwise. Throws OutOfMemory
// (memory.h), before simulating, when estimate_recovery_bytes exceeds options.max_memory_gb
// (memory_limit).
// `comm`: the ranks the run is split over. Every rank passes the same options, truth and
// (all the) given observations; each keeps its share (observation_share), and with a truth
// every rank plans the same acquisition and simulates only its share (the same references
// and noise as the one-process run: noise is seeded per observation). check_acquisition sees
// all the observations' metadata on every rank; the memory check counts this rank's share.
// Rank-local work only (no collective call): wrap it in run_agreed. The thesis's method runs
// on one rank only (std::invalid_argument on several).
PreparedRecovery prepare_recovery(const RecoveryOptions& options, const Heightfield* truth = nullptr,
                                  std::vector<Observation> observations = {}, bool show_progress = false,
                                  const Communicator& comm = serial_communicator());

// The estimate (prepared.rows × prepared.cols, texel units with prepared.texel_um and
// vscale) from a flat start, by prepared.method. on_step receives every StageMetrics of the
// method ("blur:S", "blur", "field:λ", "unwrap", "refine" for the pipeline; "thesis" every
// report_every epochs), with height_rel_rmse when a truth is known and not flat (else −1),
// each with its kind and planned total (recover.h, StageKind: a progress bar's length);
// returning false stops and returns the estimate so far.
// `comm`: the ranks prepared.observations are split over (prepared with a communicator of the
// same size, else std::invalid_argument); collective, the estimate the same on every rank,
// on_step called on every rank (recover_heights).
// `calibration`, when given, receives the acquisition as the pipeline refined it
// (recover_heights; this rank's share; the default Calibration for the thesis's method).
Heightfield run_recovery(const PreparedRecovery& prepared, const std::function<bool(const StageMetrics&)>& on_step = {},
                         const Communicator& comm = serial_communicator(), Calibration* calibration = nullptr);

// Error bars of a run's estimate (uncertainty.h; what `wavebrdf recover --uncertainty` and
// Python's recover(uncertainty=True) report): height_uncertainty at `estimate` with the run's
// loss, timed, and the report with the coverage where a truth is known. A problem without error
// bars (no residual to estimate the noise from: decided on exact sums, so the same on every
// rank) returns none and says why in *why_not (when given) instead of costing the estimate.
// Collective over `comm` (the run's communicator).
std::optional<UncertaintyReport> recovery_error_bars(const PreparedRecovery& prepared, const Heightfield& estimate,
                                                     const Communicator& comm = serial_communicator(),
                                                     std::string* why_not = nullptr,
                                                     const UncertaintySettings& settings = {});

// The convergence check's noise limit (convergence.h, add_predicted_error) for a run's estimate:
// with `sigma_um` (error bars the run computed) as given; else, where the check needs them
// (needs_error_bars: a misfit on the photon-noise floor, or a loss without a noise level), the
// bars computed here for the check alone (recovery_error_bars) when prepared.check_error_bars
// and the cost rule allow (check_error_bars_affordable: predicted_uncertainty_seconds from the
// check's pass_seconds against `run_seconds`, the recovery's CPU time; rank 0's prediction,
// the same decision on every rank). The check needs only √(mean σ²), which the probed diagonal
// estimates as well as the exact one (64²: 2.3653 % against 2.3645 %), so its bars take
// whichever of the dense and the probed solve is predicted cheaper among those whose predicted
// peak (predicted_uncertainty_cost's bytes, with the observations and heights the run holds)
// fits prepared.max_memory_gb (memory_limit; check_error_bars_fit). Bars that fit neither way
// are not computed, Always included ("skipped" under Auto, "unavailable" under Always, the
// note require_memory's message). check.error_bars and its note say what was done. Collective.
void judge_noise_limit(ConvergenceCheck& check, const PreparedRecovery& prepared, const Heightfield& estimate,
                       const std::vector<double>* sigma_um, double run_seconds,
                       const Communicator& comm = serial_communicator());
// The texture check (texel_texture.h) after the noise limit: at the error bars' rms σ where
// judge_noise_limit or the run computed them, else the photon plan's predicted rms error less its
// bias (studies with --noise poisson), else the Fisher diagonal's lower bound; else not judged.
void judge_texture(ConvergenceCheck& check, const PreparedRecovery& prepared, const Heightfield& estimate);

// The model check's misfits as a run reports them (run_recovery's metrics stream: the steps of
// kinds ModelMisfit and ModelSelect), for the convergence check.
struct ModelCheckMisfits {
    double gabor = -1.0, field = -1.0;  // −1: not reported
    std::string selected;               // "gabor" or "field"; "" without the check
    void record(const StageMetrics& step);
};

// What follows run_recovery, as both front ends report it: the error bars (with
// prepared.uncertainty and a run not stopped: recovery_error_bars; a problem without bars keeps
// its estimate and says why in no_error_bars) and whether the run converged, judged without the
// truth (check_convergence on the run's floor, the model check's misfits, the bars and the noise
// limit: judge_noise_limit with `run_seconds`, the recovery's CPU time, not after a stop).
// `calibration`: the run's, this rank's share (null or ignored without self-calibration).
// Collective over `comm`.
struct RecoveryJudgement {
    std::optional<UncertaintyReport> error_bars;
    std::string no_error_bars;  // why there are none, where they were asked for and there are none
    ConvergenceCheck convergence;
};
RecoveryJudgement judge_recovery(const PreparedRecovery& prepared, const Heightfield& estimate,
                                 const ModelCheckMisfits& misfits, const Calibration* calibration, bool stopped,
                                 double run_seconds, const Communicator& comm = serial_communicator());

}  // namespace wavebrdf
