// The MPI plugin's interface (libwavebrdf_mpi.so, src/plugins/mpi/mpi_plugin.cpp): MPI's calls
// the communicator needs, behind plain C functions, so that the core library, the CLI and the
// Python module never link MPI; a process started by mpiexec (or one that already holds MPI,
// mpi4py) loads the plugin on first use (src/core/plugin.h). Communicators cross the interface
// as Fortran handles (MPI_Comm_c2f), which every MPI defines as an int. Each call returns
// MPI's error code (0: success); error_string turns one into words.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wavebrdf::detail {

// Raised whenever a member's meaning changes: a plugin of another version is refused.
constexpr int k_mpi_api_version = 1;

struct MpiApi {
    int version;
    int (*initialized)(int* flag);
    int (*init_thread_funneled)();
    // MPI_Finalize unless MPI is already finalised.
    int (*finalize)();
    int (*world)(long long* handle);
    int (*rank)(long long comm, int* rank);
    int (*size)(long long comm, int* size);
    int (*gather_doubles)(const double* send, int count, double* receive, int root, long long comm);
    int (*gather_ints)(const int* send, int count, int* receive, int root, long long comm);
    int (*gatherv_doubles)(const double* send, int count, double* receive, const int* counts, const int* offsets,
                           int root, long long comm);
    int (*broadcast_doubles)(double* values, int count, int root, long long comm);
    int (*gather_words)(const std::uint64_t* send, int count, std::uint64_t* receive, int root, long long comm);
    int (*broadcast_words)(std::uint64_t* words, int count, int root, long long comm);
    // In place on every rank: `count` sums of 192-bit integers (three words each), a commutative
    // operation (integer addition, so any order gives the same bits).
    int (*allreduce_words192)(std::uint64_t* words, int count, long long comm);
    int (*allreduce_or)(int* flag, long long comm);
    int (*barrier)(long long comm);
    int (*abort)(long long comm, int code);
    void (*error_string)(int code, char* text, int capacity);
};

}  // namespace wavebrdf::detail

// The one symbol the plugin exports.
extern "C" const wavebrdf::detail::MpiApi* wavebrdf_mpi_api();
