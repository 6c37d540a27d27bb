#pragma once
// Internal: sums over observations that do not depend on the order of their terms, exactly, so
// a result does not depend on the number of threads or MPI ranks (docs/scale.md, "Equality with
// one process").
//
// Each double term v is rounded once to the fixed-point integer round(v · 2^F) (F fraction
// bits, default 72) and the integers are summed in 128 bits, where addition is exact and
// associative: any grouping — per thread, per rank, in any order — gives the same integer, and
// the sum is converted to a double once at the end (one rounding). Per term the rounding error
// is at most 2^−(F+1) (2.1e-22 at F = 72 in absolute terms); a term must be below 2^(104−F) in
// magnitude (4.3e9 at F = 72) — larger, NaN or infinite terms throw std::overflow_error naming
// the value, and so does a sum leaving the 128-bit range (more than 2^23 terms of the largest
// size on one element), never wrapping silently.
//
// The contributions of ONE observation must reach the accumulator separately from those of any
// other (adding two observations' doubles first would make the result depend on how
// observations are grouped again). The pattern (ExactParallelSum): every thread has a zeroed
// double scratch the size of the result; an observation's body writes its contribution into it
// (as it would into a gradient) and hands the box it wrote over (take_box), whose values are
// added to the exact accumulator and zeroed, so the cost is that of the footprint, not of the
// whole vector.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/parallel.h"
#include "core/words192.h"
#include "wavebrdf/communicator.h"

namespace wavebrdf::detail {

constexpr int k_exact_fraction_bits = 72;

// Throws std::overflow_error naming `value` and the accumulator's range (cold path).
[[noreturn]] void exact_sum_refuse(double value, double limit);
// Throws std::overflow_error: a sum left the 128-bit range.
[[noreturn]] void exact_sum_overflow();

// A vector of exact sums (signed 128-bit fixed-point integers with F fraction bits).
class ExactVector {
public:
    using Word = __int128;

    // n sums, all 0. fraction_bits F: 8 … 100 (the resolution 2^−F, the largest term 2^(104−F)).
    explicit ExactVector(std::size_t n = 0, int fraction_bits = k_exact_fraction_bits) : m_sum(n, 0) {
        if (fraction_bits < 8 || fraction_bits > 100)
            throw std::invalid_argument("exact sum fraction bits " + std::to_string(fraction_bits) +
                                        " is invalid; expected 8 to 100");
        m_bits = fraction_bits;
        m_scale = std::ldexp(1.0, fraction_bits);
        m_inv_scale = std::ldexp(1.0, -fraction_bits);
        m_limit = std::ldexp(1.0, 104);
    }
    // Copies the sums (not the locks: a copy has its own, when the original has any).
    ExactVector(const ExactVector& other)
        : m_sum(other.m_sum),
          m_bits(other.m_bits),
          m_scale(other.m_scale),
          m_inv_scale(other.m_inv_scale),
          m_limit(other.m_limit) {
        if (other.m_locks) enable_locks();
    }
    ExactVector& operator=(const ExactVector& other) {
        if (this != &other) {
            m_sum = other.m_sum;
            m_bits = other.m_bits;
            m_scale = other.m_scale;
            m_inv_scale = other.m_inv_scale;
            m_limit = other.m_limit;
            if (other.m_locks) enable_locks();
        }
        return *this;
    }
    ExactVector(ExactVector&&) noexcept = default;
    ExactVector& operator=(ExactVector&&) noexcept = default;

    std::size_t size() const { return m_sum.size(); }
    int fraction_bits() const { return m_bits; }
    // The largest term's magnitude accepted (exclusive).
    double max_term() const { return m_limit * m_inv_scale; }
    // Sets every sum to 0 (and the size to n).
    void assign_zero(std::size_t n) { m_sum.assign(n, 0); }
    void set_zero() { std::fill(m_sum.begin(), m_sum.end(), Word(0)); }

    // The fixed-point integer of one term, round(v · 2^F) (ties to even). Throws
    // std::overflow_error when |v| ≥ max_term() or v is not finite.
    Word to_fixed(double v) const {
        const double x = v * m_scale;  // exact: a power of two
        // Most terms (|x| < 2^62): one rounding to an integer, the same value as below.
        if (std::abs(x) < 0x1p62) return Word(static_cast<std::int64_t>(std::rint(x)));
        if (!(std::abs(x) < m_limit)) exact_sum_refuse(v, max_term());
        // x = hi · 2^52 + rest, both parts exact: x·2^−52 − trunc(x·2^−52) is exact in binary
        // floating point, and |hi| < 2^52, |rest| < 2^52.
        const double hi = std::trunc(x * 0x1p-52);
        const double rest = x - hi * 0x1p52;
        // (A product, not a shift: shifting a negative value left is undefined before C++20.)
        return Word(static_cast<std::int64_t>(hi)) * (Word(1) << 52) + Word(static_cast<std::int64_t>(std::rint(rest)));
    }
    static Word checked_add(Word a, Word b) {
        Word r;
        if (__builtin_add_overflow(a, b, &r)) exact_sum_overflow();
        return r;
    }

    // sum[k] += v.
    void add(std::size_t k, double v) { m_sum[k] = checked_add(m_sum[k], to_fixed(v)); }
    // sum[first + j] += scratch[first + j] for j < count, then those scratch values are 0.
    void take_range(double* scratch, std::size_t first, std::size_t count) {
        for (std::size_t k = first; k < first + count; ++k) take(scratch, k);
    }
    // The same for the box rows × cols of a row-major grid of grid_cols columns with `width`
    // doubles per grid element (1; 2 for complex values): the elements r · grid_cols + c for r
    // in rows, c in cols (each listed once; a footprint's rows wrap around the tile), i.e.
    // scratch indices width · (r · grid_cols + c) + 0 … width − 1.
    void take_box(double* scratch, const std::vector<int>& rows, const std::vector<int>& cols, std::size_t grid_cols,
                  int width = 1) {
        for (int r : rows) take_row(scratch, r, cols, grid_cols, width);
    }
    // As take_box, safe to call from several threads at once on one accumulator: each row is
    // added under one of a set of locks (integer sums: the order threads take them in does
    // not matter).
    void take_box_locked(double* scratch, const std::vector<int>& rows, const std::vector<int>& cols,
                         std::size_t grid_cols, int width = 1) {
        if (!m_locks) throw std::logic_error("ExactVector::take_box_locked needs enable_locks() first");
        for (int r : rows) {
            std::lock_guard<std::mutex> lock(m_locks[std::size_t(r) % k_locks]);
            take_row(scratch, r, cols, grid_cols, width);
        }
    }
    // sum[k] += v, safe from several threads at once (as take_box_locked).
    void add_locked(std::size_t k, double v) {
        if (!m_locks) throw std::logic_error("ExactVector::add_locked needs enable_locks() first");
        const Word w = to_fixed(v);
        std::lock_guard<std::mutex> lock(m_locks[k % k_locks]);
        m_sum[k] = checked_add(m_sum[k], w);
    }
    void enable_locks() {
        if (!m_locks) m_locks = std::make_unique<std::mutex[]>(k_locks);
    }

    // sum += other's sums (the same size and fraction bits): per-thread accumulators combined,
    // in any order.
    void merge(const ExactVector& other) {
        if (other.m_sum.size() != m_sum.size() || other.m_bits != m_bits)
            throw std::invalid_argument("exact sums of " + std::to_string(other.m_sum.size()) + " values with " +
                                        std::to_string(other.m_bits) + " fraction bits merged into " +
                                        std::to_string(m_sum.size()) + " with " + std::to_string(m_bits));
        for (std::size_t k = 0; k < m_sum.size(); ++k) m_sum[k] = checked_add(m_sum[k], other.m_sum[k]);
    }

    // Every rank's sums added, on every rank (collective; the same bits on every rank and for
    // any number of ranks: integer sums). Nothing on one rank.
    void allreduce(const Communicator& comm);

    // The sum k as a double (one rounding, to nearest).
    double value(std::size_t k) const {
        const Word w = m_sum[k];
        // Sums that fit 64 bits (most): one hardware conversion, the same correctly rounded value.
        const std::int64_t narrow = static_cast<std::int64_t>(w);
        return (Word(narrow) == w ? double(narrow) : double(w)) * m_inv_scale;
    }
    // Every sum as a double into out[0 … size() − 1] (on all threads for long vectors).
    void values(double* out) const { values(out, m_sum.size()); }
    // The first n sums (n ≤ size()).
    void values(double* out, std::size_t n) const {
#pragma omp parallel for schedule(static) if (worth_parallel((long long)n))
        for (std::size_t k = 0; k < n; ++k) out[k] = value(k);
    }
    std::vector<double> values() const {
        std::vector<double> out(m_sum.size());
        values(out.data());
        return out;
    }
    // As values(out, n), and every sum set to 0 afterwards (for the next round of sums).
    void take_values(double* out, std::size_t n) {
        const std::size_t all = m_sum.size();
#pragma omp parallel for schedule(static) if (worth_parallel((long long)all))
        for (std::size_t k = 0; k < all; ++k) {
            if (k < n) out[k] = value(k);
            m_sum[k] = 0;
        }
    }
    Word word(std::size_t k) const { return m_sum[k]; }

private:
    static constexpr std::size_t k_locks = 64;
    void take(double* scratch, std::size_t k) {
        const double v = scratch[k];
        if (v != 0.0) {
            m_sum[k] = checked_add(m_sum[k], to_fixed(v));
            scratch[k] = 0.0;
        }
    }
    void take_row(double* scratch, int r, const std::vector<int>& cols, std::size_t grid_cols, int width) {
        const std::size_t w = std::size_t(width);
        const std::size_t row = std::size_t(r) * grid_cols;
        // Runs of consecutive columns are contiguous in the scratch: taken in blocks.
        const std::size_t n = cols.size();
        for (std::size_t j = 0; j < n;) {
            std::size_t end = j + 1;
            while (end < n && cols[end] == cols[end - 1] + 1) ++end;
            take_run(scratch, (row + std::size_t(cols[j])) * w, (end - j) * w);
            j = end;
        }
    }
    // take() for scratch[first … first + count), the same sums: where every value of a block is
    // below 2^62 after scaling (almost always), its fixed-point integers are formed in one
    // vectorisable pass and added (adding a zero term changes no sum); otherwise per value.
    void take_run(double* scratch, std::size_t first, std::size_t count) {
        constexpr std::size_t kBlock = 64;
        double* v = scratch + first;
        Word* sum = m_sum.data() + first;
        std::int64_t fixed[kBlock];
        for (std::size_t b = 0; b < count; b += kBlock) {
            const std::size_t len = std::min(kBlock, count - b);
            bool small = true;  // false for a large, NaN or infinite value
            for (std::size_t k = 0; k < len; ++k) small &= std::abs(v[b + k] * m_scale) < 0x1p62;
            if (!small) {  // the general path (it refuses NaN, infinities and too large terms)
                for (std::size_t k = 0; k < len; ++k) take(scratch, first + b + k);
                continue;
            }
            for (std::size_t k = 0; k < len; ++k) fixed[k] = static_cast<std::int64_t>(std::rint(v[b + k] * m_scale));
            for (std::size_t k = 0; k < len; ++k) sum[b + k] = checked_add(sum[b + k], Word(fixed[k]));
            std::fill(v + b, v + b + len, 0.0);
        }
    }

    std::vector<Word> m_sum;
    int m_bits = k_exact_fraction_bits;
    double m_scale = 0.0, m_inv_scale = 0.0, m_limit = 0.0;
    std::unique_ptr<std::mutex[]> m_locks;
};

// Σ_i v_i over `local` on this rank and every other rank (collective), exactly and
// independently of the order, for values of any magnitude: the terms are scaled by a power of
// two from the largest magnitude over all ranks (so each is below the accumulator's range)
// before they are summed. Throws std::overflow_error for a non-finite value.
double exact_total(const std::vector<double>& local, const Communicator& comm);

// True: ExactParallelSum checks after every body that the scratch is all zeros again (a box
// handed to take_box that missed a written value throws std::logic_error). For tests; costs a
// pass over the scratch per observation.
std::atomic<bool>& exact_scratch_check();

// One thread's view of an ExactParallelSum while a body runs: its scratch and the ways to hand
// the written box to the shared exact accumulator.
class ExactScratch {
public:
    // The scratch: n doubles, zero when the body starts. Write this observation's contribution.
    std::vector<double>& vector() { return *m_scratch; }
    double* data() { return m_scratch->data(); }
    std::complex<double>* complex_data() { return reinterpret_cast<std::complex<double>*>(m_scratch->data()); }
    // Adds the box (ExactVector::take_box) to the sums and zeroes it there.
    void take_box(const std::vector<int>& rows, const std::vector<int>& cols, std::size_t grid_cols, int width = 1) {
        m_total->take_box_locked(m_scratch->data(), rows, cols, grid_cols, width);
    }
    // The whole scratch (for small vectors).
    void take_all() {
        for (std::size_t k = 0; k < m_scratch->size(); ++k)
            if ((*m_scratch)[k] != 0.0) {
                m_total->add_locked(k, (*m_scratch)[k]);
                (*m_scratch)[k] = 0.0;
            }
    }

private:
    friend class ExactParallelSum;
    std::vector<double>* m_scratch = nullptr;
    ExactVector* m_total = nullptr;
};

// Σ over observations of a scalar (the loss) and a vector (its gradient, n doubles), exact
// and independent of the thread count and of how the observations are split over ranks:
//   ExactParallelSum sum(n);                       // keep it from call to call
//   double loss = sum.run(count, comm, gradient, [&](std::size_t i, ExactScratch& s) {
//       ... write observation i's gradient into s.vector() ...
//       s.take_box(rows, cols, grid_cols);         // every value written lies in the box
//       return loss_i;                             // added exactly too
//   });
// Runs body(i, scratch) for i = 0 … count − 1 on all threads (a dynamic schedule: the order
// does not matter), then sums over the ranks of comm (collective) and writes the vector sums
// into gradient (resized to n) and returns the scalar sum. The scratches (n doubles per
// thread) and the shared accumulator (16 bytes per value) are kept between calls.
class ExactParallelSum {
public:
    explicit ExactParallelSum(std::size_t n, int fraction_bits = k_exact_fraction_bits)
        : m_n(n), m_total(n + 1, fraction_bits) {
        m_total.enable_locks();
    }

    template <typename Body>
    double run(std::size_t count, const Communicator& comm, std::vector<double>& gradient, Body&& body) {
        gradient.resize(m_n);
        return run(count, comm, gradient.data(), std::forward<Body>(body));
    }
    // The same into out[0 … n − 1] (e.g. complex values as 2n doubles).
    template <typename Body>
    double run(std::size_t count, const Communicator& comm, double* out, Body&& body) {
        run_local(count, std::forward<Body>(body));
        return finish(comm, out);
    }
    // The same without the ranks' sum: this rank's exact sums (then total(), or finish).
    // accumulate: add to the sums of the run_local before (e.g. the observations of one
    // wavelength after another's, each with its own data prepared) instead of starting at 0.
    template <typename Body>
    void run_local(std::size_t count, Body&& body, bool accumulate = false) {
        if (!m_zero && !accumulate) m_total.set_zero();
        m_zero = false;
        const int threads = m_parallel && count > 1 && !in_parallel_region() ? std::max(1, omp_get_max_threads()) : 1;
        if (m_scratch.size() < std::size_t(threads)) m_scratch.resize(std::size_t(threads));
        const bool check = exact_scratch_check().load(std::memory_order_relaxed);
        RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
        {
            std::vector<double>& scratch = m_scratch[std::size_t(omp_get_thread_num())];
            guard.run([&] { scratch.resize(m_n, 0.0); });  // zero on the first call, kept zero after
            ExactScratch s;
            s.m_scratch = &scratch;
            s.m_total = &m_total;
#pragma omp for schedule(dynamic)
            for (std::size_t i = 0; i < count; ++i)
                guard.run([&] {
                    const double value = body(i, s);
                    m_total.add_locked(m_n, value);
                    if (check) verify_zero(scratch, i);
                });
        }
        if (guard.failed())  // a body that threw may have left values behind
            for (std::vector<double>& scratch : m_scratch) std::fill(scratch.begin(), scratch.end(), 0.0);
        guard.rethrow();
    }
    // After run_local(s): sums over the ranks of comm (collective), writes the vector sums into
    // out[0 … n − 1] and returns the scalar sum (as run's end; the sums are zero after).
    double finish(const Communicator& comm, double* out) {
        m_total.allreduce(comm);
        const double value = m_total.value(m_n);
        m_total.take_values(out, m_n);  // and zero for the next call
        m_zero = true;
        return value;
    }
    ExactVector& total() { return m_total; }
    // false: the bodies run on the calling thread only, in order (e.g. when they share a
    // cache that is not thread-safe); the sums are the same either way.
    void set_parallel(bool parallel) { m_parallel = parallel; }

private:
    static void verify_zero(const std::vector<double>& scratch, std::size_t i);
    std::size_t m_n;
    ExactVector m_total;  // m_n vector sums, then the scalar
    bool m_zero = true;   // m_total is all zeros
    bool m_parallel = true;
    std::vector<std::vector<double>> m_scratch;
};

}  // namespace wavebrdf::detail
