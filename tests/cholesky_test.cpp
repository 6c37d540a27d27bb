// The one dense Cholesky factorisation (core/cholesky.h) that the error bars, the photon plan,
// the cone bound and the position field use: L Lᵀ reproduces the matrix, the solve inverts it,
// the first non-positive pivot is named, and the threads do not change the bits.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <vector>

#include "core/cholesky.h"

namespace wavebrdf {
namespace {

// B Bᵀ + n·I for a random B: symmetric positive definite, row-major.
std::vector<double> random_spd(std::size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    std::vector<double> b(n * n), a(n * n, 0.0);
    for (double& x : b) x = normal(rng);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < n; ++j) {
            for (std::size_t k = 0; k < n; ++k) a[i * n + j] += b[i * n + k] * b[j * n + k];
            if (i == j) a[i * n + j] += double(n);
        }
    return a;
}

TEST(Cholesky, TheFactorReproducesTheMatrixAndTheSolveInvertsIt) {
    const std::size_t n = 37;
    const std::vector<double> a = random_spd(n, 11);
    std::vector<double> l = a;
    ASSERT_EQ(detail::cholesky_in_place(l, n, false), n);
    double worst = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j <= i; ++j) {
            double s = 0.0;
            for (std::size_t k = 0; k <= j; ++k) s += l[i * n + k] * l[j * n + k];
            worst = std::max(worst, std::abs(s - a[i * n + j]));
            scale = std::max(scale, std::abs(a[i * n + j]));
        }
    EXPECT_LT(worst, 1e-13 * scale);
    std::vector<double> x(n);
    for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(double(i));
    std::vector<double> b(n, 0.0);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < n; ++j) b[i] += a[i * n + j] * x[j];
    detail::cholesky_solve(l, n, b);
    for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR(b[i], x[i], 1e-12);
}

TEST(Cholesky, NamesTheFirstPivotThatIsNotPositive) {
    // Row 3 repeats row 1 and column 3 column 1: the 4th pivot is 0 (up to rounding), and a
    // negative diagonal at index 0 stops at once.
    const std::size_t n = 6;
    std::vector<double> a = random_spd(n, 3);
    for (std::size_t j = 0; j < n; ++j) a[3 * n + j] = a[1 * n + j];
    for (std::size_t i = 0; i < n; ++i) a[i * n + 3] = a[i * n + 1];
    a[3 * n + 3] = a[1 * n + 1] * (1.0 - 1e-15);
    EXPECT_EQ(detail::cholesky_in_place(a, n, false), 3u);
    std::vector<double> negative = random_spd(n, 4);
    negative[0] = -1.0;
    EXPECT_EQ(detail::cholesky_in_place(negative, n, false), 0u);
    std::vector<double> infinite = random_spd(n, 5);
    infinite[2 * n + 2] = std::numeric_limits<double>::infinity();
    EXPECT_EQ(detail::cholesky_in_place(infinite, n, false), 2u);
}

TEST(Cholesky, ThreadsGiveTheSameBits) {
    const std::size_t n = 300;  // above the 64 rows below a pivot where rows are split
    std::vector<double> serial = random_spd(n, 7), parallel = serial;
    ASSERT_EQ(detail::cholesky_in_place(serial, n, false), n);
    ASSERT_EQ(detail::cholesky_in_place(parallel, n, true), n);
    EXPECT_EQ(serial, parallel);
}

}  // namespace
}  // namespace wavebrdf
