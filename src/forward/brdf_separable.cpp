// The separable path for one slice (docs/model.md §10): the node layer (forward/c3_nodes.h)
// over the separable engine (forward/separable_engine.h). For OHS and ROHS, ĝ_k(u) factorises
// into a function of u_x and one of u_y, so on the slice's grid
//   I(u_x[p], u_y[q]) = Σ_k X[p,k] · w_k · Y[q,k]  =  (X · diag(w) · Yᵀ)[p,q]
// with X[p,k] = exp(−2π²σ²(u_x[p] + a_kx)²) e^{−i2π u_x[p] δ_kx}, the same in y, and
// w_k = c_k w² e^{−i(4π/λ) H_k}. (The kernel's C_k e^{−i2π(u+a)·μ} collapses to
// w² e^{−i(4π/λ)H_k} e^{−i2π u·μ_k}; μ_k = μ_p + δ_k and e^{−i2π u·μ_p} is a global phase.)
// GHS, RGHS and Kirchhoff scale heights and slopes by S = C3/2 per pixel: one such product per
// Chebyshev node in S, interpolated per pixel (forward/c3_nodes.h).
#include "forward/c3_nodes.h"
#include "forward/field_engine.h"
#include "forward/separable.h"
#include "wavebrdf/brdf.h"

namespace wavebrdf {

template <typename Float>
std::vector<Float> render_slice_separable(const FootprintKernels& k, const Query& query, double lambda_um, int n,
                                          Progress* progress, double tolerance) {
    const detail::SliceGrid grid(query, lambda_um, n);
    const auto engine = detail::make_field_engine<Float>(RenderPath::Separable, k, grid, lambda_um, n, tolerance,
                                                         false);
    detail::C3Nodes<Float> nodes(query, grid, lambda_um, n, tolerance);
    detail::ComplexMatrix<Float> field;
    std::vector<Float> slice = nodes.forward(*engine, k, field, progress);
    // More nodes than k_max_c3_nodes would be needed: the direct sum is cheaper and exact.
    if (slice.empty()) return render_slice_direct<Float>(k, query, lambda_um, n, 0.0, progress);
    return slice;
}

template std::vector<float> render_slice_separable<float>(const FootprintKernels&, const Query&, double, int, Progress*,
                                                          double);
template std::vector<double> render_slice_separable<double>(const FootprintKernels&, const Query&, double, int,
                                                            Progress*, double);

}  // namespace wavebrdf
