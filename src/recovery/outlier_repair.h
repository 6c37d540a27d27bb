#pragma once
// Single-texel outliers after the refinement (experiments/2026-11-23-recovery-speed.md): a texel
// left about half a wavelength from the surface around it by the field stage's phase is a local
// minimum of the loss in that texel alone, which the refinement (L-BFGS, local) does not leave
// while every other texel converges.
#include <cstddef>
#include <functional>
#include <vector>

namespace wavebrdf::detail {

struct OutlierRepairCounts {
    int flagged = 0;      // texels evaluated (still standing out when their turn came)
    int evaluations = 0;  // calls of local_loss
    int kept = 0;         // texels changed
};

// Flags the texels whose height h (value units, rows × cols, periodic) differs from the quadratic
// through its 8 neighbours (½ Σ edge − ¼ Σ corner neighbours) by more than `threshold` robust
// deviations (1.4826 · the median absolute difference over all texels) and by more than
// `min_residual` (value units), largest first, at most `max_candidates`. For each (in that order,
// each from the heights the ones before left, and only if it still stands out: a neighbour of a
// repaired texel stood out through it): local_loss(h, t), the loss of the observations that see
// texel t (collective: the same value on every rank), at h, then at these trial values of h[t]:
// the neighbours' quadratic, their median, and h[t] ± w for each w in `wrap_heights` (value
// units, e.g. λ/2 of each observed wavelength). The trial of lowest loss is kept when it is below
// the loss at h. Returns the counts (flagged: the texels evaluated); nothing is evaluated when
// rows or cols < 3, the sizes disagree or threshold ≤ 0. Deterministic: the same heights give the
// same choices on every rank.
OutlierRepairCounts repair_outlier_texels(
    std::vector<double>& heights, int rows, int cols, double threshold, double min_residual, int max_candidates,
    const std::vector<double>& wrap_heights,
    const std::function<double(const std::vector<double>&, std::size_t)>& local_loss);

}  // namespace wavebrdf::detail
