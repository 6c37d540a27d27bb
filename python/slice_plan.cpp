// The library's SlicePlan (slice_plan.h) for wavebrdf.torch: a forward and its adjoint.
#include <memory>

#include "slice_args.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

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

}  // namespace

void bind_slice_plan(py::module_& m) {
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
}

}  // namespace wavebrdf::python
