// The grayscale design loop (grayscale.h).
#include "design/grayscale.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/random.h"

namespace wavebrdf::detail {

namespace {

// Each texel's weight split between the two levels around h/Δ (level-major, K · N²).
void split_weights(const std::vector<double>& h, double step, int levels, std::vector<double>& weights,
                   std::vector<int>& lower, std::vector<double>& upper_share) {
    const std::size_t n2 = h.size();
    weights.assign(n2 * static_cast<std::size_t>(levels), 0.0);
    lower.resize(n2);
    upper_share.resize(n2);
    for (std::size_t t = 0; t < n2; ++t) {
        const double x = std::clamp(h[t] / step, 0.0, static_cast<double>(levels - 1));
        const int l = std::min(levels - 2, static_cast<int>(std::floor(x)));
        const double s = x - l;
        lower[t] = l;
        upper_share[t] = s;
        weights[static_cast<std::size_t>(l) * n2 + t] = 1.0 - s;
        weights[static_cast<std::size_t>(l + 1) * n2 + t] = s;
    }
}

}  // namespace

double grayscale_loss(const FeatureFilter& filter, Evaluator& evaluator, double height_range_um, int levels,
                      const std::vector<double>& z, std::vector<double>* gradient, Fractions* nominal) {
    const std::size_t n2 = z.size();
    const double step = height_range_um / (levels - 1);
    std::vector<double> h, weights, upper_share, weights_gradient;
    std::vector<int> lower;
    filtered_heights(filter, height_range_um, z, h);
    split_weights(h, step, levels, weights, lower, upper_share);
    const double loss = evaluator.evaluate(weights, gradient ? &weights_gradient : nullptr, nominal);
    if (gradient) {
        // ∂p_ℓ/∂h = −1/Δ for the lower level, +1/Δ for the upper (inside a segment).
        std::vector<double> dh(n2);
        for (std::size_t t = 0; t < n2; ++t) {
            const std::size_t l = static_cast<std::size_t>(lower[t]);
            dh[t] = (weights_gradient[(l + 1) * n2 + t] - weights_gradient[l * n2 + t]) / step;
        }
        filtered_heights_adjoint(filter, height_range_um, z, dh, *gradient);
    }
    return loss;
}

std::vector<int> grayscale_design(const PreparedDesign& p, Evaluator& evaluator,
                                  const std::function<void(const DesignStep&)>& report, const bool& stopped,
                                  Fractions& relaxed_fractions, std::vector<double>& latent,
                                  const std::vector<double>* warm, int iteration0) {
    const DesignOptions& o = p.options;
    const int N = o.size, K = o.levels;
    const std::size_t n2 = static_cast<std::size_t>(N) * static_cast<std::size_t>(N);
    const FeatureFilter filter(N, o.texel_um, o.min_feature_um);
    std::mt19937_64 rng(derive_seed(o.seed, 0x67a7));
    std::vector<double> z(n2), grad, m1(n2, 0.0), m2(n2, 0.0);
    if (warm && warm->size() == n2)
        z = *warm;
    else
        fill_standard_normal(z.data(), z.size(), rng);
    constexpr double k_rate = 0.1, k_b1 = 0.9, k_b2 = 0.999;
    for (int it = 0; it < o.iterations && !stopped; ++it) {
        const double loss = grayscale_loss(filter, evaluator, o.height_range_um, K, z, &grad, &relaxed_fractions);
        // A constrained target's multipliers move at the end of each tenth of the iterations.
        if (p.target->constrained() && (it + 1) % std::max(1, (o.iterations + 9) / 10) == 0)
            p.target->update_multipliers(relaxed_fractions);
        const double c1 = 1.0 - std::pow(k_b1, it + 1), c2 = 1.0 - std::pow(k_b2, it + 1);
        for (std::size_t t = 0; t < n2; ++t) {
            m1[t] = k_b1 * m1[t] + (1.0 - k_b1) * grad[t];
            m2[t] = k_b2 * m2[t] + (1.0 - k_b2) * grad[t] * grad[t];
            z[t] -= k_rate * (m1[t] / c1) / (std::sqrt(m2[t] / c2) + 1e-12);
        }
        report({"relaxed", iteration0 + it, loss, 0.0});
    }
    std::vector<double> h;
    filtered_heights(filter, o.height_range_um, z, h);
    const double step = o.height_range_um / (K - 1);
    std::vector<int> level(n2);
    for (std::size_t t = 0; t < n2; ++t)
        level[t] = std::clamp(static_cast<int>(std::lround(h[t] / step)), 0, K - 1);
    latent.swap(z);
    return level;
}

}  // namespace wavebrdf::detail
