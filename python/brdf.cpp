// Rendering slices and their vector-Jacobian products (brdf.h); the Query is model.cpp's, the
// plan slice_plan.cpp's.
//
// RGB and the adjoint: a slice is always (n, n, 3), the library's spectral mix
// (spectral_mix_weights, spectrum.h): one wavelength λ gives R = G = B = f_λ, several give
// channel c = Σ_l M[c, l] f_l (CIE 1931 → linear sRGB). The gradient is the library's
// SlicePlan adjoint, which maps W back with mix_spectral_to_rgb_adjoint:
// w_l[p] = Σ_c M[c, l] W_c[p]. This file only converts and validates.
#include <memory>

#include "batch.h"
#include "common.h"
#include "slice_args.h"
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

py::array gradient_array(std::vector<double>&& g, const Heightfield& hf, bool single) {
    if (!single) return owning_array(std::move(g), {hf.rows(), hf.cols()});
    return owning_array(std::vector<float>(g.begin(), g.end()), {hf.rows(), hf.cols()});
}

bool double_precision(const std::string& precision) {
    if (precision == "double") return true;
    if (precision == "float") return false;
    bad_argument("precision", "'" + precision + "'", "'float' or 'double'");
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
