#pragma once
// Arguments shared by observation.cpp and invert.cpp.
#include <vector>

#include "common.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::python {

// A Loss object or its spec string ("cmsle:EPS", "mse", "amplitude").
Loss loss_argument(const py::object& loss);
// One Observation or a non-empty list of them.
std::vector<Observation> observations_argument(const py::object& observations);
// A slice of `o`'s layout as (n, n) or (n, n, 3) float64.
py::array observation_array(std::vector<double>&& values, const Observation& o);

}  // namespace wavebrdf::python
