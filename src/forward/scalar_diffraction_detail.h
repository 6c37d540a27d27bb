#pragma once
// Internal: the scalar-diffraction simulator's settings check, shared with the simulation of
// planned observations (scalar_observations.h), which checks them before any slice.
#include "wavebrdf/scalar_diffraction.h"

namespace wavebrdf::detail {

// Throws std::domain_error naming the first setting out of range.
void validate_scalar_settings(const ScalarDiffractionSettings& settings);

}  // namespace wavebrdf::detail
