#pragma once
// Analytic lobe tables (lobe.cpp) and the table dict they share with table.cpp.
#include "common.h"

namespace wavebrdf {
struct BrdfTable;
}

namespace wavebrdf::python {

void bind_lobe(py::module_& m);

// A table (table.h) as the dict wavebrdf/table.py's BrdfTable wraps (table.cpp).
py::dict table_dict(BrdfTable&& table);

}  // namespace wavebrdf::python
