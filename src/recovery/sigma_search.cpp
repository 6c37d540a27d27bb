// The σ_p self-calibration before the field stage (sigma_search.h).
#include "recovery/sigma_search.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/exact_sum.h"
#include "recovery/calibration_detail.h"
#include "recovery/observation_loss.h"

namespace wavebrdf::detail {

double scaled_sigma_loss(const std::vector<Observation>& observations, double observations_total,
                         const Heightfield& heights, double s, const Loss& loss, bool calibrate_exposure,
                         const Communicator& comm) {
    if (!(s > 0.0) || !std::isfinite(s))
        throw std::domain_error("scaled_sigma_loss: sigma scale " + std::to_string(s) + " is invalid; expected > 0");
    std::vector<double> no_gradient;
    ExactParallelSum sum(0);
    const double total = sum.run(observations.size(), comm, no_gradient, [&](std::size_t i, ExactScratch&) {
        return observation_misfit(heights, observations[i], loss, s, nullptr, calibrate_exposure);
    });
    return total / observations_total;
}

double presearch_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                             const Heightfield& heights, const Loss& loss, bool calibrate_exposure,
                             const Communicator& comm) {
    const double t = golden_section_minimum(
        [&](double x) {
            return scaled_sigma_loss(observations, observations_total, heights, std::exp(x), loss, calibrate_exposure,
                                     comm);
        },
        -std::log(2.0), std::log(2.0), k_presearch_evaluations);
    return std::exp(t);
}

double research_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                            const Heightfield& heights, double around, const Loss& loss, bool calibrate_exposure,
                            const Communicator& comm) {
    if (!(around > 0.0) || !std::isfinite(around))
        throw std::domain_error("research_sigma_scale: sigma scale " + std::to_string(around) +
                                " is invalid; expected > 0");
    const double centre = std::log(around), half = std::log(k_research_span);
    const double t = golden_section_minimum(
        [&](double x) {
            return scaled_sigma_loss(observations, observations_total, heights, std::exp(x), loss, calibrate_exposure,
                                     comm);
        },
        centre - half, centre + half, k_research_evaluations);
    return std::exp(t);
}

double guarded_sigma_scale(const std::vector<Observation>& observations, double observations_total,
                           const Heightfield& heights, const Loss& loss, bool calibrate_exposure,
                           const Communicator& comm) {
    const double s = presearch_sigma_scale(observations, observations_total, heights, loss, calibrate_exposure, comm);
    const double at_s = scaled_sigma_loss(observations, observations_total, heights, s, loss, calibrate_exposure, comm);
    const double at_stated = scaled_sigma_loss(observations, observations_total, heights, 1.0, loss, calibrate_exposure,
                                               comm);
    return at_s < at_stated * (1.0 - k_guard_margin) ? s : 1.0;
}

bool sigma_scale_moved(double before, double after) {
    if (!(before > 0.0) || !(after > 0.0) || !std::isfinite(before) || !std::isfinite(after))
        throw std::domain_error("sigma_scale_moved: sigma scales " + std::to_string(before) + ", " +
                                std::to_string(after) + " are invalid; expected > 0");
    return std::abs(std::log(after / before)) > k_research_tolerance;
}

}  // namespace wavebrdf::detail
