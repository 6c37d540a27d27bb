#pragma once
// Internal: the node layer that turns every model into field-engine calls (field_engine.h).
// For pixel (p,q), with u = (ω_i + ω_o)/λ and S = C3/2 (docs/model.md §5; 1 for OHS, ROHS),
//   I_pq = Σ_k c_k w² c2_k · exp(−2π²σ²|u + S a_k|²) · e^{−i(4π/λ) S H_k} · e^{−i2π u·δ_k}
// (a_k = 2 s_k/λ; c2 = 1 except Kirchhoff's c2_k = 2S − λu_x s_kx − λu_y s_ky). For one fixed S
// this is one engine call with shift_scale S, so the layer interpolates in S: with Chebyshev
// nodes S_j over the S range of the disk's pixels (second kind, barycentric weights ℓ_j),
//   I_pq ≈ Σ_j ℓ_j(S_pq) F_j[p,q],  F_j = engine field, weights c_k w² e^{−i(4π/λ) S_j (H_k − H̄)}
// (Kirchhoff: three vectors w, w·s_x, w·s_y combined as 2S F⁰ − λu_x F^x − λu_y F^y). H̄, the
// mid-range of the footprint's heights, is a per-pixel phase |I|² does not see; it shrinks the
// S-dependence. The node count comes from the Chebyshev bound on a Bernstein ellipse (ρ):
//   |I − I_m| ≤ 4 ρ^{−(m−1)}/(ρ−1) · exp(α ε + β ε²) · W,  ε = (ρ − 1/ρ)/2,
//   α = (4π/λ) r max|H_k − H̄|,  β = 2π²σ² r² max|a_k|²,  r = half the S range,
//   W = Σ_k |c_k w²| (Kirchhoff: × (2 S_max + max|λu_x| |s_kx| + max|λu_y| |s_ky|))
// (summed per kernel, in cells of |H_k − H̄| and |a_k|²) minimised over ρ, and per pixel the
// pointwise form min(E, |sin θ sin((m−1)θ)| · Hermite bound), t = cos θ the pixel's S in [−1, 1]
// (0 at the nodes, e.g. normal light's specular peak at S = 1); a priori with the field at the
// middle node S_c, then checked against the computed slice: if max c1 E_pq (2|I| + E_pq) exceeds
// tolerance × the peak, the slice is computed again with more nodes (docs/c3_nodes.md).
#include <memory>
#include <vector>

#include "forward/field_engine.h"
#include "forward/separable.h"
#include "wavebrdf/kernel_gradient.h"

namespace wavebrdf {
class Progress;
}

namespace wavebrdf::detail {

// Most nodes the layer uses. A slice that would need more (a rough, steep surface far from the
// one-node regime) is left to the direct sum, which is then cheaper anyway: its cost per pixel
// and kernel is an exp and a sincos, a node's a few multiply-adds per weight vector.
constexpr int k_max_c3_nodes = 32;

// The kernels grouped for the bound: cell c holds kernels of total weight weight[c] (Σ|c_k w²|,
// Kirchhoff × its c2 bound) whose α_k ≤ alpha[c] and β_k ≤ beta[c] (α_k, β_k as α, β above
// with kernel k's own |H_k − H̄| and |a_k|²).
struct C3BoundCells {
    std::vector<double> weight, alpha, beta;
};

// min over ρ > 1 of 4 ρ^{−(nodes−1)}/(ρ−1) · Σ_c weight[c] exp(α_c ε + β_c ε²), ε = (ρ − 1/ρ)/2:
// the bound on |I − I_nodes| for `nodes` ≥ 2 Chebyshev points (second kind) in S.
double chebyshev_error_bound(int nodes, const C3BoundCells& cells);

// The pointwise form (Hermite's contour formula on E_ρ, minimised over ρ): at t ∈ [−1, 1],
// |I − I_nodes| ≤ chebyshev_node_factor(nodes, t) · chebyshev_hermite_bound(nodes, cells).
double chebyshev_hermite_bound(int nodes, const C3BoundCells& cells);
// |(1 − t²) U_{nodes−2}(t)| = |sin θ sin((nodes − 1) θ)|, t = cos θ: the normalised node polynomial
// of the second-kind points, 0 at the nodes (in [0, 1]).
double chebyshev_node_factor(int nodes, double t);

// The same for one cell of weight 1: the factor of W in the bound above; α, β ≥ 0.
double chebyshev_error_factor(int nodes, double alpha, double beta);

// The fewest nodes (2 … k_max_c3_nodes) whose bound is at most `target_error`
// (k_max_c3_nodes + 1 when none is).
int chebyshev_node_count(const C3BoundCells& cells, double target_error);
int chebyshev_node_count(double alpha, double beta, double weight_sum, double target_error);

template <typename Float>
class C3Nodes {
public:
    // The height-independent part of one slice: c1 and S of every pixel. λ in µm; `tolerance`
    // is RenderOptions::tolerance (relative to the slice's peak).
    C3Nodes(const Query& query, const SliceGrid& grid, double lambda_um, int n, double tolerance);

    // The slice f = c1 |I|² (row-major, 0 outside the disk and where not finite); `field`
    // receives I (up to a per-pixel phase: H̄). OHS and ROHS: one engine call, S ≡ 1.
    // Returns an empty vector (nodes() 0) when the tolerance needs more than k_max_c3_nodes
    // nodes: the caller then uses the direct sum.
    std::vector<Float> forward(FieldEngine<Float>& engine, const FootprintKernels& kernels, ComplexMatrix<Float>& field,
                               Progress* progress);

    // Per-kernel gradient of Σ weights · slice, the adjoint of the last forward (same kernels,
    // `field` its I). `weights`: n² values, row-major.
    KernelGradient adjoint(FieldEngine<Float>& engine, const FootprintKernels& kernels,
                           const ComplexMatrix<Float>& field, const std::vector<Float>& weights) const;

    int nodes() const { return static_cast<int>(m_node_s.size()); }  // of the last forward
    const std::vector<double>& node_s() const { return m_node_s; }   // S_j of the last forward
    double error_bound() const { return m_error; }                   // bound on |ΔI|, last forward
    const std::vector<double>& c1() const { return m_c1; }           // per pixel, row-major

private:
    // max over the disk of c1 E_pq (2 amp + E_pq), E_pq the pointwise bound with m nodes (log_sums:
    // the cells' ρ-dependent sums, c3_nodes.cpp).
    double pixel_error(int m, const std::vector<double>& log_sums, const std::vector<double>& amp) const;
    KernelWeights node_weights(const FootprintKernels& kernels, double s) const;
    // ℓ_j at pixel (p,q), j = 0 … nodes()−1, into `ell`.
    void lagrange(std::size_t at, double* ell) const;
    // `middle`: the engine's fields at the middle node (t = 0, odd node counts), or null.
    void compute_field(FieldEngine<Float>& engine, const FootprintKernels& kernels, ComplexMatrix<Float>& field,
                       Progress* progress, bool report, const std::vector<ComplexMatrix<Float>>* middle);

    Query m_query;
    SliceGrid m_grid;
    double m_lambda_um;
    int m_n;
    double m_tolerance;
    bool m_scaled;  // GHS, RGHS, Kirchhoff
    bool m_kirchhoff;
    // c1 and S of every pixel depend only on the model, ω_i, λ and n, so every plan of the same
    // wavelength and direction shares one copy (a recovery holds thousands of plans).
    struct PixelFactors {
        std::vector<double> c1, s;  // per pixel, row-major (s only when scaled)
        double s_lo = 1.0, s_hi = 1.0;
    };
    static std::shared_ptr<const PixelFactors> pixel_factors(const Query& query, double lambda_um, int n);
    std::shared_ptr<const PixelFactors> m_pixels;
    const std::vector<double>& m_c1;
    const std::vector<double>& m_s;
    double m_s_lo = 1.0, m_s_hi = 1.0;
    std::vector<double> m_node_t, m_node_s, m_bary;  // nodes in [−1, 1], in S, barycentric weights
    double m_h_ref = 0.0;
    double m_error = 0.0;
};

}  // namespace wavebrdf::detail
