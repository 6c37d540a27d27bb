// Adjoint and tangent of the direct sum (forward: brdf_direct.cpp). Each term of pixel u is
//   t_k = c_k w² K2_k exp(−E_k) e^{iΦ_k},  E_k = 2π²σ²|u + S a_k|²,  Φ_k = −(4π/λ) S H_k − 2π u·δ_k
// so ∂t/∂H_k = −i (4π/λ) S t_k and ∂t/∂s_kx = −4π²σ² (u_x + S a_kx)(2S/λ) t_k − ω_hx base_k,
// the last part only for Kirchhoff (K2 = cos θ_i + cos θ_o − (ω_i + ω_o)·s, base = t/K2).
// With f = c1 |I|², a loss Σ W f has dL = 2 Re Σ_pixels W c1 conj(I) dI.
#include <cmath>
#include <complex>
#include <omp.h>

#include "forward/direct.h"
#include "core/parallel.h"
#include "wavebrdf/kernel_gradient.h"

namespace wavebrdf::detail {

namespace {

// Calls visit(k, dt_dH, dt_dsx, dt_dsy, t) for every kernel term t of pixel (ox, oy) (t is also
// ∂t/∂ln c_k: the term is linear in its window weight).
template <typename Visit>
void visit_terms(const FootprintKernels& k, const Query& query, double lambda_um, double ox, double oy, double cutoff,
                 Visit&& visit) {
    const PixelTerms terms(k, query, lambda_um, ox, oy);
    PixelTerms::Term term;
    for (std::size_t i = 0; i < k.size(); ++i) {
        if (!terms.evaluate(i, cutoff, term)) continue;
        const std::complex<double> t = term.base * term.c2;
        const std::complex<double> dt_dh = std::complex<double>(0.0, -terms.height_phase) * t;
        std::complex<double> dt_dsx = (-2.0 * terms.gauss * term.vx * terms.freq) * t;
        std::complex<double> dt_dsy = (-2.0 * terms.gauss * term.vy * terms.freq) * t;
        if (terms.kirchhoff) {  // ∂C2/∂s = −(ω_i + ω_o)_xy
            dt_dsx -= terms.hx * term.base;
            dt_dsy -= terms.hy * term.base;
        }
        visit(i, dt_dh, dt_dsx, dt_dsy, t);
    }
}

}  // namespace

KernelGradient direct_backward(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                               const DirectField& forward, const std::vector<double>& weights) {
    const std::size_t total = k.size();
    const bool parallel = worth_parallel(static_cast<long long>(n) * n * static_cast<long long>(total));
    const int threads = parallel ? omp_get_max_threads() : 1;
    std::vector<KernelGradient> partial(static_cast<std::size_t>(threads));
    RegionGuard guard;
#pragma omp parallel if (parallel) num_threads(threads)
    {
        KernelGradient& g = partial[static_cast<std::size_t>(omp_get_thread_num())];
        guard.run([&] {
            g.height.assign(total, 0.0);
            g.slope_x.assign(total, 0.0);
            g.slope_y.assign(total, 0.0);
            g.log_weight.assign(total, 0.0);
        });
        // Static schedule: each thread always gets the same rows, so the per-thread sums and
        // their reduction are bitwise reproducible (resume relies on it).
#pragma omp for schedule(static)
        for (int p = 0; p < n; ++p)
            guard.run([&] {
                for (const auto [q, ox, oy] : disk_row(p, n)) {
                    const std::size_t at = static_cast<std::size_t>(p) * n + q;
                    const double v = forward.c1[at] * std::norm(forward.field[at]);
                    if (!std::isfinite(v) || weights[at] == 0.0) continue;
                    const std::complex<double> b = 2.0 * weights[at] * forward.c1[at] * std::conj(forward.field[at]);
                    visit_terms(k, query, lambda_um, ox, oy, forward.cutoff,
                                [&](std::size_t i, std::complex<double> dh, std::complex<double> dsx,
                                    std::complex<double> dsy, std::complex<double> t) {
                                    g.height[i] += std::real(b * dh);
                                    g.log_weight[i] += std::real(b * t);
                                    g.slope_x[i] += std::real(b * dsx);
                                    g.slope_y[i] += std::real(b * dsy);
                                });
                }
            });
    }
    guard.rethrow();
    KernelGradient sum = partial[0];
    for (std::size_t t = 1; t < partial.size(); ++t)
        for (std::size_t i = 0; i < total; ++i) {
            sum.height[i] += partial[t].height[i];
            sum.slope_x[i] += partial[t].slope_x[i];
            sum.slope_y[i] += partial[t].slope_y[i];
            sum.log_weight[i] += partial[t].log_weight[i];
        }
    return sum;
}

std::vector<double> direct_tangent(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                                   const DirectField& forward, const KernelGradient& dk) {
    std::vector<double> out(static_cast<std::size_t>(n) * n, 0.0);
    for_disk_pixels(
        n, k.size(),
        [&](std::size_t at, double ox, double oy) {
            if (!std::isfinite(forward.c1[at] * std::norm(forward.field[at]))) return;
            std::complex<double> d_field = 0.0;
            visit_terms(k, query, lambda_um, ox, oy, forward.cutoff,
                        [&](std::size_t i, std::complex<double> dh, std::complex<double> dsx, std::complex<double> dsy,
                            std::complex<double>) {
                            d_field += dh * dk.height[i] + dsx * dk.slope_x[i] + dsy * dk.slope_y[i];
                        });
            out[at] = 2.0 * forward.c1[at] * std::real(std::conj(forward.field[at]) * d_field);
        },
        [](int) {});
    return out;
}

}  // namespace wavebrdf::detail
