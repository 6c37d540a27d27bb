#pragma once
// Gradients of BRDF slices with respect to the heights, by hand-derived adjoints of the
// model (docs/model.md §12): h → (H_k, s_k) → (C_k, a_k) → I(u) → f_r → loss.
// No tape: the backward pass keeps only the forward's field I (n² complex values) and
// rebuilds the kernel factors chunk by chunk, so memory is that of the forward pass.
//
// Separable path (OHS, ROHS): with B = W ⊙ c1 ⊙ conj(I), the gradient needs Z = B·Y and
// V = Bᵀ·X, two more matrix products of the forward's size. Direct path (all models): every
// pixel scatters into per-kernel accumulators.
// For many evaluations of the same queries, build a SlicePlan (slice_plan.h) once: the
// functions here are one-call conveniences on top of it.
//
// The gradient convention (every gradient of the forward / adjoint / observation code):
// a gradient output ACCUMULATES. `std::vector<double>& gradient` (or, where the gradient is
// optional, a non-null `std::vector<double>* gradient`) receives the gradient ADDED to what it
// holds; an empty vector is first resized to the expected size and zeroed; a non-empty vector
// of any other size is refused (std::invalid_argument). So gradients of sums (wavelengths,
// observations, positions) are sums of calls, and a caller that wants one gradient alone
// passes an empty (or clear()ed) vector.
#include <functional>
#include <memory>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/kernel_gradient.h"

namespace wavebrdf {

// The gradient of L = Σ_p weights[p] · slice[p] (a vector-Jacobian product of one slice) with
// respect to every raw height value h[i][j] (texel units, as stored in the Heightfield), added
// into `gradient` (rows·cols, row-major; resized and zeroed when empty). Returns the slice.
// `weights` has resolution² entries; entries outside the disk are ignored.
template <typename Float>
std::vector<Float> slice_gradient(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                  const std::vector<Float>& weights, std::vector<double>& gradient,
                                  const RenderOptions& options = {});

// The same, with the weights computed from the slice after the forward pass (for a loss L(f):
// weights = ∂L/∂f). The callback receives the slice and returns the weights.
template <typename Float>
std::vector<Float> slice_gradient(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                  const std::function<std::vector<Float>(const std::vector<Float>&)>& weights_of_slice,
                                  std::vector<double>& gradient, const RenderOptions& options = {});

// A slice whose forward pass has run and whose backward pass can be called later, any number
// of times (e.g. once per loss, or after the slices of other wavelengths are known, as a
// spectral loss needs). Holds the forward's field: n² complex values plus the kernels.
template <typename Float>
class SliceAdjoint {
public:
    // Validates like render_slice and runs the forward pass (a one-wavelength SlicePlan). Holds
    // no reference to `heightfield`.
    SliceAdjoint(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                 const RenderOptions& options = {});
    ~SliceAdjoint();
    SliceAdjoint(SliceAdjoint&&) noexcept;
    SliceAdjoint& operator=(SliceAdjoint&&) noexcept;

    const std::vector<Float>& slice() const;
    // Adds ∂(Σ weights · slice)/∂h into `gradient` (rows·cols; resized and zeroed when empty).
    void backward(const std::vector<Float>& weights, std::vector<double>& gradient) const;

private:
    struct State;
    std::unique_ptr<State> m_state;
};

// The tangent (Jacobian-vector product) of the direct sum: d slice for a height perturbation
// `direction` (rows·cols, texel units). The reference for the adjoint's dot-product test.
std::vector<double> slice_tangent_direct(const Heightfield& heightfield, const Query& query, double lambda_um,
                                         int resolution, const std::vector<double>& direction);

}  // namespace wavebrdf
