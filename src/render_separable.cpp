// The separable path: for OHS and ROHS, ĝ_k(u) factorises into a function of u_x and one
// of u_y (MODEL.md, "What makes it fast"), so on the slice's grid
//   I(u_x[p], u_y[q]) = Σ_k X[p,k] · w_k · Y[q,k]  =  (X · diag(w) · Yᵀ)[p,q]
// with X[p,k] = exp(−2π²σ²(u_x[p] + a_kx)²) e^{−i2π u_x[p] δ_kx}, the same in y, and
// w_k = c_k w² e^{−i(4π/λ) H_k}. (The kernel's C_k e^{−i2π(u+a)·μ} collapses to
// w² e^{−i(4π/λ)H_k} e^{−i2π u·μ_k}; μ_k = μ_p + δ_k and e^{−i2π u·μ_p} is a global phase.)
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>

#include "wavebrdf/brdf.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

template <typename Float>
std::vector<Float> render_slice_separable(const FootprintKernels& k, const Query& query,
                                          double lambda_um, int n, Progress* progress) {
    if (!is_separable(query.model))
        throw std::invalid_argument(std::string("model ") + to_string(query.model) +
                                    " is not separable; expected OHS or ROHS");
    using Complex = std::complex<Float>;
    using Matrix = Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic>;
    const Eigen::Index size = n;

    std::vector<double> ux(static_cast<std::size_t>(n)), uy(static_cast<std::size_t>(n));
    for (int p = 0; p < n; ++p) {
        ux[p] = (query.omega_i[0] + slice_omega(p, n)) / lambda_um;
        uy[p] = (query.omega_i[1] + slice_omega(p, n)) / lambda_um;
    }
    const double gauss = 2.0 * kPi * kPi * k.sigma_um * k.sigma_um;  // 2π²σ²
    const double two_over_lambda = 2.0 / lambda_um;
    const double height_phase = 4.0 * kPi / lambda_um;

    // Kernels in chunks: the factor matrices stay small (memory independent of the footprint)
    // while the inner dimension stays long enough for an efficient product.
    const Eigen::Index total = static_cast<Eigen::Index>(k.size());
    const Eigen::Index budget = (Eigen::Index(32) << 20) / (2 * size * Eigen::Index(sizeof(Complex)));
    const Eigen::Index chunk = std::max<Eigen::Index>(64, std::min<Eigen::Index>(2048, budget));
    Matrix field = Matrix::Zero(size, size);
    Matrix xs(size, std::min(chunk, std::max<Eigen::Index>(total, 1)));
    Matrix ys(size, xs.cols());
    const long long units = work_units(n);
    long long reported = 0;

    for (Eigen::Index k0 = 0; k0 < total; k0 += chunk) {
        const Eigen::Index count = std::min(chunk, total - k0);
#pragma omp parallel for schedule(static)
        for (Eigen::Index c = 0; c < count; ++c) {
            const std::size_t idx = static_cast<std::size_t>(k0 + c);
            const double ax = two_over_lambda * k.slope_x[idx];
            const double ay = two_over_lambda * k.slope_y[idx];
            const double dx = k.dx_um[idx], dy = k.dy_um[idx];
            const std::complex<double> w =
                k.weight[idx] * std::polar(1.0, -height_phase * k.height_um[idx]);
            for (Eigen::Index p = 0; p < size; ++p) {
                const double vx = ux[p] + ax;
                const double phase = -2.0 * kPi * ux[p] * dx;
                xs(p, c) = Complex(std::polar(std::exp(-gauss * vx * vx), phase));
                const double vy = uy[p] + ay;
                const double phase_y = -2.0 * kPi * uy[p] * dy;
                ys(p, c) = Complex(w * std::polar(std::exp(-gauss * vy * vy), phase_y));
            }
        }
        field.noalias() += xs.leftCols(count) * ys.leftCols(count).transpose();
        if (progress) {
            const long long target = units * (k0 + count) / std::max<Eigen::Index>(total, 1);
            progress->advance(target - reported);
            reported = target;
        }
    }
    if (progress && reported < units) progress->advance(units - reported);

    std::vector<Float> slice(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), Float(0));
#pragma omp parallel for schedule(static)
    for (int p = 0; p < n; ++p) {
        const double ox = slice_omega(p, n);
        for (int q = 0; q < n; ++q) {
            const double oy = slice_omega(q, n);
            if (ox * ox + oy * oy > 1.0) continue;
            const DirectionFactors f = direction_factors(query.model, query.omega_i, ox, oy, lambda_um);
            const double value = f.c1 * static_cast<double>(std::norm(field(p, q)));
            slice[static_cast<std::size_t>(p) * n + q] = std::isfinite(value) ? Float(value) : Float(0);
        }
    }
    return slice;
}

template std::vector<float> render_slice_separable<float>(const FootprintKernels&, const Query&,
                                                          double, int, Progress*);
template std::vector<double> render_slice_separable<double>(const FootprintKernels&, const Query&,
                                                            double, int, Progress*);

}  // namespace wavebrdf
