#pragma once
// The arguments shared by render_slice, slice_gradient (brdf.cpp) and _SlicePlan
// (slice_plan.cpp): the heights' scale, the plain functions' arguments and the slice weights.
#include <string>
#include <vector>

#include "batch.h"
#include "common.h"

namespace wavebrdf::python {

// The texel width and vertical scale for `heights`: a Heightfield's own, with texel_um and
// vscale (None when not given) allowed only when they agree with it, so that its scale is never
// silently replaced by the defaults; any other heights take the keywords' values (default 1).
struct Scale {
    double texel_um = 1.0, vscale = 1.0;
};
Scale heights_scale(py::handle heights, const py::object& texel_um, const py::object& vscale);

// The plain functions' arguments, checked in the order of the signature.
struct Plain {
    Heightfield hf;
    bool single;
    PyQuery q;
};
Plain plain_arguments(py::handle heights, double texel_um, double vscale, double x_um, double y_um, double sigma_p_um,
                      const py::object& lambda_um, const py::object& spectral, const py::object& light, int resolution,
                      const std::string& model);

// RGB slice weights (n, n, 3) as doubles.
std::vector<double> weights_argument(py::handle weights, int n);

}  // namespace wavebrdf::python
