#pragma once
// Internal: the engines that compute a slice's field on its regular grid, and their adjoints.
// Every model reduces to them: OHS and ROHS are one call with shift_scale 1; GHS, RGHS and
// Kirchhoff are one call per Chebyshev node S_j of C3/2 (forward/c3_nodes.h), Kirchhoff with
// three weight vectors. Two engines compute the same sum:
//  - SeparableEngine (forward/separable_engine.h): complex matrix products X · diag(w) · Yᵀ;
//  - FftEngine (forward/fft_engine.h): the kernels spread onto a fine spatial grid, folded
//    modulo the period the slice's u spacing implies, one FFT, the slice's window cut out.
//
// What an engine computes, for V weight vectors at once (all sharing one G_k):
//   F_v[p,q] = Σ_k weights[v][k] · G_k(ux[p], uy[q]),
//   G_k(u)   = exp(−2π²σ² |u + b_k|²) · e^{−i2π u·δ_k},
//   b_k      = shift_scale · (2/λ) · (slope_x[k], slope_y[k])   (cycles/µm)
// with σ = kernels.sigma_um, δ_k = (dx_um[k], dy_um[k]) and u the engine's SliceGrid
// (u = (ω_i + ω_o)/λ). The kernels' slopes are read at each call (they follow set_heights);
// their positions, σ, the grid and λ are fixed when the engine is made.
// (OHS: weights[0][k] = c_k w² e^{−i(4π/λ)H_k}; a GHS node S_j: c_k w² e^{−i(4π/λ) S_j H_k},
// shift_scale S_j.)
//
// Adjoint convention (the one separable_backward uses): for a real loss L the caller gives
//   B_v = ∂L/∂F_v  with  dL = 2 Re Σ_pq B_v[p,q] · dF_v[p,q]
// and receives (FieldGradient)
//   weight[v][k] = Σ_pq B_v[p,q] · G_k(u_pq)      so that  dL = 2 Re Σ_vk weight[v][k] · dweights[v][k],
//   shift_x[k]   = 2 Re Σ_v Σ_pq B_v[p,q] · weights[v][k] · ∂G_k/∂b_kx   (= ∂L/∂b_kx; likewise y).
#include <complex>
#include <memory>
#include <vector>

#include "forward/separable.h"
#include "wavebrdf/brdf.h"

namespace wavebrdf::detail {

// Per-kernel weight vectors: weights[v][k], v = 0…V−1, k = 0…K−1.
using KernelWeights = std::vector<std::vector<std::complex<double>>>;

struct FieldGradient {
    KernelWeights weight;                  // [v][k], see above
    std::vector<double> shift_x, shift_y;  // [k]: ∂L/∂b_k
};

template <typename Float>
class FieldEngine {
public:
    virtual ~FieldEngine() = default;
    // fields: resized to V = weights.size(), each n × n.
    virtual void forward(const KernelWeights& weights, double shift_scale,
                         std::vector<ComplexMatrix<Float>>& fields) = 0;
    // cotangents: V matrices n × n (B_v above). `gradient` is overwritten.
    virtual void adjoint(const KernelWeights& weights, double shift_scale,
                         const std::vector<ComplexMatrix<Float>>& cotangents, FieldGradient& gradient) = 0;
};

// The engine of `path` for one slice (field_engine.cpp): SeparableEngine for Separable and Auto
// (keep_factors as SeparableEngine::keep_factors: differentiable plans), FftEngine for Fft;
// throws std::invalid_argument for Direct (no engine). Callers resolve Auto first
// (choose_field_path, path_cost.h) where the FFT engine may be cheaper.
// `kernels` must outlive the engine; `tolerance` is RenderOptions::tolerance (for engines that
// approximate).
template <typename Float>
std::unique_ptr<FieldEngine<Float>> make_field_engine(RenderPath path, const FootprintKernels& kernels,
                                                      const SliceGrid& grid, double lambda_um, int n, double tolerance,
                                                      bool keep_factors);

}  // namespace wavebrdf::detail
