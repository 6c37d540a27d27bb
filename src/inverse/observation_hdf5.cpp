// HDF5 observation files (observation_file.h): the core's side. The readers and writers are in
// the HDF5 plugin (src/plugins/hdf5/observation_hdf5.cpp), loaded on the first HDF5 call, so that
// nothing else loads HDF5 and its libraries.
#include "inverse/observation_hdf5.h"

#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/model.h"

#ifdef WAVEBRDF_HAS_HDF5
#include "core/plugin.h"
#include "plugins/hdf5_api.h"
#endif

namespace wavebrdf {

bool built_with_hdf5() {
#ifdef WAVEBRDF_HAS_HDF5
    return true;
#else
    return false;
#endif
}

namespace {

#ifdef WAVEBRDF_HAS_HDF5

void validate_query(const Query& query) { validate(query); }
void validate_observation(const Observation& observation, std::size_t index) { validate(observation, index); }
void require_memory_gb(double bytes, double max_memory_gb, const std::string& what) {
    require_memory(bytes, memory_limit(max_memory_gb), what);
}

const detail::Hdf5Host k_host = {validate_query, validate_lambda, validate_observation, require_memory_gb,
                                 write_file_atomically};

// The plugin, loaded and attached on the first call.
const detail::Hdf5Api& hdf5(const std::string&) {
    static const detail::Hdf5Api* const api = [] {
        using Entry = const detail::Hdf5Api* (*)();
        const auto entry = reinterpret_cast<Entry>(detail::plugin_symbol("hdf5", "wavebrdf_hdf5_api"));
        const detail::Hdf5Api* table = entry();
        if (table == nullptr || table->version != detail::k_hdf5_api_version)
            throw std::runtime_error("wavebrdf: the HDF5 plugin libwavebrdf_hdf5.so is of another version "
                                     "(interface " + std::to_string(table ? table->version : -1) + ", expected " +
                                     std::to_string(detail::k_hdf5_api_version) + "); rebuild it");
        table->attach(&k_host);
        return table;
    }();
    return *api;
}

#else

// Built without HDF5: every HDF5 call says so.
struct Hdf5Missing {
    [[noreturn]] static void fail(const std::string& path) {
        throw std::runtime_error(path +
                                 ": wavebrdf was built without HDF5; rebuild with libhdf5-dev installed (CMake "
                                 "option WAVEBRDF_HDF5) or use JSON observations (.json)");
    }
    static void write_observations(const std::string& path, const std::vector<Observation>&) { fail(path); }
    static ObservationIndex read_observation_index(const std::string& path, double) { fail(path); }
    static std::vector<Observation> read_observations(const std::string& path, const std::vector<std::size_t>&,
                                                      double) {
        fail(path);
    }
};
const Hdf5Missing& hdf5(const std::string&) {
    static const Hdf5Missing missing;
    return missing;
}

#endif

}  // namespace

void write_observations_hdf5(const std::string& path, const std::vector<Observation>& observations) {
    hdf5(path).write_observations(path, observations);
}

std::vector<Observation> read_observations_hdf5(const std::string& path, const std::vector<std::size_t>& indices,
                                                double max_memory_gb) {
    return hdf5(path).read_observations(path, indices, max_memory_gb);
}

namespace detail {
ObservationIndex read_observation_index_hdf5(const std::string& path, double max_memory_gb) {
    return hdf5(path).read_observation_index(path, max_memory_gb);
}
}  // namespace detail

}  // namespace wavebrdf
