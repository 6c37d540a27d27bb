#pragma once
// White light (recover.h, docs/recovery.md "White light"): the pieces of the RGB-only path:
// the defect repair after the refinement and the smoothness continuation before it.
#include <cstddef>
#include <functional>
#include <string>
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
// Checks a smoothness continuation's weights (RecoverSettings::white_smoothness): at most
// k_max_white_smoothness_weights of them, each finite in [0, 10^12]. Throws
// std::invalid_argument naming the bad weight (or the count) and `name` (how the caller spells
// the option) otherwise.
constexpr std::size_t k_max_white_smoothness_weights = 64;
void check_white_smoothness(const std::vector<double>& weights, const std::string& name = "white smoothness");

double add_smoothness_penalty(const std::vector<double>& heights, int rows, int cols, double weight,
                              std::vector<double>& gradient);

}  // namespace wavebrdf::detail

namespace wavebrdf::detail {

// Connected wrap defects (experiments/2026-11-23-white-light.md): a group of
// adjacent texels left whole wraps from the surface around it, which moving one texel at a time
// (repair_defects) cannot leave when the loss is nearly periodic in whole wraps. Flags the texels
// whose height h (value units, rows × cols, periodic) differs from its 8 neighbours' median by more
// than `threshold` robust deviations (as repair_defects), grows each by one texel (so a block whose
// inner texels pass the median test is caught through its corners), and takes the 4-connected
// components of that mask of at most `max_region_texels` texels, largest residual first. For each:
// the smooth fill (biharmonic, from the texels around it), the core (texels ≥ half a wrap from the
// fill) and these candidates: every core texel shifted by its own nearest whole number of wraps
// k·wrap_height from the fill; the core set to the fill; the core shifted together by ±1, ±2
// wraps. The candidate of lowest `loss` (of all heights, collective: the same value on every rank)
// is kept when it is below the current loss. At most `max_evaluations` loss evaluations in all
// (besides the first). Returns the number of regions changed. Deterministic: the same heights give
// the same choices on every rank. Returns 0 (nothing evaluated) when wrap_height ≤ 0, the sizes
// disagree, or the grid is smaller than 3 × 3.
int repair_defect_regions(std::vector<double>& heights, int rows, int cols, double wrap_height, double threshold,
                          int max_evaluations, int max_region_texels,
                          const std::function<double(const std::vector<double>&)>& loss);

}  // namespace wavebrdf::detail
