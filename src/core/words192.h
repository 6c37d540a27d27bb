// The exact sums' collective form (src/core/exact_sum.h), apart so that the MPI plugin
// (src/plugins/mpi/mpi_plugin.cpp) adds the same way without the rest of the exact sums.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wavebrdf::detail {

// 192-bit two's-complement integers, three words each, least significant first (the exact
// sums' collective form: Communicator::allreduce_words192). inout[i] += in[i] modulo 2^192.
inline void add_words192(const std::uint64_t* in, std::uint64_t* inout, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i, in += 3, inout += 3) {
        const unsigned __int128 low = static_cast<unsigned __int128>(in[0]) + inout[0];
        const unsigned __int128 mid = static_cast<unsigned __int128>(in[1]) + inout[1] + static_cast<std::uint64_t>(low >> 64);
        inout[0] = static_cast<std::uint64_t>(low);
        inout[1] = static_cast<std::uint64_t>(mid);
        inout[2] = in[2] + inout[2] + static_cast<std::uint64_t>(mid >> 64);
    }
}

}  // namespace wavebrdf::detail
