// Heightfield recovery (recover.h, baseline.h), acquisition planning (acquisition.h), simulated noise
// (noise.h), and recover(): `wavebrdf recover` without its output directory, through the same
// library piece as the CLI (recovery_run.h), so the same options give the same run.
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "common.h"
#include "observation_arg.h"
#include "progress.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/roughness_plan.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Noise noise_argument(const py::object& noise) {
    if (noise.is_none()) return {};
    if (!py::isinstance<py::str>(noise))
        throw py::value_error("noise = " + std::string(py::repr(noise)) +
                              " is invalid; expected 'none', 'poisson:N' or 'gaussian:REL'");
    return parse_noise(noise.cast<std::string>());  // its messages name the noise text
}

// Observations as given (Observation, list) or read from a path (JSON, or HDF5: observation_file.h).
std::vector<Observation> observations_or_file(const py::object& observations) {
    if (py::isinstance<py::str>(observations)) {
        const std::string path = observations.cast<std::string>();
        py::gil_scoped_release release;
        return read_observations_file(path);
    }
    return observations_argument(observations);
}

std::vector<double> wavelength_list(const py::object& lambdas, const char* name) {
    if (lambdas.is_none()) return {};
    std::vector<double> list;
    try {
        if (py::isinstance<py::str>(lambdas)) throw py::cast_error();
        list = lambdas.cast<std::vector<double>>();
    } catch (const py::cast_error&) {
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(lambdas)) +
                              " is invalid; expected a list of wavelengths in um (or None)");
    }
    if (list.empty()) bad_argument(name, "[]", "at least one wavelength in um (or None: planned)");
    for (double l : list)
        if (!std::isfinite(l) || l <= 0.0)
            bad_argument(name, std::string(py::repr(lambdas)), "wavelengths that are finite and > 0 (um)");
    return list;
}

int planned_resolution(int resolution) {
    if (resolution != 0) check_resolution(resolution, "resolution");
    return resolution;
}

// White light's smoothness weights (RecoverSettings::white_smoothness): None → the default;
// else a sequence of at most 64 numbers, each finite in [0, 1e12] (empty: no continuation).
std::optional<std::vector<double>> white_smoothness_argument(const py::object& value) {
    if (value.is_none()) return std::nullopt;
    std::vector<double> weights;
    bool ok = !py::isinstance<py::str>(value) && py::isinstance<py::sequence>(value) && py::len(value) <= 64;
    if (ok) {
        try {
            weights = value.cast<std::vector<double>>();
        } catch (const py::cast_error&) {
            ok = false;
        }
    }
    for (double w : weights) ok = ok && w >= 0.0 && w <= 1e12;
    if (!ok)
        throw py::value_error("white_smoothness = " + std::string(py::repr(value)) +
                              " is invalid; expected a sequence of at most 64 weights, each 0 to 1e12, largest "
                              "first, or None");
    return weights;
}

int optional_count(const py::object& value, const char* name) {
    if (value.is_none()) return -1;
    int n = 0;
    try {
        n = value.cast<int>();
    } catch (const py::cast_error&) {
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(value)) +
                              " is invalid; expected an iteration count >= 0 or None");
    }
    if (n < 0) bad_argument(name, std::to_string(n), "an iteration count >= 0 or None (the library's default)");
    return n;
}

void check_callback(const py::object& callback) {
    if (!callback.is_none() && !PyCallable_Check(callback.ptr()))
        throw py::value_error("callback is not callable; expected callback(metrics: dict) -> bool | None, or None");
}

py::dict metrics_row(const StageMetrics& m) {
    return py::dict("stage"_a = m.stage, "iteration"_a = m.iteration, "loss"_a = m.loss, "seconds"_a = m.seconds,
                    "height_rel_rmse"_a = m.height_rel_rmse >= 0.0 ? m.height_rel_rmse : kNaN,
                    "height_rel_rmse_plane_removed"_a = m.height_rel_rmse_plane_removed >= 0.0
                                                            ? m.height_rel_rmse_plane_removed
                                                            : kNaN);
}

// field_tile_threshold= / field_tile_core=: a texel count in [lo, hi] (ValueError naming it otherwise).
int tile_size(int value, const char* name, int lo, int hi) {
    if (value < lo || value > hi)
        bad_argument(name, std::to_string(value), "texels, " + std::to_string(lo) + " to " + std::to_string(hi));
    return value;
}
// The same, or -1 (the library's) for None.
int optional_tile_size(const py::object& value, const char* name, int lo, int hi) {
    if (value.is_none()) return -1;
    return tile_size(value.cast<int>(), name, lo, hi);
}

// calibrate=: None, a string ("positions,exposure", "all", "none") or a sequence of those words.
CalibrationSettings calibrate_argument(const py::object& calibrate) {
    if (calibrate.is_none()) return {};
    if (py::isinstance<py::str>(calibrate)) return parse_calibration(calibrate.cast<std::string>(), "calibrate");
    std::string joined;
    try {
        for (const py::handle item : py::iter(calibrate)) {
            if (!py::isinstance<py::str>(item)) throw py::cast_error();
            joined += (joined.empty() ? "" : ",") + item.cast<std::string>();
        }
    } catch (const py::error_already_set&) {
        throw py::value_error("calibrate = " + std::string(py::repr(calibrate)) +
                              " is invalid; expected a string or a sequence of 'positions', 'exposure', 'sigma'");
    } catch (const py::cast_error&) {
        throw py::value_error("calibrate = " + std::string(py::repr(calibrate)) +
                              " is invalid; expected a string or a sequence of 'positions', 'exposure', 'sigma'");
    }
    return joined.empty() ? CalibrationSettings{} : parse_calibration(joined, "calibrate");
}

// A Calibration as a dict: refined (str), sigma_p_scale, exposures (float64 (N,) or None),
// position_offsets_um (float64 (N, 2) or None).
py::dict calibration_dict(const CalibrationSettings& refined, const Calibration& c) {
    py::dict d;
    d["refined"] = to_string(refined);
    d["sigma_p_scale"] = c.sigma_p_scale;
    if (c.exposures.empty())
        d["exposures"] = py::none();
    else
        d["exposures"] = owning_array(std::vector<double>(c.exposures), {static_cast<py::ssize_t>(c.exposures.size())});
    if (c.position_offsets_um.empty()) {
        d["position_offsets_um"] = py::none();
    } else {
        std::vector<double> v;
        for (const auto& o : c.position_offsets_um) v.insert(v.end(), {o[0], o[1]});
        d["position_offsets_um"] = owning_array(std::move(v),
                                                {static_cast<py::ssize_t>(c.position_offsets_um.size()), 2});
    }
    return d;
}

// The metrics.csv columns as arrays: stage (str), iteration (int64), loss, seconds,
// height_rel_rmse (float64; NaN without a truth).
py::dict metrics_columns(const std::vector<StageMetrics>& history) {
    const auto n = static_cast<py::ssize_t>(history.size());
    std::vector<std::int64_t> iteration;
    std::vector<double> loss, seconds, error, plane_removed;
    py::list stage;
    for (const StageMetrics& m : history) {
        stage.append(m.stage);
        iteration.push_back(m.iteration);
        loss.push_back(m.loss);
        seconds.push_back(m.seconds);
        error.push_back(m.height_rel_rmse >= 0.0 ? m.height_rel_rmse : kNaN);
        plane_removed.push_back(m.height_rel_rmse_plane_removed >= 0.0 ? m.height_rel_rmse_plane_removed : kNaN);
    }
    py::dict d;
    d["stage"] = py::module_::import("numpy").attr("array")(stage, "dtype"_a = "str");
    d["iteration"] = owning_array(std::move(iteration), {n});
    d["loss"] = owning_array(std::move(loss), {n});
    d["seconds"] = owning_array(std::move(seconds), {n});
    d["height_rel_rmse"] = owning_array(std::move(error), {n});
    d["height_rel_rmse_plane_removed"] = owning_array(std::move(plane_removed), {n});
    return d;
}

// The communicator of a `comm` argument (communicator_argument), never null: None → the serial
// one (a Python user opts in to MPI).
std::shared_ptr<const Communicator> ranks_argument(const py::object& comm) {
    if (std::shared_ptr<const Communicator> ranks = communicator_argument(comm)) return ranks;
    return std::shared_ptr<const Communicator>(&serial_communicator(), [](const Communicator*) {});
}

// Runs `work(on_step)` without the GIL. Every step is kept in `history` and, with the GIL
// taken back, handed to `callback` (returning False stops: `stopped`); Ctrl-C and an exception
// in the callback stop the run and are raised once it has returned.
// On several ranks (MPI) Ctrl-C is seen only at the steps (a poll amid a collective call
// would leave the other ranks waiting there), and the stop is agreed by the library.
template <typename Work>
Heightfield run_released(const py::object& callback, std::vector<StageMetrics>& history, bool& stopped, Work&& work,
                         PythonProgress* progress = nullptr, bool several_ranks = false) {
    ReleasedCallback python_callback(callback);
    std::optional<Heightfield> estimate;
    {
        std::optional<InterruptibleRelease> interruptible;
        std::optional<py::gil_scoped_release> plain;
        if (several_ranks)
            plain.emplace();
        else
            interruptible.emplace();
        estimate.emplace(work([&](const StageMetrics& m) {
            history.push_back(m);
            return python_callback.step([&](const py::object& f) { return f(metrics_row(m)); });
        }));
    }
    if (progress) progress->close();  // its line ends before an error is raised
    python_callback.rethrow_if_failed();
    stopped = python_callback.stopped();
    return std::move(*estimate);
}

std::optional<Heightfield> optional_truth(const py::object& truth) {
    if (truth.is_none()) return std::nullopt;
    try {
        return truth.cast<Heightfield>();
    } catch (const py::cast_error&) {
        throw py::value_error("truth is a " + std::string(py::str(py::type::of(truth).attr("__name__"))) +
                              "; expected a Heightfield or None");
    }
}

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
    }
    if (!c.model_selected.empty()) {
        d["model_misfit_gabor"] = c.model_misfit_gabor;
        d["model_misfit_field"] = c.model_misfit_field;
        d["model_selected"] = c.model_selected;
    }
    if (c.median_sigma_relative >= 0.0) d["median_sigma_relative"] = c.median_sigma_relative;
    if (c.predicted_error_relative >= 0.0) d["predicted_error_relative"] = c.predicted_error_relative;
    d["judged"] = c.judged();
    if (!c.error_bars.empty()) {
        d["error_bars"] = c.error_bars;
        if (!c.error_bars_note.empty()) d["error_bars_note"] = c.error_bars_note;
        if (c.error_bars_predicted_seconds >= 0.0) {
            d["error_bars_predicted_seconds"] = c.error_bars_predicted_seconds;
            d["run_seconds"] = c.run_seconds;
        }
        if (c.error_bars_seconds >= 0.0) d["error_bars_seconds"] = c.error_bars_seconds;
    }
    return d;
}

py::dict roughness_dict(const MeasuredRoughness& m) {
    py::dict d;
    d["range_um"] = m.range_um;
    d["rms_slope"] = m.rms_slope;
    d["rim_fraction"] = m.rim_fraction;
    d["correlation_um"] = m.correlation_um;
    d["aspect"] = m.aspect;
    d["lay_deg"] = m.lay_deg;
    return d;
}

// A Heightfield (measured here) or a dict of measure_roughness's keys.
MeasuredRoughness roughness_argument(const py::object& value) {
    if (py::isinstance<Heightfield>(value)) {
        const Heightfield& hf = value.cast<const Heightfield&>();
        py::gil_scoped_release release;
        return measure_roughness(hf);
    }
    if (!py::isinstance<py::dict>(value))
        throw py::value_error("roughness = " + std::string(py::repr(value).cast<std::string>().substr(0, 80)) +
                              " is invalid; expected a Heightfield or a dict as measure_roughness returns");
    const py::dict d = value.cast<py::dict>();
    MeasuredRoughness m;
    const auto field = [&](const char* key, double& out, bool required) {
        if (!d.contains(key)) {
            if (required)
                throw py::value_error(std::string("roughness has no '") + key +
                                      "'; expected measure_roughness's keys (range_um, rms_slope, rim_fraction, "
                                      "correlation_um, aspect, lay_deg)");
            return;
        }
        double v = NAN;
        try {
            v = d[key].cast<double>();
        } catch (const py::cast_error&) {}
        if (!std::isfinite(v))
            bad_argument(std::string("roughness['") + key + "']", std::string(py::repr(d[key])), "a finite number");
        out = v;
    };
    field("range_um", m.range_um, true);
    field("rms_slope", m.rms_slope, true);
    field("rim_fraction", m.rim_fraction, false);
    field("correlation_um", m.correlation_um, true);
    field("aspect", m.aspect, false);
    field("lay_deg", m.lay_deg, false);
    return m;
}

RecoveryResult recover(const py::object& truth_arg, const py::object& observations_arg, const py::object& size,
                       const py::object& texel_arg, const py::object& vscale_arg, double height_range_um,
                       const py::object& correlation_texels, const std::string& model, const py::object& light,
                       double sigma_p_um, int resolution, const py::object& lambdas_um, const py::object& overlap,
                       double jitter, const py::object& noise, const py::object& loss, const std::string& method,
                       const py::object& field_iterations, const py::object& refine_iterations, int epochs,
                       std::uint64_t seed, const py::object& callback, double max_memory_gb, const py::object& quiet,
                       const py::object& comm_arg, const std::string& simulator, const py::object& calibrate,
                       double simulate_position_error_texels, const py::object& simulate_exposure,
                       double simulate_sigma_factor, bool with_uncertainty, int spectral,
                       const py::object& field_tile_threshold, const py::object& field_tile_core,
                       const py::object& white_smoothness, const py::object& white_smoothness_iterations,
                       const py::object& position_passes, const py::object& position_uncertainty_um,
                       bool oblique_lights, const py::object& plan_from_truth,
                       const std::string& check_error_bars) {
    const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
    // Options, checked before any work; the planner checks sigma_p_um, overlap and jitter.
    RecoveryOptions options;
    options.names = OptionStyle::Python;  // prepare_recovery's messages name the keywords
    options.method = parse_recovery_method(method, "method");
    options.noise = noise_argument(noise);
    options.simulator = parse_simulator(simulator, "simulator");
    if (!loss.is_none()) options.loss = loss_argument(loss);
    const std::array<int, 2> rc = size_argument(size);
    options.rows = rc[0];
    options.cols = rc[1];
    const bool truth_object = py::isinstance<Heightfield>(truth_arg);
    options.texel_um = texel_arg.is_none()
                           ? (truth_object ? truth_arg.cast<const Heightfield&>().texel_um() : options.texel_um)
                           : check_positive(texel_arg.cast<double>(), "texel_um");
    options.vscale = vscale_arg.is_none() ? (truth_object ? truth_arg.cast<const Heightfield&>().vscale() : 1.0)
                                          : check_finite(vscale_arg.cast<double>(), "vscale");
    // A truth file: its own attributes where texel_um / vscale are not given.
    if (py::isinstance<py::str>(truth_arg)) {
        const HeightfieldScale scale = heightfield_file_scale(truth_arg.cast<std::string>(), texel_arg, vscale_arg,
                                                              options.texel_um, options.vscale);
        options.texel_um = scale.texel_um;
        options.vscale = scale.vscale;
    }
    options.height_range_um = check_positive(height_range_um, "height_range_um");
    // As the CLI: a given truth is planned for its measured roughness unless a correlation length
    // is stated (then the stated plan, as a user without the truth would have it).
    const bool correlation_given = !correlation_texels.is_none();
    if (correlation_given)
        options.correlation_texels = check_positive(correlation_texels.cast<double>(), "correlation_texels");
    options.plan_from_truth = !truth_arg.is_none() && !correlation_given;
    if (!plan_from_truth.is_none()) {
        if (!py::isinstance<py::bool_>(plan_from_truth))
            bad_argument("plan_from_truth", std::string(py::repr(plan_from_truth)), "True, False or None");
        const bool wanted = plan_from_truth.cast<bool>();
        if (wanted && truth_arg.is_none())
            throw py::value_error(
                "plan_from_truth = True plans for a given truth's measured roughness; expected a truth (not "
                "observations or the generated default)");
        if (wanted && correlation_given)
            throw py::value_error(
                "plan_from_truth = True and correlation_texels exclude each other; expected one of them (the "
                "measured roughness, or the stated correlation length)");
        options.plan_from_truth = wanted;
    }
    options.model = model_from(model);
    options.omega_i = light_direction(light);
    options.oblique_lights = oblique_lights;
    options.sigma_p_um = check_finite(sigma_p_um, "sigma_p_um");
    if (!position_uncertainty_um.is_none()) options.position_uncertainty_um = position_uncertainty_um.cast<double>();
    options.resolution = planned_resolution(resolution);
    options.lambdas_um = wavelength_list(lambdas_um, "lambdas_um");
    options.spectral = spectral;
    options.overlap = overlap.is_none() ? 0.0 : check_finite(overlap.cast<double>(), "overlap");
    if (!overlap.is_none() && options.overlap == 0.0)
        bad_argument("overlap", "0", "0.6 ... 0.95, or None (the planner's: 0.6, 0.8 with calibrate 'positions')");
    options.jitter = check_finite(jitter, "jitter");
    options.field_iterations = optional_count(field_iterations, "field_iterations");
    options.refine_iterations = optional_count(refine_iterations, "refine_iterations");
    options.field_tile_threshold = optional_tile_size(field_tile_threshold, "field_tile_threshold", 0, 1000000);
    options.field_tile_core = optional_tile_size(field_tile_core, "field_tile_core", 8, 4096);
    options.white_smoothness = white_smoothness_argument(white_smoothness);
    options.white_smoothness_iterations = optional_count(white_smoothness_iterations, "white_smoothness_iterations");
    if (epochs < 0) bad_argument("epochs", std::to_string(epochs), "an epoch count >= 0");
    options.epochs = epochs;
    options.seed = seed;
    if (!std::isfinite(max_memory_gb) || max_memory_gb < 0.0)
        bad_argument("max_memory_gb", format_number(max_memory_gb), "a limit in GB > 0, or 0 for the physical memory");
    options.max_memory_gb = max_memory_gb;
    options.uncertainty = with_uncertainty;  // the plan refines to the minimum first (recovery_run.h)
    try {
        options.check_error_bars = parse_check_error_bars(check_error_bars);
    } catch (const std::invalid_argument&) {
        bad_argument("check_error_bars", "'" + check_error_bars + "'", "'auto', 'always' or 'off'");
    }
    options.calibrate = calibrate_argument(calibrate);
    options.position_passes = optional_count(position_passes, "position_passes");
    if (!std::isfinite(simulate_position_error_texels) || simulate_position_error_texels < 0.0 ||
        simulate_position_error_texels > 10.0)
        bad_argument("simulate_position_error_texels", format_number(simulate_position_error_texels),
                     "an rms in texels, 0 to 10");
    options.errors.position_rms_texels = simulate_position_error_texels;
    if (!simulate_exposure.is_none()) {
        std::vector<double> range;
        try {
            if (py::isinstance<py::str>(simulate_exposure)) throw py::cast_error();
            range = simulate_exposure.cast<std::vector<double>>();
        } catch (const py::cast_error&) {
            range.clear();
        }
        if (range.size() != 2 || !(range[0] >= 1e-3) || !(range[1] <= 1e3) || !(range[0] <= range[1]))
            throw py::value_error("simulate_exposure = " + std::string(py::repr(simulate_exposure)) +
                                  " is invalid; expected (min, max) with 0.001 <= min <= max <= 1000, or None");
        options.errors.exposure_min = range[0];
        options.errors.exposure_max = range[1];
    }
    if (!(simulate_sigma_factor >= 0.25 && simulate_sigma_factor <= 4.0))
        bad_argument("simulate_sigma_factor", format_number(simulate_sigma_factor), "a factor in [0.25, 4]");
    options.errors.sigma_p_factor = simulate_sigma_factor;
    options.errors.seed = seed;
    if (options.errors.any() && !observations_arg.is_none())
        throw py::value_error(
            "simulate_* render the observations with acquisition errors; they need a truth (or the "
            "generated default), not observations");
    check_callback(callback);
    check_quiet(quiet);
    if (!truth_arg.is_none() && !observations_arg.is_none())
        throw py::value_error("truth and observations exclude each other; expected one of them (or neither)");
    if (options.noise.kind != NoiseKind::None && !observations_arg.is_none())
        throw py::value_error("noise = '" + to_string(options.noise) +
                              "' simulates noise on rendered observations; it needs a truth (or the generated "
                              "default), not observations");

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
    std::vector<StageMetrics> history;
    RecoveryResult result;
    // Progress (progress.h): a bar per stage of known length, closed however the run ends.
    py::dict totals;
    for (const char* stage : {"blur:", "field:", "refine", "refine:", "thesis"})
        totals[stage] = stage_iterations(*prepared, stage);
    // Under MPI only rank 0 shows progress.
    PythonProgress progress("wrap_recover", callback, comm->is_root() ? quiet : py::object(py::bool_(true)), totals);
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
    result.truth = prepared->truth ? py::cast(*prepared->truth) : py::none();
    result.observations = py::cast(prepared->observations);
    result.metrics = metrics_columns(history);
    result.notes = prepared->notes;
    result.warnings = prepared->warnings;
    result.method = to_string(prepared->method);
    result.loss = to_string(prepared->loss);
    result.noise = to_string(prepared->noise);
    result.height_range_um = prepared->range_um;
    std::optional<std::vector<double>> sigma_um;  // the error bars, for the convergence check
    if (with_uncertainty && !result.stopped) {
        std::optional<UncertaintyReport> report;
        std::string why_not;
        {
            py::gil_scoped_release release;
            report = recovery_error_bars(*prepared, estimate, *comm, &why_not);
        }
        // As the CLI: a problem without error bars keeps its estimate, with a warning.
        if (!report) {
            py::module_::import("warnings").attr("warn")("no error bars: " + why_not,
                                                         py::module_::import("builtins").attr("RuntimeWarning"));
            return result;
        }
        UncertaintyReport& bars = *report;
        sigma_um = bars.map.sigma_um;
        result.uncertainty = owning_array(std::move(bars.map.sigma_um), {estimate.rows(), estimate.cols()});
        result.median_sigma_um = bars.median_sigma_um;
        result.uncertainty_seconds = bars.seconds;
        if (bars.coverage_2sigma >= 0.0) {
            result.coverage_1sigma = bars.coverage_1sigma;
            result.coverage_2sigma = bars.coverage_2sigma;
        }
    }
    // Whether it converged, judged without the truth, as run_recovery_in_directory judges it for
    // the CLI (the same floor, the model check's misfits from the metrics, the error bars).
    double misfit_gabor = -1.0, misfit_field = -1.0;
    std::string selected;
    for (const StageMetrics& m : history) {
        if (m.stage == "misfit:gabor") misfit_gabor = m.loss;
        if (m.stage == "misfit:field") misfit_field = m.loss;
        if (m.stage.rfind("select:", 0) == 0) selected = m.stage.substr(7);
    }
    ConvergenceCheck convergence;
    {
        py::gil_scoped_release release;
        const PreparedRecovery& r = *prepared;
        convergence = run_or_abort(*comm, [&] {
            const double photons = r.noise.kind == NoiseKind::Poisson ? r.noise.level
                                   : r.loss.kind == LossKind::Poisson ? r.loss.photons
                                                                      : 0.0;
            return check_convergence(r.observations, estimate, photons, r.truth && r.noise.kind == NoiseKind::None,
                                     r.pipeline.calibrate.any() ? &calibration : nullptr, *comm);
        });
    }
    add_model_check(convergence, misfit_gabor, misfit_field, selected);
    if (std::isfinite(result.median_sigma_um)) add_error_bars(convergence, result.median_sigma_um, prepared->range_um);
    if (!result.stopped) {
        py::gil_scoped_release release;
        judge_noise_limit(convergence, *prepared, estimate, sigma_um ? &*sigma_um : nullptr, run_seconds, *comm);
    }
    if (!convergence.converged) result.warnings.push_back(convergence.warning());
    result.convergence = convergence_dict(convergence);
    return result;
}

py::array positions_array(const AcquisitionPlan& plan) {
    std::vector<double> v;
    for (const auto& p : plan.positions_um) v.insert(v.end(), {p[0], p[1]});
    return owning_array(std::move(v), {static_cast<py::ssize_t>(plan.positions_um.size()), 2});
}

const char* const kSettingsDoc = R"doc(
observations  Observation(s) at several positions and wavelengths (OHS / ROHS single-wavelength
              ones feed the blurred fit and the fields; all feed the refinement and Adam); their
              weights count (a pixel of weight 0 is out of every misfit; docs/recovery.md)
size          N or (rows, cols) of the estimate, 1...16384; texel_um > 0 (um), vscale finite
truth         a Heightfield of that size, or None: only feeds height_rel_rmse in the metrics
callback      callback(metrics: dict with stage, iteration, loss, seconds, height_rel_rmse
              (NaN without a truth)) after every reported step; return False to stop early
              (the estimate so far is returned). The run releases the GIL; Ctrl-C stops it
              at the next step (KeyboardInterrupt).
)doc";

}  // namespace

void bind_recover(py::module_& m) {
    // ---- planning ------------------------------------------------------------------------
    py::class_<AcquisitionPlan>(m, "AcquisitionPlan", R"doc(
What plan_acquisition proposes: footprint centres on a jittered raster over the periodic tile,
a slice resolution that samples the window (Nyquist), and wavelengths whose synthetic
wavelengths unwrap the height range. planned_observations / simulate_observations turn it
into Observations (one per position, light and wavelength).
)doc")
        .def_readonly("sigma_p_um", &AcquisitionPlan::sigma_p_um, "footprint sigma_p, um")
        .def_readonly("resolution", &AcquisitionPlan::resolution, "slice pixels per side")
        .def_readonly("lambdas_um", &AcquisitionPlan::lambdas_um, "wavelengths in um, lambda0 first")
        .def_readonly("synthetic_um", &AcquisitionPlan::synthetic_um,
                      "the synthetic wavelengths lambda_a lambda_b / |lambda_a - lambda_b| in um, coarsest first")
        .def_property_readonly("positions_um", &positions_array,
                               "footprint centres (x_um, y_um), a float64 array (N, 2) (a copy)")
        .def_property_readonly(
            "step_um", [](const AcquisitionPlan& p) { return py::make_tuple(p.step_x_um, p.step_y_um); },
            "raster steps (x, y) in um")
        .def_readonly("overlap", &AcquisitionPlan::overlap,
                      "worst-case linear overlap 1 - d/D of neighbouring windows (D = 6 sigma_p), jitter included")
        .def_property_readonly(
            "light", [](const AcquisitionPlan& p) { return py::make_tuple(p.omega_i[0], p.omega_i[1]); },
            "projected light direction (wx, wy) (of every observation without oblique_lights)")
        .def_property_readonly(
            "oblique_lights",
            [](const AcquisitionPlan& p) {
                py::list out;
                for (const auto& w : p.oblique_omega_i) out.append(py::make_tuple(w[0], w[1]));
                return out;
            },
            "further light directions (wx, wy) under which every position is observed as well (steep "
            "surfaces; empty: one light)")
        .def_property_readonly("model", [](const AcquisitionPlan& p) { return std::string(to_string(p.model)); })
        .def_readonly("notes", &AcquisitionPlan::notes, "the choices, one line each")
        .def("__repr__", [](const AcquisitionPlan& p) {
            return "AcquisitionPlan(" + std::to_string(p.positions_um.size()) + " positions, " +
                   std::to_string(p.lambdas_um.size()) + " wavelength(s), " + std::to_string(p.resolution) + "x" +
                   std::to_string(p.resolution) + " slices, sigma_p_um=" + format_number(p.sigma_p_um) + ")";
        });

    const PlanRequest pr;
    m.def(
        "plan_acquisition",
        [](int rows, const py::object& cols, double texel_um, double height_range_um, double sigma_p_um,
           double position_uncertainty_um, double overlap, double jitter, double lambda_um, double lambda_min_um,
           double lambda_max_um, double max_step_ratio, const py::object& lambdas_um, int resolution,
           const py::object& light, const std::string& model, std::uint64_t seed, const py::object& roughness,
           bool oblique_lights) {
            PlanRequest r;
            if (rows < 1) bad_argument("rows", std::to_string(rows), "at least 1 texel");
            r.rows = rows;
            r.cols = cols.is_none() ? rows : cols.cast<int>();
            if (r.cols < 1) bad_argument("cols", std::to_string(r.cols), "at least 1 texel");
            r.texel_um = texel_um;  // the planner names texel_um, sigma_p_um, overlap, jitter, lambda_min/max_um
            if (!std::isfinite(height_range_um) || height_range_um < 0.0)
                bad_argument("height_range_um", format_number(height_range_um), "a peak-to-valley height >= 0 (um)");
            r.height_range_um = height_range_um;
            r.sigma_p_um = sigma_p_um;
            r.position_uncertainty_um = position_uncertainty_um;  // the planner names it
            r.overlap = overlap;
            r.jitter = jitter;
            if (!std::isfinite(lambda_um) || !(lambda_um >= lambda_min_um && lambda_um <= lambda_max_um))
                bad_argument("lambda_um", format_number(lambda_um),
                             "a base wavelength within lambda_min_um ... lambda_max_um (" +
                                 format_number(lambda_min_um) + " to " + format_number(lambda_max_um) + " um)");
            r.lambda_um = lambda_um;
            r.lambda_min_um = lambda_min_um;
            r.lambda_max_um = lambda_max_um;
            if (!(max_step_ratio >= 1.5 && max_step_ratio <= 100.0))
                bad_argument("max_step_ratio", format_number(max_step_ratio), "1.5 to 100");
            r.max_step_ratio = max_step_ratio;
            r.lambdas_um = wavelength_list(lambdas_um, "lambdas_um");
            r.resolution = planned_resolution(resolution);
            r.omega_i = light_direction(light);
            r.model = model_from(model);
            r.seed = seed;
            std::optional<MeasuredRoughness> measured;
            if (!roughness.is_none()) measured = roughness_argument(roughness);
            AcquisitionPlan plan = plan_acquisition(r);
            // As recover() plans a given truth (recovery_run.cpp): the rough-surface plan's long
            // wavelengths (unless the wavelengths are given) and oblique lights.
            if (measured && measured->range_um > 0.0) {
                const RoughnessPlan rough = plan_for_measured_roughness(*measured, r.texel_um);
                if (r.lambdas_um.empty()) add_long_wavelengths(rough, plan);
                if (oblique_lights) add_oblique_lights(rough, plan);
                // What was measured and what it asks of the recovery (recover() adds these too).
                plan.notes.insert(plan.notes.end(), rough.notes.begin(), rough.notes.end());
            }
            return plan;
        },
        py::kw_only(), "rows"_a = pr.rows, "cols"_a = py::none(), "texel_um"_a = pr.texel_um,
        "height_range_um"_a = pr.height_range_um, "sigma_p_um"_a = pr.sigma_p_um,
        "position_uncertainty_um"_a = pr.position_uncertainty_um, "overlap"_a = pr.overlap, "jitter"_a = pr.jitter,
        "lambda_um"_a = pr.lambda_um, "lambda_min_um"_a = pr.lambda_min_um, "lambda_max_um"_a = pr.lambda_max_um,
        "max_step_ratio"_a = pr.max_step_ratio, "lambdas_um"_a = py::none(), "resolution"_a = 0,
        "light"_a = py::make_tuple(0.0, 0.0), "model"_a = "OHS", "seed"_a = pr.seed, "roughness"_a = py::none(),
        "oblique_lights"_a = true, R"doc(
An acquisition that determines the heights of a rows x cols tile (acquisition.h): returns an
AcquisitionPlan. Keyword arguments (PlanRequest's fields):

rows, cols       heightfield size in texels (>= 1; cols defaults to rows); texel_um > 0 (um)
height_range_um  expected peak-to-valley of the heights, um (>= 0): sets the wavelength ladder
sigma_p_um       footprint sigma_p, um (> 0; 0: 1.5 texels, or k x position_uncertainty_um if
                 larger, k = 1). Window support D = 6 sigma_p.
position_uncertainty_um  how far the stage may put a footprint from where it says, um rms per
                 coordinate (>= 0): with sigma_p planned, the footprint is made at least
                 that wide (the position loop converges up to ~sigma_p, docs/recovery.md)
overlap          worst-case linear overlap 1 - d/D of neighbouring windows, 0.6 ... 0.95
jitter           position jitter, fraction of the raster step, 0 ... 0.3
lambda_um        base wavelength lambda0 (um), within lambda_min_um ... lambda_max_um (the
                 wavelengths the ladder may use); max_step_ratio: ladder step, 1.5 ... 100
lambdas_um       given wavelengths (um) instead of the ladder; None: planned
resolution       given slice size n (1...8192) instead of Nyquist's n >= 4D/lambda; 0: planned
light            projected light direction (wx, wy), wx^2 + wy^2 < 1; model: 'OHS', 'ROHS', ...
seed             the jitter
roughness        None, or a known surface's measured roughness: a Heightfield (measured here) or
                 the dict measure_roughness returns. A rough, steep or strongly striated surface
                 then gets the rough-surface plan's long wavelengths (not with lambdas_um) and,
                 with oblique_lights (default True), its oblique lights, with notes: the plan
                 recover(truth=...) makes, given the truth's rows, cols, texel_um and
                 peak-to-valley (docs/recovery.md, "Rough surfaces")
A height range the wavelengths cannot unwrap is a ValueError naming the largest they can.
)doc");

    m.def(
        "measure_roughness",
        [](const Heightfield& heightfield) {
            MeasuredRoughness m;
            {
                py::gil_scoped_release release;
                m = measure_roughness(heightfield);
            }
            return roughness_dict(m);
        },
        "heightfield"_a, R"doc(
What the recovery's planner reads from a known surface (roughness_plan.h, measure_roughness):
a dict with range_um (peak to valley, um), rms_slope (rms |grad H|, central differences across
the periodic tile: the model's slopes), rim_fraction (fraction of texels with |grad H| > 0.5,
whose light leaves a slice under normal light), correlation_um (Sal, um), aspect (Str) and
lay_deg (Std, degrees from x towards y). plan_acquisition(roughness=...) and
recover(truth=...) plan for these.
)doc");

    m.def(
        "planned_observations",
        [](const AcquisitionPlan& plan) {
            std::vector<Observation> list = planned_observations(plan);
            // The library leaves references empty; Python's Observation always holds a slice.
            for (Observation& o : list)
                o.reference.assign(std::size_t(o.resolution) * o.resolution * std::size_t(o.channels()), 0.0);
            return list;
        },
        "plan"_a,
        "One Observation per (position, wavelength) of `plan`, with zero references (fill them with\n"
        "measurements, or use simulate_observations).");
    m.def(
        "simulate_observations",
        [](const Heightfield& truth, const AcquisitionPlan& plan, const py::object& noise, std::uint64_t seed) {
            const Noise n = noise_argument(noise);
            InterruptibleRelease release;
            return simulate_observations(truth, plan, n, seed);
        },
        "truth"_a, "plan"_a, "noise"_a = "none", "seed"_a = 1, R"doc(
The planned observations of `truth` (a Heightfield), rendered in double precision, with
`noise` added: 'none', 'poisson:N' (N photons expected per slice, > 0) or 'gaussian:REL'
(sigma REL x the slice's peak, >= 0, clamped at 0). Observation i's noise is drawn from
(seed, i). Returns a list of Observations.
)doc");

    m.def(
        "add_noise",
        [](const py::object& values, const py::object& noise, std::uint64_t seed) -> py::object {
            const Noise n = noise_argument(noise);
            if (py::isinstance<Observation>(values) || py::isinstance<py::list>(values) ||
                py::isinstance<py::tuple>(values)) {
                std::vector<Observation> list = observations_argument(values);
                add_noise(list, n, seed);
                return py::cast(list);
            }
            const py::array a = float_array(values, "values");
            std::vector<double> v = to_doubles(a, "values");
            for (std::size_t k = 0; k < v.size(); ++k)
                if (v[k] < 0.0)
                    throw py::value_error("values has a negative value " + format_number(v[k]) +
                                          "; expected a slice of non-negative values");
            std::vector<double> noisy = add_noise(v, n, seed);
            return owning_array(std::move(noisy), std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
        },
        "values"_a, "noise"_a, "seed"_a = 1, R"doc(
Simulated measurement noise (noise.h), deterministic in `seed`.

values  a slice (float array of non-negative values, any shape: one slice) -> a new float64
        array of that shape; or Observation(s) -> a new list with noisy references, observation
        i seeded from (seed, i)
noise   'none', 'poisson:N' (photon noise, N photons expected per slice, > 0; a slice summing to
        0 is unchanged) or 'gaussian:REL' (additive, sigma = REL x max, REL >= 0, clamped at 0)
)doc");

    m.def(
        "check_acquisition",
        [](const py::object& observations, const py::object& size, double texel_um, const py::object& truth) {
            const std::vector<Observation> list = observations_argument(observations);
            const std::array<int, 2> rc = size_argument(size);
            check_positive(texel_um, "texel_um");
            const std::optional<Heightfield> t = optional_truth(truth);
            return check_acquisition(list, rc[0], rc[1], texel_um, t ? &*t : nullptr);
        },
        "observations"_a, "size"_a, "texel_um"_a, "truth"_a = py::none(), R"doc(
Warnings (a list of str, empty when all is well) for observations too coarse or too sparse to
determine the heights of a tile of `size` = N or (rows, cols) texels of texel_um (um):
neighbouring windows overlapping < 60 %, texels farther than 2 sigma_p from every footprint,
slices sampling u more than 4x as coarsely as Nyquist, fewer values than heights, and (with a
truth Heightfield) slopes that reflect light off the slice.
)doc");

    // ---- recovery --------------------------------------------------------------------------
    const RecoverSettings rs;
    m.def(
        "recover_heights",
        [](const py::object& observations, const py::object& size, double texel_um, double vscale,
           const py::object& truth, const std::vector<double>& blur_widths, int blur_iterations, int blur_wavelengths,
           double blur_spacing_sigma, const py::object& field_iterations, int field_passes, bool cascade,
           bool band_limit, int refine, const py::object& max_range_um, bool unwrap_from_blurred,
           const py::object& refine_iterations, int refine_history,
           const py::object& refine_loss, const py::object& callback, const py::object& comm_arg,
           const py::object& calibrate, int field_tile_threshold, int field_tile_core,
           const py::object& white_smoothness, int white_smoothness_iterations) -> py::object {
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const std::vector<Observation> list = observations_or_file(observations);
            const std::array<int, 2> rc = size_argument(size);
            check_positive(texel_um, "texel_um");
            check_finite(vscale, "vscale");
            if (vscale == 0.0) bad_argument("vscale", "0", "a non-zero vertical scale");
            RecoverSettings s;
            for (double w : blur_widths)
                if (!std::isfinite(w) || w <= 0.0)
                    bad_argument("blur_widths", format_number(w), "widths > 0 (in footprint lobes), widest first");
            s.blurred.blur_widths = blur_widths;
            if (blur_iterations < 0) bad_argument("blur_iterations", std::to_string(blur_iterations), ">= 0");
            s.blurred.iterations = blur_iterations;
            if (blur_wavelengths < 0)
                bad_argument("blur_wavelengths", std::to_string(blur_wavelengths), ">= 0 (0: all)");
            s.blur_wavelengths = blur_wavelengths;
            if (!std::isfinite(blur_spacing_sigma) || blur_spacing_sigma < 0.0)
                bad_argument("blur_spacing_sigma", format_number(blur_spacing_sigma), ">= 0 (0: all positions)");
            s.blur_spacing_sigma = blur_spacing_sigma;
            s.field.iterations = optional_count(field_iterations, "field_iterations");
            if (field_passes < 1) bad_argument("field_passes", std::to_string(field_passes), ">= 1");
            s.field_passes = field_passes;
            s.cascade = cascade;
            s.field.band_limit = band_limit;
            if (refine < 0 || (refine > 0 && refine % 2 == 0) || refine > 63)
                bad_argument("refine", std::to_string(refine), "0 (automatic) or an odd object-grid refinement 1...63");
            s.refine = refine;
            if (!max_range_um.is_none()) s.height_range_um = check_positive(max_range_um.cast<double>(), "max_range_um");
            s.unwrap_from_blurred = unwrap_from_blurred;
            s.refine_iterations = optional_count(refine_iterations, "refine_iterations");
            if (refine_history < 1) bad_argument("refine_history", std::to_string(refine_history), ">= 1");
            s.refine_history = refine_history;
            s.refine_loss = loss_argument(refine_loss);
            s.calibrate = calibrate_argument(calibrate);
            s.field_tile_threshold = tile_size(field_tile_threshold, "field_tile_threshold", 0, 1000000);
            s.field_tile_core = tile_size(field_tile_core, "field_tile_core", 8, 4096);
            s.white_smoothness = *white_smoothness_argument(
                white_smoothness.is_none() ? py::cast(s.white_smoothness) : white_smoothness);
            if (white_smoothness_iterations < 0)
                bad_argument("white_smoothness_iterations", std::to_string(white_smoothness_iterations), ">= 0");
            s.white_smoothness_iterations = white_smoothness_iterations;
            const std::optional<Heightfield> t = optional_truth(truth);
            check_callback(callback);
            std::vector<StageMetrics> history;
            bool stopped = false;
            Calibration calibration;
            Heightfield estimate = run_released(
                callback, history, stopped,
                [&](const auto& on_step) {
                    return recover_heights(list, rc[0], rc[1], texel_um, vscale, s, on_step, t ? &*t : nullptr, *comm,
                                           &calibration);
                },
                nullptr, comm->size() > 1);
            if (calibrate.is_none()) return py::cast(std::move(estimate));
            return py::make_tuple(std::move(estimate), calibration_dict(s.calibrate, calibration));
        },
        "observations"_a, "size"_a, "texel_um"_a, "vscale"_a = 1.0, py::kw_only(), "truth"_a = py::none(),
        "blur_widths"_a = rs.blurred.blur_widths, "blur_iterations"_a = rs.blurred.iterations,
        "blur_wavelengths"_a = rs.blur_wavelengths, "blur_spacing_sigma"_a = rs.blur_spacing_sigma,
        "field_iterations"_a = py::none(), "field_passes"_a = rs.field_passes, "cascade"_a = rs.cascade,
        "band_limit"_a = rs.field.band_limit, "refine"_a = rs.refine, "max_range_um"_a = py::none(),
        "unwrap_from_blurred"_a = rs.unwrap_from_blurred, "refine_iterations"_a = py::none(),
        "refine_history"_a = rs.refine_history, "refine_loss"_a = to_string(rs.refine_loss), "callback"_a = py::none(),
        "comm"_a = py::none(), "calibrate"_a = py::none(), "field_tile_threshold"_a = rs.field_tile_threshold,
        "field_tile_core"_a = rs.field_tile_core, "white_smoothness"_a = rs.white_smoothness,
        "white_smoothness_iterations"_a = rs.white_smoothness_iterations,
        (std::string(R"doc(
The heightfield whose slices match `observations`, from a flat start (recover.h): a blurred fit,
phase retrieval of the field per wavelength on a refined object grid, unwrapping, then L-BFGS
on the heights in the full model. Returns a Heightfield (size, texel units with texel_um and
vscale). Settings (defaults: the library's, in the signature; None: the schedule's, which with
every default is the schedule `wavebrdf recover` and recover() run for a smooth surface):

blur_widths         blurred fit: blur widths in footprint lobes, widest first ([] : start the
                    fields from flat); blur_iterations: L-BFGS per width (>= 0)
blur_wavelengths    the blurred fit uses this many longest wavelengths (0: all), at positions
                    at least blur_spacing_sigma sigma_p apart (0: all)
field_iterations    L-BFGS iterations of each field retrieval (>= 0; None: 25 on a smooth surface
                    without calibration, else 50); field_passes >= 1;
                    cascade: each field starts from the heights of the fields before it;
                    band_limit: keep only the object's spectrum the slices see
refine              odd object-grid refinement 1...63 (0: automatic)
max_range_um        bound on the height range for unwrapping (um, > 0; None: 4;
                    RecoverSettings::height_range_um)
unwrap_from_blurred start unwrapping from the estimate before it rather than the fields
refine_iterations   final L-BFGS iterations on the heights (>= 0; None: the schedule's, 8 after
                    a first round on the longest wavelength's slices on a smooth surface without
                    calibration, else 40; a count given is the whole refinement); refine_history >= 1;
                    refine_loss: 'amplitude', 'poisson:N', 'mse', 'cmsle:EPS' or a Loss
white_smoothness    white light (RGB slices only): the smoothness continuation's weights before
                    the refinement, largest first (at most 64, each 0 ... 1e12; [] none);
                    white_smoothness_iterations: L-BFGS iterations per weight (>= 0)
Metrics stages: 'blur:S', 'blur', 'field:LAMBDA', 'unwrap', 'refine'.
comm                None (one process) or an mpi4py communicator: `observations` is then this
                    rank's share (every rank calls with its own; docs/scale.md), the sums are
                    allreduced and every rank returns the same heights.
calibrate           self-calibration (calibration.h): None (default: the acquisition is exact;
                    returns a Heightfield), or 'positions', 'exposure', 'sigma' as a comma-
                    separated string or a sequence of them, 'all' or 'none': returns a tuple
                    (Heightfield, dict) with the refined values: refined (str), sigma_p_scale
                    (true sigma_p / stated), exposures (float64 (N,): reference ~ exposure *
                    model, per observation in the order given; None when not refined),
                    position_offsets_um (float64 (N, 2): true - stated centre; or None).
field_tile_threshold  a surface with a side above this many texels (0...10^6; 0: never) has its
                    field retrieved on tiles of about field_tile_core texels (8...4096) plus a
                    margin, blended into one field (RecoverSettings::field_tile_*; not with
                    calibrate='positions', which keeps the whole-surface field stage)
)doc") + kSettingsDoc)
            .c_str());

    const BaselineSettings bs;
    m.def(
        "recover_heights_thesis",
        [](const py::object& observations, const py::object& size, double texel_um, double vscale,
           const py::object& truth, int epochs, double lr, double beta1, double beta2, double decay,
           const py::object& loss, std::uint64_t seed, int report_every, const py::object& callback) {
            const std::vector<Observation> list = observations_or_file(observations);
            const std::array<int, 2> rc = size_argument(size);
            check_positive(texel_um, "texel_um");
            check_finite(vscale, "vscale");
            BaselineSettings s;
            if (epochs < 0) bad_argument("epochs", std::to_string(epochs), "an epoch count >= 0");
            s.epochs = epochs;
            s.adam = AdamOptions{lr, beta1, beta2, s.adam.epsilon, decay};
            { Adam check(1, s.adam); }  // the Adam options, with the library's messages
            s.loss = loss_argument(loss);
            s.seed = seed;
            if (report_every < 1) bad_argument("report_every", std::to_string(report_every), "a number of epochs >= 1");
            s.report_every = report_every;
            const std::optional<Heightfield> t = optional_truth(truth);
            check_callback(callback);
            std::vector<StageMetrics> history;
            bool stopped = false;
            return run_released(callback, history, stopped, [&](const auto& on_step) {
                return recover_heights_thesis(list, rc[0], rc[1], texel_um, vscale, s, on_step, t ? &*t : nullptr);
            });
        },
        "observations"_a, "size"_a, "texel_um"_a, "vscale"_a = 1.0, py::kw_only(), "truth"_a = py::none(),
        "epochs"_a = bs.epochs, "lr"_a = bs.adam.lr, "beta1"_a = bs.adam.beta1, "beta2"_a = bs.adam.beta2,
        "decay"_a = bs.adam.decay, "loss"_a = to_string(bs.loss), "seed"_a = bs.seed,
        "report_every"_a = bs.report_every, "callback"_a = py::none(),
        (std::string(R"doc(
The thesis's method as a baseline (baseline.h): Adam on `loss` (default cmsle:1), one
observation drawn at random (from `seed`) per epoch, from a flat start. Returns a Heightfield.
epochs >= 0; lr > 0, beta1 and beta2 in [0, 1), decay >= 0 per epoch (the thesis's 0.01, 0.9,
0.99, 0.005); the callback sees stage 'thesis' every report_every (>= 1) epochs and the last.
)doc") + kSettingsDoc)
            .c_str());

    // Heightfields or 2-D arrays: an array is in the other argument's units (a Heightfield's
    // texel_um and vscale; two arrays share theirs, which the ratio does not depend on).
    const auto height_pair = [](const py::object& estimate, const py::object& truth) {
        const bool e_hf = py::isinstance<Heightfield>(estimate), t_hf = py::isinstance<Heightfield>(truth);
        const Heightfield* scale = e_hf ? &estimate.cast<const Heightfield&>()
                                        : t_hf ? &truth.cast<const Heightfield&>() : nullptr;
        const double w = scale ? scale->texel_um() : 1.0, v = scale ? scale->vscale() : 1.0;
        return std::make_pair(e_hf ? estimate.cast<Heightfield>() : heightfield_from_array(estimate, "estimate", w, v),
                              t_hf ? truth.cast<Heightfield>() : heightfield_from_array(truth, "truth", w, v));
    };
    m.def(
        "height_rel_rmse",
        [height_pair](const py::object& estimate, const py::object& truth) {
            const auto [e, t] = height_pair(estimate, truth);
            return height_rel_rmse(e, t);
        },
        "estimate"_a, "truth"_a,
        "RMS of (estimate - truth) in um after removing each one's mean, divided by the truth's\n"
        "peak-to-valley height (um): 0.01 is 1 %. Same sizes; the truth must not be flat. Each a\n"
        "Heightfield or a 2-D array (in the other's units: the ratio needs no unit when both are arrays).");
    m.def(
        "height_rel_rmse_plane_removed",
        [height_pair](const py::object& estimate, const py::object& truth) {
            const auto [e, t] = height_pair(estimate, truth);
            return height_rel_rmse_plane_removed(e, t);
        },
        "estimate"_a, "truth"_a,
        "height_rel_rmse with the best-fit plane a + b x + c y (least squares over the texel centres)\n"
        "removed from estimate - truth: the error that is not a tilt (a tilt is not observable).\n"
        "Heightfields or 2-D arrays, as height_rel_rmse.");
    m.def(
        "with_height_range",
        [](const Heightfield& heightfield, double range_um) {
            return with_height_range(heightfield, check_positive(range_um, "range_um"));
        },
        "heightfield"_a, "range_um"_a,
        "`heightfield` scaled about its mean to the peak-to-valley height range_um (um, > 0); texel\n"
        "width and vscale unchanged. A flat heightfield is a ValueError.");

    // ---- the CLI's run -----------------------------------------------------------------------
    py::class_<RecoveryResult>(m, "RecoveryResult", "What recover() returns.")
        .def_readonly("estimate", &RecoveryResult::estimate, "the recovered Heightfield")
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
misfit_ratio (deviance / its noise floor); after the model check model_misfit_gabor,
model_misfit_field, model_selected; with error bars median_sigma_relative,
predicted_error_relative; where the check needed error bars, error_bars ('given', 'computed',
'skipped', 'off', 'unavailable'), error_bars_note, and the cost rule's error_bars_predicted_seconds,
run_seconds (CPU) and error_bars_seconds.
)doc");

    const RecoveryOptions ro;
    m.def("recover", &recover, "truth"_a = py::none(), "observations"_a = py::none(), py::kw_only(), "size"_a = ro.rows,
          "texel_um"_a = py::none(), "vscale"_a = py::none(), "height_range_um"_a = ro.height_range_um,
          "correlation_texels"_a = py::none(), "model"_a = "OHS", "light"_a = py::make_tuple(0.0, 0.0),
          "sigma_p_um"_a = ro.sigma_p_um, "resolution"_a = ro.resolution, "lambdas_um"_a = py::none(),
          "overlap"_a = py::none(), "jitter"_a = ro.jitter, "noise"_a = "none", "loss"_a = py::none(),
          "method"_a = "pipeline", "field_iterations"_a = py::none(), "refine_iterations"_a = py::none(),
          "epochs"_a = ro.epochs, "seed"_a = ro.seed, "callback"_a = py::none(), "max_memory_gb"_a = ro.max_memory_gb,
          "quiet"_a = py::none(), "comm"_a = py::none(), "simulator"_a = "gabor", "calibrate"_a = py::none(),
          "simulate_position_error_texels"_a = 0.0, "simulate_exposure"_a = py::none(), "simulate_sigma_factor"_a = 1.0,
          "uncertainty"_a = false, "spectral"_a = ro.spectral, "field_tile_threshold"_a = py::none(),
          "field_tile_core"_a = py::none(), "white_smoothness"_a = py::none(),
          "white_smoothness_iterations"_a = py::none(), "position_passes"_a = py::none(),
          "position_uncertainty_um"_a = py::none(), "oblique_lights"_a = ro.oblique_lights,
          "plan_from_truth"_a = py::none(), "check_error_bars"_a = "auto", R"doc(
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
plan_from_truth  None (default): as the CLI, a given truth is planned for its measured
              roughness (measure_roughness: peak to valley, rms slope, Sal, Str; a rough, steep
              or strongly striated surface gets long wavelengths, oblique lights and the longer
              schedule, docs/recovery.md "Rough surfaces") unless correlation_texels is given;
              True: that (a truth needed, not with correlation_texels); False: the stated plan
              (height range and correlation_texels, default 4)
model         'OHS', 'ROHS', 'GHS' or 'RGHS' (GHS-type through the separable proxy); light: (wx, wy), |w| < 1
oblique_lights  steep generated surfaces (expected rms slope > 0.2 from height_range_um and
              correlation_texels): every position is observed under 4 oblique lights at
              sin(theta_i) = 0.8 as well, so that steep facets reflect into a slice (default
              True; OHS and ROHS: GHS-type models keep one light); False: under `light` alone
              (the CLI's --no-oblique-lights)
sigma_p_um    footprint sigma_p in um (0: the planner's, 1.5 texels or position_uncertainty_um
              if larger)
position_uncertainty_um  how far the stage may put a footprint from where it says, um rms per
              coordinate (the CLI's --position-uncertainty-um): the planner makes sigma_p at
              least this and the position loop searches lost positions 4x as far; None: the simulated error's rms (simulate_position_error_texels x
              texel_um), else 0
resolution    slice size n, 1...8192 (0: the planner's Nyquist choice)
lambdas_um    wavelengths in um (None: the planner's ladder for the height range)
overlap       worst-case overlap of neighbouring windows, 0.6 ... 0.95 (None: 0.6, 0.8 with
              calibrate 'positions' or 'all'); jitter 0 ... 0.3
noise         simulated noise: 'none', 'poisson:N' (photons per slice) or 'gaussian:REL'
loss          a spec or Loss; None: matched to the noise for the pipeline (amplitude without
              noise, poisson:N, mse), cmsle:1 for the thesis's method
method        'pipeline' (blurred fit, field retrieval, unwrapping, refinement) or 'thesis'
              (Adam, one observation per epoch)
field_iterations, refine_iterations  pipeline iterations (>= 0; None: the schedule's)
epochs        thesis method: Adam epochs (>= 0)
seed          generated truth, position jitter, noise, the thesis's draws
callback      callback(metrics: dict with stage, iteration, loss, seconds, height_rel_rmse)
              after every reported step; return False to stop early.
max_memory_gb refuse (MemoryError, before any work) a run whose estimated peak memory exceeds
              this many GB; 0 (default): the physical memory
quiet         progress (a tqdm bar per stage if tqdm is installed, else a line on stderr): None
              (default) shows it when stderr is a terminal or in Jupyter, False always, True never
comm          None (default: one process) or an mpi4py communicator (e.g. MPI.COMM_WORLD, under
              mpiexec): every rank passes the same arguments and keeps its share of the
              observations (result.observations: this rank's); the sums are allreduced, every
              rank gets the same estimate, only rank 0 shows progress (docs/scale.md). The
              thesis's method runs on one process only.
simulator     how a truth's observations are simulated: 'gabor' (the model, default) or
              'scalar' (the exact field of the interpolated heights, scalar_diffraction.h;
              OHS / ROHS); not with observations
calibrate     self-calibration, the CLI's --calibrate: None or 'none' (default), 'positions',
              'exposure', 'sigma' (comma-separated or a sequence), or 'all'; the refined values
              are in result.calibration
position_passes  with calibrate 'positions' (or 'all'): at most this many passes of the
              position loop after the first recovery (the CLI's --position-passes, 0...100; 0:
              off; None: the library's, 40, stopped earlier when the loss stalls); its per-pass
              steps are in result.metrics (positions:register, positions:newton, ...)
simulate_position_error_texels, simulate_exposure, simulate_sigma_factor  a study's
              acquisition errors (the CLI's --simulate-*; a truth only): footprint positions off
              by this rms per coordinate (texels, 0...10), each slice scaled by an exposure
              log-uniform in (min, max), the true sigma_p this factor times the stated one
              (0.25...4); the recovery is given the stated acquisition
uncertainty   True: also the error bars (height_uncertainty with the run's loss): the result's
              uncertainty (sigma per texel, um), median_sigma_um and, with a truth,
              coverage_1sigma / coverage_2sigma (wavebrdf recover --uncertainty)
check_error_bars  the convergence check's own error bars where it needs them (photon counts with
              the misfit on the floor, or a loss without a noise level): 'auto' (computed when
              predicted to take at most the recovery's own CPU time), 'always' or 'off' (the
              CLI's --check-error-bars; result.convergence['error_bars'] says what was done)
spectral      white light (the CLI's --spectral): N >= 2 makes every planned observation one RGB
              slice of a broadband source sampled at N wavelengths (no laser); 0: laser slices
field_tile_threshold, field_tile_core  the field stage on tiles (the CLI's --field-tile-threshold /
              --field-tile-core): a surface with a side above the threshold (texels, 0...10^6; 0:
              never) is retrieved on tiles of about `field_tile_core` texels (8...4096) plus a
              margin; None: the library's (64, 48)
white_smoothness  white light's smoothness continuation (the CLI's --white-smoothness): weights,
              largest first (at most 64, each 0 ... 1e12; [] none; None: the library's 10, 1,
              0.1, 0.01); white_smoothness_iterations: L-BFGS iterations per weight (None: 20)
Whether the run converged is judged without the truth, as the CLI judges it (docs/recovery.md,
"Did it converge?"): result.convergence; when it did not, its warning is also the last entry
of result.warnings (as in the CLI's run.json).
The run releases the GIL; Ctrl-C stops it within about a second (KeyboardInterrupt).
)doc");

    const UncertaintySettings us;
    m.def(
        "height_uncertainty",
        [](const py::object& observations, const Heightfield& estimate, const py::object& loss, int probe_spacing,
           int rounds, double cg_tolerance, int cg_iterations, std::uint64_t seed, int dense_max_texels,
           const py::object& comm_arg) {
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const std::vector<Observation> list = observations_or_file(observations);
            const Loss l = loss_argument(loss);
            UncertaintySettings s;
            s.probe_spacing = probe_spacing;
            s.rounds = rounds;
            s.cg_tolerance = cg_tolerance;
            s.cg_iterations = cg_iterations;
            s.seed = seed;
            s.dense_max_texels = dense_max_texels;
            HeightUncertainty u;
            {
                py::gil_scoped_release release;
                u = height_uncertainty(list, estimate, l, s, *comm);
            }
            return owning_array(std::move(u.sigma_um), {estimate.rows(), estimate.cols()});
        },
        "observations"_a, "estimate"_a, "loss"_a, py::kw_only(), "probe_spacing"_a = us.probe_spacing,
        "rounds"_a = us.rounds, "cg_tolerance"_a = us.cg_tolerance, "cg_iterations"_a = us.cg_iterations,
        "seed"_a = us.seed, "dense_max_texels"_a = us.dense_max_texels, "comm"_a = py::none(),
        R"doc(
Error bars of `estimate` (a Heightfield recovered from `observations`): the standard deviation
of every height (mean removed), um, a float64 array (rows, cols), from the curvature of `loss`
(the loss it was fitted with: 'poisson:N' uses the Fisher information of N photons per slice;
'amplitude', 'mse', 'cmsle:EPS' a noise variance estimated from the residuals) at the estimate:
the diagonal of the inverse Gauss-Newton matrix G, formed sparse (one forward difference per
texel of each observation's footprint): exact (dense Cholesky) up to dense_max_texels texels
(0...16384), above by coloured probes (texels probe_spacing apart share one, 1...16; rounds
sign draws, 1...64) and conjugate gradients on the formed G (cg_tolerance in (0, 1),
cg_iterations 1...10000). comm: None or an mpi4py communicator (observations: this rank's
share; every rank gets the same map). uncertainty.h, docs/recovery.md "Error bars".
)doc");
}

}  // namespace wavebrdf::python
