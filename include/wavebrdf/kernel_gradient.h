#pragma once
// Per-kernel gradients and their chain to the raw heights: the building blocks every engine's
// adjoint (src/forward/) fills and the gradient entry points (adjoint.h, slice_plan.h) finish.
// Gradients accumulate, as adjoint.h states.
#include <vector>

#include "wavebrdf/gabor.h"
#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// ∂L/∂H_k (per µm), ∂L/∂s_kx, ∂L/∂s_ky for every footprint kernel, and ∂L/∂ln c_k, the
// gradient with respect to the log of the kernel's window weight c_k (every term of kernel k
// is linear in c_k): the footprint centre's gradient is Σ_k log_weight[k] · δ_k / σ_p²
// (SlicePlan::position_gradient). Filled by the slice plans' adjoints; scatter_to_heights
// ignores it.
struct KernelGradient {
    std::vector<double> height, slope_x, slope_y;
    std::vector<double> log_weight;
};

// Chains per-kernel gradients to the raw heights: H = v·w·h[i][j] and the central-difference
// slope stencil, which scatters ∂L/∂s to the four neighbours. Adds into `gradient` (rows·cols;
// resized and zeroed when empty; std::invalid_argument for another size).
void scatter_to_heights(const Heightfield& heightfield, const FootprintKernels& kernels,
                        const KernelGradient& kernel_gradient, std::vector<double>& gradient);

}  // namespace wavebrdf
