// Rendering slices and their vector-Jacobian products (brdf.h, adjoint.h) and the Query.
//
// RGB and the adjoint: a slice is always (n, n, 3), the library's spectral mix
// (spectral_mix_weights, spectrum.h): one wavelength λ gives R = G = B = f_λ, several give
// channel c = Σ_l M[c, l] f_l (CIE 1931 → linear sRGB). The gradient is the library's
// SlicePlan adjoint, which maps W back with mix_spectral_to_rgb_adjoint:
// w_l[p] = Σ_c M[c, l] W_c[p]. This file only converts and validates.
#include <memory>

#include "batch.h"
#include "common.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

template <typename Float>
py::array render_rgb_array(const Heightfield& hf, const PyQuery& q, int n, const RenderOptions& options) {
    std::vector<Float> rgb;
    {
        InterruptibleRelease release;
        rgb = render_rgb<Float>(hf, q.query, q.lambdas_um, n, options);
    }
    return owning_array(std::move(rgb), {n, n, 3});
}

// ∂(Σ W · rgb)/∂h (rows·cols, texel units) for RGB weights W (n²·3): the library's SlicePlan
// adjoint (its spectral mix adjoint, see the top of this file).
template <typename Float>
std::vector<double> rgb_gradient(const Heightfield& hf, const PyQuery& q, int n, const std::vector<double>& weights,
                                 const RenderOptions& options) {
    InterruptibleRelease release;
    SlicePlan<Float> plan(hf, q.query, q.lambdas_um, n, 3, options);
    plan.forward();
    std::vector<double> gradient;
    plan.adjoint(weights, gradient);
    return gradient;
}

std::vector<double> weights_argument(py::handle weights, int n) {
    const py::array w = float_array(weights, "weights");
    check_shape(w, {n, n, 3}, "weights");
    return slice_weights(w, n, "weights");
}

py::array gradient_array(std::vector<double>&& g, const Heightfield& hf, bool single) {
    if (!single) return owning_array(std::move(g), {hf.rows(), hf.cols()});
    return owning_array(std::vector<float>(g.begin(), g.end()), {hf.rows(), hf.cols()});
}

bool double_precision(const std::string& precision) {
    if (precision == "double") return true;
    if (precision == "float") return false;
    bad_argument("precision", "'" + precision + "'", "'float' or 'double'");
}

// The texel width and vertical scale for `heights`: a Heightfield's own, with texel_um and
// vscale (None when not given) allowed only when they agree with it, so that its scale is never
// silently replaced by the defaults; any other heights take the keywords' values (default 1).
struct Scale {
    double texel_um = 1.0, vscale = 1.0;
};

Scale heights_scale(py::handle heights, const py::object& texel_um, const py::object& vscale) {
    const auto number = [](const py::object& v, const char* name) {
        try {
            return v.cast<double>();
        } catch (const py::cast_error&) {
            throw py::value_error(std::string(name) + " = " + std::string(py::repr(v)) +
                                  " is invalid; expected a number");
        }
    };
    Scale s;
    if (!py::isinstance<Heightfield>(heights)) {
        if (!texel_um.is_none()) s.texel_um = number(texel_um, "texel_um");
        if (!vscale.is_none()) s.vscale = number(vscale, "vscale");
        return s;
    }
    const auto& hf = heights.cast<const Heightfield&>();
    s = {hf.texel_um(), hf.vscale()};
    const auto agree = [&](const py::object& given, double own, const char* name) {
        if (given.is_none()) return;
        const double v = number(given, name);
        if (v != own)
            throw py::value_error(std::string(name) + " = " + format_number(v) + " conflicts with the Heightfield's " +
                                  name + " " + format_number(own) + "; expected no " + name +
                                  " keyword (the Heightfield's own is used) or the same value "
                                  "(Heightfield.with_scale gives another)");
    };
    agree(texel_um, s.texel_um, "texel_um");
    agree(vscale, s.vscale, "vscale");
    return s;
}

// The plain functions' arguments, checked in the order of the signature.
struct Plain {
    Heightfield hf;
    bool single;
    PyQuery q;
};

Plain plain_arguments(py::handle heights, double texel_um, double vscale, double x_um, double y_um, double sigma_p_um,
                      const py::object& lambda_um, const py::object& spectral, const py::object& light, int resolution,
                      const std::string& model) {
    const py::array h = float_array(heights, "heights");
    const bool single = is_float32(h);
    Heightfield hf = heightfield_from_array(h, "heights", texel_um, vscale);
    check_resolution(resolution);
    return {std::move(hf), single, make_query(x_um, y_um, sigma_p_um, light, model, lambda_um, spectral)};
}

// A differentiable plan of the plain functions' arguments (wavebrdf.torch keeps one per
// forward for its backward): float32 heights plan in single precision, float64 in double.
struct PyPlan {
    std::unique_ptr<SlicePlan<float>> single_plan;
    std::unique_ptr<SlicePlan<double>> double_plan;
    int n = 0, rows = 0, cols = 0;
};

template <typename Float>
py::array plan_forward(SlicePlan<Float>& plan, int n) {
    std::vector<Float> out;
    {
        InterruptibleRelease release;
        out = plan.forward();
    }
    return owning_array(std::move(out), {n, n, 3});
}

// A scalar x_um / y_um of a single query (a Python number or a 0-d array) as a double.
double scalar(py::handle value, const char* name) {
    try {
        return py::module_::import("numpy").attr("asarray")(value, "dtype"_a = "float64").attr("item")().cast<double>();
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
    } catch (const py::cast_error&) {}
    throw py::value_error(std::string(name) + " = " + std::string(py::repr(value)) +
                          " is invalid; expected a number or an array of numbers");
}

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

const char* kPlainArgs = R"doc(
heights     float32 or float64 array (rows, cols), or (..., rows, cols) for a batch (below),
            finite, in texel units. float64 renders
            in double precision, float32 in single (the CLI's --precision); the result has the
            same dtype.
texel_um    texel width w in um, 1e-4 to 1e4 (default: a Heightfield's own, else 1; a value
            that differs from a Heightfield's is refused)
vscale      vertical scale v, 0 or 1e-6 <= |v| <= 1e4 (default: a Heightfield's own, else 1):
            height in um = vscale * texel_um * heights
x_um, y_um  footprint centre in um along x (rows) and y (columns), any finite value (periodic;
            default 0); arrays for a batch (below)
sigma_p_um  footprint (coherence) standard deviation sigma_p in um, 1e-6 to 1e6 and at most
            10 times the longer tile period (default 10)
lambda_um   one wavelength in um, 0.01 to 1000: R = G = B = its slice. Default 0.5 when spectral is None.
spectral    N (1...256): the library's N wavelengths over 0.36-0.83 um (the CLI's --spectral N),
            or a list of wavelengths in um; mapped to linear sRGB through the CIE 1931 curves.
            Excludes lambda_um.
light       projected direction towards the light (wx, wy), wx^2 + wy^2 < 1 (default (0, 0));
            an array (..., 2) for a batch (below)
resolution  slice size n, 1...8192 (required); pixel (i, j) is omega_o =
            ((i + 1/2) / n * 2 - 1, (j + 1/2) / n * 2 - 1), zero outside the unit disk
model       'OHS' (default), 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
)doc";

// render_slice's and slice_gradient's keywords: the plain arguments, then the render options.
const std::string kPlainDoc = std::string(kPlainArgs) + kRenderOptionsDoc;

}  // namespace

void bind_brdf(py::module_& m) {
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

    m.def(
        "render_slice",
        [](py::handle heights, int resolution, const py::object& texel_arg, const py::object& vscale_arg,
           const py::object& x_um, const py::object& y_um, double sigma_p_um, const py::object& lambda_um,
           const py::object& spectral, const py::object& light, const std::string& model, const std::string& path,
           double tolerance, const py::object& comm_arg) -> py::object {
            const auto [texel_um, vscale] = heights_scale(heights, texel_arg, vscale_arg);
            const RenderOptions options = render_options(path, tolerance);
            const std::shared_ptr<const Communicator> comm = communicator_argument(comm_arg);
            if (comm || !single_query(heights, x_um, y_um, light))
                return render_slice_batch(heights, resolution, texel_um, vscale, x_um, y_um, sigma_p_um, lambda_um,
                                          spectral, light, model, options, comm.get());
            const Plain a = plain_arguments(heights, texel_um, vscale, scalar(x_um, "x_um"), scalar(y_um, "y_um"),
                                            sigma_p_um, lambda_um, spectral, light, resolution, model);
            return a.single ? render_rgb_array<float>(a.hf, a.q, resolution, options)
                            : render_rgb_array<double>(a.hf, a.q, resolution, options);
        },
        "heights"_a, py::kw_only(), "resolution"_a, "texel_um"_a = py::none(), "vscale"_a = py::none(), "x_um"_a = 0.0,
        "y_um"_a = 0.0, "sigma_p_um"_a = 10.0, "lambda_um"_a = py::none(), "spectral"_a = py::none(),
        "light"_a = py::make_tuple(0.0, 0.0), "model"_a = "OHS", "path"_a = "auto", "tolerance"_a = 1e-6,
        "comm"_a = py::none(),
        (std::string("render_slice(heights, *, resolution, texel_um=None, vscale=None, x_um=0.0, y_um=0.0, "
                     "sigma_p_um=10.0, lambda_um=None, spectral=None, light=(0, 0), model='OHS', path='auto', "
                     "tolerance=1e-06, comm=None)\n\n"
                     "One BRDF slice f_r (1/sr) of the heightfield `heights`, shape (resolution, resolution, 3),\n"
                     "linear RGB. The same as `wavebrdf render` with the same options. With batch axes\n"
                     "(below): (batch..., resolution, resolution, 3), one slice per item.\n"
                     "With comm (an mpi4py communicator; every rank makes the same call): the items are split\n"
                     "over its ranks, rank 0 gets the whole array (equal to one process's), the others None.\n") +
         kPlainDoc + kBatchDoc)
            .c_str());

    py::class_<PyPlan>(m, "_SlicePlan", R"doc(
Internal (wavebrdf.torch): the library's SlicePlan for render_slice's arguments, so that a
backward pass reuses its forward. forward() -> the (n, n, 3) slice; adjoint(weights) -> the
gradient of sum(weights * slice) (as slice_gradient, after forward()).
)doc")
        .def(py::init([](py::handle heights, int resolution, const py::object& texel_arg, const py::object& vscale_arg,
                         double x_um, double y_um, double sigma_p_um, const py::object& lambda_um,
                         const py::object& spectral, const py::object& light, const std::string& model,
                         const std::string& path, double tolerance) {
                 const auto [texel_um, vscale] = heights_scale(heights, texel_arg, vscale_arg);
                 const RenderOptions options = render_options(path, tolerance);
                 const Plain a = plain_arguments(heights, texel_um, vscale, x_um, y_um, sigma_p_um, lambda_um, spectral,
                                                 light, resolution, model);
                 PyPlan p;
                 p.n = resolution;
                 p.rows = a.hf.rows();
                 p.cols = a.hf.cols();
                 if (a.single)
                     p.single_plan = std::make_unique<SlicePlan<float>>(a.hf, a.q.query, a.q.lambdas_um, resolution, 3,
                                                                        options);
                 else
                     p.double_plan = std::make_unique<SlicePlan<double>>(a.hf, a.q.query, a.q.lambdas_um, resolution, 3,
                                                                         options);
                 return p;
             }),
             "heights"_a, py::kw_only(), "resolution"_a, "texel_um"_a = py::none(), "vscale"_a = py::none(),
             "x_um"_a = 0.0, "y_um"_a = 0.0, "sigma_p_um"_a = 10.0, "lambda_um"_a = py::none(),
             "spectral"_a = py::none(), "light"_a = py::make_tuple(0.0, 0.0), "model"_a = "OHS", "path"_a = "auto",
             "tolerance"_a = 1e-6)
        .def("forward",
             [](PyPlan& p) {
                 return p.single_plan ? plan_forward(*p.single_plan, p.n) : plan_forward(*p.double_plan, p.n);
             })
        .def(
            "adjoint",
            [](const PyPlan& p, py::handle weights) {
                const std::vector<double> w = weights_argument(weights, p.n);
                std::vector<double> g;
                {
                    InterruptibleRelease release;
                    if (p.single_plan)
                        p.single_plan->adjoint(w, g);
                    else
                        p.double_plan->adjoint(w, g);
                }
                if (!p.single_plan) return py::array(owning_array(std::move(g), {p.rows, p.cols}));
                return py::array(owning_array(std::vector<float>(g.begin(), g.end()), {p.rows, p.cols}));
            },
            "weights"_a);

    m.def(
        "slice_gradient",
        [](py::handle heights, py::handle weights, int resolution, const py::object& texel_arg,
           const py::object& vscale_arg, const py::object& x_um, const py::object& y_um, double sigma_p_um,
           const py::object& lambda_um, const py::object& spectral, const py::object& light, const std::string& model,
           const std::string& path, double tolerance) {
            const auto [texel_um, vscale] = heights_scale(heights, texel_arg, vscale_arg);
            const RenderOptions options = render_options(path, tolerance);
            if (!single_query(heights, x_um, y_um, light))
                return slice_gradient_batch(heights, weights, resolution, texel_um, vscale, x_um, y_um, sigma_p_um,
                                            lambda_um, spectral, light, model, options);
            const Plain a = plain_arguments(heights, texel_um, vscale, scalar(x_um, "x_um"), scalar(y_um, "y_um"),
                                            sigma_p_um, lambda_um, spectral, light, resolution, model);
            const std::vector<double> w = weights_argument(weights, resolution);
            std::vector<double> g = a.single ? rgb_gradient<float>(a.hf, a.q, resolution, w, options)
                                             : rgb_gradient<double>(a.hf, a.q, resolution, w, options);
            return gradient_array(std::move(g), a.hf, a.single);
        },
        "heights"_a, "weights"_a, py::kw_only(), "resolution"_a, "texel_um"_a = py::none(), "vscale"_a = py::none(),
        "x_um"_a = 0.0, "y_um"_a = 0.0, "sigma_p_um"_a = 10.0, "lambda_um"_a = py::none(), "spectral"_a = py::none(),
        "light"_a = py::make_tuple(0.0, 0.0), "model"_a = "OHS", "path"_a = "auto", "tolerance"_a = 1e-6,
        (std::string("slice_gradient(heights, weights, *, resolution, **the options of render_slice)\n\n"
                     "The gradient of sum(weights * render_slice(heights, ...)) with respect to `heights`\n"
                     "(texel units), a vector-Jacobian product by the library's adjoint: an array shaped\n"
                     "and typed like `heights`. For a loss L of the slice, weights = dL/dslice gives\n"
                     "dL/dheights.\n\n"
                     "weights     float32/float64 array (resolution, resolution, 3), or (batch..., resolution,\n"
                     "            resolution, 3) for a batch (below); one weight per pixel and channel.\n"
                     "            One wavelength: R = G = B, so the three channels' weights add.\n"
                     "            Spectral: each wavelength gets sum_c M[c, l] * weights[..., c]\n"
                     "            with M = spectral_to_srgb_weights(wavelengths). Finite inside the unit\n"
                     "            disk; pixels outside it are not rendered and their weights are ignored,\n"
                     "            whatever they hold (the inf or NaN of d/dI sqrt(I) where I = 0 included).\n") +
         kPlainDoc + kBatchDoc)
            .c_str());

    m.def(
        "render",
        [](const Heightfield& hf, const PyQuery& q, int resolution, const std::string& precision,
           const std::string& path, double tolerance) {
            check_resolution(resolution);
            const bool in_double = double_precision(precision);
            const RenderOptions options = render_options(path, tolerance);
            return in_double ? render_rgb_array<double>(hf, q, resolution, options)
                             : render_rgb_array<float>(hf, q, resolution, options);
        },
        "heightfield"_a, "query"_a, "resolution"_a = 32, "precision"_a = "double", py::kw_only(), "path"_a = "auto",
        "tolerance"_a = 1e-6,
        (std::string(R"doc(
The BRDF slice of a Heightfield for a Query: (resolution, resolution, 3) linear RGB, float64
(precision='double') or float32 ('float'); resolution 1...8192.
)doc") + kRenderOptionsDoc)
            .c_str());
    m.def(
        "render",
        [](const GaborRepresentation& rep, const PyQuery& q, int resolution, const std::string& precision,
           const std::string& path, double tolerance) {
            check_resolution(resolution);
            const bool in_double = double_precision(precision);
            const RenderOptions options = render_options(path, tolerance);
            if (in_double) {
                std::vector<double> rgb;
                {
                    InterruptibleRelease release;
                    rgb = render_rgb<double>(rep, q.query, q.lambdas_um, resolution, options);
                }
                return py::array(owning_array(std::move(rgb), {resolution, resolution, 3}));
            }
            std::vector<float> rgb;
            {
                InterruptibleRelease release;
                rgb = render_rgb<float>(rep, q.query, q.lambdas_um, resolution, options);
            }
            return py::array(owning_array(std::move(rgb), {resolution, resolution, 3}));
        },
        "gabor"_a, "query"_a, "resolution"_a = 32, "precision"_a = "double", py::kw_only(), "path"_a = "auto",
        "tolerance"_a = 1e-6,
        "The same from a GaborRep made for this query's footprint (the kernels are not gathered again); path and\n"
        "tolerance as above.");

    m.def(
        "gradient",
        [](const Heightfield& hf, const PyQuery& q, py::handle weights, const std::string& precision,
           const std::string& path, double tolerance) {
            const RenderOptions options = render_options(path, tolerance);
            const py::array wa = float_array(weights, "weights");
            if (wa.ndim() != 3 || wa.shape(0) != wa.shape(1) || wa.shape(2) != 3)
                throw py::value_error("weights has shape " + shape_string(wa) + "; expected (n, n, 3)");
            const int n = check_resolution(static_cast<int>(wa.shape(0)), "weights.shape[0]");
            const std::vector<double> w = to_doubles(wa, "weights");
            std::vector<double> g = double_precision(precision) ? rgb_gradient<double>(hf, q, n, w, options)
                                                                : rgb_gradient<float>(hf, q, n, w, options);
            return owning_array(std::move(g), {hf.rows(), hf.cols()});
        },
        "heightfield"_a, "query"_a, "weights"_a, "precision"_a = "double", py::kw_only(), "path"_a = "auto",
        "tolerance"_a = 1e-6, R"doc(
The gradient of sum(weights * render(heightfield, query, n)) with respect to the heightfield's
values (texel units): float64 (rows, cols). weights: (n, n, 3), e.g. dL/dslice of a loss
(Loss.value_and_gradient); see slice_gradient for how channels map to wavelengths. path and
tolerance as render's.
)doc");
}

}  // namespace wavebrdf::python
