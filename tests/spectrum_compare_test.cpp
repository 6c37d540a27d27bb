// compare_spectra (surface_stats.h): an estimate's radial PSD against a truth's, the error's
// PSD and the band the estimate resolves, on surfaces whose spectra are known in closed form:
// a cosine puts all its power A² / 2 in the bin of its wavenumber.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/surface_stats.h"

using namespace wavebrdf;

namespace {

constexpr double pi = 3.14159265358979323846;

// Heights in µm h(x, y) at x = i · w (the Heightfield's rows), y = j · w; vscale 1.
template <typename F>
Heightfield sampled(int n, double w, F h) {
    std::vector<double> v(static_cast<std::size_t>(n) * n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) v[static_cast<std::size_t>(i) * n + j] = h(i * w, j * w) / w;
    return Heightfield(n, n, v, w, 1.0);
}

// The bin whose centre is nearest q.
std::size_t bin_of(const SpectrumComparison& c, double q) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < c.q_per_um.size(); ++k)
        if (std::abs(c.q_per_um[k] - q) < std::abs(c.q_per_um[best] - q)) best = k;
    return best;
}

}  // namespace

TEST(SpectrumCompare, AnEstimateEqualToTheTruthResolvesEveryBand) {
    std::mt19937 rng(5);
    std::normal_distribution<double> g(0.0, 0.1);
    std::vector<double> v(32 * 32);
    for (double& x : v) x = g(rng);
    const Heightfield truth(32, 32, v, 0.5, 1.0);
    const SpectrumComparison c = compare_spectra(truth, truth);
    ASSERT_EQ(c.q_per_um.size(), c.truth_um4.size());
    EXPECT_TRUE(c.resolved_all);
    EXPECT_EQ(c.error_power_ratio, 0.0);
    for (std::size_t k = 0; k < c.q_per_um.size(); ++k) {
        EXPECT_EQ(c.error_um4[k], 0.0);
        EXPECT_EQ(c.estimate_um4[k], c.truth_um4[k]);
    }
    // Bins of Δq = 2π / (32 · 0.5) up to the Nyquist frequency π / 0.5: the last bin's centre.
    EXPECT_NEAR(c.resolved_q_per_um, c.q_per_um.back(), 0.0);
    EXPECT_NEAR(c.q_per_um.back(), pi / 0.5, 2 * pi / 16);
}

// Truth: a long cosine along x and a short one along y; the estimate misses the short one and
// adds an error of its own at a wavenumber between them, where the truth has no power: the band
// is resolved up to the bin before it.
TEST(SpectrumCompare, TheResolvedBandEndsWhereTheErrorReachesTheTruth) {
    const int n = 64;
    const double w = 1.0, a = 0.2, b = 0.05, e = 0.01;
    const double k1 = 2 * pi * 2 / (n * w), k2 = 2 * pi * 12 / (n * w), k3 = 2 * pi * 6 / (n * w);
    const Heightfield truth = sampled(n, w,
                                      [&](double x, double y) { return a * std::cos(k1 * x) + b * std::cos(k2 * y); });
    const Heightfield estimate = sampled(n, w,
                                         [&](double x, double) { return a * std::cos(k1 * x) + e * std::cos(k3 * x); });
    const SpectrumComparison c = compare_spectra(truth, estimate);
    const std::size_t i1 = bin_of(c, k1), i2 = bin_of(c, k2), i3 = bin_of(c, k3);
    // Parseval per bin: a cosine's power A²/2 spread over its bin's count points, PSD =
    // (A²/2) (2π)² / (Δq² · count) on the bin's mean: the two ±k points of the cosine.
    const double dq = 2 * pi / (n * w), cell = dq * dq / (4 * pi * pi);
    EXPECT_NEAR(c.truth_um4[i1] * c.count[i1] * cell, a * a / 2, 1e-12);
    EXPECT_NEAR(c.truth_um4[i2] * c.count[i2] * cell, b * b / 2, 1e-12);
    EXPECT_NEAR(c.estimate_um4[i3] * c.count[i3] * cell, e * e / 2, 1e-12);
    EXPECT_NEAR(c.error_um4[i2] * c.count[i2] * cell, b * b / 2, 1e-12);  // the missed cosine
    EXPECT_NEAR(c.error_um4[i3] * c.count[i3] * cell, e * e / 2, 1e-12);  // the estimate's own
    // Below k3's bin the error's power is 0 (at most the truth's); at k3 it exceeds the truth's 0.
    EXPECT_FALSE(c.resolved_all);
    ASSERT_GT(i3, 0u);
    EXPECT_EQ(c.resolved_q_per_um, c.q_per_um[i3 - 1]);
    EXPECT_GT(c.resolved_q_per_um, k1);
    // The error's share of the power: (b² + e²) / (a² + b²).
    EXPECT_NEAR(c.error_power_ratio, (b * b + e * e) / (a * a + b * b), 1e-12);
    EXPECT_NEAR(c.resolved_wavelength_um,
                c.resolved_q_per_um > 0 ? 2 * pi / c.resolved_q_per_um : std::numeric_limits<double>::infinity(),
                1e-12);
}

TEST(SpectrumCompare, TheGridsMustAgree) {
    const Heightfield a(8, 8, std::vector<double>(64, 0.0), 1.0, 1.0), b(8, 4, std::vector<double>(32, 0.0), 1.0, 1.0);
    EXPECT_THROW(compare_spectra(a, b), std::invalid_argument);
    const Heightfield c(8, 8, std::vector<double>(64, 0.0), 2.0, 1.0);
    EXPECT_THROW(compare_spectra(a, c), std::invalid_argument);
}
