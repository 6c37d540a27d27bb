#pragma once
// Internal: the separable engine (field_engine.h): on the slice's regular grid G_k(u) factorises
// into a function of u_x and one of u_y, so for each weight vector v
//   F_v = X · diag(weights[v]) · Yᵀ,  X[p,k] = exp(−2π²σ²(u_x[p] + b_kx)²) e^{−i2π u_x[p] δ_kx}
// (Y likewise in y), one complex matrix product of n × K by K × n. The V weight vectors share X
// and Y. Kernels are processed in chunks so the factor matrices stay within ~32 MiB; when all
// kernels fit one chunk and keep_factors(true) was called, the factors of each shift_scale are
// kept (up to ~64 MiB beyond the first) for the adjoint, which then skips rebuilding them.
// In single precision the complex products run as three real ones (Gauss: planar operands
// re, im and re + im; see PlanarFactors), ~30 % fewer flops than Eigen's complex product.
#include <memory>
#include <vector>

#include "forward/field_engine.h"
#include "forward/separable.h"

namespace wavebrdf::detail {

// A complex single-precision matrix as its real and imaginary parts and their sum, for the
// three-multiplication product (Gauss): with P1 = a_re b_re, P2 = a_im b_im and
// P3 = (a_re + a_im)(b_re + b_im), a·b = (P1 − P2) + i (P3 − P1 − P2). The imaginary part's
// rounding scales with |a||b| rather than with |a·b|: a few float ulps of the operands' scale.
struct PlanarFactors {
    Eigen::MatrixXf re, im, sum;
    void resize(Eigen::Index rows, Eigen::Index cols) {
        re.resize(rows, cols);
        im.resize(rows, cols);
        sum.resize(rows, cols);
    }
    // Columns [0, count) of `m` into columns [0, count).
    void assign(const ComplexMatrix<float>& m, Eigen::Index count) {
        re.leftCols(count) = m.leftCols(count).real();
        im.leftCols(count) = m.leftCols(count).imag();
        sum.leftCols(count) = re.leftCols(count) + im.leftCols(count);
    }
};

// build_factors<float> (separable.h) written in planar form: columns [0, count) of xs and ys
// (sized by the caller, at least n × count) for kernels k0 … k0 + count − 1. The same bits as
// build_factors<float> followed by PlanarFactors::assign (each entry the double product of the
// Gaussian and the phase, rounded once to float; sum = re + im in float), without the
// interleaved complex copy in between.
void build_planar_factors(const FootprintKernels& k, const SliceGrid& grid, const PhaseTables& phases,
                          double lambda_um, double shift_scale, Eigen::Index k0, Eigen::Index count,
                          PlanarFactors& xs, PlanarFactors& ys);

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
        ComplexMatrix<Float> xs, ys;  // unweighted, all kernels (double engines)
        PlanarFactors px, py;         // the same in planar form (float engines)
    };
    // The kept factors of `shift_scale`, or null; drops them all when the slopes have changed.
    const Kept* kept(double shift_scale);
    // Whether `bytes` more may be kept (the first entry always may; it records the slopes).
    bool admit(double bytes);
    void keep(double shift_scale, ComplexMatrix<Float>& xs, ComplexMatrix<Float>& ys);
    void keep(double shift_scale, PlanarFactors& px, PlanarFactors& py);
    // The planar X and Y that forward_planar and adjoint_planar read chunk by chunk: the kept
    // factors of the call's shift_scale (every kernel, so chunk k0 starts at column k0), or one
    // chunk built at a time into this storage (starting at column 0).
    struct PlanarChunk {
        const Kept* cached = nullptr;
        PlanarFactors planar_x, planar_y;
        void reserve(Eigen::Index rows, Eigen::Index cols);
        const PlanarFactors& x() const { return cached ? cached->px : planar_x; }
        const PlanarFactors& y() const { return cached ? cached->py : planar_y; }
    };
    // Makes kernels [k0, k0 + count) available in `chunk`; returns the column of kernel k0.
    Eigen::Index load_chunk(double shift_scale, Eigen::Index k0, Eigen::Index count, PlanarChunk& chunk);
    // The single-precision bodies of forward and adjoint (three real products per complex one).
    void forward_planar(const KernelWeights& weights, double shift_scale, std::vector<ComplexMatrix<Float>>& fields);
    void adjoint_planar(const KernelWeights& weights, double shift_scale,
                        const std::vector<ComplexMatrix<Float>>& cotangents, FieldGradient& gradient);

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
