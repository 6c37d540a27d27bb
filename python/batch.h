#pragma once
// render_slice and slice_gradient over NumPy leading batch axes (batch.cpp), through the
// library's batch API (wavebrdf/batch.h). brdf.cpp sends a single query (2-D heights, one
// light pair, scalar x_um and y_um) down its own path, everything else here.
#include "common.h"

namespace wavebrdf::python {

// True when the arguments are one query as before batches: heights 2-D (or not an array of
// at least 3 dimensions), light of at most one dimension, x_um and y_um scalars.
bool single_query(py::handle heights, py::handle x_um, py::handle y_um, py::handle light);

// The slices (batch…, n, n, 3) of the broadcast batch; dtype of heights. With `comm` (not
// null): the items split over its ranks (render_batch_over_ranks), the array on rank 0, None on
// the others.
py::object render_slice_batch(py::handle heights, int resolution, double texel_um, double vscale, py::handle x_um,
                              py::handle y_um, double sigma_p_um, const py::object& lambda_um,
                              const py::object& spectral, py::handle light, const std::string& model,
                              const RenderOptions& options, const Communicator* comm = nullptr);

// d(sum(weights * slices))/d(heights): shaped and typed like heights; weights (batch…, n, n, 3).
py::array slice_gradient_batch(py::handle heights, py::handle weights, int resolution, double texel_um, double vscale,
                               py::handle x_um, py::handle y_um, double sigma_p_um, const py::object& lambda_um,
                               const py::object& spectral, py::handle light, const std::string& model,
                               const RenderOptions& options);

// The weights of slice_gradient (and the torch plan's adjoint): `w` holds (…, n, n, 3) values,
// read as doubles. Pixels outside the unit disk are not rendered, so their weights are ignored
// (set to 0), whatever they hold: a loss such as (sqrt(I) - sqrt(R))^2 has an infinite or NaN
// derivative where I = 0 there. Inside the disk every weight must be finite (ValueError naming
// its index otherwise).
std::vector<double> slice_weights(const py::array& w, int n, const char* name);

// The docstring paragraph on batch axes and broadcasting (render_slice, slice_gradient).
extern const char* const kBatchDoc;

}  // namespace wavebrdf::python
