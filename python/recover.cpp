// Heightfield recovery from observations (recover.h): recover_heights, height_rel_rmse,
// height_rel_rmse_plane_removed.
#include <cmath>
#include <memory>
#include <optional>
#include <vector>
#include <utility>

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

// recover_heights' settings (wb.RecoverSettings: the schedule's and its stages' own, None the
// library's) as the library's RecoverSettings; the library checks what it reads.
RecoverSettings stage_settings(const RecoverKnobs& k) {
    RecoverSettings s;
    const auto count = [](const py::object& value, const char* name, int lowest, const char* expected) {
        const int n = knob<int>(value, name, expected);
        if (n < lowest) bad_argument(name, std::to_string(n), expected);
        return n;
    };
    if (!k.blur_widths.is_none()) {
        const char* expected = "widths > 0 (in footprint lobes), widest first";
        const std::vector<double> widths = knob<std::vector<double>>(k.blur_widths, "blur_widths", expected);
        for (double w : widths)
            if (!std::isfinite(w) || w <= 0.0) bad_argument("blur_widths", format_number(w), expected);
        s.blurred.blur_widths = widths;
    }
    if (!k.blur_iterations.is_none()) s.blurred.iterations = count(k.blur_iterations, "blur_iterations", 0, ">= 0");
    if (!k.blur_wavelengths.is_none())
        s.blur_wavelengths = count(k.blur_wavelengths, "blur_wavelengths", 0, ">= 0 (0: all)");
    s.field.iterations = optional_count(k.field_iterations, "field_iterations");
    if (!k.band_limit.is_none()) s.field.band_limit = knob<bool>(k.band_limit, "band_limit", "True or False");
    if (!k.refine.is_none()) {
        const char* expected = "0 (automatic) or an odd object-grid refinement 1...63";
        const int refine = knob<int>(k.refine, "refine", expected);
        if (refine < 0 || (refine > 0 && refine % 2 == 0) || refine > 63)
            bad_argument("refine", std::to_string(refine), expected);
        s.refine = refine;
    }
    if (!k.max_range_um.is_none())
        s.height_range_um = check_positive(knob<double>(k.max_range_um, "max_range_um", "a range in um > 0"),
                                           "max_range_um");
    s.refine_iterations = optional_count(k.refine_iterations, "refine_iterations");
    if (!k.refine_history.is_none()) s.refine_history = count(k.refine_history, "refine_history", 1, ">= 1");
    if (!k.refine_loss.is_none()) s.refine_loss = loss_argument(k.refine_loss);
    if (!k.field_tile_threshold.is_none())
        s.field_tile_threshold = tile_size(knob<int>(k.field_tile_threshold, "field_tile_threshold", "texels"),
                                           "field_tile_threshold", 0, 1000000);
    if (!k.field_tile_core.is_none())
        s.field_tile_core = tile_size(knob<int>(k.field_tile_core, "field_tile_core", "texels"), "field_tile_core", 8,
                                      4096);
    if (!k.white_smoothness.is_none()) s.white_smoothness = *white_smoothness_argument(k.white_smoothness);
    if (!k.white_smoothness_iterations.is_none())
        s.white_smoothness_iterations = count(k.white_smoothness_iterations, "white_smoothness_iterations", 0, ">= 0");
    if (!k.refine_coarse_spacing.is_none())
        s.refine_coarse_spacing = optional_nonnegative(k.refine_coarse_spacing, "refine_coarse_spacing");
    if (!k.refine_coarse_weight.is_none())
        s.refine_coarse_weight = optional_nonnegative(k.refine_coarse_weight, "refine_coarse_weight");
    if (!k.refine_coarse_iterations.is_none())
        s.refine_coarse_iterations = optional_count(k.refine_coarse_iterations, "refine_coarse_iterations");
    if (!k.position_passes.is_none()) s.position_outer_passes = optional_count(k.position_passes, "position_passes");
    return s;
}

}  // namespace

void bind_recover(py::module_& m) {
    m.def(
        "recover_heights",
        [](const py::object& observations, const py::object& size, double texel_um, double vscale,
           const py::object& truth, const py::object& calibrate, const py::object& callback, const py::object& comm_arg,
           const py::object& settings, const py::kwargs& old_keywords) -> py::object {
            const RecoverKnobs k = knobs_argument(
                settings, old_keywords, "recover_heights",
                {"blur_widths", "blur_iterations", "blur_wavelengths", "band_limit", "refine", "max_range_um",
                 "refine_history", "refine_loss", "field_iterations", "refine_iterations", "field_tile_threshold",
                 "field_tile_core", "white_smoothness", "white_smoothness_iterations"},
                false);
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const HeightsArguments given = heights_arguments(observations, size, texel_um, vscale);
            RecoverSettings s = stage_settings(k);
            s.calibrate = calibrate_argument(calibrate);
            const std::optional<Heightfield> t = optional_truth(truth);
            check_callback(callback);
            std::vector<StageMetrics> history;
            bool stopped = false;
            Calibration calibration;
            Heightfield estimate = run_released(
                callback, history, stopped,
                [&](const auto& on_step) {
                    return recover_heights(given.observations, given.rows, given.cols, texel_um, vscale, s, on_step,
                                           t ? &*t : nullptr, *comm, &calibration);
                },
                nullptr, comm->size() > 1);
            if (calibrate.is_none()) return py::cast(std::move(estimate));
            return py::make_tuple(std::move(estimate), calibration_dict(s.calibrate, calibration));
        },
        "observations"_a, "size"_a, "texel_um"_a, "vscale"_a = 1.0, py::kw_only(), "truth"_a = py::none(),
        "calibrate"_a = py::none(), "callback"_a = py::none(), "comm"_a = py::none(), "settings"_a = py::none(),
        (std::string(R"doc(
The heightfield whose slices match `observations`, from a flat start (recover.h): a blurred fit,
phase retrieval of the field per wavelength on a refined object grid, unwrapping, then L-BFGS
on the heights in the full model. Returns a Heightfield (size, texel units with texel_um and
vscale). With default settings it runs the schedule `wavebrdf recover` and recover() run for a
smooth surface.

settings            a RecoverSettings (None: the defaults): the schedule's settings it shares
                    with recover() (field_iterations, refine_iterations, field tiles, the coarse
                    space, position_passes, white light's continuation) and the stages' own
                    (blur_widths, blur_iterations, blur_wavelengths, band_limit, refine,
                    max_range_um, refine_history, refine_loss; help(RecoverSettings));
                    one of the acquisition's (overlap, simulate_*, ...) set is a ValueError. Their
                    names as keywords of recover_heights still work for now, with a FutureWarning.
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
)doc") + kSettingsDoc)
            .c_str());
    // Heightfields or 2-D arrays: an array is in the other argument's units (a Heightfield's
    // texel_um and vscale; two arrays share theirs, which the ratio does not depend on).
    const auto height_pair = [](const py::object& estimate, const py::object& truth) {
        const bool e_hf = py::isinstance<Heightfield>(estimate), t_hf = py::isinstance<Heightfield>(truth);
        const Heightfield* scale = e_hf   ? &estimate.cast<const Heightfield&>()
                                   : t_hf ? &truth.cast<const Heightfield&>()
                                          : nullptr;
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
}

}  // namespace wavebrdf::python
