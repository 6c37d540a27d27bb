#pragma once
// Observations of a planned acquisition simulated by the independent scalar-diffraction
// simulator (scalar_diffraction.h), for studies of the recovery against data its own model did
// not make (RecoveryOptions::simulator, CLI --simulator).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/scalar_diffraction.h"

namespace wavebrdf {

class Progress;

// How a study simulates its observations (RecoveryOptions::simulator, CLI --simulator):
// the Gabor model itself (render_observation) or this scalar-diffraction simulator.
enum class Simulator { Gabor, Scalar };
// Parses "gabor" or "scalar"; throws std::invalid_argument "NAME 'TEXT' is unknown; expected
// gabor or scalar".
Simulator parse_simulator(const std::string& text, const std::string& name = "simulator");
const char* to_string(Simulator simulator);

// The planned observations `indices` (ascending indices into planned_observations(plan)) of
// `truth`, simulated by scalar_slice with `settings` and with `noise` added exactly as
// simulate_observations adds it (seeded per observation: the same draws for the same index),
// observations in parallel. Only single-wavelength observations (std::invalid_argument
// otherwise, naming the observation); std::invalid_argument for an index out of range; throws
// as scalar_slice. `progress` advances by one per observation.
std::vector<Observation> simulate_scalar_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                                      const Noise& noise, std::uint64_t seed,
                                                      const std::vector<std::size_t>& indices,
                                                      const ScalarDiffractionSettings& settings = {},
                                                      Progress* progress = nullptr);

}  // namespace wavebrdf

