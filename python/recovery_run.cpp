// recover(): `wavebrdf recover` without its output directory, through the same library piece
// as the CLI (recovery_run.h), so the same options give the same run.
#include <algorithm>
#include <cmath>
#include <iterator>
#include <optional>
#include <type_traits>

#include "common.h"
#include "progress.h"
#include "recovery_args.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/recovery_directory.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

struct RecoveryResult {
    py::object estimate, truth, observations, metrics, calibration;
    std::vector<std::string> notes, warnings;
    std::string method, loss, noise;
    double height_range_um = 0.0;
    bool stopped = false;
    // Error bars (uncertainty=True): σ per texel (µm) and, with a truth, the coverage.
    py::object uncertainty = py::none();
    double median_sigma_um = NAN, coverage_1sigma = NAN, coverage_2sigma = NAN, uncertainty_seconds = NAN;
    py::dict convergence;  // the run's own verdict, without the truth (convergence.h)
    py::object plan;       // run.json's plan as a dict (recovery_plan_json)
};

// run.json's "convergence" block (recovery_directory.cpp) as a dict, with its warning line.
py::dict convergence_dict(const ConvergenceCheck& c) {
    py::dict d;
    d["converged"] = c.converged;
    d["floor"] = c.floor;
    d["relative_misfit"] = c.relative_misfit;
    d["reasons"] = c.reasons;
    d["warning"] = c.warning();
    if (c.floor == "poisson") {
        d["deviance"] = c.deviance;
        d["expected_deviance"] = c.expected_deviance;
        d["deviance_sd"] = c.deviance_sd;
        d["misfit_ratio"] = c.misfit_ratio;
        d["slices_off_floor"] = c.slices_off_floor;
        d["worst_slice_excess"] = c.worst_slice_excess;
        d["worst_slice_x_um"] = c.worst_slice_x_um;
        d["worst_slice_y_um"] = c.worst_slice_y_um;
    }
    if (!c.model_selected.empty()) {
        d["model_misfit_gabor"] = c.model_misfit_gabor;
        d["model_misfit_field"] = c.model_misfit_field;
        d["model_selected"] = c.model_selected;
    }
    if (c.median_sigma_relative >= 0.0) d["median_sigma_relative"] = c.median_sigma_relative;
    if (c.predicted_error_relative >= 0.0) d["predicted_error_relative"] = c.predicted_error_relative;
    if (!c.texture_sigma_source.empty()) {
        py::dict t;
        t["sigma_relative"] = c.texture_sigma_relative;
        t["sigma_source"] = c.texture_sigma_source;
        t["texels"] = c.texture_texels;
        t["fraction"] = c.texture_fraction;
        t["power_share"] = c.texture_power_share;
        t["warned"] = c.texture_warned;
        d["texture"] = t;
    }
    d["judged"] = c.judged();
    if (!c.error_bars.empty()) {
        d["error_bars"] = c.error_bars;
        if (!c.error_bars_note.empty()) d["error_bars_note"] = c.error_bars_note;
        if (c.error_bars_predicted_seconds >= 0.0) {
            d["error_bars_predicted_seconds"] = c.error_bars_predicted_seconds;
            d["run_seconds"] = c.run_seconds;
        }
        if (c.error_bars_seconds >= 0.0) d["error_bars_seconds"] = c.error_bars_seconds;
        if (c.error_lower_bound_relative >= 0.0) {
            d["error_lower_bound_relative"] = c.error_lower_bound_relative;
            d["error_lower_bound_seconds"] = c.error_lower_bound_seconds;
        }
        if (c.error_bars_predicted_bytes >= 0.0) d["error_bars_predicted_bytes"] = c.error_bars_predicted_bytes;
        if (c.memory_limit_bytes >= 0.0) d["memory_limit_bytes"] = c.memory_limit_bytes;
    }
    return d;
}

RecoveryResult recover(const py::object& truth_arg, const py::object& observations_arg, const py::object& size,
                       const py::object& texel_arg, const py::object& vscale_arg, double height_range_um,
                       const py::object& correlation_texels, const std::string& model, const py::object& light,
                       double sigma_p_um, const py::object& position_uncertainty_um, int resolution,
                       const py::object& lambdas_um, int spectral, const py::object& noise, const py::object& loss,
                       const std::string& method, const py::object& calibrate, bool with_uncertainty,
                       const std::string& check_error_bars, double target_error, int max_exposures,
                       std::uint64_t seed, bool plan_only, const py::object& callback,
                       double max_memory_gb, const py::object& quiet, const py::object& comm_arg,
                       const py::object& settings, const py::kwargs& old_keywords) {
    const RecoverKnobs k = knobs_argument(
        settings, old_keywords, "recover",
        {"field_iterations", "refine_iterations", "field_tile_threshold", "field_tile_core", "refine_coarse_spacing",
         "refine_coarse_weight", "refine_coarse_iterations", "position_passes", "white_smoothness",
         "white_smoothness_iterations", "overlap", "jitter", "oblique_lights", "plan_from_truth", "simulator",
         "simulate_position_error_texels", "simulate_exposure", "simulate_sigma_factor", "epochs"},
        true);
    const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
    // Options, checked before any work; the planner checks sigma_p_um, overlap and jitter.
    RecoveryOptions options;
    options.names = OptionStyle::Python;  // prepare_recovery's messages name the keywords
    options.method = parse_recovery_method(method, "method");
    options.noise = noise_argument(noise);
    options.simulator = parse_simulator(knob<std::string>(k.simulator, "simulator", "'gabor' or 'scalar'"),
                                        "simulator");
    if (!loss.is_none()) options.loss = loss_argument(loss);
    const std::array<int, 2> rc = size_argument(size);
    options.rows = rc[0];
    options.cols = rc[1];
    options.height_range_um = check_positive(height_range_um, "height_range_um");
    // As the CLI: a given truth is planned for its measured roughness unless a correlation length
    // is stated (then the stated plan, as a user without the truth would have it).
    const bool correlation_given = !correlation_texels.is_none();
    if (correlation_given)
        options.correlation_texels = check_positive(correlation_texels.cast<double>(), "correlation_texels");
    options.plan_from_truth = !truth_arg.is_none() && !correlation_given;
    if (!k.plan_from_truth.is_none()) {
        if (!py::isinstance<py::bool_>(k.plan_from_truth))
            bad_argument("plan_from_truth", std::string(py::repr(k.plan_from_truth)), "True, False or None");
        options.plan_from_truth = k.plan_from_truth.cast<bool>();
    }
    options.model = model_from(model);
    options.omega_i = light_direction(light);
    if (!py::isinstance<py::bool_>(k.oblique_lights))
        bad_argument("oblique_lights", std::string(py::repr(k.oblique_lights)), "True or False");
    options.oblique_lights = k.oblique_lights.cast<bool>();
    options.sigma_p_um = check_finite(sigma_p_um, "sigma_p_um");
    if (!position_uncertainty_um.is_none()) options.position_uncertainty_um = position_uncertainty_um.cast<double>();
    options.resolution = planned_resolution(resolution);
    options.lambdas_um = wavelength_list(lambdas_um, "lambdas_um");
    options.spectral = spectral;
    // The settings as values (None: the sentinel the library reads as its default); their ranges
    // are prepare_recovery's (and the planner's) to check.
    if (!k.overlap.is_none()) options.overlap = knob<double>(k.overlap, "overlap", "0.6 ... 0.95 or None");
    options.jitter = knob<double>(k.jitter, "jitter", "0 ... 0.3");
    options.field_iterations = optional_count(k.field_iterations, "field_iterations");
    options.refine_iterations = optional_count(k.refine_iterations, "refine_iterations");
    options.field_tile_threshold = optional_int(k.field_tile_threshold, "field_tile_threshold");
    options.field_tile_core = optional_int(k.field_tile_core, "field_tile_core");
    options.refine_coarse_spacing = optional_nonnegative(k.refine_coarse_spacing, "refine_coarse_spacing");
    options.refine_coarse_weight = optional_nonnegative(k.refine_coarse_weight, "refine_coarse_weight");
    options.refine_coarse_iterations = optional_count(k.refine_coarse_iterations, "refine_coarse_iterations");
    options.white_smoothness = white_smoothness_argument(k.white_smoothness);
    options.white_smoothness_iterations = optional_count(k.white_smoothness_iterations, "white_smoothness_iterations");
    options.epochs = knob<int>(k.epochs, "epochs", "an epoch count >= 0");
    options.seed = seed;
    options.plan_only = plan_only;
    options.max_memory_gb = max_memory_gb;
    options.uncertainty = with_uncertainty;  // the plan refines to the minimum first (recovery_run.h)
    try {
        options.check_error_bars = parse_check_error_bars(check_error_bars);
    } catch (const std::invalid_argument&) {
        bad_argument("check_error_bars", "'" + check_error_bars + "'", "'auto', 'always' or 'off'");
    }
    options.target_error = target_error;  // prepare_recovery checks both ranges
    options.max_exposures = max_exposures;
    options.calibrate = calibrate_argument(calibrate);
    options.position_passes = optional_count(k.position_passes, "position_passes");
    options.errors.position_rms_texels = knob<double>(k.simulate_position_error_texels,
                                                      "simulate_position_error_texels", "an rms in texels, 0 to 10");
    if (!k.simulate_exposure.is_none()) {
        const std::vector<double> range = knob<std::vector<double>>(
            k.simulate_exposure, "simulate_exposure", "(min, max) with 0.001 <= min <= max <= 1000, or None");
        if (range.size() != 2)
            throw py::value_error("simulate_exposure = " + std::string(py::repr(k.simulate_exposure)) +
                                  " is invalid; expected (min, max) with 0.001 <= min <= max <= 1000, or None");
        options.errors.exposure_min = range[0];
        options.errors.exposure_max = range[1];
    }
    options.errors.sigma_p_factor = knob<double>(k.simulate_sigma_factor, "simulate_sigma_factor",
                                                 "a factor in [0.25, 4]");
    options.errors.seed = seed;
    check_callback(callback);
    check_quiet(quiet);
    // Every option the library checks, before any file is read (prepare_recovery checks them again).
    RecoveryInputs given;
    given.truth = !truth_arg.is_none();
    given.observations = !observations_arg.is_none();
    given.correlation = correlation_given;
    check_recovery_options(options, given);
    // The scale: given, else a truth Heightfield's or a truth file's (its header read here).
    const HeightfieldScale scale = truth_scale(truth_arg, texel_arg, vscale_arg, options.texel_um);
    options.texel_um = scale.texel_um;
    options.vscale = scale.vscale;

    std::optional<Heightfield> truth;
    std::vector<Observation> observations;
    if (!observations_arg.is_none())
        observations = observations_or_file(observations_arg);
    else if (!truth_arg.is_none())
        truth = heightfield_argument(truth_arg, "truth", options.texel_um, options.vscale,
                                     !texel_arg.is_none() || !vscale_arg.is_none());

    std::optional<PreparedRecovery> prepared;
    {
        InterruptibleRelease release;  // rank-local work: agreed below
        run_agreed(*comm, [&] {
            prepared = prepare_recovery(options, truth ? &*truth : nullptr, std::move(observations), false, *comm);
        });
    }
    RecoveryResult result;
    result.plan = py::module_::import("json").attr("loads")(recovery_plan_json(*prepared, options));
    result.truth = prepared->truth ? py::cast(*prepared->truth) : py::none();
    result.observations = py::cast(prepared->observations);
    result.notes = prepared->notes;
    result.warnings = prepared->warnings;
    result.method = to_string(prepared->method);
    result.loss = to_string(prepared->loss);
    result.noise = to_string(prepared->noise);
    result.height_range_um = prepared->range_um;
    if (plan_only) {  // the plan alone: nothing simulated or recovered
        result.estimate = py::none();
        result.metrics = py::dict();
        result.calibration = py::none();
        return result;
    }
    std::vector<StageMetrics> history;
    // Progress (progress.h): a bar per iterating stage of the length the run reports with each
    // step, closed however the run ends. Under MPI only rank 0 shows progress.
    PythonProgress progress("wrap_recover", callback, comm->is_root() ? quiet : py::object(py::bool_(true)));
    Calibration calibration;
    const double run_start = process_cpu_seconds();
    const Heightfield estimate = run_released(
        progress.callback(), history, result.stopped,
        [&](const auto& on_step) { return run_recovery(*prepared, on_step, *comm, &calibration); }, &progress,
        comm->size() > 1);
    const double run_seconds = process_cpu_seconds() - run_start;  // CPU: the error bars' cost rule
    py::dict cal = calibration_dict(options.calibrate, calibration);
    cal["truth"] = prepared->true_calibration
                       ? py::object(calibration_dict(CalibrationSettings{}, *prepared->true_calibration))
                       : py::object(py::none());
    if (prepared->true_calibration) cal["truth"].cast<py::dict>().attr("pop")("refined");
    result.calibration = cal;
    result.estimate = py::cast(estimate);
    result.metrics = metrics_columns(history);
    // The error bars and whether it converged: the library's, as for the CLI (judge_recovery).
    ModelCheckMisfits misfits;
    for (const StageMetrics& m : history) misfits.record(m);
    RecoveryJudgement judged;
    {
        py::gil_scoped_release release;
        judged = judge_recovery(*prepared, estimate, misfits, &calibration, result.stopped, run_seconds, *comm);
    }
    // As the CLI: a problem without error bars keeps its estimate, with a warning.
    if (with_uncertainty && !judged.error_bars && !judged.no_error_bars.empty())
        py::module_::import("warnings")
            .attr("warn")("no error bars: " + judged.no_error_bars,
                          py::module_::import("builtins").attr("RuntimeWarning"));
    if (judged.error_bars) {
        UncertaintyReport& bars = *judged.error_bars;
        result.median_sigma_um = bars.median_sigma_um;
        result.uncertainty_seconds = bars.seconds;
        if (bars.coverage_2sigma >= 0.0) {
            result.coverage_1sigma = bars.coverage_1sigma;
            result.coverage_2sigma = bars.coverage_2sigma;
        }
        result.uncertainty = owning_array(std::move(bars.map.sigma_um), {estimate.rows(), estimate.cols()});
    }
    const ConvergenceCheck& convergence = judged.convergence;
    if (!convergence.converged) result.warnings.push_back(convergence.warning());
    result.convergence = convergence_dict(convergence);
    return result;
}

}  // namespace

void bind_recovery_run(py::module_& m) {
    // ---- the CLI's run -----------------------------------------------------------------------
    py::class_<RecoveryResult>(m, "RecoveryResult", "What recover() returns.")
        .def_readonly("estimate", &RecoveryResult::estimate, "the recovered Heightfield (None with plan_only=True)")
        .def_readonly("truth", &RecoveryResult::truth,
                      "the truth Heightfield (given or generated; None with observations)")
        .def_readonly("observations", &RecoveryResult::observations,
                      "the Observations recovered from (simulated or given)")
        .def_readonly("notes", &RecoveryResult::notes, "the plan's choices, one line each (empty with observations)")
        .def_readonly("warnings", &RecoveryResult::warnings, "check_acquisition's warnings")
        .def_readonly("metrics", &RecoveryResult::metrics, R"doc(
dict of arrays, one entry per reported step (the CLI's metrics.csv columns): stage (str),
iteration (int64), loss, seconds (since the recovery started), height_rel_rmse and
height_rel_rmse_plane_removed (float64; NaN without a truth or before heights exist).
)doc")
        .def_readonly("method", &RecoveryResult::method, "'pipeline' or 'thesis'")
        .def_readonly("loss", &RecoveryResult::loss, "the loss fitted, as a spec")
        .def_readonly("noise", &RecoveryResult::noise, "the simulated noise, as a spec")
        .def_readonly("height_range_um", &RecoveryResult::height_range_um,
                      "the truth's peak-to-valley (um), or the bound given with observations")
        .def_readonly("plan", &RecoveryResult::plan, R"doc(
dict: the plan as the CLI's run.json states it before the run (its notes as "plan", the
wavelengths, resolution, noise and loss, with photon noise "photon_plan" with its pilot); with
plan_only=True also plan_only (True) and positions_um, the footprint centres in order.
)doc")
        .def_readonly("stopped", &RecoveryResult::stopped, "True when the callback stopped the run early")
        .def_readonly("calibration", &RecoveryResult::calibration, R"doc(
dict of the self-calibration (calibration.h): refined (str, e.g. 'exposure,sigma' or 'none'),
sigma_p_scale (true sigma_p / stated), exposures (float64 (N,), reference ~ exposure * model,
per observation of result.observations; None when not refined), position_offsets_um (float64
(N, 2), true - stated centre; None when not refined), truth: with simulated acquisition errors
the same keys with the true values (else None).
)doc")
        .def_readonly("uncertainty", &RecoveryResult::uncertainty,
                      "with uncertainty=True: sigma of every height (mean removed), um, a float64 array "
                      "(rows, cols); else None")
        .def_readonly("median_sigma_um", &RecoveryResult::median_sigma_um, "median of uncertainty (um; NaN without)")
        .def_readonly("coverage_1sigma", &RecoveryResult::coverage_1sigma,
                      "fraction of texels whose error lies within +-1 sigma (NaN without a truth or uncertainty)")
        .def_readonly("coverage_2sigma", &RecoveryResult::coverage_2sigma,
                      "fraction of texels whose error lies within +-2 sigma (NaN without a truth or uncertainty)")
        .def_readonly("uncertainty_seconds", &RecoveryResult::uncertainty_seconds,
                      "wall time of the error bars, s (NaN without)")
        .def_readonly("convergence", &RecoveryResult::convergence, R"doc(
dict: whether the recovery converged, judged without the truth (convergence.h; the CLI's
run.json "convergence"): converged (bool), floor ('poisson': the slices' photon-noise deviance,
'noiseless': a study's exact slices, 'none': the misfit not judged), relative_misfit, reasons
(list of str), warning (str, '' when converged), judged (bool: a floor or error bars judged the
run; False: reported only); with 'poisson' also deviance, expected_deviance, deviance_sd,
misfit_ratio (deviance / its noise floor), slices_off_floor (slices above their own floor) and
worst_slice_excess, worst_slice_x_um, worst_slice_y_um (the worst one's deviance over its limit, its centre); after the model check model_misfit_gabor,
model_misfit_field, model_selected; with error bars median_sigma_relative,
predicted_error_relative; texture (where the run predicts a per-texel error: sigma_relative,
sigma_source, texels, fraction, power_share, warned; texel_texture.h); where the check needed error bars, error_bars ('given', 'computed',
'skipped', 'off', 'unavailable'), error_bars_note, and the cost rule's error_bars_predicted_seconds,
run_seconds (CPU), error_bars_seconds, error_bars_predicted_bytes (the bars' predicted peak with what
the run holds) and memory_limit_bytes (max_memory_gb, else the physical memory); where the bars were
left out for their cost or memory, error_lower_bound_relative (the rms error they would predict,
bounded from below by the slices' Fisher information alone) and error_lower_bound_seconds (CPU).
)doc");
    const RecoveryOptions ro;
    py::class_<RecoverKnobs> knobs(m, "RecoverSettings", R"doc(
The recovery's rarely used settings, for recover(settings=...) and recover_heights(settings=...):
the CLI's options of the same names (docs/recovery.md, "Settings by stage") and recover_heights'
stages' own; None: the library's (the schedule's). The functions convert them and the library
checks them, naming them as here. recover() refuses the stages' own (below, last) and
recover_heights the acquisition's (overlap, jitter, oblique_lights, plan_from_truth, simulator,
simulate_*, epochs) when set. Each is an attribute of the same name.

field_iterations, refine_iterations  pipeline iterations (>= 0; None: the schedule's)
field_tile_threshold, field_tile_core  the field stage on tiles (the CLI's --field-tile-threshold /
              --field-tile-core): a surface with a side above the threshold (texels, 0...10^6; 0:
              never) is retrieved on tiles of about `field_tile_core` texels (8...4096) plus a
              margin; None: the library's (64, 48)
refine_coarse_spacing, refine_coarse_weight, refine_coarse_iterations  the refinement's coarse
              space (the CLI's --refine-coarse-*): node spacing in texels (0: off), the joint
              variables' weight, coarse-only iterations per round; None: the library's
position_passes  with calibrate 'positions' (or 'all'): at most this many passes of the
              position loop after the first recovery (the CLI's --position-passes, 0...100; 0:
              off; None: the library's, 40, stopped earlier when the loss stalls); its per-pass
              steps are in result.metrics (positions:register, positions:newton, ...)
white_smoothness  white light's smoothness continuation (the CLI's --white-smoothness): weights,
              largest first (at most 64, each 0 ... 1e12; [] none; None: the library's 10, 1,
              0.1, 0.01); white_smoothness_iterations: L-BFGS iterations per weight (None: 20)
epochs        method 'thesis': Adam epochs (>= 0, default 1000)
overlap       the planner's worst-case overlap of neighbouring windows, 0.6 ... 0.95 (None: 0.6,
              0.8 with calibrate 'positions' or 'all'); jitter 0 ... 0.3 (default 0.2)
oblique_lights  steep generated surfaces (expected rms slope > 0.2 from height_range_um and
              correlation_texels): every position is observed under 4 oblique lights at
              sin(theta_i) = 0.8 as well, so that steep facets reflect into a slice (default
              True; OHS and ROHS: GHS-type models keep one light); False: under `light` alone
              (the CLI's --no-oblique-lights)
plan_from_truth  None (default): as the CLI, a given truth is planned for its measured
              roughness (measure_roughness: peak to valley, rms slope, Sal, Str; a rough, steep
              or strongly striated surface gets long wavelengths, oblique lights and the longer
              schedule, docs/recovery.md "Rough surfaces") unless correlation_texels is given;
              True: that (a truth needed, not with correlation_texels); False: the stated plan
              (height range and correlation_texels, default 4)
simulator     how a truth's observations are simulated: 'gabor' (the model, default) or
              'scalar' (the exact field of the interpolated heights, scalar_diffraction.h;
              OHS / ROHS); not with observations
simulate_position_error_texels, simulate_exposure, simulate_sigma_factor  a study's
              acquisition errors (the CLI's --simulate-*; a truth only): footprint positions off
              by this rms per coordinate (texels, 0...10), each slice scaled by an exposure
              log-uniform in (min, max), the true sigma_p this factor times the stated one
              (0.25...4); the recovery is given the stated acquisition
The stages' own (recover_heights only; None: RecoverSettings' defaults, recover.h):
blur_widths   blurred fit: blur widths in footprint lobes, widest first ([]: start the fields
              from flat); blur_iterations: L-BFGS per width (>= 0)
blur_wavelengths  the blurred fit uses this many longest wavelengths (0: all), at positions at
              least 2 sigma_p apart
band_limit    the field stage keeps only the object's spectrum the slices see
refine        odd object-grid refinement 1...63 (0: automatic)
max_range_um  bound on the height range for unwrapping (um, > 0; None: 4)
refine_history  L-BFGS history of the refinement (>= 1); refine_loss: 'amplitude', 'poisson:N',
              'mse', 'cmsle:EPS' or a Loss
)doc");
    knobs
        .def(py::init([](const py::object& field_iterations, const py::object& refine_iterations,
                         const py::object& field_tile_threshold, const py::object& field_tile_core,
                         const py::object& refine_coarse_spacing, const py::object& refine_coarse_weight,
                         const py::object& refine_coarse_iterations, const py::object& position_passes,
                         const py::object& white_smoothness, const py::object& white_smoothness_iterations,
                         const py::object& epochs, const py::object& overlap, const py::object& jitter,
                         const py::object& oblique_lights, const py::object& plan_from_truth,
                         const py::object& simulator, const py::object& simulate_position_error_texels,
                         const py::object& simulate_exposure, const py::object& simulate_sigma_factor,
                         const py::object& blur_widths, const py::object& blur_iterations,
                         const py::object& blur_wavelengths, const py::object& band_limit, const py::object& refine,
                         const py::object& max_range_um, const py::object& refine_history,
                         const py::object& refine_loss) {
                 RecoverKnobs k;
                 k.field_iterations = field_iterations;
                 k.refine_iterations = refine_iterations;
                 k.field_tile_threshold = field_tile_threshold;
                 k.field_tile_core = field_tile_core;
                 k.refine_coarse_spacing = refine_coarse_spacing;
                 k.refine_coarse_weight = refine_coarse_weight;
                 k.refine_coarse_iterations = refine_coarse_iterations;
                 k.position_passes = position_passes;
                 k.white_smoothness = white_smoothness;
                 k.white_smoothness_iterations = white_smoothness_iterations;
                 k.epochs = epochs;
                 k.overlap = overlap;
                 k.jitter = jitter;
                 k.oblique_lights = oblique_lights;
                 k.plan_from_truth = plan_from_truth;
                 k.simulator = simulator;
                 k.simulate_position_error_texels = simulate_position_error_texels;
                 k.simulate_exposure = simulate_exposure;
                 k.simulate_sigma_factor = simulate_sigma_factor;
                 k.blur_widths = blur_widths;
                 k.blur_iterations = blur_iterations;
                 k.blur_wavelengths = blur_wavelengths;
                 k.band_limit = band_limit;
                 k.refine = refine;
                 k.max_range_um = max_range_um;
                 k.refine_history = refine_history;
                 k.refine_loss = refine_loss;
                 return k;
             }),
             py::kw_only(), "field_iterations"_a = py::none(), "refine_iterations"_a = py::none(),
             "field_tile_threshold"_a = py::none(), "field_tile_core"_a = py::none(),
             "refine_coarse_spacing"_a = py::none(), "refine_coarse_weight"_a = py::none(),
             "refine_coarse_iterations"_a = py::none(), "position_passes"_a = py::none(),
             "white_smoothness"_a = py::none(), "white_smoothness_iterations"_a = py::none(), "epochs"_a = ro.epochs,
             "overlap"_a = py::none(), "jitter"_a = ro.jitter, "oblique_lights"_a = ro.oblique_lights,
             "plan_from_truth"_a = py::none(), "simulator"_a = "gabor", "simulate_position_error_texels"_a = 0.0,
             "simulate_exposure"_a = py::none(), "simulate_sigma_factor"_a = 1.0, "blur_widths"_a = py::none(),
             "blur_iterations"_a = py::none(), "blur_wavelengths"_a = py::none(), "band_limit"_a = py::none(),
             "refine"_a = py::none(), "max_range_um"_a = py::none(), "refine_history"_a = py::none(),
             "refine_loss"_a = py::none())
        .def("__repr__", [](const RecoverKnobs& k) {
            // The settings that differ from a default RecoverSettings.
            const RecoverKnobs defaults;
            std::string text = "RecoverSettings(";
            bool first = true;
            for (const auto& [name, field] : knob_fields())
                if (!(k.*field).equal(defaults.*field)) {
                    text += std::string(first ? "" : ", ") + name + "=" + std::string(py::repr(k.*field));
                    first = false;
                }
            return text + ")";
        });
    for (const auto& [name, field] : knob_fields()) knobs.def_readwrite(name, field);
    m.def("recover", &recover, "truth"_a = py::none(), "observations"_a = py::none(), py::kw_only(), "size"_a = ro.rows,
          "texel_um"_a = py::none(), "vscale"_a = py::none(), "height_range_um"_a = ro.height_range_um,
          "correlation_texels"_a = py::none(), "model"_a = "OHS", "light"_a = py::make_tuple(0.0, 0.0),
          "sigma_p_um"_a = ro.sigma_p_um, "position_uncertainty_um"_a = py::none(), "resolution"_a = ro.resolution,
          "lambdas_um"_a = py::none(), "spectral"_a = ro.spectral, "noise"_a = "none", "loss"_a = py::none(),
          "method"_a = "pipeline", "calibrate"_a = py::none(), "uncertainty"_a = false, "check_error_bars"_a = "auto",
          "target_error"_a = ro.target_error, "max_exposures"_a = ro.max_exposures, "seed"_a = ro.seed, "plan_only"_a = false, "callback"_a = py::none(), "max_memory_gb"_a = ro.max_memory_gb, "quiet"_a = py::none(),
          "comm"_a = py::none(), "settings"_a = py::none(), R"doc(
Heightfield recovery as ``wavebrdf recover`` runs it, without its output directory: the same
options and seed give the same estimate. Returns a RecoveryResult.

truth         Heightfield, 2-D array (texel units) or EXR path: the acquisition is planned for
              it and its observations simulated. Default: a generated isotropic surface of
              `size` (correlation_texels, peak-to-valley height_range_um, `seed`). Excludes
              `observations`.
observations  Observation(s) or a JSON path (the CLI's --observations): recovered as given, on
              a `size` grid, with height_range_um as the bound for unwrapping
size          N or (rows, cols), 1...16384 (default 32)
texel_um      texel width in um (> 0), vscale: vertical scale; default the truth Heightfield's,
              else 2 um and 1. Given, they apply to the truth and the estimate.
height_range_um  generated truth: peak-to-valley in um (> 0, default 2: +-1 um); with
              observations: bound on the height range
correlation_texels  generated truth: correlation length in texels (> 0; None: 4). With a given
              truth: the stated correlation the acquisition is planned for (as a user without
              the truth would plan it) instead of the truth's measured roughness
model         'OHS', 'ROHS', 'GHS' or 'RGHS' (GHS-type through the separable proxy); light: (wx, wy), |w| < 1
sigma_p_um    footprint sigma_p in um (0: the planner's, 1.5 texels or position_uncertainty_um
              if larger)
position_uncertainty_um  how far the stage may put a footprint from where it says, um rms per
              coordinate (the CLI's --position-uncertainty-um): the planner makes sigma_p at
              least this and the position loop searches lost positions 4x as far; None: the
              simulated error's rms (settings.simulate_position_error_texels x texel_um), else 0
resolution    slice size n, 1...8192 (0: the planner's: 48, or more where the window needs it)
lambdas_um    wavelengths in um (None: the planner's ladder for the height range)
spectral      white light (the CLI's --spectral): N >= 2 makes every planned observation one RGB
              slice of a broadband source sampled at N wavelengths (no laser); 0: laser slices
noise         simulated noise: 'none', 'poisson:N' (photons per slice) or 'gaussian:REL'
loss          a spec or Loss; None: matched to the noise for the pipeline (amplitude without
              noise, poisson:N, mse), cmsle:1 for the thesis's method
method        'pipeline' (blurred fit, field retrieval, unwrapping, refinement) or 'thesis'
              (Adam, one observation per epoch; settings.epochs)
calibrate     self-calibration, the CLI's --calibrate: None or 'none' (default), 'positions',
              'exposure', 'sigma' (comma-separated or a sequence), or 'all'; the refined values
              are in result.calibration
uncertainty   True: also the error bars (height_uncertainty with the run's loss): the result's
              uncertainty (sigma per texel, um), median_sigma_um and, with a truth,
              coverage_1sigma / coverage_2sigma (wavebrdf recover --uncertainty)
check_error_bars  the convergence check's own error bars where it needs them (photon counts with
              the misfit on the floor, or a loss without a noise level): 'auto' (computed when
              predicted to take at most the recovery's own CPU time), 'always' or 'off' (the
              CLI's --check-error-bars; result.convergence['error_bars'] says what was done)
target_error  photon noise: the rms height error the planner aims at, a fraction of the truth's
              peak to valley (default 0.01; 0: off): where the planned slices' predicted error
              (their error bars and bias; within 1.5x of the target scaled by a pilot of the
              recovery on 32x32 to 64x64 tiles, result.notes) is more, every slice is taken as several exposures of the noise's N photons, summed
              (result.noise then says k*N; result.notes says why), at most max_exposures
              (1 ... 10000, default 16); the CLI's --target-error, --max-exposures
seed          generated truth, position jitter, noise, the thesis's draws
plan_only     True: plan the acquisition (with photon noise the exposures and their pilot) as
              the run would and stop there, nothing simulated or recovered (the CLI's
              --plan-only): result.plan holds the plan with "positions_um", the footprint
              centres; result.observations the planned slices (no references); estimate None
callback      callback(metrics: dict with stage, kind, total (the stage's planned iterations, 0
              for a result: what the progress bars show), iteration, loss, seconds,
              height_rel_rmse) after every reported step; return False to stop early.
max_memory_gb refuse (MemoryError, before any work) a run whose estimated peak memory exceeds
              this many GB; 0 (default): the physical memory
quiet         progress (a tqdm bar per stage if tqdm is installed, else a line on stderr): None
              (default) shows it when stderr is a terminal or in Jupyter, False always, True never
comm          None (default: one process) or an mpi4py communicator (e.g. MPI.COMM_WORLD, under
              mpiexec): every rank passes the same arguments and keeps its share of the
              observations (result.observations: this rank's); the sums are allreduced, every
              rank gets the same estimate, only rank 0 shows progress (docs/scale.md). The
              thesis's method runs on one process only.
settings      a RecoverSettings: the rarely used settings (iterations, tiles, the position
              loop's passes, white light's continuation, the planner's overlap and lights, a
              study's simulated acquisition errors); None: the defaults. Their names as
              keywords of recover() still work for now, with a FutureWarning.
Whether the run converged is judged without the truth, as the CLI judges it (docs/recovery.md,
"Did it converge?"): result.convergence; when it did not, its warning is also the last entry
of result.warnings (as in the CLI's run.json).
The run releases the GIL; Ctrl-C stops it within about a second (KeyboardInterrupt).
)doc");
}

}  // namespace wavebrdf::python
