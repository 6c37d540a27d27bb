#pragma once
// A slice plan (in the manner of FINUFFT's plans): everything of a set of slice queries that
// does not depend on the heights, computed once; then set_heights / forward / adjoint any
// number of times. Of the model (docs/model.md §10), only the kernels' C_k (through H_k) and
// a_k (through the slopes s_k) depend on the heights. The plan keeps the rest:
//  - the heightfield's geometry (rows, cols, texel width, vertical scale);
//  - the footprint (x, y, σ_p): its kernels' texels, window weights c_k w² and offsets δ_k;
//  - the directions and wavelengths: the slice grid u = (ω_i + ω_o)/λ per wavelength, the
//    separable path's phase tables e^{−i2π u δ} (they depend only on δ and u), and the
//    per-pixel factors c1 and C3 over the disk (differentiable plans);
//  - the spectral mix (spectral_mix_weights), the model and the RenderOptions (path, pruning).
// render_slice, render_rgb, slice_gradient and SliceAdjoint are one-call conveniences on top.
//
// A plan is not thread-safe (forward and set_heights change it); use one plan per thread.
#include <array>
#include <cstddef>
#include <memory>
#include <vector>

#include "wavebrdf/brdf.h"

namespace wavebrdf {

// Throws std::domain_error when options.prune_tolerance is outside 0 … 1e-6 or
// options.tolerance outside 1e-12 … 1e-2, and std::invalid_argument when options.path is Fft
// (not available yet). Every model has the separable and direct paths.
void validate(const RenderOptions& options, Model model);

template <typename Float>
class SlicePlan {
public:
    // A plan for the slices of `query` at `lambdas_um` (µm; at least one), resolution ×
    // resolution pixels (1…8192), with `channels` output values per pixel: 1 (one wavelength
    // only: its slice) or 3 (RGB through spectral_mix_weights: one wavelength gives R = G = B).
    // `heightfield` gives the geometry and the first heights (set_heights replaces them).
    // `differentiable`: keep what adjoint needs (each wavelength's field and slice); false for
    // forward-only use, which then holds one wavelength's field at a time.
    // Validates like render_rgb (std::domain_error / std::invalid_argument naming the value;
    // std::invalid_argument for channels other than 1 or 3, or 1 with several wavelengths).
    // options.progress is advanced by every forward; options.max_memory_gb is not checked here
    // (render_slice and render_rgb check it before building their plan).
    SlicePlan(const Heightfield& heightfield, const Query& query, const std::vector<double>& lambdas_um, int resolution,
              int channels = 3, const RenderOptions& options = {}, bool differentiable = true);
    ~SlicePlan();
    SlicePlan(SlicePlan&&) noexcept;
    SlicePlan& operator=(SlicePlan&&) noexcept;

    // New heights: rows·cols raw values h[i][j] (texel units, row-major). Recomputes the
    // kernels' H_k and slopes only (cost: the footprint's kernels, not rows·cols). Throws
    // std::invalid_argument on a size mismatch and std::domain_error on a non-finite value among
    // those the footprint reads (the others cannot change the slice). Invalidates the last forward.
    void set_heights(const std::vector<double>& values);
    // The same from a heightfield of this plan's geometry (std::invalid_argument otherwise).
    void set_heights(const Heightfield& heightfield);

    // Renders every wavelength for the current heights: resolution² · channels values
    // (row-major, channel-interleaved), the same as render_slice / render_rgb bit for bit.
    const std::vector<Float>& forward();
    // After forward, on a differentiable plan: wavelength l's own slice (resolution² values).
    const std::vector<Float>& slice(std::size_t wavelength) const;

    // After forward, on a differentiable plan: adds scale · ∂(Σ weights · output)/∂h into
    // `gradient` (rows·cols; see adjoint.h for the gradient convention). `weights` has
    // resolution² · channels entries (as forward's output); pixels outside the disk are ignored.
    void adjoint(const std::vector<double>& weights, std::vector<double>& gradient, double scale = 1.0) const;
    // The same for one wavelength's slice: adds ∂(Σ weights · slice(l))/∂h (weights: resolution²).
    void adjoint_wavelength(std::size_t wavelength, const std::vector<Float>& weights,
                            std::vector<double>& gradient) const;

    // After forward, on a differentiable plan: ∂(Σ weights · output)/∂(x_um, y_um), the
    // gradient with respect to the footprint centre (µm⁻¹ times the output's unit; weights as
    // for adjoint). Only the window weights c_k = G(μ_k − μ_p) depend on the centre (a common
    // phase e^{−i2π u·μ_p} drops out of |I|²), so it is Σ_k ∂L/∂ln c_k · δ_k / σ_p² from one
    // adjoint pass. The 3σ_p cut is held fixed: a kernel entering or leaving the cut (weight
    // e^{−4.5} ≈ 1 % of the centre's) is a jump the derivative does not see.
    std::array<double, 2> position_gradient(const std::vector<double>& weights) const;
    // adjoint and position_gradient in one pass: adds scale · ∂(Σ weights · output)/∂h into
    // `gradient` and returns scale · ∂(Σ weights · output)/∂(x_um, y_um).
    std::array<double, 2> adjoint_with_position(const std::vector<double>& weights, std::vector<double>& gradient,
                                                double scale = 1.0) const;

    // Frees what forward kept for the adjoint (every wavelength's field, factors and slice),
    // forward's output (its reference is then empty) and the phase tables the next call
    // rebuilds bit for bit; the kernels and the per-pixel factors (shared by every plan of the
    // same wavelength, direction and resolution) stay. adjoint and slice need a new forward
    // afterwards. A plan kept this way between calls holds ~10 KB (48² slices, σ_p 1.5 texels).
    void release();

    // True when this plan serves exactly these arguments (geometry, query, wavelengths,
    // resolution, channels, path and prune tolerance), so a cache can reuse it.
    bool matches(const Heightfield& heightfield, const Query& query, const std::vector<double>& lambdas_um,
                 int resolution, int channels, const RenderOptions& options) const;

    // The texel rows and columns adjoint / adjoint_wavelength add into: the footprint's kernels'
    // and their neighbours' (the slopes' central differences), wrapped around the tile, each
    // once, ascending. Every gradient value the adjoint writes lies in rows × cols (a box for
    // exact per-observation sums, core/exact_sum.h). Depends on the geometry only.
    void gradient_box(std::vector<int>& rows, std::vector<int>& cols) const;

    int resolution() const;
    int channels() const;
    std::size_t wavelengths() const;
    std::size_t kernels() const;  // footprint kernels within 3σ_p

private:
    struct State;
    std::unique_ptr<State> m_state;
};

}  // namespace wavebrdf
