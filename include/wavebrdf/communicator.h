#pragma once
// The processes one run is split over (MPI ranks, docs/scale.md) and the few collective
// operations the library needs. Every rank holds a share of the observations (the data) and a
// copy of the unknowns (heights, object); the losses and gradients of the shares are summed
// with allreduce_sum, in rank order, so a run is the same bit for bit for a given number of
// ranks, and differs from the one-process run only by the order of a few sums.
//
// Without MPI (a build without it, or a program not started by mpirun) the communicator is
// serial_communicator(): one rank, every operation a copy or nothing. Collective calls must be
// made by every rank, in the same order, from the thread that created the communicator.
#include <array>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace wavebrdf {

class Communicator {
public:
    virtual ~Communicator() = default;
    virtual int rank() const = 0;  // 0 … size() − 1
    virtual int size() const = 0;  // ≥ 1

    // values[i] ← Σ_r values_r[i] on every rank, summed in rank order 0, 1, …, size() − 1
    // (reproducible for a given size, the same bits on every rank).
    virtual void allreduce_sum(double* values, std::size_t count) const = 0;
    // values ← root's values on every rank.
    virtual void broadcast(double* values, std::size_t count, int root = 0) const = 0;
    // The concatenation of every rank's `local`, in rank order, on `root` (empty elsewhere).
    virtual std::vector<double> gather(const std::vector<double>& local, int root = 0) const = 0;
    // Word-level collectives (the exact, order-independent sums of core/exact_sum.h combine
    // 128-bit integers with them). gather_words: every rank passes `count` words (the same count
    // on every rank); `all` on root receives size() · count words, rank r's at r · count (ignored
    // elsewhere: may be null). broadcast_words: words ← root's words on every rank.
    virtual void gather_words(const std::uint64_t* local, std::size_t count, std::uint64_t* all,
                              int root = 0) const = 0;
    virtual void broadcast_words(std::uint64_t* words, std::size_t count, int root = 0) const = 0;
    // Sums of `count` 192-bit two's-complement integers, three words each, least significant
    // first: words[3i … 3i + 2] ← Σ_r words_r[3i … 3i + 2] modulo 2^192, on every rank. Integer
    // addition is associative and commutative, so the result does not depend on the order in
    // which the ranks are combined. This default gathers to rank 0 and broadcasts (rank 0
    // receives size() × the words of a piece); the MPI communicator overrides it with
    // MPI_Allreduce and its own operation, where no rank holds more than its own words.
    virtual void allreduce_words192(std::uint64_t* words, std::size_t count) const;
    // True on every rank when `flag` is true on any rank (e.g. one rank was interrupted).
    virtual bool any(bool flag) const = 0;
    virtual void barrier() const = 0;
    // Ends every rank's process with exit status `code` (MPI_Abort; serial: std::exit): the way
    // out when one rank fails while the others may wait in a collective call for it.
    [[noreturn]] virtual void abort(int code) const = 0;

    void allreduce_sum(std::vector<double>& values) const { allreduce_sum(values.data(), values.size()); }
    void broadcast(std::vector<double>& values, int root = 0) const { broadcast(values.data(), values.size(), root); }
    bool is_root() const { return rank() == 0; }
};

// The concatenation of every rank's `local`, in rank order, on every rank (gather to rank 0,
// then broadcast). `counts`, when given, receives each rank's count. Collective.
std::vector<double> all_gather(const Communicator& comm, const std::vector<double>& local,
                               std::vector<std::size_t>* counts = nullptr);

// The one agreement on failures (docs/scale.md, "Errors"). Thrown by run_agreed on EVERY rank
// when its work failed on some rank: failed_rank() is the rank whose failure is reported (the
// lowest that failed by itself), message() its exception's what(), what() the message prefixed
// "rank R: " when R != 0: the same on every rank, so rank 0 alone can print it. cause() is
// that rank's own exception on that rank (to rethrow when its type matters, e.g. Python's
// ValueError or the CLI's exit status), null on the others. A RankFailed means every rank
// agreed on the failure: it may pass through further agreements and run_or_abort unchanged.
class RankFailed : public std::runtime_error {
public:
    RankFailed(int failed_rank, const std::string& message, std::exception_ptr cause = nullptr);
    int failed_rank() const { return m_rank; }
    const std::string& message() const { return m_message; }
    const std::exception_ptr& cause() const { return m_cause; }

private:
    int m_rank;
    std::string m_message;
    std::exception_ptr m_cause;
};

// Runs `work` on every rank and agrees on its outcome (one allreduce after it; three
// broadcasts more when it failed), so that a failure on one rank does not leave the others
// waiting in their next collective call. With one rank, `work`'s exceptions propagate
// unchanged. With several, when `work` threw on any rank, every rank throws RankFailed naming
// the lowest rank that failed by itself (a RankFailed thrown by `work`, i.e. an agreement
// inside it, counts only when no rank failed by itself, and is passed on as it is). Use it for
// checks whose outcome may differ between ranks (a rank's share, files only rank 0 touches),
// and around a whole command (then every failure is printed once, by rank 0). `work` may make
// collective calls only where every rank makes them alike; a failure of one rank amid them
// must end all ranks (run_or_abort).
void run_agreed(const Communicator& comm, const std::function<void()>& work);

// Runs `work` (which makes collective calls) and, when it throws on a run of more than one
// rank anything but RankFailed (which every rank throws alike), prints "wavebrdf: error: rank
// R: WHAT" on stderr and ends every rank (Communicator::abort(1)): the others may be waiting
// in a collective call for this one. On one rank the exception passes through.
template <typename Work>
auto run_or_abort(const Communicator& comm, Work&& work) -> decltype(work());

// The one-rank communicator (rank 0 of 1).
const Communicator& serial_communicator();

// True when the library was built with MPI (CMake option WAVEBRDF_MPI, on when MPI is found).
bool built_with_mpi();

// The world of the processes mpirun started, as a communicator: MPI_COMM_WORLD when the
// library was built with MPI and this process was started by an MPI launcher (its environment
// says so: OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK) or MPI is already initialised (e.g. by
// mpi4py); else the serial communicator. The first call initialises MPI when needed (and
// finalises it at exit); later calls return the same object. Throws std::runtime_error when
// MPI's initialisation fails.
std::shared_ptr<const Communicator> world_communicator();

// A communicator from an MPI communicator's Fortran handle (mpi4py: comm.py2f()), for the
// Python module. Throws std::runtime_error when the library was built without MPI or MPI is
// not initialised.
std::shared_ptr<const Communicator> communicator_from_fortran_handle(long long handle);

// The contiguous block [begin, end) of `count` items that rank `rank` of `size` holds: balanced
// (sizes differ by at most one, the larger blocks first), in order, together covering
// 0 … count − 1. Throws std::invalid_argument unless 0 ≤ rank < size.
struct Share {
    std::size_t begin = 0, end = 0;
    std::size_t size() const { return end - begin; }
};
Share share_of(std::size_t count, int rank, int size);

// The observations a rank holds: the distinct footprint centres (positions_um[i] of
// observation i, in order of first appearance) are split into contiguous blocks (share_of),
// and a rank holds every observation at the centres of its block (all their wavelengths and
// light directions), so its footprints cover one region of the tile. Returns the indices of
// its observations, ascending. Throws std::invalid_argument unless 0 ≤ rank < size.
std::vector<std::size_t> observation_share(const std::vector<std::array<double, 2>>& positions_um, int rank, int size);

namespace detail {
[[noreturn]] void abort_after(const Communicator& comm, const char* what);
}

template <typename Work>
auto run_or_abort(const Communicator& comm, Work&& work) -> decltype(work()) {
    if (comm.size() == 1) return work();
    try {
        return work();
    } catch (const RankFailed&) {
        throw;  // agreed: every rank throws it
    } catch (const std::exception& e) {
        detail::abort_after(comm, e.what());
    } catch (...) {
        detail::abort_after(comm, "unknown error");
    }
}

}  // namespace wavebrdf
