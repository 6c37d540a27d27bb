#pragma once
// Internal: the grayscale design loop (`--min-feature-um F`, docs/design.md): the heights are
// the filtered parameterisation of feature_filter.h, h = H · G(σ(z)), evaluated by the design
// loop's K-level identity on k_grayscale_levels equally spaced levels across [0, H] with each
// texel's weight split linearly between the two levels around its height (the phasor
// e^{−ikhq} interpolated between them: within (kqΔ)²/8 of exact), Adam on z.
#include <functional>
#include <vector>

#include "design/evaluator.h"
#include "design/feature_filter.h"

namespace wavebrdf::detail {

// The evaluation grid of a grayscale design.
constexpr int k_grayscale_levels = 256;

// The loss of latent z and, with `gradient`, ∂loss/∂z (the evaluator's gradient through the
// linear split, the filter's adjoint and the sigmoid).
double grayscale_loss(const FeatureFilter& filter, Evaluator& evaluator, double height_range_um, int levels,
                      const std::vector<double>& z, std::vector<double>* gradient, Fractions* nominal = nullptr);

// The relaxed phase of a grayscale design: `iterations` Adam steps on z (seeded from `seed`, or
// from `warm`, an earlier run's final z), each reported from iteration `iteration0`; returns each
// texel's nearest level of the final heights (the relief as written) and leaves the final z in
// `latent`.
std::vector<int> grayscale_design(const PreparedDesign& p, Evaluator& evaluator,
                                  const std::function<void(const DesignStep&)>& report, const bool& stopped,
                                  Fractions& relaxed_fractions, std::vector<double>& latent,
                                  const std::vector<double>* warm = nullptr, int iteration0 = 0);

}  // namespace wavebrdf::detail
