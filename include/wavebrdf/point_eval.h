#pragma once
// Point evaluation: the BRDF of one footprint at one pair of directions (ω_i, ω_o), for many
// such samples and several wavelengths at once — what a camera pixel needs, where every pixel
// has its own footprint centre, its own σ_p and its own directions. The value is the slice's
// (docs/model.md §5, §10): f_r = c1 · |I(u)|², u = (ω_i + ω_o)/λ, over the kernels within 3σ_p
// of the centre, so a sample equals render_slice of its footprint at its direction.
//
// The sum is written per kernel k as
//   I(λ) = Σ_k a_k exp(−e_k / λ²) e^{−i 2π p_k / λ},
//   a_k = c_k w² K_k,  e_k = 2π²σ² |ω_h + 2S s_k|²,  p_k = 2S H_k + ω_h · δ_k,
// with ω_h = (ω_i + ω_o)_xy, S and K_k of the model (§5): everything but the two exponentials is
// independent of λ, so the kernels are gathered once per sample and the wavelengths are a short
// inner loop. p_k is the kernel's optical path difference in µm.
//
// Pruning with a stated bound: with prune_tolerance τ > 0, a kernel whose Gaussian exponent
// e_k / λ_max² exceeds T = ln(3/τ) is skipped at every wavelength (its factor exp(−e_k/λ²) is
// below e^{−T} for all λ ≤ λ_max). The skipped amplitude is then ε ≤ e^{−T} A with
// A = Σ_k |a_k|, and since |I| ≤ A every value satisfies
//   |f − f_unpruned| ≤ c1 (2A + ε) ε ≤ 3 e^{−T} c1 A² = τ · c1 A²,
// where c1 A² is the largest value the footprint could take at that direction (all kernels in
// phase; the specular peak of a flat mirror). evaluate() can return that bound per value.
#include <array>
#include <cstddef>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf {

// One sample: a footprint (centre and σ_p, µm, as Query) and two projected directions, ω_i
// towards the light and ω_o towards the viewer, both with |ω| < 1.
struct PointSample {
    double x_um = 0.0, y_um = 0.0;
    double sigma_p_um = 10.0;
    std::array<double, 2> omega_i{{0.0, 0.0}};
    std::array<double, 2> omega_o{{0.0, 0.0}};
};

struct PointEvalOptions {
    Model model = Model::OHS;
    // τ of the header: 0 (the full sum, equal to render_slice's direct path without pruning)
    // or 1e-12 … 1e-1.
    double prune_tolerance = 0.0;
    // evaluate() in single precision (float kernels and polynomials, twice the SIMD lanes):
    // values within about 1e-5 of c1 A² of the double sum (tests/point_eval_test.cpp); the
    // pruning bound does not cover that rounding. adjoint() and tangent() stay in double.
    bool single_precision = false;
};

// Throws std::domain_error naming the value: σ_p or the centre as validate(Query) does, σ_p too
// large for the tile (validate_footprint), |ω_i| or |ω_o| ≥ 1 or not finite.
void validate(const PointSample& sample, const Heightfield& heightfield);
// Throws std::domain_error unless τ is 0 or within 1e-12 … 1e-1.
void validate_prune_tolerance(double prune_tolerance);

// The heightfield's heights and slopes per texel (3 doubles per texel: the only memory beyond
// the caller's outputs), built once and shared by every evaluation; thread-safe to use.
class PointEvaluator {
public:
    // Validates the wavelengths (validate_lambda, at least one, at most k_max_spectral_samples)
    // and the options; copies what it needs of the heightfield.
    PointEvaluator(const Heightfield& heightfield, std::vector<double> lambdas_um, const PointEvalOptions& options);

    std::size_t wavelengths() const { return m_lambdas.size(); }
    const std::vector<double>& lambdas_um() const { return m_lambdas; }
    const PointEvalOptions& options() const { return m_options; }

    // f_r of sample s at wavelength l into values[s · L + l] (L = wavelengths()), 1/sr; a value
    // that is not finite (cos θ = 0 at the rim for ROHS, RGHS, Kirchhoff) is written as 0.
    // `bound` (optional, same layout): the a-posteriori pruning bound c1 (2|Ĩ| + ε) ε of each
    // value (0 without pruning). Samples are assumed valid (validate them first); threads over
    // the samples unless called inside a parallel region.
    void evaluate(const PointSample* samples, std::size_t count, double* values, double* bound = nullptr) const;

    // The adjoint: adds Σ_{s,l} weights[s · L + l] · ∂f_{s,l}/∂h into `gradient` (rows · cols,
    // per raw height value h in texel units; an empty vector is sized and zeroed first). The same
    // kernels as evaluate(), pruned the same way, so it is the exact gradient of what evaluate
    // returns. Non-finite values contribute nothing.
    void adjoint(const PointSample* samples, std::size_t count, const double* weights,
                 std::vector<double>& gradient) const;

    // The tangent: Σ_h ∂f_{s,l}/∂h · direction[h] into values[s · L + l] (for the dot-product
    // check of the adjoint; direction has rows · cols values).
    void tangent(const PointSample* samples, std::size_t count, const std::vector<double>& direction,
                 double* values) const;

    int rows() const { return m_rows; }
    int cols() const { return m_cols; }

private:
    Heightfield m_heightfield;  // for the footprint's kernel selection (gabor.h's, the same kernels)
    std::vector<double> m_lambdas;
    PointEvalOptions m_options;
    double m_cutoff;  // T (infinity without pruning)
    int m_rows, m_cols;
    std::vector<double> m_height_um, m_slope_x, m_slope_y;
};

}  // namespace wavebrdf
