// The chain from per-kernel gradients to the raw heights (kernel_gradient.h), shared by every
// engine's adjoint and the gradient entry points.
#include <stdexcept>
#include <string>

#include "forward/kernel_gradient_detail.h"
#include "wavebrdf/kernel_gradient.h"

namespace wavebrdf {

namespace detail {

void scatter_to_heights(int rows, int cols, double texel_um, double vscale, const FootprintKernels& k,
                        const KernelGradient& g, std::vector<double>& gradient) {
    const double v = vscale, w = texel_um;
    auto at = [&](int i, int j) -> double& {
        i = ((i % rows) + rows) % rows;
        j = ((j % cols) + cols) % cols;
        return gradient[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)];
    };
    for (std::size_t idx = 0; idx < k.size(); ++idx) {
        const int i = k.row[idx], j = k.col[idx];
        at(i, j) += v * w * g.height[idx];         // H = v·w·h[i][j]
        at(i + 1, j) += 0.5 * v * g.slope_x[idx];  // s_x = v (h[i+1][j] − h[i−1][j]) / 2
        at(i - 1, j) -= 0.5 * v * g.slope_x[idx];
        at(i, j + 1) += 0.5 * v * g.slope_y[idx];  // s_y = v (h[i][j+1] − h[i][j−1]) / 2
        at(i, j - 1) -= 0.5 * v * g.slope_y[idx];
    }
}

void prepare_gradient(std::vector<double>& gradient, std::size_t cells) {
    if (gradient.empty()) gradient.assign(cells, 0.0);
    if (gradient.size() != cells)
        throw std::invalid_argument("gradient has " + std::to_string(gradient.size()) +
                                    " entries; expected rows*cols = " + std::to_string(cells));
}

}  // namespace detail

void scatter_to_heights(const Heightfield& hf, const FootprintKernels& k, const KernelGradient& g,
                        std::vector<double>& gradient) {
    detail::prepare_gradient(gradient, hf.values().size());
    detail::scatter_to_heights(hf.rows(), hf.cols(), hf.texel_um(), hf.vscale(), k, g, gradient);
}

}  // namespace wavebrdf
