#pragma once
// The texture check: whether the estimate holds texel-scale spikes, pits or a binary texture of
// the kind the recovery does not resolve reliably at its noise level (docs/recovery.md, "Did
// it converge?"; docs/surfaces.md, "Spikes"). Read from the estimate alone, no truth.
//
// Why: on sur-2's 128² patch (a scan whose texels flip between two levels ~7.5 nm apart over
// 40 % of the tile) the recovery at 10⁴ photons ends in a local minimum of that texture, with a
// higher loss than the one next to the truth, and its error there is 1.9–2.5 × the error bars'
// σ against 0.85 × off it, while the summed misfit sits on the floor and the bars (whose Fisher
// information of nm phases does not depend on the heights) are the same on and off the
// texture: 1.21 % of the range with 2 exposures, not warned by the other checks
// (experiments/2026-11-30-texture-check.md). The estimate reproduces the texture (98–99 % of
// the truth's spike texels), so the check reads it there.
//
// The rule: a texel is texture where the estimate stands off the median of its 3 × 3
// neighbourhood (periodic) by more than both k_texture_sigmas σ and the estimate's rms height.
// σ is the run's predicted per-texel rms error (the error bars' √(mean σ²) where computed, else
// the photon planner's prediction less its bias, else the lower bound from the Fisher
// diagonal): the estimate's own noise stands 0.97 σ rms off the median (white noise), and 4 σ
// leaves 1–2·10⁻⁴ of the texels to it. The rms height: a surface smooth at the texel scale stands off the median by
// its curvature over one texel, a fraction of its rms height (a Gaussian-correlated surface of
// correlation 4 texels: at most 0.6 ×; the scans' striations and grooves, plu-1, x3p-2 and the
// bullet land: at most 0.24 % of the texels beyond 1 ×), so what passes both is texel-scale
// content of the surface's own amplitude: spikes, pits, a binary texture, or a surface rough
// at the texel scale (correlation ≲ 1 texel). A run is warned where at least
// k_texture_fraction of the texels are texture and twice σ (the error measured on such
// texture) exceeds the target (k_predicted_error_limit): then the texture alone can carry the
// error past the target; runs whose bars are far inside the target are not warned.
#include <string>

#include "wavebrdf/convergence.h"
#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// A texel is texture above this many σ off its 3 × 3 median.
constexpr double k_texture_sigmas = 4.0;
// Warned from this fraction of texture texels (on the conditioned truths at the runs' σ: sur-2
// 128² 6.6 %; sur-2 64², met at 0.71 %, 1.3 %; every other scan below 0.25 %).
constexpr double k_texture_fraction = 0.05;
// The error measured on such texture, in units of the bars' σ (sur-2 128²: 1.9 × with 3
// exposures, 2.5 × on the spike texels themselves).
constexpr double k_texture_error_factor = 2.0;

struct TexelTexture {
    int texels = 0;             // texels more than threshold_um off their 3 × 3 median
    double fraction = 0.0;      // texels over all texels
    double power_share = 0.0;   // their share of Σ (h − median₃ₓ₃ h)² over the tile (0 when flat)
    double rms_height_um = 0.0; // the estimate's, mean removed
    double threshold_um = 0.0;  // max(k_texture_sigmas σ, rms_height_um)
};

// The rule's count on heights `estimate` at per-texel rms error `sigma_um` (> 0, finite; else
// std::invalid_argument naming the value).
TexelTexture texel_texture(const Heightfield& estimate, double sigma_um);

// Adds the texture check to `check` (its texture_* fields; a reason when the run is warned):
// σ over the height range `sigma_relative` (> 0, finite; else nothing is added) from `source`
// ("error bars", "photon plan" or "error lower bound"), the range `range_um` (> 0).
void add_texel_texture(ConvergenceCheck& check, const Heightfield& estimate, double sigma_relative,
                       double range_um, const std::string& source);

}  // namespace wavebrdf
