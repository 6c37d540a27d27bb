#pragma once
// The Python GaborRep: a heightfield's footprint kernels with the geometry needed to map them
// back to texels (shared by gabor.cpp and brdf.cpp, which renders from them).
#include <vector>

#include "wavebrdf/gabor.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf::python {

struct GaborRep {
    GaborRep(const Heightfield& heightfield, double x_um, double y_um, double sigma_p_um);
    FootprintKernels kernels;
    int rows, cols;
    double texel_um, vscale;
    double x_um, y_um, sigma_p_um;  // the footprint the kernels were gathered for
};

// An RGB slice (n² · 3) from the kernels, as render_rgb (brdf.h) computes it from a heightfield.
template <typename Float>
std::vector<Float> render_kernels_rgb(const GaborRep& rep, const Query& query, const std::vector<double>& lambdas_um,
                                      int resolution);

}  // namespace wavebrdf::python
