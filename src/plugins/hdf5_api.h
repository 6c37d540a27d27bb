// The HDF5 plugin's interface (libwavebrdf_hdf5.so, src/plugins/hdf5/): the readers and writers
// of HDF5 files, loaded on first use (src/core/plugin.h) so that the core library, the CLI and
// the Python module never link HDF5. The plugin links no part of the core library: what it needs
// of the core (validation, the memory bound, atomic writes) it calls through Hdf5Host, which the
// core hands it once after loading. Both sides are compiled from this tree by one compiler, so
// C++ types and exceptions cross the interface; a plugin of another version is refused.
// Another HDF5 reader (another file format) adds its entry at the end of Hdf5Api and its file in
// src/plugins/hdf5/, and raises k_hdf5_api_version.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/observation.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf::detail {

// 2: Observation gained per-pixel weights (its layout changed). 3: read_datx.
constexpr int k_hdf5_api_version = 3;

// What the plugin calls in the core (the functions of the same names in wavebrdf/model.h,
// wavebrdf/observation.h, wavebrdf/memory.h and wavebrdf/io.h).
struct Hdf5Host {
    void (*validate_query)(const Query& query);
    void (*validate_lambda)(double lambda_um);
    void (*validate_observation)(const Observation& observation, std::size_t index);
    // require_memory(bytes, memory_limit(max_memory_gb), what)
    void (*require_memory)(double bytes, double max_memory_gb, const std::string& what);
    void (*write_file_atomically)(const std::string& path,
                                  const std::function<void(const std::string& temporary_path)>& write);
};

struct Hdf5Api {
    int version;
    // Called once, before any other entry; `host` lives as long as the process.
    void (*attach)(const Hdf5Host* host);
    // observation_file.h's functions of the same names.
    void (*write_observations)(const std::string& path, const std::vector<Observation>& observations);
    ObservationIndex (*read_observation_index)(const std::string& path, double max_memory_gb);
    std::vector<Observation> (*read_observations)(const std::string& path, const std::vector<std::size_t>& indices,
                                                  double max_memory_gb);
    // A Zygo datx file's surface from the file's bytes `data` named `name` (surface_file.h's
    // reader, src/io/surface_datx.cpp). Calls nothing of the host: the surface readers (core
    // and io) use it without attaching, whether or not the observation readers attached first.
    MeasuredSurface (*read_datx)(const std::string& data, const std::string& name);
};

}  // namespace wavebrdf::detail

// The one symbol the plugin exports.
extern "C" const wavebrdf::detail::Hdf5Api* wavebrdf_hdf5_api();
