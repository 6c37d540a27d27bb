#pragma once
// Internal: FFTW's planner is not thread-safe (only fftw_execute* is): every FFTW user in the
// library (the FFT engine, the surface generator, the field retrieval and the unwrapper) makes
// and destroys its plans under this one lock.
#include <mutex>

namespace wavebrdf::detail {

std::mutex& fftw_planner_mutex();

}  // namespace wavebrdf::detail
