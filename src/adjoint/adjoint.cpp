// Entry points of the gradients: forward once, weights from the caller, backward by the
// adjoint of the path that rendered, then the chain to the raw heights.
#include <cmath>
#include <stdexcept>
#include <string>

#include "forward/direct.h"
#include "forward/separable.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf {

namespace detail {
KernelGradient direct_backward(const FootprintKernels&, const Query&, double, int, const DirectField&,
                               const std::vector<double>&);
std::vector<double> direct_tangent(const FootprintKernels&, const Query&, double, int, const DirectField&,
                                   const KernelGradient&);
}  // namespace detail

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

namespace {

void validate_all(const Query& query, double lambda_um, int resolution, const RenderOptions& options) {
    validate(query);
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    validate(options, query.model);
}

template <typename Float>
void check_weights(const std::vector<Float>& weights, int resolution) {
    if (weights.size() != static_cast<std::size_t>(resolution) * resolution)
        throw std::invalid_argument(
            "weights have " + std::to_string(weights.size()) +
            " entries; expected resolution^2 = " + std::to_string(static_cast<long long>(resolution) * resolution));
}

}  // namespace

// A one-wavelength, one-channel SlicePlan whose forward has run.
template <typename Float>
struct SliceAdjoint<Float>::State {
    SlicePlan<Float> plan;
};

template <typename Float>
SliceAdjoint<Float>::SliceAdjoint(const Heightfield& hf, const Query& query, double lambda_um, int n,
                                  const RenderOptions& options) {
    validate_all(query, lambda_um, n, options);
    m_state = std::make_unique<State>(State{SlicePlan<Float>(hf, query, {lambda_um}, n, 1, options)});
    m_state->plan.forward();
}

template <typename Float>
SliceAdjoint<Float>::~SliceAdjoint() = default;
template <typename Float>
SliceAdjoint<Float>::SliceAdjoint(SliceAdjoint&&) noexcept = default;
template <typename Float>
SliceAdjoint<Float>& SliceAdjoint<Float>::operator=(SliceAdjoint&&) noexcept = default;

template <typename Float>
const std::vector<Float>& SliceAdjoint<Float>::slice() const {
    return m_state->plan.slice(0);
}

template <typename Float>
void SliceAdjoint<Float>::backward(const std::vector<Float>& weights, std::vector<double>& gradient) const {
    m_state->plan.adjoint_wavelength(0, weights, gradient);
}

template class SliceAdjoint<float>;
template class SliceAdjoint<double>;

template <typename Float>
std::vector<Float> slice_gradient(const Heightfield& hf, const Query& query, double lambda_um, int n,
                                  const std::function<std::vector<Float>(const std::vector<Float>&)>& weights_of_slice,
                                  std::vector<double>& gradient, const RenderOptions& options) {
    const std::size_t cells = static_cast<std::size_t>(hf.rows()) * hf.cols();
    if (!gradient.empty() && gradient.size() != cells)
        throw std::invalid_argument("gradient has " + std::to_string(gradient.size()) +
                                    " entries; expected rows*cols = " + std::to_string(cells));
    const SliceAdjoint<Float> adjoint(hf, query, lambda_um, n, options);
    adjoint.backward(weights_of_slice(adjoint.slice()), gradient);
    return adjoint.slice();
}

template <typename Float>
std::vector<Float> slice_gradient(const Heightfield& hf, const Query& query, double lambda_um, int n,
                                  const std::vector<Float>& weights, std::vector<double>& gradient,
                                  const RenderOptions& options) {
    check_weights(weights, n);
    return slice_gradient<Float>(hf, query, lambda_um, n,
                                 std::function<std::vector<Float>(const std::vector<Float>&)>(
                                     [&weights](const std::vector<Float>&) { return weights; }),
                                 gradient, options);
}

std::vector<double> slice_tangent_direct(const Heightfield& hf, const Query& query, double lambda_um, int n,
                                         const std::vector<double>& direction) {
    validate_all(query, lambda_um, n, RenderOptions{});
    if (direction.size() != static_cast<std::size_t>(hf.rows()) * hf.cols())
        throw std::invalid_argument("direction has " + std::to_string(direction.size()) +
                                    " entries; expected rows*cols");
    const FootprintKernels k = footprint_kernels(hf, query.x_um, query.y_um, query.sigma_p_um);
    // Push the height perturbation through H = v·w·h and the slope stencil.
    const Heightfield dh = hf.with_values(direction);
    KernelGradient dk;
    for (std::size_t idx = 0; idx < k.size(); ++idx) {
        const auto s = dh.slope(k.row[idx], k.col[idx]);
        dk.height.push_back(dh.height_um(k.row[idx], k.col[idx]));
        dk.slope_x.push_back(s[0]);
        dk.slope_y.push_back(s[1]);
    }
    const detail::DirectField field = detail::direct_field(k, query, lambda_um, n, 0.0, nullptr);
    return detail::direct_tangent(k, query, lambda_um, n, field, dk);
}

template std::vector<float> slice_gradient<float>(const Heightfield&, const Query&, double, int,
                                                  const std::vector<float>&, std::vector<double>&,
                                                  const RenderOptions&);
template std::vector<double> slice_gradient<double>(const Heightfield&, const Query&, double, int,
                                                    const std::vector<double>&, std::vector<double>&,
                                                    const RenderOptions&);
template std::vector<float> slice_gradient<float>(const Heightfield&, const Query&, double, int,
                                                  const std::function<std::vector<float>(const std::vector<float>&)>&,
                                                  std::vector<double>&, const RenderOptions&);
template std::vector<double> slice_gradient<double>(
    const Heightfield&, const Query&, double, int,
    const std::function<std::vector<double>(const std::vector<double>&)>&, std::vector<double>&, const RenderOptions&);

}  // namespace wavebrdf
