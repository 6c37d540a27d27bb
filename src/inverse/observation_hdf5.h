#pragma once
// The HDF5 side of observation_file.h (src/inverse/observation_hdf5.cpp): what observation_file.cpp
// dispatches to. Every function throws std::runtime_error "PATH: wavebrdf was built without
// HDF5 ..." when the library was built without it.
#include <string>

#include "wavebrdf/observation_file.h"

namespace wavebrdf::detail {

// read_observation_index for an HDF5 file; the index's memory is checked against `max_memory_gb`.
ObservationIndex read_observation_index_hdf5(const std::string& path, double max_memory_gb);

}  // namespace wavebrdf::detail
