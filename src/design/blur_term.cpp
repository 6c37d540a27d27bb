#include "design/blur_term.h"

#include <algorithm>
#include <cmath>

#include "design/grayscale.h"

namespace wavebrdf::detail {

std::vector<double> periodic_blur(const std::vector<double>& h, int size, double sigma_texels) {
    if (sigma_texels <= 0.0) return h;
    const int radius = std::min(size / 2, static_cast<int>(std::ceil(4.0 * sigma_texels)));
    std::vector<double> kernel(static_cast<std::size_t>(2 * radius + 1));
    double sum = 0.0;
    for (int d = -radius; d <= radius; ++d)
        sum += kernel[static_cast<std::size_t>(d + radius)] = std::exp(-0.5 * d * d / (sigma_texels * sigma_texels));
    for (double& k : kernel) k /= sum;
    std::vector<double> tmp(h.size(), 0.0), out(h.size(), 0.0);
    const auto N = static_cast<std::size_t>(size);
    for (int i = 0; i < size; ++i)
        for (int j = 0; j < size; ++j) {
            double acc = 0.0;
            for (int d = -radius; d <= radius; ++d)
                acc += kernel[static_cast<std::size_t>(d + radius)] *
                       h[static_cast<std::size_t>(((i + d) % size + size) % size) * N + static_cast<std::size_t>(j)];
            tmp[static_cast<std::size_t>(i) * N + static_cast<std::size_t>(j)] = acc;
        }
    for (int i = 0; i < size; ++i)
        for (int j = 0; j < size; ++j) {
            double acc = 0.0;
            for (int d = -radius; d <= radius; ++d)
                acc += kernel[static_cast<std::size_t>(d + radius)] *
                       tmp[static_cast<std::size_t>(i) * N + static_cast<std::size_t>(((j + d) % size + size) % size)];
            out[static_cast<std::size_t>(i) * N + static_cast<std::size_t>(j)] = acc;
        }
    return out;
}

BlurTerm::BlurTerm(const PreparedDesign& p, double sigma_texels) : m_grid(p), m_levels_um(p.levels_um), m_sigma(sigma_texels) {
    const double top = p.levels_um.back();
    m_grid.options.levels = k_grayscale_levels;
    m_step = top / (k_grayscale_levels - 1);
    m_grid.levels_um.resize(k_grayscale_levels);
    for (int l = 0; l < k_grayscale_levels; ++l) m_grid.levels_um[static_cast<std::size_t>(l)] = m_step * l;
    m_evaluator = std::make_unique<Evaluator>(m_grid, std::vector<double>{1.0});
}

BlurTerm::~BlurTerm() = default;

double BlurTerm::evaluate(const std::vector<int>& level, std::vector<double>* height_gradient, Fractions* fractions) {
    std::vector<double> h(level.size());
    for (std::size_t t = 0; t < level.size(); ++t) h[t] = m_levels_um[static_cast<std::size_t>(level[t])];
    return evaluate_heights(h, height_gradient, fractions);
}

double BlurTerm::evaluate_heights(const std::vector<double>& heights_um, std::vector<double>* height_gradient,
                                  Fractions* fractions) {
    const int N = m_grid.options.size, K = k_grayscale_levels;
    const std::size_t n2 = heights_um.size();
    const std::vector<double> b = periodic_blur(heights_um, N, m_sigma);
    std::vector<double> weights(n2 * static_cast<std::size_t>(K), 0.0), upper(n2);
    std::vector<int> lower(n2);
    for (std::size_t t = 0; t < n2; ++t) {
        const double x = std::clamp(b[t] / m_step, 0.0, static_cast<double>(K - 1));
        const int l = std::min(K - 2, static_cast<int>(std::floor(x)));
        lower[t] = l;
        upper[t] = x - l;
        weights[static_cast<std::size_t>(l) * n2 + t] = 1.0 - upper[t];
        weights[static_cast<std::size_t>(l + 1) * n2 + t] = upper[t];
    }
    std::vector<double> wg;
    const double loss = m_evaluator->evaluate(weights, height_gradient ? &wg : nullptr, fractions);
    if (height_gradient) {
        // ∂p_ℓ/∂h = −1/Δ for the lower level, +1/Δ for the upper; then the blur's adjoint (itself).
        std::vector<double> dh(n2);
        for (std::size_t t = 0; t < n2; ++t) {
            const std::size_t l = static_cast<std::size_t>(lower[t]);
            dh[t] = (wg[(l + 1) * n2 + t] - wg[l * n2 + t]) / m_step;
        }
        *height_gradient = periodic_blur(dh, N, m_sigma);
    }
    return loss;
}

double blur_term_bytes(int size) {
    const double n2 = static_cast<double>(size) * size;
    // Spectra, two threads' gradient buffers and the summed one, weights and their gradient.
    return 16.0 * k_grayscale_levels * n2 * 4.0 + 2.0 * 8.0 * k_grayscale_levels * n2;
}

}  // namespace wavebrdf::detail
