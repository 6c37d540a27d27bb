#pragma once
// White light (recover.h, docs/recovery.md "White light"): the pieces of the RGB-only path:
// the defect repair after the refinement and the smoothness continuation before it.
#include <functional>
#include <vector>

namespace wavebrdf::detail {

// Isolated defects of a refined estimate (docs/recovery.md, White light): a texel left a
// wrap (≈ λ/2 of one wavelength) away from its neighbours is a local minimum of the spectral
// loss the refinement cannot leave. Candidates are the texels whose height h (texel units,
// rows × cols, periodic) differs from the median of its 8 neighbours by more than
// `threshold` robust deviations (1.4826 · the median absolute difference over all texels),
// largest first, at most `max_candidates`; each is set to that median and kept only when
// `loss` (of all heights, collective: the same value on every rank) decreases. Returns the
// number kept. Deterministic: the same heights give the same choices on every rank.
int repair_defects(std::vector<double>& heights, int rows, int cols, double threshold, int max_candidates,
                   const std::function<double(const std::vector<double>&)>& loss);

// A smoothness penalty for the white-light refinement's continuation (docs/recovery.md, White
// light): weight · mean over texels of (Δh)², Δ the periodic 5-point Laplacian of the heights
// h (texel units, rows × cols), which wrap defects and checkerboards (the spectral loss's local
// minima) raise and a smooth surface does not. Returns the value; adds its gradient to
// `gradient` (the same size as h). Returns 0 and adds nothing when weight ≤ 0 or the sizes
// disagree. Deterministic (the same bits on every rank).
double add_smoothness_penalty(const std::vector<double>& heights, int rows, int cols, double weight,
                              std::vector<double>& gradient);

}  // namespace wavebrdf::detail
