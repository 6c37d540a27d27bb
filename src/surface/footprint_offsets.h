#pragma once
// Internal: where footprint_kernels' (wavebrdf/gabor.h) kernels are, without their heights,
// slopes and weights: texel (row, col) and offset δ (µm), the same values in the same order.
// The field operators (recover_field.cpp) need only these, on a grid ~80 samples per texel.
#include <cstddef>
#include <vector>

#include "wavebrdf/heightfield.h"

namespace wavebrdf::detail {

struct FootprintOffsets {
    std::vector<int> row, col;
    std::vector<double> dx_um, dy_um;
    double sigma_um = 0.0;  // kernel σ = w / 2
    std::size_t size() const { return row.size(); }
};

// As footprint_kernels (the same checks and exceptions).
FootprintOffsets footprint_offsets(const Heightfield& heightfield, double x_um, double y_um, double sigma_p_um);

}  // namespace wavebrdf::detail
