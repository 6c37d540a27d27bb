#pragma once
// Internal: the chain to the raw heights on a plan's own grid (no Heightfield at hand), and the
// gradient convention's size check (adjoint.h), for the plans and the entry points.
#include <cstddef>
#include <vector>

#include "wavebrdf/kernel_gradient.h"

namespace wavebrdf::detail {

// Adds the per-kernel gradient, chained to the heights of a rows × cols periodic grid, into
// `gradient` (already prepared).
void scatter_to_heights(int rows, int cols, double texel_um, double vscale, const FootprintKernels& kernels,
                        const KernelGradient& kernel_gradient, std::vector<double>& gradient);
// Resizes an empty gradient to `cells` zeros; std::invalid_argument for another size.
void prepare_gradient(std::vector<double>& gradient, std::size_t cells);

}  // namespace wavebrdf::detail
