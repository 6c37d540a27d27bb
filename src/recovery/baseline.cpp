#include "wavebrdf/baseline.h"

#include <algorithm>
#include <chrono>
#include <random>
#include <stdexcept>
#include <string>

#include "core/random.h"

namespace wavebrdf {

Heightfield recover_heights_thesis(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                                   double vscale, const BaselineSettings& settings,
                                   const std::function<bool(const StageMetrics&)>& on_step, const Heightfield* truth) {
    if (observations.empty()) throw std::invalid_argument("no observations given; expected at least one");
    validate_iterations(settings.epochs, "epochs");
    if (settings.report_every < 1)
        throw std::invalid_argument("report_every " + std::to_string(settings.report_every) +
                                    " is invalid; expected >= 1");
    for (std::size_t i = 0; i < observations.size(); ++i) validate(observations[i], i);
    const auto start = std::chrono::steady_clock::now();
    Heightfield estimate(rows, cols, std::vector<double>(static_cast<std::size_t>(rows) * cols, 0.0), texel_um, vscale);
    Adam adam(estimate.values().size(), settings.adam);
    std::mt19937_64 rng(detail::derive_seed(settings.seed, 23));
    std::vector<double> gradient;
    for (int epoch = 0; epoch < settings.epochs; ++epoch) {
        const std::size_t pick = static_cast<std::size_t>(rng() % observations.size());
        gradient.clear();  // observation_loss adds into its gradient (adjoint.h)
        const double loss = observation_loss(estimate, {observations[pick]}, settings.loss, &gradient);
        std::vector<double> x = estimate.values();
        adam.step(x, gradient, epoch);
        estimate = estimate.with_values(std::move(x));
        if (on_step && ((epoch + 1) % settings.report_every == 0 || epoch + 1 == settings.epochs)) {
            StageMetrics m;
            m.stage = "thesis";
            m.kind = StageKind::Thesis;
            m.total = std::max(settings.epochs, 1);
            m.iteration = epoch + 1;
            m.loss = loss;
            m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (truth) m.height_rel_rmse = height_rel_rmse(estimate, *truth);
            if (!on_step(m)) break;
        }
    }
    return estimate;
}

}  // namespace wavebrdf
