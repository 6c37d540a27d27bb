#pragma once
// Fabrication exports (fabrication.h) for Python.
#include "common.h"

namespace wavebrdf::python {

void bind_fabrication(py::module_& m);

}  // namespace wavebrdf::python
