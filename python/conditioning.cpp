// Conditioning measured heights (conditioning.h): wavebrdf.condition_surface and
// Heightfield.conditioned.
#include <array>
#include <optional>

#include "common.h"
#include "wavebrdf/conditioning.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

ConditioningOptions conditioning_options(const std::string& fill, const std::string& detrend,
                                         const py::object& crop, const py::object& resample_um,
                                         const std::string& periodic) {
    ConditioningOptions o;
    o.fill = parse_fill_method(fill, "fill");
    o.detrend_order = parse_detrend(detrend, "detrend");
    if (!crop.is_none()) {
        const auto c = crop.cast<std::vector<int>>();
        if (c.size() != 4) throw py::value_error("crop has " + std::to_string(c.size()) +
                                                 " values; expected (r0, c0, rows, cols)");
        o.crop = std::array<int, 4>{c[0], c[1], c[2], c[3]};
    }
    if (!resample_um.is_none()) o.resample_um = check_positive(resample_um.cast<double>(), "resample_um");
    o.periodic = parse_periodic_method(periodic, "periodic");
    return o;
}

// The grid of a heightfield as it is stored (row i, column j; no transposition: the square
// texels make the axes interchangeable, and crop indices stay the heightfield's own).
MeasuredSurface surface_of(const Heightfield& hf) {
    MeasuredSurface s;
    s.rows = hf.rows();
    s.cols = hf.cols();
    s.dx_um = s.dy_um = hf.texel_um();
    s.heights_um = heights_um(hf);
    return s;
}

}  // namespace

void bind_conditioning(py::module_& m) {
    m.def(
        "condition_surface",
        [](const py::object& heights_um, double dx_um, const py::object& dy_um, const std::string& fill,
           const std::string& detrend, const py::object& crop, const py::object& resample_um,
           const std::string& periodic) {
            const py::array a = float_array(heights_um, "heights_um");
            if (a.ndim() != 2) throw py::value_error("heights_um has shape " + shape_string(a) + "; expected 2-D");
            MeasuredSurface s;
            s.rows = static_cast<int>(a.shape(0));
            s.cols = static_cast<int>(a.shape(1));
            s.dx_um = check_positive(dx_um, "dx_um");
            s.dy_um = dy_um.is_none() ? s.dx_um : check_positive(dy_um.cast<double>(), "dy_um");
            s.heights_um = to_doubles(a, "heights_um", false);
            s.format = "npy";
            const ConditioningOptions o = conditioning_options(fill, detrend, crop, resample_um, periodic);
            ConditioningReport report;
            MeasuredSurface out;
            {
                py::gil_scoped_release release;
                out = condition(s, o, &report);
            }
            py::dict d;
            d["heights_um"] = owning_array(std::move(out.heights_um), {out.rows, out.cols});
            d["dx_um"] = out.dx_um;
            d["dy_um"] = out.dy_um;
            d["steps"] = report.steps;
            d["seam_ratio_before"] = report.seam_ratio_before < 0 ? py::object(py::none()) : py::float_(report.seam_ratio_before);
            d["seam_ratio_after"] = report.seam_ratio_after < 0 ? py::object(py::none()) : py::float_(report.seam_ratio_after);
            return d;
        },
        "heights_um"_a, "dx_um"_a, "dy_um"_a = py::none(), "fill"_a = "none", "detrend"_a = "none",
        "crop"_a = py::none(), "resample_um"_a = py::none(), "periodic"_a = "none", R"doc(
Conditions measured heights (as `wavebrdf convert`): a 2-D array in um, NaN where unmeasured,
axis 0 along y with spacing dy_um (default dx_um), axis 1 along x with spacing dx_um. In order:
crop (r0, c0, rows, cols), detrend ('none', 'mean', 'plane', 'poly:N'), fill ('none' refuses
NaN where a later step needs every point; 'nearest', 'harmonic', 'mean'), resample_um (square
texels, bilinear), periodic ('none', 'smooth' periodic-plus-smooth, 'mirror'). Returns a dict:
heights_um, dx_um, dy_um, steps (one line each) and the seam's slope ratio before and after the
periodic step (None without one). ValueError naming the argument on bad input.
)doc");


    auto cls = py::reinterpret_borrow<py::class_<Heightfield>>(m.attr("Heightfield"));
    cls.def(
        "conditioned",
        [](const Heightfield& hf, const std::string& detrend, const py::object& crop, const py::object& resample_um,
           const std::string& periodic) {
            const ConditioningOptions o = conditioning_options("none", detrend, crop, resample_um, periodic);
            MeasuredSurface out;
            {
                py::gil_scoped_release release;
                out = condition(surface_of(hf), o);
            }
            std::vector<double> values = std::move(out.heights_um);
            const double scale = hf.vscale() != 0.0 ? hf.vscale() : 1.0;
            for (double& x : values) x /= scale * out.dx_um;
            return Heightfield(out.rows, out.cols, std::move(values), out.dx_um, scale);
        },
        "detrend"_a = "none", "crop"_a = py::none(), "resample_um"_a = py::none(), "periodic"_a = "none", R"doc(
This heightfield conditioned (as `wavebrdf convert`; crop indices are (i0, j0, rows, cols) of
this heightfield), in order: crop, detrend ('none', 'mean', 'plane', 'poly:N'), resample_um
(bilinear) and periodic ('none', 'smooth', 'mirror'). Heights in um are kept; the vertical scale
is kept (1 for a flat vscale 0).
)doc");
}

}  // namespace wavebrdf::python
