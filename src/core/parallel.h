#pragma once
// Internal: when a loop is worth running on several threads. Small problems (the thesis's
// 16×16 heights, 32×32 slices) run thousands of tiny parallel regions per second; on a machine
// where another process holds a core, every one of them waits at its barrier for the thread
// that is not scheduled, which made a 2 s inversion take 12–50 s. Below this much work a loop
// runs on the calling thread only.
#include <omp.h>

#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <vector>

#include "wavebrdf/interrupt.h"

namespace wavebrdf::detail {

// Makes a parallel region safe to throw from. An exception escaping an OpenMP thread calls
// std::terminate (an out-of-memory in one thread used to abort the program, and Python with
// it), so every body in a region runs through `run`: the first exception of any thread is
// kept, the other threads skip their remaining bodies, and `rethrow` raises it on the calling
// thread after the region. `run` also polls check_interrupt() (only the calling thread has a
// scope to poll), so an interrupt ends the region the same way, as Interrupted.
//   RegionGuard guard;
//   #pragma omp parallel for
//   for (...) guard.run([&] { ...body... });
//   guard.rethrow();
class RegionGuard {
public:
    template <typename Body>
    void run(Body&& body) noexcept {
        if (m_failed.load(std::memory_order_relaxed)) return;
        try {
            check_interrupt();
            body();
        } catch (...) {
            std::lock_guard<std::mutex> lock(m_mutex);
            if (!m_error) m_error = std::current_exception();
            m_failed.store(true, std::memory_order_relaxed);
        }
    }
    // True once a body has thrown (the region is winding down).
    bool failed() const { return m_failed.load(std::memory_order_relaxed); }
    // After the region, on the calling thread: throws the first exception, if any.
    void rethrow() const {
        if (m_error) std::rethrow_exception(m_error);
    }

private:
    std::atomic<bool> m_failed{false};
    std::mutex m_mutex;
    std::exception_ptr m_error;
};

constexpr long long kParallelWork = 1LL << 16;  // loop iterations × inner entries

// True inside an active parallel region (a batch spreading its items over the threads, batch.h):
// there every loop below runs on its own thread, so an item does not spawn (or wait for) a
// nested team of its own.
inline bool in_parallel_region() { return omp_in_parallel() != 0; }

inline bool worth_parallel(long long work) { return work >= kParallelWork && !in_parallel_region(); }

// Matrix products: Eigen's own OpenMP splitting starts at ~1e5 multiply-adds and has no way to
// stay serial below a size we choose, so the library builds with EIGEN_DONT_PARALLELIZE and
// splits the products itself: `body(first_column, count)` per column block of the result, one
// block per thread when the product has at least this many multiply-adds.
constexpr double kParallelProduct = 4.0e6;

template <typename Body>
void for_column_blocks(long long columns, double multiply_adds, Body&& body) {
    const int blocks = multiply_adds >= kParallelProduct && !in_parallel_region() ? omp_get_max_threads() : 1;
    RegionGuard guard;
#pragma omp parallel for schedule(static) num_threads(blocks) if (blocks > 1)
    for (int b = 0; b < blocks; ++b) {
        guard.run([&] {
            const long long first = columns * b / blocks, last = columns * (b + 1) / blocks;
            if (last > first) body(first, last - first);
        });
    }
    guard.rethrow();
}

// Σ_i body(i, local) over i = 0…count−1, and the sum of the vectors each call adds into
// `local` (sized like `total`, zeroed) added into `total`, on all threads when `parallel`.
// Reproducible for a given thread count: a static schedule gives every thread the same items
// on every call, and the per-thread partial sums are combined in thread order afterwards (an
// OpenMP reduction or a critical section combines them in whatever order threads finish).
template <typename T, typename Body>
double ordered_parallel_sum(std::size_t count, std::vector<T>& total, bool parallel, Body&& body) {
    const int threads = parallel && !in_parallel_region() ? omp_get_max_threads() : 1;
    std::vector<std::vector<T>> locals(static_cast<std::size_t>(threads));
    std::vector<double> values(static_cast<std::size_t>(threads), 0.0);
    RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
        guard.run([&] { locals[t].assign(total.size(), T(0)); });
#pragma omp for schedule(static)
        for (std::size_t i = 0; i < count; ++i) guard.run([&] { values[t] += body(i, locals[t]); });
    }
    guard.rethrow();
    double value = 0.0;
    for (std::size_t t = 0; t < locals.size(); ++t) {
        value += values[t];
        for (std::size_t k = 0; k < locals[t].size(); ++k) total[k] += locals[t][k];
    }
    return value;
}

}  // namespace wavebrdf::detail
