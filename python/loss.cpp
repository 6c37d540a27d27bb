// Losses between slices, their gradients, and the thesis's reporting metrics (loss.h).
#include "common.h"
#include "wavebrdf/loss.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

// Estimate and reference as the library's flat slices: same shape; channels = the last extent
// of an (n, n, c) array, 1 otherwise.
struct Pair {
    std::vector<double> estimate, reference;
    int channels;
    std::vector<py::ssize_t> shape;
};

Pair slice_pair(py::handle estimate, py::handle reference, const char* second = "reference") {
    const py::array e = float_array(estimate, "estimate");
    const py::array r = float_array(reference, second);
    if (e.size() == 0) throw py::value_error("estimate is empty; expected at least one value");
    if (shape_string(e) != shape_string(r))
        throw py::value_error(std::string(second) + " has shape " + shape_string(r) + "; expected the estimate's " +
                              shape_string(e));
    Pair p{to_doubles(e, "estimate"), to_doubles(r, second), e.ndim() == 3 ? static_cast<int>(e.shape(2)) : 1,
           std::vector<py::ssize_t>(e.shape(), e.shape() + e.ndim())};
    return p;
}

const char* kShapes =
    "estimate, reference: float arrays of the same shape, finite; an (n, n, c) array has c\n"
    "channels per pixel, any other shape one. The loss is a mean over pixels of a sum over channels.";

}  // namespace

void bind_loss(py::module_& m) {
    py::class_<Loss>(m, "Loss",
                     (std::string(R"doc(
A loss between an estimated and a reference slice (the thesis's Definition 3.2):
    'cmsle:EPS'  1/|P| sum_p sum_c (log(I + EPS) - log(R + EPS))^2, EPS > 0 ('cmsle' = 'cmsle:1')
    'mse'        1/|P| sum_p sum_c (I - R)^2
    'amplitude'  1/|P| sum_p sum_c (sqrt(I) - sqrt(R))^2
    'poisson:N'  1/|P| sum_p sum_c 2 (k log(k / mu) - (k - mu)), k = s R, mu = s I, s = N / sum(R):
                 the Poisson deviance of a slice measured with N photons (N > 0)
Negative values are clamped to 0 for the log and square root (and get gradient 0).
Loss(spec='cmsle:1'); loss(estimate, reference) -> float;
loss.value_and_gradient(estimate, reference) -> (float, dloss/destimate shaped like estimate).
)doc") + kShapes)
                         .c_str())
        .def(py::init([](const std::string& spec) { return parse_loss(spec); }), "spec"_a = "cmsle:1")
        .def_property_readonly(
            "kind",
            [](const Loss& l) {
                const std::string spec = to_string(l);
                return spec.substr(0, spec.find(':'));
            },
            "'cmsle', 'mse', 'amplitude' or 'poisson'")
        .def_property_readonly(
            "epsilon", [](const Loss& l) { return l.epsilon; }, "CMSLE's epsilon")
        .def_property_readonly(
            "photons", [](const Loss& l) { return l.photons; }, "Poisson's photons per slice N")
        .def(
            "__call__",
            [](const Loss& l, py::handle e, py::handle r) {
                const Pair p = slice_pair(e, r);
                return loss_value(l, p.estimate, p.reference, p.channels);
            },
            "estimate"_a, "reference"_a)
        .def(
            "value_and_gradient",
            [](const Loss& l, py::handle e, py::handle r) {
                const Pair p = slice_pair(e, r);
                std::vector<double> g;
                const double v = loss_value(l, p.estimate, p.reference, p.channels, &g);
                return py::make_tuple(v, owning_array(std::move(g), p.shape));
            },
            "estimate"_a, "reference"_a)
        .def("__str__", [](const Loss& l) { return to_string(l); })
        .def("__repr__", [](const Loss& l) { return "Loss('" + to_string(l) + "')"; });

    m.def(
        "cmsle",
        [](py::handle e, py::handle r, double epsilon) {
            const Pair p = slice_pair(e, r);
            return loss_value(Loss{LossKind::CMSLE, check_positive(epsilon, "epsilon")}, p.estimate, p.reference,
                              p.channels);
        },
        "estimate"_a, "reference"_a, "epsilon"_a = 1.0,
        (std::string("Corrected mean squared log error with epsilon > 0 (see Loss).\n") + kShapes).c_str());
    m.def(
        "mse",
        [](py::handle e, py::handle r) {
            const Pair p = slice_pair(e, r);
            return loss_value(Loss{LossKind::MSE, 1.0}, p.estimate, p.reference, p.channels);
        },
        "estimate"_a, "reference"_a, (std::string("Mean squared error (see Loss).\n") + kShapes).c_str());
    m.def(
        "amplitude",
        [](py::handle e, py::handle r) {
            const Pair p = slice_pair(e, r);
            return loss_value(Loss{LossKind::Amplitude, 1.0}, p.estimate, p.reference, p.channels);
        },
        "estimate"_a, "reference"_a,
        (std::string("Squared error of amplitudes sqrt(I) (see Loss).\n") + kShapes).c_str());

    const char* metric_doc =
        "Reporting metric of the thesis (Fig. 5.3), mean over pixels and channels of\n"
        "(T(I) - T(R))^2 with T(x) = x / (1 + x) (rgb_mse) or (x / (1 + x))^(1/2.2)\n"
        "(rgb_gamma_mse). (n, n, 3) RGB or (n, n) / (n, n, 1) grey slices.";
    m.def(
        "rgb_mse",
        [](py::handle e, py::handle r) {
            const Pair p = slice_pair(e, r);
            return rgb_mse(p.estimate, p.reference, p.channels);
        },
        "estimate"_a, "reference"_a, metric_doc);
    m.def(
        "rgb_gamma_mse",
        [](py::handle e, py::handle r) {
            const Pair p = slice_pair(e, r);
            return rgb_gamma_mse(p.estimate, p.reference, p.channels);
        },
        "estimate"_a, "reference"_a, metric_doc);
    m.def(
        "height_mse",
        [](py::handle e, py::handle t) {
            const Pair p = slice_pair(e, t, "truth");
            return height_mse(p.estimate, p.reference);
        },
        "estimate"_a, "truth"_a,
        "Mean squared difference of two heightfields (same shape) after removing each one's mean,\n"
        "which no slice can see; in the squared units of the inputs.");
}

}  // namespace wavebrdf::python
