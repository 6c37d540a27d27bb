// The serial communicator, the shares, and (built with MPI) the MPI communicator
// (include/wavebrdf/communicator.h), whose calls go through the MPI plugin (src/plugins/mpi_api.h).
#include "wavebrdf/communicator.h"

#include "core/exact_sum.h"

#include <algorithm>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <exception>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>

#ifdef WAVEBRDF_HAS_MPI
#include "core/plugin.h"
#include "plugins/mpi_api.h"
#endif

namespace wavebrdf {

namespace {

class SerialCommunicator final : public Communicator {
public:
    int rank() const override { return 0; }
    int size() const override { return 1; }
    void allreduce_sum(double*, std::size_t) const override {}
    void broadcast(double*, std::size_t, int root) const override { check_root(root); }
    std::vector<double> gather(const std::vector<double>& local, int root) const override {
        check_root(root);
        return local;
    }
    void gather_words(const std::uint64_t* local, std::size_t count, std::uint64_t* all, int root) const override {
        check_root(root);
        if (count > 0) std::memmove(all, local, count * sizeof(std::uint64_t));
    }
    void broadcast_words(std::uint64_t*, std::size_t, int root) const override { check_root(root); }
    bool any(bool flag) const override { return flag; }
    void barrier() const override {}
    [[noreturn]] void abort(int code) const override {
        std::fflush(nullptr);
        std::exit(code);
    }

private:
    static void check_root(int root) {
        if (root != 0)
            throw std::invalid_argument("root rank " + std::to_string(root) + " is out of range; expected 0");
    }
};

#ifdef WAVEBRDF_HAS_MPI

// MPI counts are int: long arrays go in pieces of this many values.
constexpr std::size_t k_chunk = std::size_t(1) << 24;

// MPI, through the plugin (src/plugins/mpi_api.h), loaded on the first call.
const detail::MpiApi& mpi() {
    static const detail::MpiApi* const api = [] {
        using Entry = const detail::MpiApi* (*)();
        const auto entry = reinterpret_cast<Entry>(detail::plugin_symbol("mpi", "wavebrdf_mpi_api"));
        const detail::MpiApi* table = entry();
        if (table == nullptr || table->version != detail::k_mpi_api_version)
            throw std::runtime_error("wavebrdf: the MPI plugin libwavebrdf_mpi.so is of another version (interface " +
                                     std::to_string(table ? table->version : -1) + ", expected " +
                                     std::to_string(detail::k_mpi_api_version) + "); rebuild it");
        return table;
    }();
    return *api;
}

void check_mpi(int code, const char* what) {
    if (code == 0) return;
    char message[512];
    mpi().error_string(code, message, int(sizeof message));
    throw std::runtime_error(std::string("MPI: ") + what + " failed: " + message);
}

class MpiCommunicator final : public Communicator {
public:
    explicit MpiCommunicator(long long comm) : m_comm(comm) {
        check_mpi(mpi().rank(comm, &m_rank), "MPI_Comm_rank");
        check_mpi(mpi().size(comm, &m_size), "MPI_Comm_size");
    }
    int rank() const override { return m_rank; }
    int size() const override { return m_size; }

    // Gather to rank 0, sum there in rank order, broadcast: the same bits on every rank and for
    // every run with this many ranks (MPI_Allreduce may sum in any order).
    void allreduce_sum(double* values, std::size_t count) const override {
        if (m_size == 1) return;
        std::vector<double> all;
        for (std::size_t start = 0; start < count; start += k_chunk) {
            const std::size_t n = std::min(k_chunk, count - start);
            if (m_rank == 0) all.resize(n * std::size_t(m_size));
            check_mpi(mpi().gather_doubles(values + start, int(n), m_rank == 0 ? all.data() : nullptr, 0, m_comm),
                      "MPI_Gather");
            if (m_rank == 0) {
                for (std::size_t i = 0; i < n; ++i) {
                    double sum = all[i];
                    for (int r = 1; r < m_size; ++r) sum += all[std::size_t(r) * n + i];
                    values[start + i] = sum;
                }
            }
            check_mpi(mpi().broadcast_doubles(values + start, int(n), 0, m_comm), "MPI_Bcast");
        }
    }
    void broadcast(double* values, std::size_t count, int root) const override {
        check_root(root);
        for (std::size_t start = 0; start < count; start += k_chunk) {
            const std::size_t n = std::min(k_chunk, count - start);
            check_mpi(mpi().broadcast_doubles(values + start, int(n), root, m_comm), "MPI_Bcast");
        }
    }
    std::vector<double> gather(const std::vector<double>& local, int root) const override {
        check_root(root);
        if (local.size() > std::size_t(1) << 30)
            throw std::invalid_argument("gather of " + std::to_string(local.size()) +
                                        " values per rank; expected at most 2^30");
        int mine = int(local.size());
        std::vector<int> counts(static_cast<std::size_t>(m_size)), offsets(static_cast<std::size_t>(m_size));
        check_mpi(mpi().gather_ints(&mine, 1, counts.data(), root, m_comm), "MPI_Gather");
        std::vector<double> all;
        if (m_rank == root) {
            long long total = 0;
            for (int r = 0; r < m_size; ++r) {
                offsets[std::size_t(r)] = int(total);
                total += counts[std::size_t(r)];
            }
            if (total > (1LL << 31) - 1)
                throw std::invalid_argument("gather of " + std::to_string(total) + " values; expected below 2^31");
            all.resize(std::size_t(total));
        }
        check_mpi(mpi().gatherv_doubles(local.data(), mine, all.data(), counts.data(), offsets.data(), root, m_comm),
                  "MPI_Gatherv");
        return all;
    }
    void gather_words(const std::uint64_t* local, std::size_t count, std::uint64_t* all, int root) const override {
        check_root(root);
        const bool here = m_rank == root;
        std::vector<std::uint64_t> chunk;
        for (std::size_t start = 0; start < count; start += k_chunk) {
            const std::size_t n = std::min(k_chunk, count - start);
            if (here) chunk.resize(n * std::size_t(m_size));
            check_mpi(mpi().gather_words(local + start, int(n), here ? chunk.data() : nullptr, root, m_comm),
                      "MPI_Gather");
            if (here)
                for (std::size_t r = 0; r < std::size_t(m_size); ++r)
                    std::memcpy(all + r * count + start, chunk.data() + r * n, n * sizeof(std::uint64_t));
        }
    }
    void broadcast_words(std::uint64_t* words, std::size_t count, int root) const override {
        check_root(root);
        for (std::size_t start = 0; start < count; start += k_chunk) {
            const std::size_t n = std::min(k_chunk, count - start);
            check_mpi(mpi().broadcast_words(words + start, int(n), root, m_comm), "MPI_Bcast");
        }
    }
    // MPI_Allreduce with a commutative operation on 192-bit integers (the reduction's order is
    // MPI's, the sum's bits are not: integer addition).
    void allreduce_words192(std::uint64_t* words, std::size_t count) const override {
        if (m_size == 1 || count == 0) return;
        const std::size_t piece = k_chunk / 3;
        for (std::size_t start = 0; start < count; start += piece) {
            const std::size_t n = std::min(piece, count - start);
            check_mpi(mpi().allreduce_words192(words + 3 * start, int(n), m_comm), "MPI_Allreduce");
        }
    }
    bool any(bool flag) const override {
        int result = flag ? 1 : 0;
        check_mpi(mpi().allreduce_or(&result, m_comm), "MPI_Allreduce");
        return result != 0;
    }
    void barrier() const override { check_mpi(mpi().barrier(m_comm), "MPI_Barrier"); }
    [[noreturn]] void abort(int code) const override {
        std::fflush(nullptr);
        mpi().abort(m_comm, code);
        std::_Exit(code);  // MPI_Abort does not return; should it, end this rank at least
    }

private:
    void check_root(int root) const {
        if (root < 0 || root >= m_size)
            throw std::invalid_argument("root rank " + std::to_string(root) + " is out of range; expected 0 … " +
                                        std::to_string(m_size - 1));
    }
    long long m_comm;  // a Fortran handle (MPI_Comm_c2f)
    int m_rank = 0, m_size = 1;
};

bool launched_by_mpi() {
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
        if (std::getenv(name) != nullptr) return true;
    return false;
}

// Finalises MPI at exit when this library initialised it.
struct MpiLifetime {
    bool initialised_here = false;
    ~MpiLifetime() {
        if (initialised_here) mpi().finalize();
    }
};

#endif

}  // namespace

void Communicator::allreduce_words192(std::uint64_t* words, std::size_t count) const {
    if (size() == 1) return;
    constexpr std::size_t piece = std::size_t(1) << 18;  // sums per gather: bounds rank 0's buffer
    const std::size_t ranks = static_cast<std::size_t>(size());
    std::vector<std::uint64_t> all;
    for (std::size_t start = 0; start < count; start += piece) {
        const std::size_t n = std::min(piece, count - start);
        std::uint64_t* mine = words + 3 * start;
        if (is_root()) all.resize(3 * n * ranks);
        gather_words(mine, 3 * n, is_root() ? all.data() : nullptr);
        if (is_root())
            for (std::size_t r = 1; r < ranks; ++r) detail::add_words192(all.data() + 3 * n * r, mine, n);
        broadcast_words(mine, 3 * n);
    }
}

const Communicator& serial_communicator() {
    static const SerialCommunicator serial;
    return serial;
}

bool built_with_mpi() {
#ifdef WAVEBRDF_HAS_MPI
    return true;
#else
    return false;
#endif
}

std::shared_ptr<const Communicator> world_communicator() {
    static std::mutex mutex;
    static std::shared_ptr<const Communicator> world;
    std::lock_guard<std::mutex> lock(mutex);
    if (world) return world;
#ifdef WAVEBRDF_HAS_MPI
    // The plugin (and MPI with it) is loaded only when MPI can be in use: this process was
    // started by mpiexec, or it already holds an MPI library (mpi4py).
    if (launched_by_mpi() || detail::library_loaded("libmpi")) {
        static MpiLifetime lifetime;
        int initialised = 0;
        check_mpi(mpi().initialized(&initialised), "MPI_Initialized");
        if (!initialised && launched_by_mpi()) {
            check_mpi(mpi().init_thread_funneled(), "MPI_Init_thread");
            lifetime.initialised_here = true;
            initialised = 1;
        }
        if (initialised) {
            long long handle = 0;
            check_mpi(mpi().world(&handle), "MPI_COMM_WORLD");
            world = std::make_shared<MpiCommunicator>(handle);
            return world;
        }
    }
#endif
    // Not owned: the serial communicator lives for the whole program.
    world = std::shared_ptr<const Communicator>(&serial_communicator(), [](const Communicator*) {});
    return world;
}

std::shared_ptr<const Communicator> communicator_from_fortran_handle(long long handle) {
#ifdef WAVEBRDF_HAS_MPI
    int initialised = 0;
    check_mpi(mpi().initialized(&initialised), "MPI_Initialized");
    if (!initialised)
        throw std::runtime_error("an MPI communicator was given but MPI is not initialised (import mpi4py.MPI first)");
    return std::make_shared<MpiCommunicator>(handle);
#else
    (void)handle;
    throw std::runtime_error(
        "an MPI communicator was given but wavebrdf was built without MPI "
        "(Debian: libopenmpi-dev; CMake option WAVEBRDF_MPI)");
#endif
}

std::vector<double> all_gather(const Communicator& comm, const std::vector<double>& local,
                               std::vector<std::size_t>* counts) {
    if (comm.size() == 1) {
        if (counts) *counts = {local.size()};
        return local;
    }
    std::vector<double> sizes = comm.gather({double(local.size())});
    sizes.resize(std::size_t(comm.size()));
    comm.broadcast(sizes);
    std::vector<double> all = comm.gather(local);
    std::size_t total = 0;
    for (double n : sizes) total += std::size_t(n);
    all.resize(total);
    comm.broadcast(all);
    if (counts) {
        counts->clear();
        for (double n : sizes) counts->push_back(std::size_t(n));
    }
    return all;
}

RankFailed::RankFailed(int failed_rank, const std::string& message, std::exception_ptr cause)
    : std::runtime_error(failed_rank == 0 ? message : "rank " + std::to_string(failed_rank) + ": " + message),
      m_rank(failed_rank),
      m_message(message),
      m_cause(std::move(cause)) {}

namespace {

// `text` from `from` to every rank, as bytes in doubles (a broadcast copies bits). Collective.
std::string broadcast_text(const Communicator& comm, const std::string& text, int from) {
    double length = comm.rank() == from ? double(text.size()) : 0.0;
    comm.broadcast(&length, 1, from);
    const std::size_t bytes = static_cast<std::size_t>(length);
    std::vector<double> packed((bytes + sizeof(double) - 1) / sizeof(double), 0.0);
    if (comm.rank() == from && bytes > 0) std::memcpy(packed.data(), text.data(), bytes);
    comm.broadcast(packed, from);
    std::string received(bytes, '\0');
    if (bytes > 0) std::memcpy(&received[0], packed.data(), bytes);
    return received;
}

}  // namespace

void run_agreed(const Communicator& comm, const std::function<void()>& work) {
    if (comm.size() == 1) {
        work();
        return;
    }
    std::exception_ptr error;
    bool agreed = false;  // work's own agreement failed (on every rank alike)
    int agreed_rank = 0;
    std::string message;
    try {
        work();
    } catch (const RankFailed& e) {
        error = std::current_exception();
        agreed = true;
        agreed_rank = e.failed_rank();
        message = e.message();
    } catch (const std::exception& e) {
        error = std::current_exception();
        message = e.what();
    } catch (...) {
        error = std::current_exception();
        message = "unknown error";
    }
    // 2: this rank failed by itself, 1: an agreement inside work failed, 0: it did not fail.
    std::vector<double> failed(std::size_t(comm.size()), 0.0);
    if (error) failed[std::size_t(comm.rank())] = agreed ? 1.0 : 2.0;
    comm.allreduce_sum(failed);
    const double worst = *std::max_element(failed.begin(), failed.end());
    if (worst == 0.0) return;
    const int from = int(std::find(failed.begin(), failed.end(), worst) - failed.begin());
    if (worst == 1.0) {
        // Every failure is an earlier agreement's: pass the reporting rank's on, as it is.
        double rank = double(agreed_rank);
        comm.broadcast(&rank, 1, from);
        const std::string text = broadcast_text(comm, message, from);
        if (agreed && agreed_rank == int(rank) && message == text) std::rethrow_exception(error);
        throw RankFailed(int(rank), text);
    }
    const std::string text = broadcast_text(comm, message, from);
    throw RankFailed(from, text, comm.rank() == from ? error : nullptr);
}

namespace detail {
void abort_after(const Communicator& comm, const char* what) {
    std::fprintf(stderr, "wavebrdf: error: rank %d: %s\n", comm.rank(), what);
    comm.abort(1);
    std::abort();  // not reached (abort is noreturn; said again for the compiler)
}
}  // namespace detail

Share share_of(std::size_t count, int rank, int size) {
    if (size < 1 || rank < 0 || rank >= size)
        throw std::invalid_argument("rank " + std::to_string(rank) + " of " + std::to_string(size) +
                                    " is out of range; expected 0 <= rank < size");
    const std::size_t k = std::size_t(size), r = std::size_t(rank);
    const std::size_t base = count / k, extra = count % k;
    Share share;
    share.begin = r * base + std::min(r, extra);
    share.end = share.begin + base + (r < extra ? 1 : 0);
    return share;
}

std::vector<std::size_t> observation_share(const std::vector<std::array<double, 2>>& positions_um, int rank, int size) {
    std::map<std::pair<double, double>, std::size_t> index_of;
    std::vector<std::size_t> position_of(positions_um.size());
    for (std::size_t i = 0; i < positions_um.size(); ++i) {
        const auto key = std::make_pair(positions_um[i][0], positions_um[i][1]);
        const auto found = index_of.emplace(key, index_of.size()).first;
        position_of[i] = found->second;
    }
    const Share block = share_of(index_of.size(), rank, size);
    std::vector<std::size_t> mine;
    for (std::size_t i = 0; i < positions_um.size(); ++i)
        if (position_of[i] >= block.begin && position_of[i] < block.end) mine.push_back(i);
    return mine;
}

}  // namespace wavebrdf
