#pragma once
// Internal: the anti-mirror's level step (docs/design.md "The level step"). For normal light the
// mirror order's amplitude is a polynomial in the levels' shares that must stay small on the arc
// of phases the band sweeps (dark_mirror_shares); on the steps where it can, the run surveys the
// step by designing a small tile on each (the region fraction is many-peaked in the step: a local
// move of the step, which the loop makes by its gradient, finds the peak nearest its start only),
// and the design starts on the best.
#include <functional>
#include <nlohmann/json.hpp>
#include <vector>

#include "wavebrdf/design_run.h"

namespace wavebrdf::detail {

// How dark levels 0, Δ, …, (K−1)Δ can keep the mirror order at every wavelength: the levels'
// shares of least mean power over the band, and their worst power over it.
struct MirrorShares {
    std::vector<double> shares;
    double worst_power = 1.0;
};
MirrorShares dark_mirror_shares(double step_um, int levels, const std::vector<double>& lambdas_um, double cos_i);

// The rule's step: the largest Δ ≤ H/(K−1) on which dark_mirror_shares keeps the mirror order's
// power at most 1e-4 at every wavelength of the band, else the step of least such power.
double anti_mirror_step(double range_um, int levels, const std::vector<double>& lambdas_um, double cos_i);

// Plans the step survey into p (p.step_survey_um, p.step_survey_size, a note) where the step is
// free (`free`) and the design starts at random: the rule's step p.levels_um holds and every step
// of a grid over (0, H/(K−1)] on which the mirror order can be kept below the cone's aim. Needs
// p's stages, anneal plan and order sets (the survey's tile is the first tile the loop designs, at
// most 32²; the light's obliquity from the orders).
void plan_step_survey(PreparedDesign& p, bool free);

// Designs p's survey tile on each of p.step_survey_um at the run's budget (the same seed, no
// continuation, no anneal), each scored by its exact metrics: the region's band mean less
// Σ max(0, x / limit − 1) over the cone's and the uniformity's worst. Reports the loops' steps
// through on_step (phase "step survey"); a false return stops the survey at the steps designed.
struct StepSurvey {
    double step_um = 0.0;  // the best step
    DesignResult tile;     // its tile's design
    nlohmann::json json;   // design.json's "step_survey"
};
StepSurvey run_step_survey(const PreparedDesign& p, const std::function<bool(const DesignStep&)>& on_step);

}  // namespace wavebrdf::detail
