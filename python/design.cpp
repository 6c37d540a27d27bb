// design(): `wavebrdf design` through the same library run (design_run.h), returning arrays;
// with out= it writes the same run directory.
#include "design.h"

#include <cmath>
#include <optional>

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::dict design(const std::string& target, const py::object& image, const py::object& out, bool force,
                std::array<double, 2> light, const py::object& lambda_um, const py::object& spectral,
                std::array<double, 2> band_um, double specular_cone, double cone_limit, double uniformity_limit,
                const std::string& region, double window,
                const py::object& view, double view_cone, int size, double texel_um, double height_range_um,
                int levels, double level_step_um, double min_feature_um, const std::string& fabrication_error,
                std::uint64_t seed, int iterations, int refine_passes, double max_memory_gb,
                double delta_uv_tolerance, double delta_uv_ceiling, const py::object& start,
                const std::string& continuation, const py::object& anneal_sweeps) {
    DesignOptions o;
    if (!image.is_none()) {
        if (target != "pattern")
            bad_argument("image", "an array", "None unless target='pattern' (a pattern's grey image)");
        const py::array a = float_array(image, "image");
        check_shape(a, {-1, -1}, "image");
        o.target = pattern_target(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), to_doubles(a, "image"));
    } else if (target == "pattern") {
        bad_argument("target", "'pattern'", "'pattern:IMAGE.png', or target='pattern' with image=ARRAY");
    } else {
        o.target = parse_design_target(target);
    }
    o.omega_i = light;
    if (!lambda_um.is_none() && !spectral.is_none())
        bad_argument("lambda_um", "given with spectral", "one of lambda_um (a laser) or spectral (white light)");
    if (!lambda_um.is_none() && o.target.kind == DesignKind::Brdf)
        bad_argument("lambda_um", "given with a brdf target", "None: a brdf target's wavelengths are its table's");
    if (!lambda_um.is_none()) o.lambda_um = lambda_um.cast<double>();
    if (!spectral.is_none()) {
        o.spectral = spectral.cast<int>();
        if (o.spectral < 1) bad_argument("spectral", std::to_string(o.spectral), "1 to 256 wavelengths");
    }
    o.band_um = band_um;
    o.specular_cone = specular_cone;
    o.cone_limit = cone_limit;
    o.uniformity_limit = uniformity_limit;
    o.region = region;
    o.window = window;
    if (!view.is_none() && o.target.kind == DesignKind::Iridescent)
        bad_argument("view", "given with an iridescent target", "None: the views are the spec's pairs");
    set_common_design_options(o, view, view_cone, size, texel_um, height_range_um, levels, level_step_um,
                              fabrication_error, seed, iterations, refine_passes, max_memory_gb);
    o.min_feature_um = min_feature_um;
    o.delta_uv_tolerance = delta_uv_tolerance;
    o.delta_uv_ceiling = delta_uv_ceiling;
    o.continuation = continuation;
    if (!anneal_sweeps.is_none()) o.anneal_sweeps = anneal_sweeps.cast<int>();
    if (!start.is_none()) {
        const py::array a = float_array(start, "start");
        check_shape(a, {size, size}, "start");
        o.start_heights_um = to_doubles(a, "start");
    }
    const DesignResult result = run_design_into(
        out, force, [&] { return run_design(prepare_design(o)); },
        [&](const std::string& dir, const DesignResult& r) { write_design_directory(dir, r, force); });
    const auto n = static_cast<py::ssize_t>(result.size);
    py::array_t<double> heights({n, n});
    std::copy(result.heights_um.begin(), result.heights_um.end(), heights.mutable_data());
    py::array_t<int> level({n, n});
    std::copy(result.level.begin(), result.level.end(), level.mutable_data());
    const auto p = static_cast<py::ssize_t>(result.picture_size);
    py::array_t<float> target_picture({p, p, py::ssize_t{3}}), far_field({p, p, py::ssize_t{3}});
    std::copy(result.target_picture.begin(), result.target_picture.end(), target_picture.mutable_data());
    std::copy(result.far_field_picture.begin(), result.far_field_picture.end(), far_field.mutable_data());
    py::list curve;
    for (const DesignStep& s : result.curve)
        curve.append(py::make_tuple(s.iteration, s.loss, s.phase, s.temperature));
    const py::object info = py::module_::import("json").attr("loads")(result.metrics_json);
    warn_design_warnings(info);
    return py::dict("heights_um"_a = heights, "level"_a = level, "levels_um"_a = result.levels_um,
                    "lambdas_um"_a = result.lambdas_um, "texel_um"_a = result.texel_um, "target"_a = target_picture,
                    "far_field"_a = far_field, "picture_extent"_a = result.picture_extent, "curve"_a = curve,
                    "metrics"_a = info["metrics"], "design"_a = info);
}

}  // namespace

void warn_design_warnings(const py::object& info) {
    if (!info.contains("warnings")) return;
    for (const auto& w : info["warnings"])
        if (PyErr_WarnEx(PyExc_UserWarning, ("design: " + w.cast<std::string>()).c_str(), 1) != 0)
            throw py::error_already_set();
}

void set_common_design_options(DesignOptions& o, const py::object& view, double view_cone, int size, double texel_um,
                               double height_range_um, int levels, double level_step_um,
                               const std::string& fabrication_error, std::uint64_t seed, int iterations,
                               int refine_passes, double max_memory_gb) {
    if (!view.is_none()) o.view = view.cast<std::array<double, 2>>();
    o.view_cone = view_cone;
    o.size = size;
    o.texel_um = texel_um;
    o.height_range_um = height_range_um;
    o.levels = levels;
    o.level_step_um = level_step_um;
    o.errors = parse_fabrication_errors(fabrication_error);
    o.seed = seed;
    o.iterations = iterations;
    o.refine_passes = refine_passes;
    o.max_memory_gb = max_memory_gb;
}

void bind_design(py::module_& m) {
    m.def("design", &design, "target"_a = "anti-mirror", "image"_a = py::none(), "out"_a = py::none(),
          "force"_a = false, "light"_a = std::array<double, 2>{{0.0, 0.0}}, "lambda_um"_a = py::none(),
          "spectral"_a = py::none(), "band_um"_a = std::array<double, 2>{{0.36, 0.83}}, "specular_cone"_a = 0.05,
          "cone_limit"_a = 0.002, "uniformity_limit"_a = 0.25, "region"_a = "annulus:0.1,0.5", "window"_a = 0.3, "view"_a = py::none(), "view_cone"_a = 0.05,
          "size"_a = 256, "texel_um"_a = 0.5, "height_range_um"_a = 2.0, "levels"_a = 8, "level_step_um"_a = 0.0,
          "min_feature_um"_a = 0.0, "fabrication_error"_a = "", "seed"_a = 1, "iterations"_a = 200,
          "refine_passes"_a = 60, "max_memory_gb"_a = 0.0, "delta_uv_tolerance"_a = 0.0, "delta_uv_ceiling"_a = 0.04, "start"_a = py::none(),
          "continuation"_a = "auto", "anneal_sweeps"_a = py::none(),
          R"(A texel relief for a target appearance: `wavebrdf design` (docs/design.md), the same library run.

target: 'anti-mirror', 'pattern:IMAGE.png', 'colour:#RRGGBB', 'iridescent:SPEC.json' (view and colour
pairs), 'brdf:TABLE.exr' (a wavebrdf table or lobe file; its lights and wavelengths), or 'pattern' with
image= (a 2-D grey array, rows along omega_x). light: the projected light direction. lambda_um (a laser, default 0.5)
or spectral=N (white light, N equal-energy wavelengths over band_um). specular_cone, cone_limit,
uniformity_limit, region (anti-mirror; a limit the relief breaks is also a UserWarning), window (pattern), view (default the mirror direction), view_cone,
delta_uv_tolerance and delta_uv_ceiling (colour, iridescent; a colour the brightness trade leaves below Y 5 % is also a UserWarning) as the CLI's options; size, texel_um, height_range_um, levels, level_step_um (0: the default rule; the anti-mirror designs its own, from the best of a survey of steps: design['step_survey']),
min_feature_um with levels=0 (a grayscale relief: no lateral detail finer than it),
fabrication_error ('scale:5%,blur:0.3um'), seed, iterations, refine_passes, max_memory_gb likewise.
start: a size x size array of heights (um) on the run's levels to start from instead of a random
relief (the CLI's --start HEIGHTS.exr; e.g. an earlier design's heights_um).
continuation: 'auto' (the anti-mirror from a random start on an even size: designed on size/2 first,
and on its halves while one holds an order besides the mirror one inside the specular cone at every
wavelength, each tiled and continued; so is a colour, or an iridescent target with a pair, half of
whose optimal-colour limit is below Y 10 %, with the view cone), 'off', or tile sizes such as
'64,128' (the CLI's --continuation; anti-mirror, colour and iridescent).
anneal_sweeps: the anti-mirror's annealed last stage (the CLI's --anneal-sweeps): heat-bath sweeps over
the continuation's smallest tile after the loop designed it, then that tile repeated and scored;
None: 400 where it applies (levels, a random start, no fabrication errors), 0: none.
out: also write the run directory there (force: reuse one holding only a design's outputs).

Returns a dict: heights_um (size x size float64, um), level (each texel's level index), levels_um,
lambdas_um, texel_um, target and far_field (256 x 256 x 3 float32 pictures over +-picture_extent
about the mirror direction), curve [(iteration, loss, phase, temperature)], metrics (design.json's
metrics: model, exact, relaxed, ...) and design (all of design.json). The same options and seed give
the same design as the CLI.)");
}

}  // namespace wavebrdf::python
