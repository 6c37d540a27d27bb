// Surface metrology (surface_stats.h): the ISO 25178-2 parameters, PSD and ACF of a
// heightfield, and Heightfield.from_um.
#include "common.h"
#include "wavebrdf/surface_stats.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::dict profile_dict(const RadialProfile& p, const char* r_name, const char* v_name) {
    py::dict d;
    d[r_name] = owning_array(std::vector<double>(p.r), {static_cast<py::ssize_t>(p.r.size())});
    d[v_name] = owning_array(std::vector<double>(p.value), {static_cast<py::ssize_t>(p.value.size())});
    d["count"] = owning_array(std::vector<int>(p.count), {static_cast<py::ssize_t>(p.count.size())});
    return d;
}

}  // namespace

void bind_surface(py::module_& m) {
    m.def(
        "surface_stats",
        [](const py::object& heightfield) {
            const Heightfield hf = heightfield_argument(heightfield, "heightfield", 1.0, 1.0, false);
            SurfaceParameters p;
            {
                py::gil_scoped_release release;
                p = surface_parameters(hf);
            }
            py::dict d;
            for (const auto& [name, value] : parameter_list(p)) d[py::str(name)] = value;
            d["acf_decayed_everywhere"] = p.acf_decayed_everywhere;
            return d;
        },
        "heightfield"_a, R"doc(
The ISO 25178-2 areal parameters of a heightfield (a Heightfield, an EXR path or a 2-D array of
heights in texel units with texel 1 um), over the whole tile, the mean removed: a dict with
Sa, Sq, Sp, Sv, Sz (um), Ssk, Sku, Sdq, Sdr (%), Sal (um), Str, Std (degrees, the lay's
direction from x towards y, x along the heightfield's rows) and acf_decayed_everywhere (False:
Str is an upper bound). Definitions: docs/surfaces.md, "Parameters". ValueError for a tile
smaller than 2 x 2.
)doc");
    m.def(
        "surface_psd",
        [](const py::object& heightfield) {
            const Heightfield hf = heightfield_argument(heightfield, "heightfield", 1.0, 1.0, false);
            Spectrum2d s;
            RadialProfile r;
            {
                py::gil_scoped_release release;
                const HeightGrid g = height_grid(hf);
                s = power_spectrum_2d(g);
                r = radial_power_spectrum(g);
            }
            py::dict d = profile_dict(r, "q_per_um", "psd_um4");
            d["psd_2d_um4"] = owning_array(std::move(s.values), {s.rows, s.cols});
            d["dq_x_per_um"] = s.step_x;
            d["dq_y_per_um"] = s.step_y;
            return d;
        },
        "heightfield"_a, R"doc(
The power spectral density of a heightfield (periodic, no window): a dict with the radial
average q_per_um (rad/um), psd_um4 (um^4) and count (FFT bins per ring), and the 2-D PSD
psd_2d_um4 (image frame: axis 0 along y, axis 1 along x, zero frequency at the centre) with its
steps dq_x_per_um, dq_y_per_um. sum(psd_2d_um4) * dq_x * dq_y / (2 pi)^2 = Sq^2.
)doc");
    m.def(
        "surface_acf",
        [](const py::object& heightfield) {
            const Heightfield hf = heightfield_argument(heightfield, "heightfield", 1.0, 1.0, false);
            Spectrum2d s;
            RadialProfile r;
            {
                py::gil_scoped_release release;
                const HeightGrid g = height_grid(hf);
                s = autocorrelation_2d(g);
                r = radial_autocorrelation(g);
            }
            py::dict d = profile_dict(r, "lag_um", "acf");
            d["acf_2d"] = owning_array(std::move(s.values), {s.rows, s.cols});
            d["step_x_um"] = s.step_x;
            d["step_y_um"] = s.step_y;
            return d;
        },
        "heightfield"_a, R"doc(
The areal autocorrelation function (ISO 25178-2; not wrapped, normalised by the overlapping
points and to 1 at zero lag): a dict with the radial average lag_um, acf, count, and the 2-D
ACF acf_2d ((2 rows - 1) x (2 cols - 1) in the image frame, zero lag at the centre) with its
lag steps step_x_um, step_y_um.
)doc");
    auto cls = py::reinterpret_borrow<py::class_<Heightfield>>(m.attr("Heightfield"));
    cls.def_static(
        "from_um",
        [](const py::object& heights_um, double texel_um, double vscale) {
            const double w = check_positive(texel_um, "texel_um");
            const double v = check_finite(vscale, "vscale");
            if (v == 0.0) throw py::value_error("vscale 0 cannot hold heights in um; expected a non-zero scale");
            const py::array a = float_array(heights_um, "heights_um");
            if (a.ndim() != 2) throw py::value_error("heights_um has shape " + shape_string(a) + "; expected 2-D");
            std::vector<double> values = to_doubles(a, "heights_um");
            for (double& x : values) x /= v * w;
            return Heightfield(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), std::move(values), w, v);
        },
        "heights_um"_a, "texel_um"_a, "vscale"_a = 1.0, R"doc(
A Heightfield from heights in um (2-D, finite; axis 0 along x as Heightfield(values)) on square
texels of texel_um: values heights_um / (vscale * texel_um). For NaN or non-square spacing,
wavebrdf.condition_surface first.
)doc");
}

}  // namespace wavebrdf::python
