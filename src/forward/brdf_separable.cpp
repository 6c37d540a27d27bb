// The separable path: for OHS and ROHS, ĝ_k(u) factorises into a function of u_x and one
// of u_y (docs/model.md §10), so on the slice's grid
//   I(u_x[p], u_y[q]) = Σ_k X[p,k] · w_k · Y[q,k]  =  (X · diag(w) · Yᵀ)[p,q]
// with X[p,k] = exp(−2π²σ²(u_x[p] + a_kx)²) e^{−i2π u_x[p] δ_kx}, the same in y, and
// w_k = c_k w² e^{−i(4π/λ) H_k}. (The kernel's C_k e^{−i2π(u+a)·μ} collapses to
// w² e^{−i(4π/λ)H_k} e^{−i2π u·μ_k}; μ_k = μ_p + δ_k and e^{−i2π u·μ_p} is a global phase.)
#include <algorithm>
#include <cmath>
#include <string>
#include <stdexcept>

#include "forward/separable.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

namespace detail {

template <typename Float>
ComplexMatrix<Float> separable_field(const FootprintKernels& k, const SliceGrid& grid, const PhaseTables& phases,
                                     double lambda_um, int n, Progress* progress, SeparableFactors<Float>* keep) {
    const Eigen::Index total = static_cast<Eigen::Index>(k.size());
    const Eigen::Index chunk = chunk_size(n, sizeof(std::complex<Float>), 2);
    const Eigen::Index cols = std::min(chunk, std::max<Eigen::Index>(total, 1));
    const std::string size = std::to_string(n) + "x" + std::to_string(n);
    ComplexMatrix<Float> field = allocating("the " + size + " slice's field",
                                            double(n) * n * sizeof(std::complex<Float>),
                                            [&] { return ComplexMatrix<Float>(ComplexMatrix<Float>::Zero(n, n)); });
    ComplexMatrix<Float> xs, ys;
    allocating("the " + size + " slice's factor matrices", 2.0 * double(n) * double(cols) * sizeof(std::complex<Float>),
               [&] {
                   xs.resize(n, cols);
                   ys.resize(n, cols);
               });
    const long long units = work_units(n);
    long long reported = 0;
    for (Eigen::Index k0 = 0; k0 < total; k0 += chunk) {
        const Eigen::Index count = std::min(chunk, total - k0);
        build_factors<Float>(k, grid, phases, lambda_um, k0, count, true, xs, ys);
        for_column_blocks(n, double(n) * n * double(count), [&](long long first, long long cols) {
            field.middleCols(first, cols).noalias() += xs.leftCols(count) *
                                                       ys.leftCols(count).middleRows(first, cols).transpose();
        });
        if (progress) {
            const long long target = units * (k0 + count) / total;
            progress->advance(target - reported);
            reported = target;
        }
    }
    if (progress && reported < units) progress->advance(units - reported);
    if (keep && total > 0 && total <= chunk) {
        keep->xs = std::move(xs);
        keep->ys = std::move(ys);
    }
    return field;
}

template ComplexMatrix<float> separable_field<float>(const FootprintKernels&, const SliceGrid&, const PhaseTables&,
                                                     double, int, Progress*, SeparableFactors<float>*);
template ComplexMatrix<double> separable_field<double>(const FootprintKernels&, const SliceGrid&, const PhaseTables&,
                                                       double, int, Progress*, SeparableFactors<double>*);

}  // namespace detail

template <typename Float>
std::vector<Float> render_slice_separable(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                                          Progress* progress) {
    if (!is_separable(query.model))
        throw std::invalid_argument(std::string("model ") + to_string(query.model) +
                                    " is not separable; expected OHS or ROHS");
    const detail::ComplexMatrix<Float> field = detail::separable_field<Float>(k, query, lambda_um, n, progress);
    return detail::separable_slice<Float>(field, query, lambda_um, n);
}

template std::vector<float> render_slice_separable<float>(const FootprintKernels&, const Query&, double, int,
                                                          Progress*);
template std::vector<double> render_slice_separable<double>(const FootprintKernels&, const Query&, double, int,
                                                            Progress*);

}  // namespace wavebrdf
