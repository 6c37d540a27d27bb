// Optimisers: Adam and L-BFGS (optim.h).
#include <cstring>

#include "common.h"
#include "wavebrdf/optim.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

// x must be updated in place: a writable, C-contiguous float64 array of `size` values.
py::array_t<double> inplace_argument(py::handle x, std::size_t size) {
    if (!py::isinstance<py::array>(x))
        throw py::value_error("x is not a NumPy array; expected a writable float64 array to update in place");
    py::array a = py::reinterpret_borrow<py::array>(x);
    if (!a.dtype().equal(py::dtype::of<double>()))
        throw py::value_error("x has dtype " + std::string(py::str(a.dtype())) +
                              "; expected float64 (updated in place)");
    if (!(a.flags() & py::array::c_style) || !a.writeable())
        throw py::value_error("x is not a writable C-contiguous array; expected one (it is updated in place)");
    if (static_cast<std::size_t>(a.size()) != size)
        throw py::value_error("x has " + std::to_string(a.size()) + " values; expected the optimiser's size " +
                              std::to_string(size));
    return py::array_t<double>(a);
}

std::vector<double> doubles_of(const py::array_t<double>& a) {
    return std::vector<double>(a.data(), a.data() + a.size());
}

}  // namespace

void bind_optim(py::module_& m) {
    py::class_<Adam>(m, "Adam", R"doc(
Adam (Kingma and Ba 2015) with an exponential learning-rate decay per epoch:
lr_epoch = lr * exp(-decay * epoch). Defaults are the thesis's.

Adam(size, lr=0.01, beta1=0.9, beta2=0.99, epsilon=1e-8, decay=0.005)
    size    number of parameters (e.g. rows * cols heights), >= 1
    lr > 0; beta1, beta2 in [0, 1); epsilon > 0; decay >= 0 (per epoch)
)doc")
        .def(py::init([](std::size_t size, double lr, double beta1, double beta2, double epsilon, double decay) {
                 if (size < 1) bad_argument("size", std::to_string(size), "at least 1 parameter");
                 return Adam(size, AdamOptions{lr, beta1, beta2, epsilon, decay});
             }),
             "size"_a, "lr"_a = 0.01, "beta1"_a = 0.9, "beta2"_a = 0.99, "epsilon"_a = 1e-8, "decay"_a = 0.005)
        .def(
            "step",
            [](Adam& adam, py::handle x, py::handle gradient, int epoch) {
                const std::size_t size = adam.state().m.size();
                py::array_t<double> xa = inplace_argument(x, size);
                const py::array g = float_array(gradient, "gradient");
                if (static_cast<std::size_t>(g.size()) != size)
                    throw py::value_error("gradient has " + std::to_string(g.size()) + " values; expected " +
                                          std::to_string(size));
                if (epoch < 0) bad_argument("epoch", std::to_string(epoch), "an epoch >= 0");
                std::vector<double> v = doubles_of(xa);
                adam.step(v, to_doubles(g, "gradient"), epoch);
                std::memcpy(xa.mutable_data(), v.data(), v.size() * sizeof(double));
                return xa;
            },
            "x"_a, "gradient"_a, "epoch"_a = 0, R"doc(
One update of x (a writable C-contiguous float64 array of `size` values, any shape, changed in
place and returned) against `gradient` (same number of finite values), at the learning rate
of `epoch` (0-based).
)doc")
        .def("learning_rate", &Adam::learning_rate, "epoch"_a, "lr * exp(-decay * epoch)")
        .def_property_readonly("size", [](const Adam& a) { return a.state().m.size(); })
        .def_property_readonly(
            "steps", [](const Adam& a) { return a.state().steps; }, "steps taken (bias correction)")
        .def_property_readonly(
            "m",
            [](const Adam& a) {
                return owning_array(std::vector<double>(a.state().m), {static_cast<py::ssize_t>(a.state().m.size())});
            },
            "first moment (a copy)")
        .def_property_readonly(
            "v",
            [](const Adam& a) {
                return owning_array(std::vector<double>(a.state().v), {static_cast<py::ssize_t>(a.state().v.size())});
            },
            "second moment (a copy)")
        .def(
            "set_state",
            [](Adam& a, py::handle m_, py::handle v_, long long steps) {
                Adam::State s;
                s.m = to_doubles(float_array(m_, "m"), "m");
                s.v = to_doubles(float_array(v_, "v"), "v");
                s.steps = steps;
                a.set_state(s);
            },
            "m"_a, "v"_a, "steps"_a, "Restores moments and step count (e.g. from a checkpoint).");

    py::class_<LbfgsResult>(m, "LbfgsResult", "The outcome of lbfgs_minimize.")
        .def_readonly("iterations", &LbfgsResult::iterations, "accepted steps")
        .def_readonly("evaluations", &LbfgsResult::evaluations, "objective calls, the first included")
        .def_readonly("value", &LbfgsResult::value, "objective at the returned x")
        .def_readonly("converged", &LbfgsResult::converged, "max |gradient| <= gradient_tolerance")
        .def("__repr__", [](const LbfgsResult& r) {
            return "LbfgsResult(iterations=" + std::to_string(r.iterations) +
                   ", evaluations=" + std::to_string(r.evaluations) + ", value=" + format_number(r.value) +
                   ", converged=" + (r.converged ? "True" : "False") + ")";
        });

    m.def(
        "lbfgs_minimize",
        [](py::function objective, py::handle x0, int history, int max_iterations, double gradient_tolerance,
           int max_line_search, py::object callback) {
            const py::array a = float_array(x0, "x0");
            if (a.size() == 0) throw py::value_error("x0 is empty; expected at least one parameter");
            const std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
            std::vector<double> x = to_doubles(a, "x0");
            const auto f = [&](const std::vector<double>& at, std::vector<double>& gradient) {
                py::object out = objective(owning_array(std::vector<double>(at), shape));
                const bool is_pair = (py::isinstance<py::tuple>(out) || py::isinstance<py::list>(out)) &&
                                     py::len(out) == 2;
                if (!is_pair)
                    throw py::value_error("objective returned " + std::string(py::repr(out)) +
                                          "; expected a pair (value, gradient)");
                const py::sequence pair = py::reinterpret_borrow<py::sequence>(out);
                const py::array g = float_array(pair[1], "gradient");
                if (static_cast<std::size_t>(g.size()) != at.size())
                    throw py::value_error("objective's gradient has " + std::to_string(g.size()) +
                                          " values; expected " + std::to_string(at.size()));
                // Not checked for finiteness here: L-BFGS treats a non-finite trial as a failed step.
                gradient = to_doubles(g, "gradient", false);
                if (!py::isinstance<py::float_>(pair[0]) && !py::isinstance<py::int_>(pair[0]) &&
                    !py::isinstance(pair[0], py::module_::import("numpy").attr("number")))
                    throw py::value_error("objective returned the value " + std::string(py::repr(pair[0])) +
                                          "; expected a number");
                return py::float_(pair[0]).cast<double>();
            };
            std::function<bool(int, double)> on_iteration;
            if (!callback.is_none())
                on_iteration = [&](int iteration, double value) {
                    py::object r = callback(iteration, value);
                    return r.is_none() || r.cast<bool>();
                };
            LbfgsOptions options{history, max_iterations, gradient_tolerance, max_line_search};
            const LbfgsResult result = lbfgs_minimize(f, x, options, on_iteration);
            return py::make_tuple(owning_array(std::move(x), shape), result);
        },
        "objective"_a, "x0"_a, py::kw_only(), "history"_a = 10, "max_iterations"_a = 100,
        "gradient_tolerance"_a = 1e-10, "max_line_search"_a = 20, "callback"_a = py::none(), R"doc(
Minimises objective(x) -> (value, gradient) from x0 by L-BFGS with a backtracking (Armijo)
line search (Nocedal and Wright, Algorithms 7.4, 7.5, 3.1). x is passed as a new float64 array
shaped like x0; gradient: any float array with as many values. Options: history >= 1 pairs,
max_iterations >= 0, gradient_tolerance >= 0 (stop when max |g| <= it), max_line_search >= 1
trials. callback(iteration, value), after each accepted step, may return False to stop.
Returns (x, LbfgsResult). ValueError when f or its gradient at x0 is not finite.
)doc");
}

}  // namespace wavebrdf::python
