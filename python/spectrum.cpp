// Wavelengths and colour (spectrum.h): spectral_wavelengths_um, spectral_to_srgb_weights,
// cie1931_xyz.
#include <vector>

#include "common.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_spectrum(py::module_& m) {
    m.def(
        "spectral_wavelengths_um",
        [](int count) {
            if (count < 1 || count > 256) bad_argument("count", std::to_string(count), "1 to 256");
            return spectral_wavelengths_um(count);
        },
        "count"_a, "The library's N wavelengths in um: 0.36 + (k + 1/2) * 0.47 / N (N = 8: genBrdf's samples).");
    m.def(
        "spectral_to_srgb_weights",
        [](const std::vector<double>& lambdas_um) {
            std::vector<double> w = spectral_to_srgb_weights(lambdas_um);
            const auto n = static_cast<py::ssize_t>(lambdas_um.size());
            return owning_array(std::move(w), {3, n});
        },
        "lambdas_um"_a, R"doc(
The (3, N) matrix M mapping values at the N wavelengths (um) to linear sRGB (CIE 1931,
Bradford to D65): rgb[c] = sum_l M[c, l] f(lambda_l). A constant spectrum maps to grey.
)doc");
    m.def(
        "cie1931_xyz",
        [](double lambda_um) {
            const auto v = cie1931_xyz(check_finite(lambda_um, "lambda_um"));
            return py::make_tuple(v[0], v[1], v[2]);
        },
        "lambda_um"_a, "CIE 1931 2-degree colour-matching functions (x, y, z) at a wavelength in um.");
}

}  // namespace wavebrdf::python
