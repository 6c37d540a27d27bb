// The arguments the recovery's bindings share (recovery_args.h).
#include "recovery_args.h"

#include <algorithm>

#include <cmath>

#include "observation_arg.h"
#include "wavebrdf/observation_file.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

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

HeightsArguments heights_arguments(const py::object& observations, const py::object& size, double texel_um,
                                   double vscale) {
    HeightsArguments a;
    a.observations = observations_or_file(observations);
    const std::array<int, 2> rc = size_argument(size);
    a.rows = rc[0];
    a.cols = rc[1];
    check_positive(texel_um, "texel_um");
    check_finite(vscale, "vscale");
    if (vscale == 0.0) bad_argument("vscale", "0", "a non-zero vertical scale");
    return a;
}

int planned_resolution(int resolution) {
    if (resolution != 0) check_resolution(resolution, "resolution");
    return resolution;
}

// White light's smoothness weights (RecoverSettings::white_smoothness): None → the default;
// else a sequence of numbers (empty: no continuation; the library bounds their count and range).
std::optional<std::vector<double>> white_smoothness_argument(const py::object& value) {
    if (value.is_none()) return std::nullopt;
    std::vector<double> weights;
    // The type here; the count and the range are the library's to check.
    bool ok = !py::isinstance<py::str>(value) && py::isinstance<py::sequence>(value);
    if (ok) {
        try {
            weights = value.cast<std::vector<double>>();
        } catch (const py::cast_error&) {
            ok = false;
        }
    }
    if (!ok)
        throw py::value_error("white_smoothness = " + std::string(py::repr(value)).substr(0, 80) +
                              " is invalid; expected a sequence of weights (numbers), largest first, or None");
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
    return py::dict("stage"_a = m.stage, "kind"_a = stage_kind_name(m.kind), "total"_a = m.total,
                    "iteration"_a = m.iteration, "loss"_a = m.loss, "seconds"_a = m.seconds,
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

std::optional<Heightfield> optional_truth(const py::object& truth) {
    if (truth.is_none()) return std::nullopt;
    try {
        return truth.cast<Heightfield>();
    } catch (const py::cast_error&) {
        throw py::value_error("truth is a " + std::string(py::str(py::type::of(truth).attr("__name__"))) +
                              "; expected a Heightfield or None");
    }
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

const char* const kSettingsDoc = R"doc(
observations  Observation(s) at several positions and wavelengths (OHS / ROHS single-wavelength
              ones feed the blurred fit and the fields; all feed the refinement and Adam); their
              weights count (a pixel of weight 0 is out of every misfit; docs/recovery.md)
size          N or (rows, cols) of the estimate, 1...16384; texel_um > 0 (um), vscale finite
truth         a Heightfield of that size, or None: only feeds height_rel_rmse in the metrics
callback      callback(metrics: dict with stage, kind (the stage's kind: 'field:', 'refine', ...),
              total (its planned iterations; 0 for a result), iteration, loss, seconds,
              height_rel_rmse (NaN without a truth)) after every reported step; return False to stop early
              (the estimate so far is returned). The run releases the GIL; Ctrl-C stops it
              at the next step (KeyboardInterrupt).
)doc";

int optional_int(const py::object& value, const char* name) {
    if (value.is_none()) return -1;
    const int n = knob<int>(value, name, "an integer >= 0 or None");
    if (n < 0) bad_argument(name, std::to_string(n), "an integer >= 0 or None (the library's default)");
    return n;
}
double optional_nonnegative(const py::object& value, const char* name) {
    if (value.is_none()) return -1.0;
    const double x = knob<double>(value, name, "a number >= 0 or None");
    if (!(x >= 0.0)) bad_argument(name, format_number(x), "a number >= 0 or None (the library's default)");
    return x;
}

const std::vector<std::pair<const char*, KnobField>>& knob_fields() {
    static const std::vector<std::pair<const char*, KnobField>> fields = {
        {"field_iterations", &RecoverKnobs::field_iterations},
        {"refine_iterations", &RecoverKnobs::refine_iterations},
        {"field_tile_threshold", &RecoverKnobs::field_tile_threshold},
        {"field_tile_core", &RecoverKnobs::field_tile_core},
        {"refine_coarse_spacing", &RecoverKnobs::refine_coarse_spacing},
        {"refine_coarse_weight", &RecoverKnobs::refine_coarse_weight},
        {"refine_coarse_iterations", &RecoverKnobs::refine_coarse_iterations},
        {"position_passes", &RecoverKnobs::position_passes},
        {"white_smoothness", &RecoverKnobs::white_smoothness},
        {"white_smoothness_iterations", &RecoverKnobs::white_smoothness_iterations},
        {"epochs", &RecoverKnobs::epochs},
        {"overlap", &RecoverKnobs::overlap},
        {"jitter", &RecoverKnobs::jitter},
        {"oblique_lights", &RecoverKnobs::oblique_lights},
        {"plan_from_truth", &RecoverKnobs::plan_from_truth},
        {"simulator", &RecoverKnobs::simulator},
        {"simulate_position_error_texels", &RecoverKnobs::simulate_position_error_texels},
        {"simulate_exposure", &RecoverKnobs::simulate_exposure},
        {"simulate_sigma_factor", &RecoverKnobs::simulate_sigma_factor},
        {"blur_widths", &RecoverKnobs::blur_widths},
        {"blur_iterations", &RecoverKnobs::blur_iterations},
        {"blur_wavelengths", &RecoverKnobs::blur_wavelengths},
        {"band_limit", &RecoverKnobs::band_limit},
        {"refine", &RecoverKnobs::refine},
        {"max_range_um", &RecoverKnobs::max_range_um},
        {"refine_history", &RecoverKnobs::refine_history},
        {"refine_loss", &RecoverKnobs::refine_loss},
    };
    return fields;
}

RecoverKnobs knobs_argument(const py::object& settings, const py::kwargs& old, const char* function,
                            const std::vector<std::string>& accepted, bool for_recover) {
    RecoverKnobs k;
    if (!settings.is_none()) {
        try {
            k = settings.cast<RecoverKnobs>();
        } catch (const py::cast_error&) {
            throw py::value_error("settings = " + std::string(py::repr(settings)).substr(0, 80) +
                                  " is invalid; expected a RecoverSettings or None");
        }
    }
    const auto& fields = knob_fields();
    for (const auto& [key, value] : old) {
        const std::string name = py::str(key);
        const auto field = std::find_if(fields.begin(), fields.end(), [&](const auto& f) { return name == f.first; });
        if (field == fields.end() || std::find(accepted.begin(), accepted.end(), name) == accepted.end())
            throw py::type_error(std::string(function) + "() got an unexpected keyword argument '" + name + "'");
        py::module_::import("warnings")
            .attr("warn")(std::string(function) + "(" + name + "=...) is deprecated; pass settings=RecoverSettings(" +
                              name + "=...)",
                          py::module_::import("builtins").attr("FutureWarning"), 2);
        k.*(field->second) = py::reinterpret_borrow<py::object>(value);
    }
    // The fields the other function reads: recover_heights' stages' own, recover()'s acquisition.
    const std::vector<std::string> foreign = for_recover
                                                 ? std::vector<std::string>{"blur_widths",      "blur_iterations",
                                                                            "blur_wavelengths", "band_limit",
                                                                            "refine",           "max_range_um",
                                                                            "refine_history",   "refine_loss"}
                                                 : std::vector<std::string>{"overlap",
                                                                            "jitter",
                                                                            "oblique_lights",
                                                                            "plan_from_truth",
                                                                            "simulator",
                                                                            "simulate_position_error_texels",
                                                                            "simulate_exposure",
                                                                            "simulate_sigma_factor",
                                                                            "epochs"};
    const RecoverKnobs defaults;
    for (const auto& [name, field] : fields)
        if (std::find(foreign.begin(), foreign.end(), name) != foreign.end() && !(k.*field).equal(defaults.*field))
            throw py::value_error(
                std::string("settings.") + name + " = " + std::string(py::repr(k.*field)).substr(0, 80) +
                (for_recover ? " is a setting of recover_heights' stages; expected None in recover(), which plans "
                               "the schedule"
                             : " is a setting of the acquisition's plan or simulation; expected its default in "
                               "recover_heights, which recovers the observations given"));
    return k;
}

}  // namespace wavebrdf::python
