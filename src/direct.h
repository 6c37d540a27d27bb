#pragma once
// Internal: the direct sum's per-pixel field, shared by the forward pass (render_direct.cpp)
// and its adjoint and tangent (adjoint_direct.cpp).
#include <complex>
#include <vector>

#include "wavebrdf/gabor.h"
#include "wavebrdf/model.h"

namespace wavebrdf {
class Progress;
}

namespace wavebrdf::detail {

struct DirectField {
    std::vector<std::complex<double>> field;  // I per pixel (0 outside the disk)
    std::vector<double> c1;                   // f = c1 |I|²
    std::vector<double> value;                // the slice (non-finite → 0)
    double cutoff = 0.0;                      // Gaussian exponent beyond which kernels were skipped
};

// The direct sum with the pruning bound of RenderOptions::prune_tolerance (0: none).
DirectField direct_field(const FootprintKernels& kernels, const Query& query, double lambda_um,
                         int n, double prune_tolerance, Progress* progress);

}  // namespace wavebrdf::detail
