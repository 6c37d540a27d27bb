// Heightfield recovery from observations (recover.h): recover_heights, height_rel_rmse,
// height_rel_rmse_plane_removed.
#include <cmath>
#include <utility>

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_recover(py::module_& m) {
    const RecoverSettings rs;
    m.def(
        "recover_heights",
        [](const py::object& observations, const py::object& size, double texel_um, double vscale,
           const py::object& truth, const std::vector<double>& blur_widths, int blur_iterations, int blur_wavelengths,
           const py::object& field_iterations, bool band_limit, int refine, const py::object& max_range_um,
           const py::object& refine_iterations, int refine_history,
           const py::object& refine_loss, const py::object& callback, const py::object& comm_arg,
           const py::object& calibrate, int field_tile_threshold, int field_tile_core,
           const py::object& white_smoothness, int white_smoothness_iterations) -> py::object {
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const HeightsArguments given = heights_arguments(observations, size, texel_um, vscale);
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
            s.field.iterations = optional_count(field_iterations, "field_iterations");
            s.field.band_limit = band_limit;
            if (refine < 0 || (refine > 0 && refine % 2 == 0) || refine > 63)
                bad_argument("refine", std::to_string(refine), "0 (automatic) or an odd object-grid refinement 1...63");
            s.refine = refine;
            if (!max_range_um.is_none()) s.height_range_um = check_positive(max_range_um.cast<double>(), "max_range_um");
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
                    return recover_heights(given.observations, given.rows, given.cols, texel_um, vscale, s, on_step,
                                           t ? &*t : nullptr, *comm, &calibration);
                },
                nullptr, comm->size() > 1);
            if (calibrate.is_none()) return py::cast(std::move(estimate));
            return py::make_tuple(std::move(estimate), calibration_dict(s.calibrate, calibration));
        },
        "observations"_a, "size"_a, "texel_um"_a, "vscale"_a = 1.0, py::kw_only(), "truth"_a = py::none(),
        "blur_widths"_a = rs.blurred.blur_widths, "blur_iterations"_a = rs.blurred.iterations,
        "blur_wavelengths"_a = rs.blur_wavelengths, "field_iterations"_a = py::none(),
        "band_limit"_a = rs.field.band_limit, "refine"_a = rs.refine, "max_range_um"_a = py::none(),
        "refine_iterations"_a = py::none(),
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
                    at least 2 sigma_p apart
field_iterations    L-BFGS iterations of each field retrieval (>= 0; None: 25 on a smooth surface
                    without calibration, else 50), longest wavelength first, each started from
                    the heights of the fields before it;
                    band_limit: keep only the object's spectrum the slices see
refine              odd object-grid refinement 1...63 (0: automatic)
max_range_um        bound on the height range for unwrapping (um, > 0; None: 4;
                    RecoverSettings::height_range_um)
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
}

}  // namespace wavebrdf::python
