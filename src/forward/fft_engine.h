#pragma once
// Internal: the FFT engine. The slice's field is the Fourier transform
//   F(u) = ∫ f(x) e^{−i2π u·x} dx  of  f(x) = Σ_k w_k G_σ(x − δ_k) e^{−i2π b_k·(x − δ_k)}
// (G_σ the normalised 2-D Gaussian), sampled on the slice's grid u = U0 + j·du. Sampling in u
// at spacing du periodises f with period P = 1/du (Poisson: exact), so the engine
//  1. demodulates by e^{−i2π U0·x} (the window starts at frequency 0),
//  2. spreads every kernel, truncated at radius R_x, onto an Mx × My grid of spacing
//     h = P/M (separably: one vector in x, one in y, outer product, indices modulo M),
//  3. takes one 2-D FFT (FFTW_FORWARD) and keeps j < n, times hx·hy.
// Two errors, both set by `tolerance` (relative to the slice's peak): the truncation of each
// Gaussian at R_x = σ √(2 ln(1/t)), and the aliases of its spectrum (centre −b_k, radius
// R_u = √(ln(1/t) / (2π²σ²))), which M keeps out of the window; kernels whose whole spectrum
// lies farther than R_u from the window are skipped (their contribution is below t·|w_k|).
// M follows the slopes, so it is chosen at every call (FFTW plans are cached per size).
// The adjoint (the FieldEngine's transpose convention) embeds the cotangent in the grid, takes
// the same forward FFT and gathers every kernel with the same separable vectors.
// docs/fft_path.md explains the method, its error control and its cost.
#include <memory>
#include <vector>

#include "forward/field_engine.h"

namespace wavebrdf::detail {

// The grid an FftEngine call uses: its size and the kernels it spreads (for the cost model and
// the benchmarks).
struct FftGridInfo {
    int mx = 0, my = 0;           // FFT grid size (rows ↔ u_x, columns ↔ u_y)
    double hx_um = 0, hy_um = 0;  // grid spacing, µm
    int span_x = 0, span_y = 0;   // spread points per kernel and axis (at most)
    std::size_t kept = 0;         // kernels spread (the others are below the tolerance)
};

template <typename Float>
class FftEngine : public FieldEngine<Float> {
public:
    // `kernels`: kept by reference (its slopes are read at every call; its positions, σ and
    // size must not change while the engine lives). `grid`: the slice's SliceGrid (n entries
    // per axis, uniform with spacing 2/(nλ)). `lambda_um` > 0, 1 ≤ n ≤ 65536, `tolerance` in
    // [1e-12, 1e-2] (relative to the slice's peak; float engines reach ~1e-6 at best).
    // Throws std::invalid_argument / std::domain_error naming a bad value.
    FftEngine(const FootprintKernels& kernels, const SliceGrid& grid, double lambda_um, int n, double tolerance);
    ~FftEngine() override;
    FftEngine(const FftEngine&) = delete;
    FftEngine& operator=(const FftEngine&) = delete;

    // See FieldEngine. Every weights[v] has K = kernels.size() entries (std::invalid_argument
    // otherwise); shift_scale finite. OutOfMemory (memory.h) when the grid the slopes need
    // exceeds the machine's memory (checked before allocating).
    void forward(const KernelWeights& weights, double shift_scale, std::vector<ComplexMatrix<Float>>& fields) override;
    void adjoint(const KernelWeights& weights, double shift_scale, const std::vector<ComplexMatrix<Float>>& cotangents,
                 FieldGradient& gradient) override;

    // The grid the last call used (zeros before the first call).
    const FftGridInfo& last_grid() const { return m_info; }
    // The grid a call with `shift_scale` would use at the kernels' current slopes (no work).
    FftGridInfo plan_grid(double shift_scale) const;

private:
    struct Layout;
    struct Workspace;
    Layout layout(double shift_scale) const;
    void prepare(const Layout& layout, std::size_t grids);
    void check_weights(const KernelWeights& weights) const;

    const FootprintKernels& m_kernels;
    int m_n;
    double m_lambda_um, m_tolerance;
    double m_u0x, m_u0y, m_du;  // window start (cycles/µm) and spacing
    double m_radius_x_um;       // spatial truncation radius R_x
    double m_radius_u;          // spectral radius R_u (cycles/µm)
    std::unique_ptr<Workspace> m_work;
    FftGridInfo m_info;
};

// The smallest 2^a 3^b 5^c ≥ `at_least` (≥ 1); FFTW is fastest on these.
long long good_fft_size(long long at_least);

extern template class FftEngine<float>;
extern template class FftEngine<double>;

}  // namespace wavebrdf::detail
