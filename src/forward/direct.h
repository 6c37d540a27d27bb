#pragma once
// Internal: the direct sum's per-pixel field, shared by the forward pass (brdf_direct.cpp)
// and its adjoint and tangent (brdf_direct_adjoint.cpp).
#include <cmath>
#include <complex>
#include <cstddef>
#include <vector>

#include "core/parallel.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/kernel_gradient.h"
#include "wavebrdf/model.h"

namespace wavebrdf {
class Progress;
}

namespace wavebrdf::detail {

// One pixel of the direct sum (docs/model.md §10), shared by the forward pass, its adjoint and
// its tangent: the per-pixel constants, and each kernel's term
//   t_k = base_k · c2_k,  base_k = c_k w² exp(−E_k) e^{iΦ_k},  E_k = 2π²σ²|u + S a_k|²,
//   Φ_k = −(4π/λ) S H_k − 2π u·δ_k,  c2_k = C2 for Kirchhoff (1 otherwise)
// with u = (ω_i + ω_o)/λ, S = C3/2 for the GHS-type models (1 otherwise), a_k = 2 s_k / λ.
struct PixelTerms {
    struct Term {
        double vx, vy;              // u + S a_k, the Gaussian's argument
        std::complex<double> base;  // c_k w² exp(−E_k) e^{iΦ_k}
        double c2;                  // Kirchhoff's C2, else 1
    };

    PixelTerms(const FootprintKernels& kernels, const Query& query, double lambda_um, double ox, double oy)
        : k(kernels), factors(direction_factors(query.model, query.omega_i, ox, oy, lambda_um)) {
        ux = (query.omega_i[0] + ox) / lambda_um;
        uy = (query.omega_i[1] + oy) / lambda_um;
        gauss = 2.0 * k_pi * k_pi * k.sigma_um * k.sigma_um;
        freq = factors.phase_scale * 2.0 / lambda_um;
        height_phase = factors.phase_scale * 4.0 * k_pi / lambda_um;
        kirchhoff = query.model == Model::Kirchhoff;
        hx = query.omega_i[0] + ox;
        hy = query.omega_i[1] + oy;
        hz = factors.cos_theta_i + factors.cos_theta_o;
    }

    // Kernel i's term; false (and `out` untouched) when its exponent exceeds `cutoff`.
    bool evaluate(std::size_t i, double cutoff, Term& out) const {
        const double vx = ux + freq * k.slope_x[i];
        const double vy = uy + freq * k.slope_y[i];
        const double exponent = gauss * (vx * vx + vy * vy);
        if (exponent > cutoff) return false;
        const double phase = -(height_phase * k.height_um[i] + 2.0 * k_pi * (ux * k.dx_um[i] + uy * k.dy_um[i]));
        out.vx = vx;
        out.vy = vy;
        out.base = std::polar(k.weight[i] * std::exp(-exponent), phase);
        // Kirchhoff: C2 = (ω_o + ω_i)·m / m_z with m ∝ (−s, 1), the kernel's own (unscaled) slope.
        out.c2 = kirchhoff ? hz - hx * k.slope_x[i] - hy * k.slope_y[i] : 1.0;
        return true;
    }

    const FootprintKernels& k;
    DirectionFactors factors;
    double ux, uy, gauss, freq, height_phase, hx, hy, hz;
    bool kirchhoff;
};

struct DirectField {
    std::vector<std::complex<double>> field;  // I per pixel (0 outside the disk)
    std::vector<double> c1;                   // f = c1 |I|²
    std::vector<double> value;                // the slice (non-finite → 0)
    double cutoff = 0.0;                      // Gaussian exponent beyond which kernels were skipped
};

// pixel(at, ox, oy) for every pixel of the n × n slice's visible disk (at = p n + q, (ox, oy) its
// ω_o), then row_done(p) after row p: the loop of the direct sum's forward pass and tangent. Rows
// are spread over the threads with a dynamic schedule (the disk's rows differ in length) when
// n² × kernels is worth it; an exception in any row is rethrown here.
template <typename Pixel, typename RowDone>
void for_disk_pixels(int n, std::size_t kernels, Pixel&& pixel, RowDone&& row_done) {
    RegionGuard guard;
    const long long work = static_cast<long long>(n) * n * static_cast<long long>(kernels);
#pragma omp parallel for schedule(dynamic, 1) if (worth_parallel(work))
    for (int p = 0; p < n; ++p)
        guard.run([&] {
            for (const auto [q, ox, oy] : disk_row(p, n)) pixel(static_cast<std::size_t>(p) * n + q, ox, oy);
            row_done(p);
        });
    guard.rethrow();
}

// The direct sum with the pruning bound of RenderOptions::prune_tolerance (0: none).
DirectField direct_field(const FootprintKernels& kernels, const Query& query, double lambda_um, int n,
                         double prune_tolerance, Progress* progress);

// The direct sum's adjoint (per-kernel gradient of Σ weights · slice) and tangent (d slice for a
// per-kernel perturbation), from the forward's field (brdf_direct_adjoint.cpp).
KernelGradient direct_backward(const FootprintKernels& kernels, const Query& query, double lambda_um, int n,
                               const DirectField& field, const std::vector<double>& weights);
std::vector<double> direct_tangent(const FootprintKernels& kernels, const Query& query, double lambda_um, int n,
                                   const DirectField& field, const KernelGradient& direction);

}  // namespace wavebrdf::detail
