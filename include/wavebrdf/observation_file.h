#pragma once
// Observation files that scale: every observation of a run in one HDF5 file, a layout close to
// the CXI convention of ptychography (a stack of slices, the sample's translations; our own exact
// queries and wavelengths beside them; docs/observations_hdf5.md), read in parts: a process reads
// the metadata of every observation (read_observation_index) and then only the slices it holds
// (read_observations_hdf5, hyperslabs of the stack), so a rank of an MPI run (communicator.h)
// reads only its share. Serial HDF5: every rank opens the file read-only.
//
// read_observations_file / write_observations_file choose the format by the file: HDF5 for the
// extensions .h5, .hdf5, .cxi (and, when reading, any file that starts with the HDF5
// signature), else the JSON (+ EXR) of observation.h, which stays for small sets.
//
// Built without HDF5 (CMake option WAVEBRDF_HDF5 off), the HDF5 functions throw
// std::runtime_error "PATH: wavebrdf was built without HDF5 ...".
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/observation.h"

namespace wavebrdf {

// What a file says of its observations, without the slices.
struct ObservationIndex {
    std::vector<Query> queries;                   // one per observation, in file order
    std::vector<std::vector<double>> lambdas_um;  // the wavelengths of each observation (µm)
    int resolution = 0;                           // n of every n × n slice
    int channels = 0;                             // 1 (one wavelength) or 3 (RGB) for every slice

    std::size_t size() const { return queries.size(); }
    // The footprint centres (query.x_um, query.y_um) in µm, one per observation: what
    // observation_share (communicator.h) splits.
    std::vector<std::array<double, 2>> positions_um() const;
};

// Whether the library was built with HDF5 (CMake option WAVEBRDF_HDF5).
bool built_with_hdf5();

// Whether `path` names an HDF5 observation file by its extension (.h5, .hdf5, .cxi; any case).
bool is_hdf5_path(const std::string& path);

// Whether read_observations_file reads `path` as HDF5: is_hdf5_path, or a file that starts with
// the HDF5 signature (false when it cannot be read).
bool is_hdf5_file(const std::string& path);

// Writes `observations` to the HDF5 file `path` (layout: docs/observations_hdf5.md), slices as
// float32 (the references are rounded to float), everything else exact. Atomic like every
// writer of io.h: written to a temporary file beside `path` and renamed onto it, so an existing
// file is replaced only by a complete one; a `path` that exists and is not a regular file is
// refused. Every observation must be valid (validate) and all must share one resolution and
// one channel count (std::invalid_argument naming the first that does not); at least one.
// Throws std::runtime_error naming the file when it cannot be written.
void write_observations_hdf5(const std::string& path, const std::vector<Observation>& observations);

// The metadata of every observation in `path`: queries, wavelengths, resolution, channels. An
// HDF5 file reads its small metadata datasets only (every dimension bounded and checked first:
// at most 1e8 observations, k_max_spectral_samples wavelengths each); a JSON file is read whole
// (read_observations_json) and its references dropped, and must have one resolution and
// channel count. The index's memory is checked against `max_memory_gb` GB (0: the physical
// memory; OutOfMemory). Throws std::runtime_error naming the file and the dataset on any problem.
ObservationIndex read_observation_index(const std::string& path, double max_memory_gb = 0.0);

// The observations `indices` (0-based positions in the file, each < the file's count; in the
// order given, repeats allowed) of the HDF5 file `path`: only their slices are read (one
// hyperslab each). The memory of the result (resolution² · channels doubles each) is checked
// against `max_memory_gb` GB (0: the physical memory; memory.h) before anything is allocated
// (OutOfMemory). Throws std::runtime_error naming the file and the dataset for a file that is
// not one of ours or is damaged (wrong types, ranks or dimensions, truncated data, non-finite
// values), std::out_of_range for an index beyond the file.
std::vector<Observation> read_observations_hdf5(const std::string& path, const std::vector<std::size_t>& indices,
                                                double max_memory_gb = 0.0);

// The observations of `path` that rank `rank` of `size` holds (observation_share of the file's
// footprint positions; rank 0 of 1: all of them), in file order, and their positions in the
// file in `*indices` when not null. HDF5 files (is_hdf5_path, or the HDF5 signature at the
// start) read the index and then only the share's slices; any other file is read as JSON
// (read_observations_json) whole, and the observations of other ranks are dropped (a JSON set
// is small). `max_memory_gb` as read_observations_hdf5's (for JSON: read_observations_json's,
// for the whole file). Throws std::invalid_argument unless 0 ≤ rank < size, and whatever the
// readers throw.
std::vector<Observation> read_observations_file(const std::string& path, int rank = 0, int size = 1,
                                                double max_memory_gb = 0.0,
                                                std::vector<std::size_t>* indices = nullptr);

// Writes `observations` to `path`: write_observations_hdf5 for an HDF5 extension
// (is_hdf5_path; `references` is then ignored: the slices are in the file), else
// write_observations_json with `references`.
void write_observations_file(const std::string& path, const std::vector<Observation>& observations,
                             ReferenceStorage references = ReferenceStorage::Inline);

}  // namespace wavebrdf
