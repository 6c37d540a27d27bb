// Exact, order-independent sums (src/core/exact_sum.h): the same bits in any order and
// grouping, close to a long-double reference, refusal of what does not fit, and the
// parallel-sum pattern with its box check.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

#include "core/exact_sum.h"
#include "wavebrdf/communicator.h"

namespace wavebrdf::detail {
namespace {

// Values of mixed magnitude and sign: 1e-12 … 1e6, some exact cancellations.
std::vector<double> mixed_values(std::size_t count, unsigned seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
    std::uniform_int_distribution<int> exponent(-40, 20);
    std::vector<double> v(count);
    for (double& x : v) x = std::ldexp(mantissa(rng), exponent(rng));
    for (std::size_t k = 0; k + 1 < count; k += 17) v[k + 1] = -v[k];
    return v;
}

TEST(ExactSum, AnyOrderAndGroupingGivesTheSameBits) {
    const std::vector<double> v = mixed_values(5000, 1);
    ExactVector reference(1);
    for (double x : v) reference.add(0, x);
    std::mt19937_64 rng(2);
    for (int trial = 0; trial < 20; ++trial) {
        std::vector<double> shuffled = v;
        std::shuffle(shuffled.begin(), shuffled.end(), rng);
        // Random groups (as threads or ranks), each summed alone, merged in a random order.
        const std::size_t groups = 1 + rng() % 7;
        std::vector<ExactVector> parts(groups, ExactVector(1));
        for (double x : shuffled) parts[rng() % groups].add(0, x);
        std::shuffle(parts.begin(), parts.end(), rng);
        ExactVector total(1);
        for (const ExactVector& p : parts) total.merge(p);
        EXPECT_EQ(total.word(0), reference.word(0)) << "trial " << trial;
        EXPECT_EQ(total.value(0), reference.value(0));
    }
    // Plain double sums of the same shuffles do differ (what this accumulator is for).
    double forward = 0.0, backward = 0.0;
    for (double x : v) forward += x;
    for (auto it = v.rbegin(); it != v.rend(); ++it) backward += *it;
    EXPECT_NE(forward, backward);
}

TEST(ExactSum, MergeIsAssociative) {
    const std::vector<double> v = mixed_values(300, 3);
    ExactVector a(3), b(3), c(3);
    for (std::size_t k = 0; k < v.size(); ++k) (k % 3 == 0 ? a : k % 3 == 1 ? b : c).add(k % 3, v[k]);
    ExactVector ab_c = a, a_bc = a, bc = b;  // copies: (a + b) + c and a + (b + c)
    ab_c.merge(b);
    ab_c.merge(c);
    bc.merge(c);
    a_bc.merge(bc);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(ab_c.word(k), a_bc.word(k));
    EXPECT_THROW(a.merge(ExactVector(2)), std::invalid_argument);
    EXPECT_THROW(a.merge(ExactVector(3, 60)), std::invalid_argument);
}

TEST(ExactSum, EqualsALongDoubleReferenceWithinTheResolution) {
    for (unsigned seed = 10; seed < 15; ++seed) {
        const std::vector<double> v = mixed_values(20000, seed);
        ExactVector sum(1);
        long double reference = 0.0L, compensation = 0.0L;  // Kahan in long double
        for (double x : v) {
            sum.add(0, x);
            const long double y = (long double)x - compensation, t = reference + y;
            compensation = (t - reference) - y;
            reference = t;
        }
        // Per term at most half a unit of 2^−72, then one rounding to double.
        const double bound = double(v.size()) * std::ldexp(0.5, -k_exact_fraction_bits) +
                             std::abs(double(reference)) * 0x1p-52 + 1e-300;
        EXPECT_NEAR(sum.value(0), double(reference), bound) << "seed " << seed;
    }
    // Exactly representable sums come out exactly.
    ExactVector exact(1);
    exact.add(0, 0.1);
    exact.add(0, 0.2);
    exact.add(0, -0.1);
    exact.add(0, -0.2);
    exact.add(0, 3.0);
    EXPECT_EQ(exact.value(0), 3.0);
    ExactVector small(1);
    small.add(0, std::ldexp(1.0, -70));
    EXPECT_EQ(small.value(0), std::ldexp(1.0, -70));
}

TEST(ExactSum, RefusesWhatDoesNotFitInsteadOfWrapping) {
    ExactVector sum(1);
    EXPECT_NO_THROW(sum.add(0, 0.99 * sum.max_term()));
    EXPECT_THROW(sum.add(0, sum.max_term()), std::overflow_error);
    EXPECT_THROW(sum.add(0, -2.0 * sum.max_term()), std::overflow_error);
    EXPECT_THROW(sum.add(0, std::nan("")), std::overflow_error);
    EXPECT_THROW(sum.add(0, HUGE_VAL), std::overflow_error);
    try {
        sum.add(0, 1e300);
    } catch (const std::overflow_error& e) {
        EXPECT_NE(std::string(e.what()).find("1e+300"), std::string::npos) << e.what();
    }
    // A sum beyond the 128-bit range: 2^23 terms of the largest size, reached by merging.
    ExactVector big(1, 8);  // largest term 2^96
    big.add(0, 0.9 * big.max_term());
    ExactVector doubled = big;
    EXPECT_THROW(
        {
            for (int k = 0; k < 40; ++k) doubled.merge(doubled);
        },
        std::overflow_error);
    EXPECT_THROW(ExactVector(1, 7), std::invalid_argument);
    EXPECT_THROW(ExactVector(1, 101), std::invalid_argument);
}

TEST(ExactSum, BoxesTakeTheirValuesAndZeroTheScratch) {
    // A 4 × 5 grid of complex values; a box wrapping around the edges.
    std::vector<double> scratch(2 * 20, 0.0);
    ExactVector sum(2 * 20);
    const std::vector<int> rows{3, 0}, cols{4, 0, 1};
    for (int r : rows)
        for (int c : cols) {
            scratch[2 * (r * 5 + c)] = r + 0.25 * c;
            scratch[2 * (r * 5 + c) + 1] = -1.0;
        }
    sum.take_box(scratch.data(), rows, cols, 5, 2);
    EXPECT_TRUE(std::all_of(scratch.begin(), scratch.end(), [](double x) { return x == 0.0; }));
    EXPECT_EQ(sum.value(2 * (3 * 5 + 4)), 4.0);
    EXPECT_EQ(sum.value(2 * (0 * 5 + 1) + 1), -1.0);
    EXPECT_EQ(sum.value(2 * (1 * 5 + 1)), 0.0);
    scratch[7] = 2.0;
    sum.take_range(scratch.data(), 6, 2);
    EXPECT_EQ(scratch[7], 0.0);
    EXPECT_EQ(sum.value(7), 2.0);
}

// take_box converts runs of consecutive columns in blocks: the same integer sums as adding each
// value alone, for small terms, terms beyond the blocks' fast range (2^62 after scaling), zeros,
// a run split by a wrap and several blocks per run; a NaN or infinity inside a run is refused.
TEST(ExactSum, BoxRunsGiveTheSameWordsAsOneValueAtATime) {
    const std::size_t grid_cols = 300;
    std::vector<int> cols;
    for (int c = 150; c < 300; ++c) cols.push_back(c);  // a run of 150 (three blocks at width 1)
    for (int c = 0; c < 70; ++c) cols.push_back(c);     // wrapped: a second run
    const std::vector<int> rows{2, 0};
    for (int width : {1, 2}) {
        SCOPED_TRACE(width);
        const std::size_t n = std::size_t(width) * 3 * grid_cols;
        std::vector<double> scratch(n, 0.0);
        ExactVector boxed(n), single(n);
        std::uint64_t state = 12345;
        for (int round = 0; round < 3; ++round) {
            for (int r : rows)
                for (int c : cols)
                    for (int e = 0; e < width; ++e) {
                        state = state * 6364136223846793005ull + 1442695040888963407ull;
                        const double u = double(state >> 11) * 0x1p-53 - 0.5;
                        const std::size_t k = (std::size_t(r) * grid_cols + std::size_t(c)) * std::size_t(width) +
                                              std::size_t(e);
                        // Mostly small, some zeros, and a few above 2^62 · 2^-72 (the per-value path).
                        scratch[k] = c % 17 == 0 ? 0.0 : (c % 41 == 3 ? 50.0 * u : 1e-6 * u);
                        single.add(k, scratch[k]);
                    }
            boxed.take_box(scratch.data(), rows, cols, grid_cols, width);
            EXPECT_TRUE(std::all_of(scratch.begin(), scratch.end(), [](double x) { return x == 0.0; }));
        }
        for (std::size_t k = 0; k < n; ++k) ASSERT_TRUE(boxed.word(k) == single.word(k)) << k;
        for (double bad : {std::nan(""), HUGE_VAL}) {
            scratch[std::size_t(width) * 200] = bad;  // row 0, column 200: inside the first run
            EXPECT_THROW(boxed.take_box(scratch.data(), {0}, cols, grid_cols, width), std::overflow_error);
            std::fill(scratch.begin(), scratch.end(), 0.0);
        }
    }
}

TEST(ExactSum, ParallelSumIsIndependentOfTheThreadCountAndChecksTheBox) {
    // Observation i adds a few terms (in double, its own order) at cells near i on a periodic
    // 1 × 64 grid, and a value.
    const std::vector<double> v = mixed_values(4000, 7);
    const std::size_t n = 64;
    const auto body = [&](std::size_t i, ExactScratch& s) {
        std::vector<int> cols;
        for (int d = -2; d <= 2; ++d) {
            const int c = int((i + n + std::size_t(d)) % n);
            cols.push_back(c);
            s.data()[c] += v[i] * (d + 3);
            s.data()[c] += v[(i + 1) % v.size()];
        }
        s.take_box({0}, cols, n);
        return v[i];
    };
    std::vector<double> one, two;
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    ExactParallelSum sum1(n);
    const double value1 = sum1.run(v.size(), serial_communicator(), one, body);
    omp_set_num_threads(std::max(2, threads));
    ExactParallelSum sum2(n);
    const double value2 = sum2.run(v.size(), serial_communicator(), two, body);
    omp_set_num_threads(threads);
    EXPECT_EQ(value1, value2);
    EXPECT_EQ(one, two);
    // Split into "ranks" (contiguous blocks), merged: the same bits.
    ExactVector merged(n + 1);
    for (std::size_t block = 0; block < 3; ++block) {
        ExactParallelSum part(n);
        const std::size_t first = v.size() * block / 3, last = v.size() * (block + 1) / 3;
        part.run_local(last - first, [&](std::size_t i, ExactScratch& s) { return body(first + i, s); });
        merged.merge(part.total());
    }
    EXPECT_EQ(merged.value(n), value1);
    for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(merged.value(k), one[k]);
    // In groups on one sum (run_local, accumulate, then finish; the groups in another order):
    // the same bits; without accumulate a group starts again from zero.
    {
        ExactParallelSum grouped(n);
        std::vector<double> out(n);
        const std::size_t half = v.size() / 2;
        grouped.run_local(v.size() - half, [&](std::size_t i, ExactScratch& s) { return body(half + i, s); });
        grouped.run_local(half, body, true);
        EXPECT_EQ(grouped.finish(serial_communicator(), out.data()), value1);
        EXPECT_EQ(out, one);
        grouped.run_local(v.size() - half, [&](std::size_t i, ExactScratch& s) { return body(half + i, s); });
        grouped.run_local(half, body);  // not accumulated: the first group is dropped
        EXPECT_NE(grouped.finish(serial_communicator(), out.data()), value1);
    }
    // A box too small leaves values in the scratch: the check names it; the sum stays usable.
    exact_scratch_check() = true;
    EXPECT_THROW(sum1.run(v.size(), serial_communicator(), one,
                          [&](std::size_t i, ExactScratch& s) {
                              s.data()[i % n] = 1.0;
                              s.data()[(i + 1) % n] = 1.0;
                              s.take_box({0}, {int(i % n)}, n);
                              return 0.0;
                          }),
                 std::logic_error);
    EXPECT_NO_THROW(sum1.run(v.size(), serial_communicator(), one, body));
    exact_scratch_check() = false;
    EXPECT_EQ(one, two);
}

TEST(ExactSum, TotalOfAnyMagnitudeIsOrderIndependent) {
    std::vector<double> v = mixed_values(1000, 9);
    for (double& x : v) x *= 1e250;  // far beyond one accumulator's range: scaled first
    const double total = exact_total(v, serial_communicator());
    std::reverse(v.begin(), v.end());
    EXPECT_EQ(exact_total(v, serial_communicator()), total);
    long double reference = 0.0L;
    for (const double x : v) reference += static_cast<long double>(x);
    EXPECT_NEAR(total, double(reference), 1e-12 * std::abs(double(reference)));
    EXPECT_EQ(exact_total({}, serial_communicator()), 0.0);
    EXPECT_THROW(exact_total({1.0, std::nan("")}, serial_communicator()), std::overflow_error);
}

}  // namespace
}  // namespace wavebrdf::detail
