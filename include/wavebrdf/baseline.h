#pragma once
// The thesis's method as a baseline for recovery (recover.h): Adam on the log loss, one
// observation per epoch drawn at random from the given ones (its stochastic multi-position
// mode), from a flat start. It sees the same data as recover_heights, so the two can be
// compared side by side (docs/recovery.md).
#include <cstdint>
#include <functional>
#include <vector>

#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/recover.h"

namespace wavebrdf {

struct BaselineSettings {
    int epochs = 1000;
    AdamOptions adam;                 // the thesis's: 0.01, 0.9, 0.99, decay 0.005
    Loss loss{LossKind::CMSLE, 1.0};  // the thesis's first experiment
    std::uint64_t seed = 1;           // which observation each epoch draws
    int report_every = 10;            // epochs between on_step calls (and the last one)
};

// Heights (rows × cols, texel units with texel_um and vscale) from a flat start. on_step gets
// stage "thesis", the epoch, the loss of that epoch's observation, the seconds, and
// height_rel_rmse when `truth` is given; returning false stops. Throws std::invalid_argument
// for no observations, epochs outside 0 … k_max_iterations (10^7) or report_every < 1; Adam's options are validated by Adam.
Heightfield recover_heights_thesis(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                                   double vscale, const BaselineSettings& settings = {},
                                   const std::function<bool(const StageMetrics&)>& on_step = {},
                                   const Heightfield* truth = nullptr);

}  // namespace wavebrdf
