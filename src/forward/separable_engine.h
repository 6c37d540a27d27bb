#pragma once
// Internal: the separable engine (field_engine.h): on the slice's regular grid G_k(u) factorises
// into a function of u_x and one of u_y, so for each weight vector v
//   F_v = X · diag(weights[v]) · Yᵀ,  X[p,k] = exp(−2π²σ²(u_x[p] + b_kx)²) e^{−i2π u_x[p] δ_kx}
// (Y likewise in y), one complex matrix product of n × K by K × n. The V weight vectors share X
// and Y. Kernels are processed in chunks so the factor matrices stay within ~32 MiB; when all
// kernels fit one chunk and keep_factors(true) was called, the factors of each shift_scale are
// kept (up to ~64 MiB beyond the first) for the adjoint, which then skips rebuilding them.
#include <memory>
#include <vector>

#include "forward/field_engine.h"
#include "forward/separable.h"

namespace wavebrdf::detail {

template <typename Float>
class SeparableEngine : public FieldEngine<Float> {
public:
    // `kernels` is referenced, not copied: it must outlive the engine (its slopes are read at
    // every call). `grid` is the slice's (n points each way); λ in µm.
    SeparableEngine(const FootprintKernels& kernels, const SliceGrid& grid, double lambda_um, int n);

    // Keep the factor matrices built by forward for the adjoint (differentiable plans).
    void keep_factors(bool keep);
    // Frees the phase tables and the kept factors (the next call rebuilds the tables, with the
    // same values): what a plan kept between calls is then only the kernels.
    void release_tables();

    void forward(const KernelWeights& weights, double shift_scale, std::vector<ComplexMatrix<Float>>& fields) override;
    void adjoint(const KernelWeights& weights, double shift_scale, const std::vector<ComplexMatrix<Float>>& cotangents,
                 FieldGradient& gradient) override;

private:
    struct Kept {
        double shift_scale = 0.0;
        ComplexMatrix<Float> xs, ys;  // unweighted, all kernels
    };
    // The kept factors of `shift_scale`, or null; drops them all when the slopes have changed.
    const Kept* kept(double shift_scale);
    void keep(double shift_scale, ComplexMatrix<Float>& xs, ComplexMatrix<Float>& ys);

    const FootprintKernels& m_kernels;
    SliceGrid m_grid;
    std::unique_ptr<PhaseTables> m_phases;  // built on first use (phases())
    const PhaseTables& phases();
    double m_lambda_um;
    int m_n;
    bool m_keep = false;
    std::vector<Kept> m_kept;
    std::vector<double> m_kept_slope_x, m_kept_slope_y;  // the slopes the kept factors were built from
    double m_kept_bytes = 0.0;
};

}  // namespace wavebrdf::detail
