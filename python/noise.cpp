// Simulated measurement noise (noise.h): add_noise.
#include <vector>

#include "common.h"
#include "observation_arg.h"
#include "recovery_args.h"
#include "wavebrdf/noise.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_noise(py::module_& m) {
    m.def(
        "add_noise",
        [](const py::object& values, const py::object& noise, std::uint64_t seed) -> py::object {
            const Noise n = noise_argument(noise);
            if (py::isinstance<Observation>(values) || py::isinstance<py::list>(values) ||
                py::isinstance<py::tuple>(values)) {
                std::vector<Observation> list = observations_argument(values);
                add_noise(list, n, seed);
                return py::cast(list);
            }
            const py::array a = float_array(values, "values");
            std::vector<double> v = to_doubles(a, "values");
            for (std::size_t k = 0; k < v.size(); ++k)
                if (v[k] < 0.0)
                    throw py::value_error("values has a negative value " + format_number(v[k]) +
                                          "; expected a slice of non-negative values");
            std::vector<double> noisy = add_noise(v, n, seed);
            return owning_array(std::move(noisy), std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
        },
        "values"_a, "noise"_a, "seed"_a = 1, R"doc(
Simulated measurement noise (noise.h), deterministic in `seed`.

values  a slice (float array of non-negative values, any shape: one slice) -> a new float64
        array of that shape; or Observation(s) -> a new list with noisy references, observation
        i seeded from (seed, i)
noise   'none', 'poisson:N' (photon noise, N photons expected per slice, > 0; a slice summing to
        0 is unchanged) or 'gaussian:REL' (additive, sigma = REL x max, REL >= 0, clamped at 0)
)doc");
}

}  // namespace wavebrdf::python
