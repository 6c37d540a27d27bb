#include "core/fftw_planner.h"

namespace wavebrdf::detail {

std::mutex& fftw_planner_mutex() {
    static std::mutex mutex;
    return mutex;
}

}  // namespace wavebrdf::detail
