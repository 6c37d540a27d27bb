#include "wavebrdf/scalar_observations.h"

#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "core/random.h"
#include "forward/scalar_diffraction_detail.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

Simulator parse_simulator(const std::string& text, const std::string& name) {
    if (text == "gabor") return Simulator::Gabor;
    if (text == "scalar") return Simulator::Scalar;
    throw std::invalid_argument(name + " '" + text + "' is unknown; expected gabor or scalar");
}

const char* to_string(Simulator simulator) { return simulator == Simulator::Scalar ? "scalar" : "gabor"; }

std::vector<Observation> simulate_scalar_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                                      const Noise& noise, std::uint64_t seed,
                                                      const std::vector<std::size_t>& indices,
                                                      const ScalarDiffractionSettings& settings, Progress* progress) {
    detail::validate_scalar_settings(settings);
    const std::vector<Observation> planned = planned_observations(plan);
    std::vector<Observation> observations;
    observations.reserve(indices.size());
    for (std::size_t i : indices) {
        if (i >= planned.size())
            throw std::invalid_argument("simulate_scalar_observations: index " + std::to_string(i) +
                                        " is out of range; the plan has " + std::to_string(planned.size()) +
                                        " observations");
        if (planned[i].lambdas_um.size() != 1)
            throw std::invalid_argument("simulate_scalar_observations: observation " + std::to_string(i) + " has " +
                                        std::to_string(planned[i].lambdas_um.size()) +
                                        " wavelengths; expected one (the simulator is single-wavelength)");
        observations.push_back(planned[i]);
    }
    // One observation per thread; inside, scalar_field's loops and products run serially
    // (in_parallel_region), so a slice has the same bits however the observations are shared
    // among ranks (even a share of one).
    const bool parallel = !detail::in_parallel_region();
    detail::RegionGuard guard;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (std::size_t k = 0; k < observations.size(); ++k)
        guard.run([&] {
            Observation& o = observations[k];
            o.reference = to_reference(
                add_noise(scalar_slice(truth, o.query, o.lambdas_um[0], o.resolution, settings), noise,
                          detail::derive_seed(seed, 1 + indices[k])));  // as add_noise does for all
            if (progress) progress->advance(1);
        });
    guard.rethrow();
    return observations;
}

}  // namespace wavebrdf
