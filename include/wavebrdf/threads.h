#pragma once
// The number of threads the library's parallel loops use (OpenMP). By default OpenMP's own:
// the environment variable OMP_NUM_THREADS when set, else every core. The CLI's --threads N
// calls set_thread_count before any work.
namespace wavebrdf {

// The most threads set_thread_count accepts.
constexpr int k_max_thread_count = 1024;

// Sets the number of threads the calling thread's later parallel work uses
// (omp_set_num_threads). Throws std::domain_error naming the value unless 1 ≤ threads ≤ 1024.
void set_thread_count(int threads);

// The number of threads the next parallel work of the calling thread may use
// (omp_get_max_threads; 1 in a build without OpenMP).
int thread_count();

}  // namespace wavebrdf
