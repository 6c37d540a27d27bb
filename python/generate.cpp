// Generated heightfields and their statistics (generate.h): Heightfield.generate,
// Heightfield.stats and with_height_range.

#include <optional>

#include "common.h"
#include "wavebrdf/generate.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_generate(py::module_& m) {
    // Methods of the class heightfield.cpp binds (registered before this).
    auto heightfield = py::reinterpret_borrow<py::class_<Heightfield>>(m.attr("Heightfield"));
    heightfield
        .def_static(
            "generate",
            [](const std::string& type, int rows, std::optional<int> cols, double texel_um, std::uint64_t seed,
               double rms_height_um, double rms_slope, double correlation_um, double anisotropy, int scratch_count,
               double scratch_depth_um, double scratch_width_um, double amplitude_um, double period_um) {
                SurfaceParams p;
                p.type = parse_surface_type(type);
                p.rows = rows;
                p.cols = cols.value_or(rows);
                p.texel_um = texel_um;
                p.seed = seed;
                p.rms_height_um = rms_height_um;
                p.rms_slope = rms_slope;
                p.correlation_um = correlation_um;
                p.anisotropy = anisotropy;
                p.scratch_count = scratch_count;
                p.scratch_depth_um = scratch_depth_um;
                p.scratch_width_um = scratch_width_um;
                p.amplitude_um = amplitude_um;
                p.period_um = period_um;
                py::gil_scoped_release release;
                return generate_heightfield(p);
            },
            "type"_a = "isotropic", "rows"_a = 256, "cols"_a = py::none(), "texel_um"_a = 1.0, "seed"_a = 1,
            "rms_height_um"_a = 0.1, "rms_slope"_a = 0.0, "correlation_um"_a = 4.0, "anisotropy"_a = 8.0,
            "scratch_count"_a = 40, "scratch_depth_um"_a = 0.05, "scratch_width_um"_a = 1.5, "amplitude_um"_a = 0.1,
            "period_um"_a = 32.0, R"doc(
A procedural periodic surface, deterministic in ``seed`` (as ``wavebrdf heightfield``).

type  'flat', 'isotropic' (Gaussian-correlated noise with rms height rms_height_um, or rms
      slope rms_slope when > 0, correlation length correlation_um), 'brushed' (the same,
      anisotropy times longer along y), 'scratched' (scratch_count Gaussian grooves of depth
      scratch_depth_um and width scratch_width_um on a smooth base) or 'grating'
      (amplitude_um * sin(2 pi x / period_um)). Lengths in um; rows, cols in 1...16384
      (cols defaults to rows). The result has vscale 1 and texel width texel_um.
)doc")
        .def(
            "stats",
            [](const Heightfield& hf) {
                const HeightStats s = height_stats(hf);
                return py::dict("mean_um"_a = s.mean_um, "rms_height_um"_a = s.rms_height_um, "min_um"_a = s.min_um,
                                "max_um"_a = s.max_um, "rms_slope"_a = s.rms_slope);
            },
            "Mean, rms height, min and max in um (vscale included) and rms slope.");

    m.def(
        "with_height_range",
        [](const Heightfield& heightfield, double range_um) {
            return with_height_range(heightfield, check_positive(range_um, "range_um"));
        },
        "heightfield"_a, "range_um"_a,
        "`heightfield` scaled about its mean to the peak-to-valley height range_um (um, > 0); texel\n"
        "width and vscale unchanged. A flat heightfield is a ValueError.");
}

}  // namespace wavebrdf::python
