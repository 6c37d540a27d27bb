#pragma once
// A plate of palette designs showing a picture (design_plate.h) for Python.
#include "common.h"

namespace wavebrdf::python {

void bind_design_plate(py::module_& m);

}  // namespace wavebrdf::python
