#pragma once
// Internal: footprint positions from stitching per-footprint patches (docs/recovery.md,
// "Self-calibration: positions", round 11b), as interferometric sub-aperture stitching.
//
// A slice sees |F[P(x − μ) e^{−i(4π/λ)h(x)}]|²; with g(y) = h(μ + y) it is
// |F[P(y) e^{−i(4π/λ)g(y)}]|², whatever μ is, so one footprint's slices determine its local
// patch g in the window's own coordinates (up to a constant and the twin g(y) → −g(−y)). A patch
// recovered alone and placed at its stated centre c_i reads h(x + d_i), d_i = true − stated.
// Two overlapping patches registered against each other give d_i − d_j; a weighted least
// squares over all overlapping pairs gives every d_i (gauge: mean 0), with no global heights.
//
// Coordinates are in texels of the global grid: u = x_um / texel_um along the rows, v along the
// columns; texel (i, j) has its centre at (i + 0.5, j + 0.5). Deterministic: no threads, fixed
// orders, so the same bits for any thread count.
#include <array>
#include <vector>

namespace wavebrdf::detail {

// One footprint's patch: heights (µm) on a rows × cols tile whose texel (a, b) is the global
// texel (origin_row + a, origin_col + b), read as if its window sat at its stated centre.
struct StitchPatch {
    int origin_row = 0;
    int origin_col = 0;
    int rows = 0;
    int cols = 0;
    std::vector<double> heights_um;  // rows · cols, row-major
    std::array<double, 2> centre{};  // stated window centre (u, v), texels
};

// The patch's heights at global point (u, v) (texels), Catmull-Rom bicubic; false (and 0) where
// the 4 × 4 stencil leaves the tile.
bool sample_patch(const StitchPatch& patch, double u, double v, double& value_um);

// The twin read back: p'(x) = −p(2c − x) about the patch's stated centre c, on the same tile
// (bicubic; texels whose mirror point leaves the tile keep −p of the nearest one inside).
StitchPatch flip_patch(const StitchPatch& patch);

// One pair's registration: b(x + shift) ≈ a(x) + constant, so shift ≈ d_a − d_b (texels).
struct PairRegistration {
    std::array<double, 2> shift{};  // texels
    double misfit = 1e300;          // weighted misfit / the patches' weighted variance (0: perfect)
    double overlap = 0.0;           // Σ P_a P_b / √(Σ P_a² Σ P_b²) at the shift, ~e^{−|Δ|²/(4σ²)}
};

// Registers b against a: the shift minimising the misfit of a(x) − b(x + s) − m weighted by
// P_a(x) P_b(x + s) (the windows exp(−|y|²/(2σ²)) about the stated centres, σ = sigma_texels),
// over the shifts where the windows overlap by at least min_overlap (|c_a + s − c_b| ≤
// 2σ√(−ln min_overlap)): a grid of half texels, then a pattern search down to 1/64 texel.
PairRegistration register_patch_pair(const StitchPatch& a, const StitchPatch& b, double sigma_texels,
                                     double min_overlap);

// The least squares of the offsets: minimises Σ w_k |d_a − d_b − shift_k|² with Σ d = 0.
struct StitchPair {
    int a = 0;
    int b = 0;
    std::array<double, 2> shift{};
    double weight = 1.0;
    double misfit = 0.0;  // the registration's (orders the spanning tree that starts the solve)
};
std::vector<std::array<double, 2>> solve_stitch_offsets(int count, const std::vector<StitchPair>& pairs);

struct StitchSettings {
    double sigma_texels = 1.5;  // the window's σ_p in texels
    // (the defaults: docs/recovery.md round 11b's "wide" settings, which connect the pair graph)
    double max_distance_texels = 14.0;  // pairs whose stated centres are at most this far apart
    double search_overlap = 0.02;       // register_patch_pair's min_overlap: the region searched
    double min_overlap = 0.1;           // pairs whose best shift overlaps less are left out (the best
                                        // at the searched region's edge is a false match)
    double max_misfit = 0.05;           // pairs with a worse misfit are left out
    // The solve starts from a spanning tree of the best pairs (lowest misfit first), then keeps
    // the pairs whose residual is within a threshold halved from 2 texels to this, solving again.
    double outlier_texels = 0.5;
    // Patches with fewer pairs left after the solve are unresolved: offset 0 (the stated centre),
    // the others' mean 0.
    int min_pairs = 3;
};

struct StitchResult {
    std::vector<std::array<double, 2>> offsets_texels;  // d_i = true − stated (mean 0), texels
    std::vector<int> twin;                              // 1: the patch was the twin (flipped to read h)
    std::vector<int> resolved;                          // 1: at least min_pairs pairs fix the offset
    int unresolved = 0;
    int pairs_used = 0;
    int pairs_tried = 0;
    double residual_rms_texels = 0.0;  // of the pairs used, after the solve (before the unresolved are zeroed)
    // The better orientation's misfit of every candidate pair whose best shift overlaps by at
    // least min_overlap (a diagnostic for max_misfit), in the candidates' order.
    std::vector<double> candidate_misfits;
    std::vector<StitchPair> pairs;  // the pairs used in the final solve
};

// Every patch's offset from the patches alone. The twins: each pair is registered as it is and
// with b flipped; the better of the two gives the pair's relative orientation, and a union-find
// with parity over the pairs in order of misfit assigns every patch's (up to a global flip);
// both global choices are solved and the one whose offsets have the smaller rms is returned
// (the other is the point reflection of the whole surface, offsets of the raster's size).
// Patches with fewer than min_pairs pairs left get offset 0 (unresolved).
// `known_twins` (a study's oracle, 1 per twin patch), when given, replaces the orientation step.
StitchResult stitch_positions(const std::vector<StitchPatch>& patches, const StitchSettings& settings = {},
                              const std::vector<int>* known_twins = nullptr);

}  // namespace wavebrdf::detail
