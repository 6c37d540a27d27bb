// The Query (model.h): one BRDF query as render and gradient (brdf.cpp) take it.
#include "common.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

std::string query_repr(const PyQuery& q) {
    std::string s = "Query(x_um=" + format_number(q.query.x_um) + ", y_um=" + format_number(q.query.y_um) +
                    ", sigma_p_um=" + format_number(q.query.sigma_p_um) + ", light=(" +
                    format_number(q.query.omega_i[0]) + ", " + format_number(q.query.omega_i[1]) + "), model='" +
                    to_string(q.query.model) + "', ";
    if (!q.spectral) return s + "lambda_um=" + format_number(q.lambdas_um[0]) + ")";
    s += "spectral=[";
    for (std::size_t i = 0; i < q.lambdas_um.size(); ++i) s += (i ? ", " : "") + format_number(q.lambdas_um[i]);
    return s + "])";
}

}  // namespace

void bind_model(py::module_& m) {
    py::class_<PyQuery>(m, "Query", R"doc(
One BRDF query: a Gaussian footprint on the surface, a light direction, a diffraction model
and the wavelength(s).

Query(x_um=0.0, y_um=0.0, sigma_p_um=10.0, light=(0.0, 0.0), model='OHS', lambda_um=None,
      spectral=None)
    x_um, y_um   footprint centre in um (x along rows, y along columns); finite, periodic
    sigma_p_um   footprint standard deviation in um, 1e-6 to 1e6 (and <= 10 tile periods)
    light        projected direction towards the light (wx, wy), wx^2 + wy^2 < 1
    model        'OHS', 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
    lambda_um    one wavelength in um (0.01 to 1000); default 0.5 when spectral is None
    spectral     N samples over 0.36-0.83 um (1...256) or a list of wavelengths in um, to
                 linear sRGB (CIE 1931); excludes lambda_um
Position, sigma_p, light and model can be set later (validated); the wavelengths are fixed.
)doc")
        .def(py::init(&make_query), "x_um"_a = 0.0, "y_um"_a = 0.0, "sigma_p_um"_a = 10.0,
             "light"_a = py::make_tuple(0.0, 0.0), "model"_a = "OHS", "lambda_um"_a = py::none(),
             "spectral"_a = py::none())
        .def_property(
            "x_um", [](const PyQuery& q) { return q.query.x_um; },
            [](PyQuery& q, double v) { q.query.x_um = check_finite(v, "x_um"); })
        .def_property(
            "y_um", [](const PyQuery& q) { return q.query.y_um; },
            [](PyQuery& q, double v) { q.query.y_um = check_finite(v, "y_um"); })
        .def_property(
            "sigma_p_um", [](const PyQuery& q) { return q.query.sigma_p_um; },
            [](PyQuery& q, double v) { q.query.sigma_p_um = check_positive(v, "sigma_p_um"); })
        .def_property(
            "light", [](const PyQuery& q) { return py::make_tuple(q.query.omega_i[0], q.query.omega_i[1]); },
            [](PyQuery& q, py::object v) { q.query.omega_i = light_direction(v); })
        .def_property(
            "model", [](const PyQuery& q) { return std::string(to_string(q.query.model)); },
            [](PyQuery& q, const std::string& v) { q.query.model = model_from(v); })
        .def_property_readonly(
            "lambdas_um", [](const PyQuery& q) { return q.lambdas_um; }, "the wavelengths in um")
        .def_property_readonly(
            "spectral", [](const PyQuery& q) { return q.spectral; },
            "True when the slice is spectral (RGB through CIE 1931)")
        .def(
            "kwargs",
            [](const PyQuery& q) {
                py::dict d("x_um"_a = q.query.x_um, "y_um"_a = q.query.y_um, "sigma_p_um"_a = q.query.sigma_p_um,
                           "light"_a = py::make_tuple(q.query.omega_i[0], q.query.omega_i[1]),
                           "model"_a = to_string(q.query.model));
                if (q.spectral)
                    d["spectral"] = q.lambdas_um;
                else
                    d["lambda_um"] = q.lambdas_um[0];
                return d;
            },
            "The query as keyword arguments of render_slice and slice_gradient.")
        .def("copy", [](const PyQuery& q) { return PyQuery(q); })
        .def("__copy__", [](const PyQuery& q) { return PyQuery(q); })
        .def(
            "__deepcopy__", [](const PyQuery& q, py::dict) { return PyQuery(q); }, "memo"_a)
        .def("__repr__", &query_repr);
}

}  // namespace wavebrdf::python
