// Entry points of the gradients: forward once, weights from the caller, backward by the
// adjoint of the path that rendered, then the chain to the raw heights.
#include <cmath>
#include <stdexcept>
#include <string>

#include "forward/direct.h"
#include "forward/separable.h"
#include "forward/kernel_gradient_detail.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf {

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
