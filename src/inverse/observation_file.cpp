// Observation files by format (observation_file.h): HDF5 (src/inverse/observation_hdf5.cpp) for the
// extensions .h5/.hdf5/.cxi or a file with the HDF5 signature, else JSON (observation.h), and a
// rank's share of them (communicator.h observation_share).
#include "wavebrdf/observation_file.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "inverse/observation_hdf5.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/communicator.h"

namespace wavebrdf {

namespace {

// Whether the file starts with the HDF5 signature (at offset 0; files with a user block are
// recognised by their extension).
bool has_hdf5_signature(const std::string& path) {
    check_readable_file(path);
    std::ifstream in(path, std::ios::binary);
    char head[8] = {};
    if (!in.read(head, sizeof head)) return false;
    return std::memcmp(head, "\x89HDF\r\n\x1a\n", 8) == 0;
}

void check_rank(int rank, int size) {
    if (size < 1 || rank < 0 || rank >= size)
        throw std::invalid_argument("rank " + std::to_string(rank) + " of " + std::to_string(size) +
                                    " is invalid; expected 0 <= rank < size");
}

}  // namespace

std::vector<std::array<double, 2>> ObservationIndex::positions_um() const {
    std::vector<std::array<double, 2>> out(queries.size());
    for (std::size_t i = 0; i < queries.size(); ++i) out[i] = {queries[i].x_um, queries[i].y_um};
    return out;
}

bool is_hdf5_path(const std::string& path) {
    const std::size_t dot = path.find_last_of("./");
    if (dot == std::string::npos || path[dot] != '.') return false;
    std::string ext = path.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext == "h5" || ext == "hdf5" || ext == "cxi";
}

bool is_hdf5_file(const std::string& path) { return is_hdf5_path(path) || has_hdf5_signature(path); }

ObservationIndex read_observation_index(const std::string& path, double max_memory_gb) {
    if (is_hdf5_file(path)) return detail::read_observation_index_hdf5(path, max_memory_gb);
    // JSON: read whole (its references are needed to know nothing more, but a JSON set is small).
    std::vector<Observation> all = read_observations_json(path, max_memory_gb);
    ObservationIndex index;
    index.resolution = all.front().resolution;
    index.channels = all.front().channels();
    for (std::size_t i = 0; i < all.size(); ++i) {
        if (all[i].resolution != index.resolution || all[i].channels() != index.channels)
            throw std::runtime_error(path + ": observation " + std::to_string(i) +
                                     " has another resolution or channel count than observation 0; an index "
                                     "needs one of each");
        index.queries.push_back(all[i].query);
        index.lambdas_um.push_back(std::move(all[i].lambdas_um));
    }
    return index;
}

std::vector<Observation> read_observations_file(const std::string& path, int rank, int size, double max_memory_gb,
                                                std::vector<std::size_t>* indices) {
    check_rank(rank, size);
    std::vector<std::size_t> share;
    std::vector<Observation> out;
    if (is_hdf5_file(path)) {
        const ObservationIndex index = detail::read_observation_index_hdf5(path, max_memory_gb);
        share = observation_share(index.positions_um(), rank, size);
        out = read_observations_hdf5(path, share, max_memory_gb);
    } else {
        // JSON: read whole, then the other ranks' observations are dropped (a JSON set is small;
        // large sets belong in HDF5).
        std::vector<Observation> all = read_observations_json(path, max_memory_gb);
        share = observation_share(footprint_centres(all), rank, size);
        out.reserve(share.size());
        for (std::size_t i : share) out.push_back(std::move(all[i]));
    }
    if (indices != nullptr) *indices = std::move(share);
    return out;
}

void write_observations_file(const std::string& path, const std::vector<Observation>& observations,
                             ReferenceStorage references) {
    if (is_hdf5_path(path))
        write_observations_hdf5(path, observations);
    else
        write_observations_json(path, observations, references);
}

}  // namespace wavebrdf
