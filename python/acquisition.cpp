// Acquisition planning (acquisition.h): AcquisitionPlan, plan_acquisition, planned_observations,
// simulate_observations, check_acquisition.
#include <cmath>
#include <optional>

#include "common.h"
#include "observation_arg.h"
#include "recovery_args.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::array positions_array(const AcquisitionPlan& plan) {
    std::vector<double> v;
    for (const auto& p : plan.positions_um) v.insert(v.end(), {p[0], p[1]});
    return owning_array(std::move(v), {static_cast<py::ssize_t>(plan.positions_um.size()), 2});
}

}  // namespace

void bind_acquisition(py::module_& m) {
    py::class_<AcquisitionPlan>(m, "AcquisitionPlan", R"doc(
What plan_acquisition proposes: footprint centres on a jittered raster over the periodic tile,
a slice resolution that samples the window (within 4x of Nyquist, at least 48), and wavelengths whose synthetic
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
resolution       given slice size n (1...8192); 0: planned, n >= D/lambda (within 4x of Nyquist's
                 4D/lambda) and at least 48
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
}

}  // namespace wavebrdf::python
