#pragma once
// The arguments the recovery's bindings share (acquisition.cpp, recover.cpp, baseline.cpp,
// recovery_run.cpp, uncertainty.cpp, noise.cpp, roughness_plan.cpp): observations, wavelengths,
// counts, calibration, the metrics stream and running a recovery without the GIL.
#include <array>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "common.h"
#include "observation_arg.h"
#include "progress.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf::python {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The first arguments of recover_heights and recover_heights_thesis: the observations (or their
// file) and the grid they recover, size texels of texel_um (> 0) with vscale (finite, non-zero).
struct HeightsArguments {
    std::vector<Observation> observations;
    int rows = 0, cols = 0;
};
HeightsArguments heights_arguments(const py::object& observations, const py::object& size, double texel_um,
                                   double vscale);

// The recovery's rarely used settings (wb.RecoverSettings) as given; None: the library's (the
// schedule's). recover() reads the acquisition's and the schedule's (the CLI's options of the
// same names), recover_heights the schedule's and its stages' own (RecoverSettings, recover.h);
// each refuses the other's when set.
struct RecoverKnobs {
    py::object overlap = py::none(), jitter = py::float_(RecoveryOptions{}.jitter), oblique_lights = py::bool_(true),
               plan_from_truth = py::none(), simulator = py::str("gabor"), field_iterations = py::none(),
               refine_iterations = py::none(), field_tile_threshold = py::none(), field_tile_core = py::none(),
               refine_coarse_spacing = py::none(), refine_coarse_weight = py::none(),
               refine_coarse_iterations = py::none(), white_smoothness = py::none(),
               white_smoothness_iterations = py::none(), position_passes = py::none(),
               epochs = py::int_(RecoveryOptions{}.epochs), simulate_position_error_texels = py::float_(0.0),
               simulate_exposure = py::none(), simulate_sigma_factor = py::float_(1.0), blur_widths = py::none(),
               blur_iterations = py::none(), blur_wavelengths = py::none(), band_limit = py::none(),
               refine = py::none(), max_range_um = py::none(), refine_history = py::none(), refine_loss = py::none();
};
using KnobField = py::object RecoverKnobs::*;
// Every field by its name (the constructor's keywords and the attributes), in the signature's order.
const std::vector<std::pair<const char*, KnobField>>& knob_fields();

// settings= (a RecoverSettings or None) with `function`'s old keywords for its fields, each
// still accepted, with a FutureWarning, where `accepted` names it (a TypeError otherwise, as
// Python's own); then the fields `function` does not read refused when set (ValueError):
// recover() (for_recover) reads no stage's own, recover_heights nothing of the acquisition's.
RecoverKnobs knobs_argument(const py::object& settings, const py::kwargs& old, const char* function,
                            const std::vector<std::string>& accepted, bool for_recover);

// `value` as a T (ValueError naming `name` and what was expected otherwise).
template <typename T>
T knob(const py::object& value, const char* name, const char* expected) {
    try {
        if (!py::isinstance<py::str>(value) || std::is_same_v<T, std::string>) return value.cast<T>();
    } catch (const py::cast_error&) {}
    throw py::value_error(std::string(name) + " = " + std::string(py::repr(value)) + " is invalid; expected " +
                          expected);
}
// None → `unset` (-1, the library's default); else an integer / a number >= 0.
int optional_int(const py::object& value, const char* name);
double optional_nonnegative(const py::object& value, const char* name);

// noise=: None, 'none', 'poisson:N' or 'gaussian:REL'.
Noise noise_argument(const py::object& noise);
// Observations as given (Observation, list) or read from a path (JSON, or HDF5: observation_file.h).
std::vector<Observation> observations_or_file(const py::object& observations);
// A list of wavelengths in µm, or empty for None (ValueError naming `name` otherwise).
std::vector<double> wavelength_list(const py::object& lambdas, const char* name);
// resolution=: 0 (planned) or a slice size.
int planned_resolution(int resolution);
// White light's smoothness weights (RecoverSettings::white_smoothness): None → the default;
// else a sequence of at most 64 numbers, each finite in [0, 1e12] (empty: no continuation).
std::optional<std::vector<double>> white_smoothness_argument(const py::object& value);
// An iteration count >= 0, or -1 (the library's) for None.
int optional_count(const py::object& value, const char* name);
// callback=: None or a callable.
void check_callback(const py::object& callback);
// A StageMetrics as the callback's dict.
py::dict metrics_row(const StageMetrics& m);
// field_tile_threshold= / field_tile_core=: a texel count in [lo, hi] (ValueError naming it otherwise).
int tile_size(int value, const char* name, int lo, int hi);
// The same, or -1 (the library's) for None.
int optional_tile_size(const py::object& value, const char* name, int lo, int hi);
// calibrate=: None, a string ("positions,exposure", "all", "none") or a sequence of those words.
CalibrationSettings calibrate_argument(const py::object& calibrate);
// A Calibration as a dict: refined (str), sigma_p_scale, exposures (float64 (N,) or None),
// position_offsets_um (float64 (N, 2) or None).
py::dict calibration_dict(const CalibrationSettings& refined, const Calibration& c);
// The metrics.csv columns as arrays: stage (str), iteration (int64), loss, seconds,
// height_rel_rmse (float64; NaN without a truth).
py::dict metrics_columns(const std::vector<StageMetrics>& history);
// The communicator of a `comm` argument (communicator_argument), never null: None → the serial
// one (a Python user opts in to MPI).
std::shared_ptr<const Communicator> ranks_argument(const py::object& comm);
// truth=: None or a Heightfield.
std::optional<Heightfield> optional_truth(const py::object& truth);
// measure_roughness's dict, and a Heightfield (measured here) or such a dict as an argument.
py::dict roughness_dict(const MeasuredRoughness& m);
MeasuredRoughness roughness_argument(const py::object& value);

// The settings text shared by recover_heights' and recover_heights_thesis's docs.
extern const char* const kSettingsDoc;

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

}  // namespace wavebrdf::python
