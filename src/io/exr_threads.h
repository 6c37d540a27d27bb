// OpenEXR's thread pool for the library's EXR files (src/io/io.cpp).
#pragma once

namespace wavebrdf::detail {

// Sets OpenEXR's global thread pool to the library's thread count (--threads, OMP_NUM_THREADS)
// and returns it, for an Imf::InputFile or Imf::OutputFile's numThreads: line blocks are then
// compressed and decompressed on that many threads. The same bytes either way.
int exr_threads();

}  // namespace wavebrdf::detail
