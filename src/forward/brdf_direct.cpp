// The direct sum: every slice pixel sums the analytic transforms of every footprint kernel
// (docs/model.md §5), for all five models. It is the reference the fast path is tested on.
//   I(u) = Σ_k c_k w² K2_k exp(−2π²σ²|u + S a_k|²) e^{−i[(4π/λ) S H_k + 2π u·δ_k]}
// with S = C3/2 for GHS, RGHS and Kirchhoff (1 otherwise), K2_k = C2 for Kirchhoff (1
// otherwise) and u = (ω_i + ω_o)/λ.
#include <algorithm>
#include <cmath>
#include <string>
#include <complex>
#include <limits>

#include "wavebrdf/brdf.h"
#include "wavebrdf/memory.h"
#include "forward/direct.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

namespace {

struct PixelSum {
    std::complex<double> field;
    double c1;
};

// The sum at one pixel, skipping kernels whose Gaussian exponent exceeds `cutoff`.
PixelSum sum_pixel(const FootprintKernels& k, const Query& query, double lambda_um, double ox, double oy,
                   double cutoff) {
    const detail::PixelTerms terms(k, query, lambda_um, ox, oy);
    detail::PixelTerms::Term t;
    std::complex<double> sum = 0.0;
    for (std::size_t i = 0; i < k.size(); ++i)
        if (terms.evaluate(i, cutoff, t)) sum += t.base * t.c2;
    return {sum, terms.factors.c1};
}

// Upper bound on Σ_k c_k w² |K2_k|, the amplitude the pruned kernels can at most carry
// before their Gaussian factor.
double amplitude_bound(const FootprintKernels& k, Model model) {
    double total = 0.0;
    for (std::size_t i = 0; i < k.size(); ++i) {
        double factor = 1.0;
        // |C2| ≤ cos θ_i + cos θ_o + |ω_i + ω_o| |s| ≤ 2 + 2|s|.
        if (model == Model::Kirchhoff) factor = 2.0 + 2.0 * std::hypot(k.slope_x[i], k.slope_y[i]);
        total += k.weight[i] * factor;
    }
    return total;
}

}  // namespace

namespace detail {

DirectField direct_field(const FootprintKernels& k, const Query& query, double lambda_um, int n, double prune_tolerance,
                         Progress* progress) {
    const std::size_t pixels = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    DirectField out;
    allocating("the " + std::to_string(n) + "x" + std::to_string(n) + " slice's field",
               double(pixels) * (sizeof(std::complex<double>) + 2 * sizeof(double)), [&] {
                   out.field.assign(pixels, 0.0);
                   out.c1.assign(pixels, 0.0);
                   out.value.assign(pixels, 0.0);
               });
    const double bound = amplitude_bound(k, query.model);
    // Start by dropping terms below 1e-3 · tolerance of the bound; tighten if the a-posteriori
    // check below fails. No pruning at all when the tolerance is 0.
    double cutoff = prune_tolerance > 0.0 ? std::log(1e3 / prune_tolerance) : std::numeric_limits<double>::infinity();
    const long long units = work_units(n);
    for (int attempt = 0;; ++attempt) {
        for_disk_pixels(
            n, k.size(),
            [&](std::size_t at, double ox, double oy) {
                const PixelSum s = sum_pixel(k, query, lambda_um, ox, oy, cutoff);
                out.field[at] = s.field;
                out.c1[at] = s.c1;
                const double v = s.c1 * std::norm(s.field);
                out.value[at] = std::isfinite(v) ? v : 0.0;
            },
            [&](int p) {
                if (progress && attempt == 0) progress->advance(units / n + (p < units % n ? 1 : 0));
            });
        if (!std::isfinite(cutoff)) break;
        // Error bound: each pixel's dropped amplitude ε ≤ e^{−cutoff} · bound, so
        // |f − f̃| ≤ c1 (2|Ĩ| + ε) ε. Accept when every pixel is within tolerance · (peak − err).
        const double eps = std::exp(-cutoff) * bound;
        double peak = 0.0, worst = 0.0;
        for (std::size_t at = 0; at < pixels; ++at) {
            peak = std::max(peak, out.value[at]);
            const double err = out.c1[at] * (2.0 * std::abs(out.field[at]) + eps) * eps;
            if (std::isfinite(err)) worst = std::max(worst, err);
        }
        if (worst <= prune_tolerance * std::max(peak - worst, 0.0)) break;
        // Not provable yet: tighten, and after three tries fall back to the full sum.
        cutoff = attempt >= 2 ? std::numeric_limits<double>::infinity() : cutoff + std::log(1e4);
    }
    out.cutoff = cutoff;
    return out;
}

}  // namespace detail

template <typename Float>
std::vector<Float> render_slice_direct(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                                       double prune_tolerance, Progress* progress) {
    const detail::DirectField f = detail::direct_field(k, query, lambda_um, n, prune_tolerance, progress);
    return std::vector<Float>(f.value.begin(), f.value.end());
}

template std::vector<float> render_slice_direct<float>(const FootprintKernels&, const Query&, double, int, double,
                                                       Progress*);
template std::vector<double> render_slice_direct<double>(const FootprintKernels&, const Query&, double, int, double,
                                                         Progress*);

}  // namespace wavebrdf
