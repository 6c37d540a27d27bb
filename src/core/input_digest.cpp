#include "wavebrdf/input_digest.h"

#include <cstdio>
#include <stdexcept>
#include <string>

namespace wavebrdf {

void InputDigest::add_bytes(const void* bytes, std::size_t count) {
    const auto* p = static_cast<const unsigned char*>(bytes);
    for (std::size_t k = 0; k < count; ++k) {
        m_hash ^= p[k];
        m_hash *= 1099511628211ull;
    }
}

void agree_on_inputs(const Communicator& comm, std::uint64_t digest, const std::string& what) {
    if (comm.size() == 1) return;
    std::uint64_t root = digest;
    comm.broadcast_words(&root, 1, 0);
    run_agreed(comm, [&] {
        if (digest == root) return;
        char text[80];
        std::snprintf(text, sizeof text, " (digest %016llx here, %016llx on rank 0)",
                      static_cast<unsigned long long>(digest), static_cast<unsigned long long>(root));
        throw std::invalid_argument("the ranks were given different " + what + text +
                                    "; expected every rank to run the same job with the same inputs");
    });
}

}  // namespace wavebrdf
