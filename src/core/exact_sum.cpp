// Exact, order-independent sums (core/exact_sum.h): the cold paths and the collectives.
#include "core/exact_sum.h"

#include <cstring>

#include "wavebrdf/text.h"

namespace wavebrdf::detail {

void exact_sum_refuse(double value, double limit) {
    throw std::overflow_error("exact sum: term " + format_shortest(value) +
                              " is out of range; expected a finite value below " + format_shortest(limit) +
                              " in magnitude");
}

void exact_sum_overflow() {
    throw std::overflow_error(
        "exact sum: a sum left the 128-bit fixed-point range (more than 2^23 of the largest "
        "terms on one value)");
}

namespace {
// Sums per collective call (three words each): bounds each rank's buffer to 6 MB.
constexpr std::size_t k_exact_chunk = std::size_t(1) << 18;

// A 128-bit sum sign-extended to 192 bits, and back: the sum of K ranks' 128-bit sums fits in
// 192 bits for any K below 2^64, so the collective sum is exact whatever the order of the ranks;
// only a total outside the 128-bit range is refused (on every rank alike: the same bits).
void to_words192(ExactVector::Word w, std::uint64_t* out) {
    const unsigned __int128 u = static_cast<unsigned __int128>(w);
    out[0] = static_cast<std::uint64_t>(u);
    out[1] = static_cast<std::uint64_t>(u >> 64);
    out[2] = w < 0 ? ~std::uint64_t(0) : 0;
}
ExactVector::Word from_words192(const std::uint64_t* in) {
    if (in[2] != ((in[1] >> 63) != 0 ? ~std::uint64_t(0) : 0)) exact_sum_overflow();
    const unsigned __int128 u = (static_cast<unsigned __int128>(in[1]) << 64) | in[0];
    return static_cast<ExactVector::Word>(u);
}
}  // namespace

void ExactVector::allreduce(const Communicator& comm) {
    if (comm.size() == 1) return;
    const std::size_t n = m_sum.size();
    std::vector<std::uint64_t> words;
    for (std::size_t start = 0; start < n; start += k_exact_chunk) {
        const std::size_t count = std::min(k_exact_chunk, n - start);
        words.resize(3 * count);
        for (std::size_t k = 0; k < count; ++k) to_words192(m_sum[start + k], &words[3 * k]);
        comm.allreduce_words192(words.data(), count);
        for (std::size_t k = 0; k < count; ++k) m_sum[start + k] = from_words192(&words[3 * k]);
    }
}

double exact_total(const std::vector<double>& local, const Communicator& comm) {
    double largest = 0.0;
    for (double v : local) largest = std::isfinite(v) ? std::max(largest, std::abs(v)) : HUGE_VAL;
    for (double m : all_gather(comm, {largest})) largest = std::max(largest, m);  // max: any order
    if (std::isinf(largest)) {
        for (double v : local)
            if (!std::isfinite(v)) exact_sum_refuse(v, HUGE_VAL);
        throw std::overflow_error("exact sum: another rank's term is not finite; expected finite values");
    }
    if (largest == 0.0) return 0.0;
    // Every term scaled below 2^31 (the accumulator takes up to 2^32 at 72 fraction bits).
    const int e = std::ilogb(largest) + 1;  // largest < 2^e
    ExactVector sum(1);
    for (double v : local) sum.add(0, std::ldexp(v, 31 - e));
    sum.allreduce(comm);
    return std::ldexp(sum.value(0), e - 31);
}

std::atomic<bool>& exact_scratch_check() {
    static std::atomic<bool> check{false};
    return check;
}

void ExactParallelSum::verify_zero(const std::vector<double>& scratch, std::size_t i) {
    for (std::size_t k = 0; k < scratch.size(); ++k)
        if (scratch[k] != 0.0)
            throw std::logic_error("exact sum: observation " + std::to_string(i) + " wrote scratch value " +
                                   std::to_string(k) + " outside the box it handed over");
}

}  // namespace wavebrdf::detail
