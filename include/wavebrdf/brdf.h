#pragma once
// Rendering BRDF slices (docs/model.md §1, §6): f_r over the projected outgoing disk.
//
// Two paths compute the same sum over the footprint's kernels:
//  - separable: for OHS and ROHS, I = X · diag(c_k C_k) · Yᵀ on the slice's regular grid, a
//    complex matrix product (exact: no pruning beyond the model's 3σ_p cut); for GHS, RGHS
//    and Kirchhoff one such product per Chebyshev node in C3, interpolated per pixel (error
//    within RenderOptions::tolerance of the slice's peak);
//  - direct: every pixel sums every kernel (all five models), optionally skipping kernels
//    whose Gaussian factor is so small that the total error stays below `prune_tolerance`
//    times the slice's peak (checked after rendering; re-rendered tighter if not met).
// Slices are row-major n × n: value[i * n + j] for ω_o = (slice_omega(i), slice_omega(j)),
// zero outside the unit disk; non-finite values (cos θ_o = 0 at the rim) are written as 0.
#include <vector>

#include "wavebrdf/gabor.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf {

class Progress;

// Separable: the field as complex matrix products (GHS, RGHS and Kirchhoff: one product per
// Chebyshev node in C3); Fft: the kernels spread onto a fine grid, folded and Fourier
// transformed (the same nodes); Direct: every pixel sums every kernel. Auto picks by cost.
enum class RenderPath { Auto, Separable, Direct, Fft };

struct RenderOptions {
    RenderPath path = RenderPath::Auto;
    // Separable (GHS-type models) and Fft paths: bound on their error relative to the slice's
    // peak, which sets the number of C3 nodes and the FFT grid; 1e-12 … 1e-2.
    double tolerance = 1e-6;
    // Direct path: bound on the pruning error relative to the slice's peak; at most 1e-6.
    // 0 disables pruning (the plain reference sum).
    double prune_tolerance = 1e-7;
    Progress* progress = nullptr;  // advanced by `work_units` (below) per slice
    // render_slice and render_rgb refuse (OutOfMemory, before any work) a render whose
    // estimate_render_bytes exceeds this many GB; 0: the physical memory.
    double max_memory_gb = 0.0;
};

// Estimated peak memory (bytes) of render_rgb (`rgb`) or render_slice of `heightfield` for
// `query` at `resolution`, in float (`float_bytes` 4) or double (8): the footprint's kernels
// (about π(3σ_p/w)², at most the heightfield's texels), the slice and the RGB result, and the
// path's field (and factor matrices, at most 32 MiB). Arguments as render_slice (unchecked).
double estimate_render_bytes(const Heightfield& heightfield, const Query& query, int resolution,
                             const RenderOptions& options, std::size_t float_bytes, bool rgb);

// Units of progress one slice reports (so callers can size a Progress bar).
long long work_units(int resolution);

// One single-wavelength slice of `heightfield` for `query` at λ = lambda_um (µm),
// resolution × resolution pixels (1…8192). Validates every argument (std::domain_error /
// std::invalid_argument naming the value). Float is float or double.
template <typename Float>
std::vector<Float> render_slice(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                const RenderOptions& options = {});

// The separable matrix-product path, every model (GHS, RGHS and Kirchhoff: one product per
// Chebyshev node in C3, as many as keep the error within `tolerance` of the slice's peak,
// 1e-12 … 1e-2). Arguments are assumed valid.
template <typename Float>
std::vector<Float> render_slice_separable(const FootprintKernels& kernels, const Query& query, double lambda_um,
                                          int resolution, Progress* progress = nullptr, double tolerance = 1e-6);

// The direct sum, the slow reference for every model. `prune_tolerance` as in RenderOptions.
template <typename Float>
std::vector<Float> render_slice_direct(const FootprintKernels& kernels, const Query& query, double lambda_um,
                                       int resolution, double prune_tolerance = 0.0, Progress* progress = nullptr);

// An RGB slice (resolution² × 3, row-major, channel-interleaved). One wavelength: its slice in
// R, G and B. Several: each wavelength's slice weighted to linear sRGB with
// spectral_to_srgb_weights (spectrum.h).
template <typename Float>
std::vector<Float> render_rgb(const Heightfield& heightfield, const Query& query, const std::vector<double>& lambdas_um,
                              int resolution, const RenderOptions& options = {});

// The same from a Gabor representation gathered once for `query`'s footprint (x, y and σ_p
// must equal the representation's: std::invalid_argument otherwise), honouring options.path
// and options.prune_tolerance as render_rgb does (bit for bit the same values).
template <typename Float>
std::vector<Float> render_rgb(const GaborRepresentation& representation, const Query& query,
                              const std::vector<double>& lambdas_um, int resolution, const RenderOptions& options = {});

}  // namespace wavebrdf
