// Adjoint of the separable path (forward: brdf_separable.cpp). With the forward field I and
// B[p,q] = W[p,q] c1[p,q] conj(I[p,q]), a loss L = Σ W f has dL = 2 Re Σ_pq B dI, and
//   dI[p,q] = Σ_k X[p,k] Y[q,k] dw_k + w_k (∂_a X[p,k] Y[q,k] da_kx + X[p,k] ∂_a Y[q,k] da_ky)
// with dw_k = −i(4π/λ) w_k dH_k, ∂_a X[p,k] = −4π²σ²(u_x[p] + a_kx) X[p,k], da = (2/λ) ds.
// With the forward's weighted factor Y_w = Y·diag(w), Z = B·Y_w and V = Bᵀ·X (two matrix
// products of the forward's size):
//   ∂L/∂H_k  = 2 Re[−i(4π/λ) Σ_p X[p,k] Z[p,k]]
//   ∂L/∂s_kx = 2 Re[(2/λ) Σ_p ∂_a X[p,k] Z[p,k]],  ∂L/∂s_ky = 2 Re[(2/λ) Σ_q ∂_a Y_w[q,k] V[q,k]].
// The factors are the forward's own when it kept them (one chunk), else rebuilt chunk by chunk.
#include <algorithm>
#include <cmath>
#include <string>
#include <optional>

#include "forward/separable.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/memory.h"

namespace wavebrdf::detail {

// When the adjoint rebuilds factors, it holds four n × chunk matrices (X, Y_w, Z, V): a chunk
// of 512 kernels keeps its peak below the forward's (two n × 2048) at no measurable cost in
// the products (256² heights, 128² slice: 10.6 → 7.0 MiB peak in float).
constexpr Eigen::Index kAdjointChunkColumns = 512;

template <typename Float>
KernelGradient separable_backward(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                                  const SliceGrid& grid, const PhaseTables* given_phases, const std::vector<double>* c1,
                                  const ComplexMatrix<Float>& field, const std::vector<Float>& weights,
                                  const SeparableFactors<Float>* kept) {
    using Complex = std::complex<Float>;
    ComplexMatrix<Float> b = ComplexMatrix<Float>::Zero(n, n);
    RegionGuard b_guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n))
    for (int p = 0; p < n; ++p)
        b_guard.run([&] {
            for (const auto [q, ox, oy] : disk_row(p, n)) {
                const std::size_t at = static_cast<std::size_t>(p) * n + q;
                const double factor = c1 ? (*c1)[at]
                                         : direction_factors(query.model, query.omega_i, ox, oy, lambda_um).c1;
                const double scale = double(weights[at]) * factor;
                // The forward wrote non-finite pixels as 0: they carry no gradient.
                if (!std::isfinite(scale * double(std::norm(field(p, q))))) continue;
                b(p, q) = Complex(Float(scale)) * std::conj(field(p, q));
            }
        });
    b_guard.rethrow();

    const std::size_t total = k.size();
    KernelGradient g;
    g.height.assign(total, 0.0);
    g.slope_x.assign(total, 0.0);
    g.slope_y.assign(total, 0.0);
    const bool reuse = kept && !kept->empty() && kept->xs.cols() == Eigen::Index(total);
    std::optional<PhaseTables> built_phases;
    if (!reuse && !given_phases) built_phases.emplace(k, grid);
    const PhaseTables* phases = given_phases ? given_phases : (built_phases ? &*built_phases : nullptr);
    const Eigen::Index chunk = reuse ? Eigen::Index(total) : chunk_size(n, sizeof(Complex), 4, kAdjointChunkColumns);
    const Eigen::Index cols = std::min<Eigen::Index>(chunk, std::max<Eigen::Index>(Eigen::Index(total), 1));
    ComplexMatrix<Float> built_xs, built_ys, z, v;
    allocating("the " + std::to_string(n) + "x" + std::to_string(n) + " slice's adjoint factor matrices",
               (reuse ? 2.0 : 4.0) * double(n) * double(cols) * sizeof(Complex), [&] {
                   if (!reuse) {
                       built_xs.resize(n, cols);
                       built_ys.resize(n, cols);
                   }
                   z.resize(n, cols);
                   v.resize(n, cols);
               });
    const ComplexMatrix<Float>& xs = reuse ? kept->xs : built_xs;
    const ComplexMatrix<Float>& ys = reuse ? kept->ys : built_ys;
    const double gauss = 2.0 * k_pi * k_pi * k.sigma_um * k.sigma_um;
    const double two_over_lambda = 2.0 / lambda_um;
    const std::complex<double> height_factor(0.0, -4.0 * k_pi / lambda_um);
    for (Eigen::Index k0 = 0; k0 < Eigen::Index(total); k0 += chunk) {
        const Eigen::Index count = std::min<Eigen::Index>(chunk, Eigen::Index(total) - k0);
        if (!reuse) build_factors<Float>(k, grid, *phases, lambda_um, k0, count, true, built_xs, built_ys);
        // Z = B·Y_w and V = Bᵀ·X, split over kernels (columns).
        for_column_blocks(count, 2.0 * double(n) * n * double(count), [&](long long first, long long cols) {
            z.middleCols(first, cols).noalias() = b * ys.middleCols(first, cols);
            v.middleCols(first, cols).noalias() = b.transpose() * xs.middleCols(first, cols);
        });
        RegionGuard guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(count) * n))
        for (Eigen::Index c = 0; c < count; ++c)
            guard.run([&] {
                const std::size_t idx = static_cast<std::size_t>(k0 + c);
                const double ax = two_over_lambda * k.slope_x[idx];
                const double ay = two_over_lambda * k.slope_y[idx];
                std::complex<double> t0 = 0.0, t1 = 0.0, t2 = 0.0;
                for (Eigen::Index p = 0; p < n; ++p) {
                    const std::complex<double> xz = std::complex<double>(xs(p, c)) * std::complex<double>(z(p, c));
                    t0 += xz;
                    t1 += -2.0 * gauss * (grid.ux[p] + ax) * xz;
                    t2 += -2.0 * gauss * (grid.uy[p] + ay) * std::complex<double>(ys(p, c)) *
                          std::complex<double>(v(p, c));
                }
                g.height[idx] = 2.0 * std::real(height_factor * t0);
                g.slope_x[idx] = 2.0 * std::real(two_over_lambda * t1);
                g.slope_y[idx] = 2.0 * std::real(two_over_lambda * t2);
            });
        guard.rethrow();
    }
    return g;
}

template KernelGradient separable_backward<float>(const FootprintKernels&, const Query&, double, int, const SliceGrid&,
                                                  const PhaseTables*, const std::vector<double>*,
                                                  const ComplexMatrix<float>&, const std::vector<float>&,
                                                  const SeparableFactors<float>*);
template KernelGradient separable_backward<double>(const FootprintKernels&, const Query&, double, int, const SliceGrid&,
                                                   const PhaseTables*, const std::vector<double>*,
                                                   const ComplexMatrix<double>&, const std::vector<double>&,
                                                   const SeparableFactors<double>*);

}  // namespace wavebrdf::detail
