#pragma once
// Internal: tile continuation (DesignOptions::continuation, docs/design.md): the design run on
// smaller tiles first, each tile's relief repeated to the next size and continued there.
#include <functional>
#include <vector>

#include "wavebrdf/design_run.h"

namespace wavebrdf::detail {

// The continuation's smaller tiles and their budgets (empty: the design runs on its tile alone);
// std::invalid_argument naming the value for a schedule that is not one or does not fit the run.
std::vector<DesignStage> continuation_stages(const DesignOptions& o, bool grayscale);

// `level` (n² level indices, row-major) repeated into an N × N tile (n divides N).
std::vector<int> tile_levels(const std::vector<int>& level, int n, int size);

using DesignStepFn = std::function<bool(const DesignStep&)>;
using RunOneDesign = std::function<DesignResult(const PreparedDesign&, const DesignStepFn&)>;
// Runs p's stages, then p's own tile from the last stage's relief tiled, each by run_one (the run
// on one tile); the result is the last tile's, its curve every stage's steps, and design.json
// says the schedule ("continuation") with every stage's exact metrics and time. `first_tile`, where
// given, is the first stage's design, made already (the step survey's best tile: its steps were
// reported then, and enter the curve only).
DesignResult run_continued(const PreparedDesign& p, const DesignStepFn& on_step, const RunOneDesign& run_one,
                           const DesignResult* first_tile = nullptr);

}  // namespace wavebrdf::detail
