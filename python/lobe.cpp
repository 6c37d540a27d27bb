// Analytic lobes (lobe.h) as BRDF tables, as dicts wavebrdf/table.py wraps (wavebrdf.lobe_table),
// and the lobe's BRDF at given directions. This file only converts and validates.
#include "lobe.h"
#include "wavebrdf/lobe.h"
#include "wavebrdf/table.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

Lobe make_lobe(const std::string& distribution, double alpha_x, double alpha_y, double fresnel_f0) {
    Lobe lobe;
    lobe.distribution = parse_lobe_distribution(distribution);
    lobe.alpha_x = check_finite(alpha_x, "alpha_x");
    lobe.alpha_y = check_finite(alpha_y, "alpha_y");
    lobe.fresnel_f0 = check_finite(fresnel_f0, "fresnel_f0");
    validate(lobe);
    return lobe;
}

}  // namespace

void bind_lobe(py::module_& m) {
    m.def(
        "_lobe_table",
        [](const std::string& distribution, double alpha_x, double alpha_y, double fresnel_f0, const py::object& lights,
           double max_light_sin, int resolution, double lambda_um, double max_memory_gb, const std::string& out) {
            LobeTableSpec spec;
            spec.lobe = make_lobe(distribution, alpha_x, alpha_y, fresnel_f0);
            const std::array<int, 2> grid = size_argument(lights, "lights");
            spec.lights = {grid[0], grid[1], check_finite(max_light_sin, "max_light_sin")};
            spec.resolution = resolution;
            spec.lambda_um = check_finite(lambda_um, "lambda_um");
            BrdfTable t;
            {
                py::gil_scoped_release release;
                t = lobe_table(spec, max_memory_gb);
                if (!out.empty()) write_brdf_table(out, t);
            }
            return table_dict(std::move(t));
        },
        "distribution"_a, "alpha_x"_a, "alpha_y"_a, "fresnel_f0"_a, "lights"_a, "max_light_sin"_a, "resolution"_a,
        "lambda_um"_a, "max_memory_gb"_a, "out"_a,
        "lobe_table (and write_brdf_table when out is not empty) as a dict (wavebrdf.lobe_table).");
    m.def(
        "_lobe_brdf",
        [](const std::string& distribution, double alpha_x, double alpha_y, double fresnel_f0, double omega_i_x,
           double omega_i_y, double omega_o_x, double omega_o_y) {
            return lobe_brdf(make_lobe(distribution, alpha_x, alpha_y, fresnel_f0), omega_i_x, omega_i_y, omega_o_x,
                             omega_o_y);
        },
        "distribution"_a, "alpha_x"_a, "alpha_y"_a, "fresnel_f0"_a, "omega_i_x"_a, "omega_i_y"_a, "omega_o_x"_a,
        "omega_o_y"_a, "lobe_brdf: f_r in 1/sr of the lobe for projected directions (wavebrdf.lobe_brdf).");
}

}  // namespace wavebrdf::python
