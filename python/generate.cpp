// Generated heightfields (generate.h) beyond Heightfield.generate (heightfield.cpp): with_height_range.

#include "common.h"
#include "wavebrdf/generate.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_generate(py::module_& m) {
    m.def(
        "with_height_range",
        [](const Heightfield& heightfield, double range_um) {
            return with_height_range(heightfield, check_positive(range_um, "range_um"));
        },
        "heightfield"_a, "range_um"_a,
        "`heightfield` scaled about its mean to the peak-to-valley height range_um (um, > 0); texel\n"
        "width and vscale unchanged. A flat heightfield is a ValueError.");
}

}  // namespace wavebrdf::python
