#include "wavebrdf/threads.h"

#include <stdexcept>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace wavebrdf {

void set_thread_count(int threads) {
    if (threads < 1 || threads > k_max_thread_count)
        throw std::domain_error("thread count " + std::to_string(threads) + " is out of range; expected 1 to " +
                                std::to_string(k_max_thread_count));
#ifdef _OPENMP
    omp_set_num_threads(threads);
#endif
}

int thread_count() {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

}  // namespace wavebrdf
