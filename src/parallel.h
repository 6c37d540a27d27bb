#pragma once
// Internal: when a loop is worth running on several threads. Small problems (the thesis's
// 16×16 heights, 32×32 slices) run thousands of tiny parallel regions per second; on a machine
// where another process holds a core, every one of them waits at its barrier for the thread
// that is not scheduled, which made a 2 s inversion take 12–50 s. Below this much work a loop
// runs on the calling thread only.
#include <omp.h>

namespace wavebrdf::detail {

constexpr long long kParallelWork = 1LL << 16;  // loop iterations × inner entries

inline bool worth_parallel(long long work) { return work >= kParallelWork; }

// Matrix products: Eigen's own OpenMP splitting starts at ~1e5 multiply-adds and has no way to
// stay serial below a size we choose, so the library builds with EIGEN_DONT_PARALLELIZE and
// splits the products itself: `body(first_column, count)` per column block of the result, one
// block per thread when the product has at least this many multiply-adds.
constexpr double kParallelProduct = 4.0e6;

template <typename Body>
void for_column_blocks(long long columns, double multiply_adds, Body&& body) {
    const int blocks = multiply_adds >= kParallelProduct ? omp_get_max_threads() : 1;
#pragma omp parallel for schedule(static) num_threads(blocks) if (blocks > 1)
    for (int b = 0; b < blocks; ++b) {
        const long long first = columns * b / blocks, last = columns * (b + 1) / blocks;
        if (last > first) body(first, last - first);
    }
}

}  // namespace wavebrdf::detail
