// libwavebrdf_mpi.so: MPI's C interface behind src/plugins/mpi_api.h. The only file of the
// project that includes <mpi.h>; the communicator itself (src/core/communicator.cpp) calls it
// through the table below.
#include "plugins/mpi_api.h"

#include "core/words192.h"

#include <algorithm>
#include <cstring>

// MPI's C interface only (not the deprecated C++ bindings, which need libmpi_cxx).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>

namespace {

MPI_Comm comm_of(long long handle) { return MPI_Comm_f2c(static_cast<MPI_Fint>(handle)); }

int initialized(int* flag) { return MPI_Initialized(flag); }
int init_thread_funneled() {
    int provided = 0;
    return MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
}
int finalize() {
    int finalized = 0;
    MPI_Finalized(&finalized);
    return finalized ? MPI_SUCCESS : MPI_Finalize();
}
int world(long long* handle) {
    *handle = static_cast<long long>(MPI_Comm_c2f(MPI_COMM_WORLD));
    return MPI_SUCCESS;
}
int rank(long long comm, int* r) { return MPI_Comm_rank(comm_of(comm), r); }
int size(long long comm, int* s) { return MPI_Comm_size(comm_of(comm), s); }
int gather_doubles(const double* send, int count, double* receive, int root, long long comm) {
    return MPI_Gather(send, count, MPI_DOUBLE, receive, count, MPI_DOUBLE, root, comm_of(comm));
}
int gather_ints(const int* send, int count, int* receive, int root, long long comm) {
    return MPI_Gather(send, count, MPI_INT, receive, count, MPI_INT, root, comm_of(comm));
}
int gatherv_doubles(const double* send, int count, double* receive, const int* counts, const int* offsets, int root,
                    long long comm) {
    return MPI_Gatherv(send, count, MPI_DOUBLE, receive, counts, offsets, MPI_DOUBLE, root, comm_of(comm));
}
int broadcast_doubles(double* values, int count, int root, long long comm) {
    return MPI_Bcast(values, count, MPI_DOUBLE, root, comm_of(comm));
}
int gather_words(const std::uint64_t* send, int count, std::uint64_t* receive, int root, long long comm) {
    return MPI_Gather(send, count, MPI_UINT64_T, receive, count, MPI_UINT64_T, root, comm_of(comm));
}
int broadcast_words(std::uint64_t* words, int count, int root, long long comm) {
    return MPI_Bcast(words, count, MPI_UINT64_T, root, comm_of(comm));
}

// MPI_User_function: inout ← in + inout, element-wise on 192-bit integers (three words each).
void sum_words192(void* in, void* inout, int* count, MPI_Datatype*) {
    wavebrdf::detail::add_words192(static_cast<const std::uint64_t*>(in), static_cast<std::uint64_t*>(inout),
                                   static_cast<std::size_t>(*count));
}

int allreduce_words192(std::uint64_t* words, int count, long long comm) {
    MPI_Datatype type = MPI_DATATYPE_NULL;
    MPI_Op op = MPI_OP_NULL;
    int code = MPI_Type_contiguous(3, MPI_UINT64_T, &type);
    if (code == MPI_SUCCESS) code = MPI_Type_commit(&type);
    if (code == MPI_SUCCESS) code = MPI_Op_create(&sum_words192, 1, &op);
    if (code == MPI_SUCCESS) code = MPI_Allreduce(MPI_IN_PLACE, words, count, type, op, comm_of(comm));
    if (op != MPI_OP_NULL) MPI_Op_free(&op);
    if (type != MPI_DATATYPE_NULL) MPI_Type_free(&type);
    return code;
}
int allreduce_or(int* flag, long long comm) {
    int mine = *flag;
    return MPI_Allreduce(&mine, flag, 1, MPI_INT, MPI_LOR, comm_of(comm));
}
int barrier(long long comm) { return MPI_Barrier(comm_of(comm)); }
int abort_all(long long comm, int code) { return MPI_Abort(comm_of(comm), code); }
void error_string(int code, char* text, int capacity) {
    if (capacity <= 0) return;
    char message[MPI_MAX_ERROR_STRING];
    int length = 0;
    if (MPI_Error_string(code, message, &length) != MPI_SUCCESS) length = 0;
    const int n = std::min(length, capacity - 1);
    std::memcpy(text, message, static_cast<std::size_t>(std::max(n, 0)));
    text[std::max(n, 0)] = '\0';
}

const wavebrdf::detail::MpiApi k_api = {
    wavebrdf::detail::k_mpi_api_version,
    initialized, init_thread_funneled, finalize, world, rank, size, gather_doubles, gather_ints,
    gatherv_doubles, broadcast_doubles, gather_words, broadcast_words, allreduce_words192, allreduce_or,
    barrier, abort_all, error_string,
};

}  // namespace

extern "C" __attribute__((visibility("default"))) const wavebrdf::detail::MpiApi* wavebrdf_mpi_api() {
    return &k_api;
}
