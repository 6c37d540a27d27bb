#pragma once
// Whether every rank of a run was given the same job: a digest of its options and inputs,
// compared over the ranks before the first collective call that depends on them.
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/communicator.h"

namespace wavebrdf {

// A 64-bit digest (FNV-1a) of what a rank was given, to check before the first collective call
// that depends on it that every rank runs the same job (agree_on_inputs).
class InputDigest {
public:
    void add_bytes(const void* bytes, std::size_t count);
    void add(double value) { add_bytes(&value, sizeof value); }
    void add(long long value) { add_bytes(&value, sizeof value); }
    void add(const std::string& text) {
        add(static_cast<long long>(text.size()));
        add_bytes(text.data(), text.size());
    }
    void add(const std::vector<double>& values) {
        add(static_cast<long long>(values.size()));
        add_bytes(values.data(), values.size() * sizeof(double));
    }
    std::uint64_t value() const { return m_hash; }

private:
    std::uint64_t m_hash = 14695981039346656037ull;
};

// Throws RankFailed on every rank when `digest` is not the same on every rank: ranks started
// with different options or files (mpiexec's MPMD form, node-local copies that differ) would
// otherwise give a wrong answer with exit 0, or abort in a collective of mismatched sizes.
// `what` names what the digest covers in the message ("rank R: the ranks were given different
// WHAT ..."). Collective: one broadcast of one word and one agreement, whatever the inputs.
void agree_on_inputs(const Communicator& comm, std::uint64_t digest, const std::string& what);

}  // namespace wavebrdf
