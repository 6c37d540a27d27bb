#pragma once
// Surface design (design_run.h) for Python.
#include "common.h"

namespace wavebrdf::python {

void bind_design(py::module_& m);

}  // namespace wavebrdf::python
