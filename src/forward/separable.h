#pragma once
// Internal: the slice grid, phase tables and factor matrices of the separable path
// (SeparableEngine, forward/separable_engine.h), and the slice f = c1 |I|² of a field.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "core/parallel.h"
#include "wavebrdf/kernel_gradient.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/model.h"

namespace wavebrdf {
class Progress;
}

namespace wavebrdf::detail {

template <typename Float>
using ComplexMatrix = Eigen::Matrix<std::complex<Float>, Eigen::Dynamic, Eigen::Dynamic>;

// Spatial frequencies of the slice's rows (u_x) and columns (u_y): u = (ω_i + ω_o)/λ.
struct SliceGrid {
    std::vector<double> ux, uy;
    SliceGrid(const Query& query, double lambda_um, int n) : ux(n), uy(n) {
        for (int p = 0; p < n; ++p) {
            ux[p] = (query.omega_i[0] + slice_omega(p, n)) / lambda_um;
            uy[p] = (query.omega_i[1] + slice_omega(p, n)) / lambda_um;
        }
    }
};

// Kernels per chunk: long enough for an efficient matrix product (at least 64, at most
// `max_columns`), small enough that the factor matrices (`matrices` of them, n × chunk complex)
// stay within ~32 MiB.
inline Eigen::Index chunk_size(int n, std::size_t bytes_per_entry, int matrices, Eigen::Index max_columns = 2048) {
    const Eigen::Index budget = (Eigen::Index(32) << 20) / (Eigen::Index(matrices) * n * Eigen::Index(bytes_per_entry));
    return std::max<Eigen::Index>(64, std::min<Eigen::Index>(max_columns, budget));
}

// w_k = c_k w² e^{−i(4π/λ) H_k}: the kernel's complex weight.
inline std::complex<double> kernel_weight(const FootprintKernels& k, std::size_t idx, double lambda_um) {
    return k.weight[idx] * std::polar(1.0, -4.0 * k_pi / lambda_um * k.height_um[idx]);
}

// The phase factors e^{−i2π u_x[p] δ_x} and e^{−i2π u_y[q] δ_y}. δ_x depends only on the
// kernel's row and δ_y only on its column, so there are only as many distinct phase vectors as
// rows (columns) the footprint spans: tabulating them once per wavelength replaces a sincos per
// matrix entry by a table lookup.
struct PhaseTables {
    std::vector<int> slot_x, slot_y;    // per kernel: column of phase_x / phase_y
    Eigen::MatrixXcd phase_x, phase_y;  // n × (distinct rows / columns)

    PhaseTables(const FootprintKernels& k, const SliceGrid& grid) {
        const Eigen::Index n = static_cast<Eigen::Index>(grid.ux.size());
        slot_x = slots(k.row, k.dx_um, phase_x, grid.ux, n);
        slot_y = slots(k.col, k.dy_um, phase_y, grid.uy, n);
    }

private:
    static std::vector<int> slots(const std::vector<int>& index, const std::vector<double>& offset,
                                  Eigen::MatrixXcd& table, const std::vector<double>& u, Eigen::Index n) {
        int max_index = -1;
        for (int i : index) max_index = std::max(max_index, i);
        std::vector<int> slot_of(static_cast<std::size_t>(max_index + 1), -1), out(index.size());
        std::vector<double> offsets;
        for (std::size_t k = 0; k < index.size(); ++k) {
            int& s = slot_of[static_cast<std::size_t>(index[k])];
            if (s < 0) {
                s = static_cast<int>(offsets.size());
                offsets.push_back(offset[k]);
            }
            out[k] = s;
        }
        // u is uniform, so along a column the phase advances by a fixed rotation: one sincos
        // per 32 entries (exact restarts keep the recurrence's error at a few ulps).
        table.resize(n, static_cast<Eigen::Index>(offsets.size()));
        const double du = n > 1 ? u[1] - u[0] : 0.0;
        for (Eigen::Index c = 0; c < table.cols(); ++c) {
            const double delta = offsets[static_cast<std::size_t>(c)];
            const std::complex<double> rotation = std::polar(1.0, -2.0 * k_pi * du * delta);
            for (Eigen::Index p = 0; p < n; ++p)
                table(p, c) = p % 32 == 0 ? std::polar(1.0, -2.0 * k_pi * u[static_cast<std::size_t>(p)] * delta)
                                          : table(p - 1, c) * rotation;
        }
        return out;
    }
};

// g[p] = exp(−gauss · (v0 + p·dv)²) for p = 0…n−1 with three exps instead of n: the ratio of
// neighbours, exp(−gauss·dv·(2v ± dv)), changes by the constant factor exp(−2·gauss·dv²) per
// step, so both are carried multiplicatively outward from the sample nearest the peak (values
// only shrink away from it, so an underflow to 0 is the true value's underflow). Relative error
// grows by a few ulps per step: ≤ 1e-12 in double at n = 8192.
inline void gaussian_samples(double gauss, double v0, double dv, Eigen::Index n, double* g) {
    const double step = std::exp(-2.0 * gauss * dv * dv);
    const Eigen::Index peak = std::clamp<Eigen::Index>(Eigen::Index(std::lround(-v0 / dv)), 0, n - 1);
    const double vp = v0 + double(peak) * dv;
    g[peak] = std::exp(-gauss * vp * vp);
    double ratio = std::exp(-gauss * dv * (2.0 * vp + dv));  // g[p+1] / g[p] at p = peak
    for (Eigen::Index p = peak + 1; p < n; ++p, ratio *= step) g[p] = g[p - 1] * ratio;
    ratio = std::exp(gauss * dv * (2.0 * vp - dv));  // g[p−1] / g[p] at p = peak
    for (Eigen::Index p = peak - 1; p >= 0; --p, ratio *= step) g[p] = g[p + 1] * ratio;
}

// The column walker of the factor matrices: for c = 0…count−1 (kernel k0 + c), in parallel over
// columns, calls write(c, gx, gy, px, py) with the Gaussians gx[p], gy[p] (p = 0…n−1) and the
// kernel's phase columns px, py, so that X[p,c] = gx[p]·px[p] and Y[q,c] = gy[q]·py[q]:
//   X[p,c] = exp(−2π²σ²(u_x[p] + b_x)²) e^{−i2π u_x[p] δ_x}, Y likewise in y,
// with b = shift_scale·(2/λ)·s_k (field_engine.h). The grid is uniform (u[p] = u[0] + p·du),
// so the Gaussians come from gaussian_samples. build_factors and build_planar_factors
// (separable_engine.h) are its two writers (interleaved complex, planar float).
template <typename Write>
void for_each_factor_column(const FootprintKernels& k, const SliceGrid& grid, const PhaseTables& phases,
                            double lambda_um, double shift_scale, Eigen::Index k0, Eigen::Index count, Write&& write) {
    const Eigen::Index n = static_cast<Eigen::Index>(grid.ux.size());
    const double gauss = 2.0 * k_pi * k_pi * k.sigma_um * k.sigma_um;  // 2π²σ²
    const double shift = shift_scale * 2.0 / lambda_um;
    const double du = 2.0 / (double(n) * lambda_um);  // slice_omega's spacing / λ
    RegionGuard guard;
#pragma omp parallel if (worth_parallel(static_cast <long long>(count) * n))
    {
        std::vector<double> gx, gy;
        guard.run([&] {
            gx.resize(static_cast<std::size_t>(n));
            gy.resize(static_cast<std::size_t>(n));
        });
#pragma omp for schedule(static)
        for (Eigen::Index c = 0; c < count; ++c)
            guard.run([&] {
                const std::size_t idx = static_cast<std::size_t>(k0 + c);
                gaussian_samples(gauss, grid.ux[0] + shift * k.slope_x[idx], du, n, gx.data());
                gaussian_samples(gauss, grid.uy[0] + shift * k.slope_y[idx], du, n, gy.data());
                write(c, gx.data(), gy.data(), &phases.phase_x(0, phases.slot_x[idx]),
                      &phases.phase_y(0, phases.slot_y[idx]));
            });
    }
    guard.rethrow();
}

// Columns c = 0…count−1 of X and Y (for_each_factor_column) for kernels k0…k0+count−1, as
// complex matrices. Weights are applied by the caller.
template <typename Float>
void build_factors(const FootprintKernels& k, const SliceGrid& grid, const PhaseTables& phases, double lambda_um,
                   double shift_scale, Eigen::Index k0, Eigen::Index count, ComplexMatrix<Float>& xs,
                   ComplexMatrix<Float>& ys) {
    using Complex = std::complex<Float>;
    const Eigen::Index n = static_cast<Eigen::Index>(grid.ux.size());
    for_each_factor_column(k, grid, phases, lambda_um, shift_scale, k0, count,
                           [&](Eigen::Index c, const double* gx, const double* gy, const std::complex<double>* px,
                               const std::complex<double>* py) {
                               for (Eigen::Index p = 0; p < n; ++p) {
                                   xs(p, c) = Complex(gx[p] * px[p]);
                                   ys(p, c) = Complex(gy[p] * py[p]);
                               }
                           });
}

// c1 of every pixel of the n × n slice inside the disk (0 outside), row-major: the height-
// independent per-pixel factor of f = c1 |I|² (a plan computes it once per wavelength).
inline std::vector<double> disk_c1(const Query& query, double lambda_um, int n) {
    std::vector<double> c1(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), 0.0);
    for (int p = 0; p < n; ++p) {
        const double ox = slice_omega(p, n);
        for (int q = 0; q < n; ++q) {
            const double oy = slice_omega(q, n);
            if (ox * ox + oy * oy > 1.0) continue;
            c1[static_cast<std::size_t>(p) * n + q] =
                direction_factors(query.model, query.omega_i, ox, oy, lambda_um).c1;
        }
    }
    return c1;
}

// f = c1 |I|² over the disk (0 outside it and where the value is not finite), row-major.
// `c1`: disk_c1's table, or null to compute each pixel's factor here (the same values).
template <typename Float>
std::vector<Float> separable_slice(const ComplexMatrix<Float>& field, const Query& query, double lambda_um, int n,
                                   const std::vector<double>* c1 = nullptr) {
    std::vector<Float> slice(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), Float(0));
    if (c1) {
        // The table is 0 outside the disk (disk_c1), so every pixel takes the same formula
        // there (0, or a non-finite product written as 0): one branch-free pass, the same values.
        const double* factor = c1->data();
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n))
        for (int p = 0; p < n; ++p)
            for (int q = 0; q < n; ++q) {
                const std::size_t at = static_cast<std::size_t>(p) * n + q;
                const double value = factor[at] * static_cast<double>(std::norm(field(p, q)));
                slice[at] = std::isfinite(value) ? Float(value) : Float(0);
            }
        return slice;
    }
    RegionGuard guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n))
    for (int p = 0; p < n; ++p)
        guard.run([&] {
            for (const auto [q, ox, oy] : disk_row(p, n)) {
                const std::size_t at = static_cast<std::size_t>(p) * n + q;
                const double factor = c1 ? (*c1)[at]
                                         : direction_factors(query.model, query.omega_i, ox, oy, lambda_um).c1;
                const double value = factor * static_cast<double>(std::norm(field(p, q)));
                slice[at] = std::isfinite(value) ? Float(value) : Float(0);
            }
        });
    guard.rethrow();
    return slice;
}

}  // namespace wavebrdf::detail
