// Tests of the simulated noise: Poisson counts have the Poisson distribution (mean, variance
// and frequencies against the probability mass function, for small and large means, i.e. both
// samplers), Gaussian noise has the requested σ, seeds reproduce, and the parser names bad text.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"

using namespace wavebrdf;

namespace {

// Photon counts of a flat slice of `values` values with `mean` photons expected per value.
std::vector<double> flat_counts(std::size_t values, double mean, std::uint64_t seed) {
    const std::vector<double> slice(values, 2.5);  // any constant: counts do not depend on units
    const double photons = mean * double(values);
    std::vector<double> noisy = add_noise(slice, Noise{NoiseKind::Poisson, photons}, seed);
    for (double& v : noisy) v *= photons / (2.5 * double(values));
    return noisy;
}

}  // namespace

TEST(NoiseTest, PoissonCountsHaveMeanAndVarianceOfTheMean) {
    const std::size_t m = 40000;
    for (double mean : {0.05, 3.0, 9.9, 10.0, 25.0, 400.0}) {
        const auto counts = flat_counts(m, mean, 7);
        double sum = 0.0, sum_sq = 0.0;
        for (double k : counts) {
            ASSERT_NEAR(k, std::round(k), 1e-9 * (1.0 + k)) << "counts are whole numbers";
            ASSERT_GE(k, 0.0);
            sum += k;
        }
        const double sample_mean = sum / double(m);
        for (double k : counts) sum_sq += (k - sample_mean) * (k - sample_mean);
        const double sample_var = sum_sq / double(m - 1);
        // Standard errors: of the mean √(μ/m); of the variance ≈ √((2μ² + μ)/m).
        EXPECT_NEAR(sample_mean, mean, 5.0 * std::sqrt(mean / double(m))) << "mean " << mean;
        EXPECT_NEAR(sample_var, mean, 5.0 * std::sqrt((2.0 * mean * mean + mean) / double(m))) << "mean " << mean;
    }
}

TEST(NoiseTest, PoissonFrequenciesFollowTheProbabilityMassFunction) {
    const std::size_t m = 100000;
    for (double mean : {3.0, 25.0}) {  // Knuth's sampler and the transformed rejection
        const auto counts = flat_counts(m, mean, 11);
        const int lo = int(std::floor(mean - 3.0 * std::sqrt(mean))), hi = int(std::ceil(mean + 3.0 * std::sqrt(mean)));
        for (int k = std::max(lo, 0); k <= hi; ++k) {
            double seen = 0.0;
            for (double c : counts) seen += std::round(c) == double(k) ? 1.0 : 0.0;
            const double p = std::exp(k * std::log(mean) - mean - std::lgamma(k + 1.0));
            const double expected = p * double(m);
            EXPECT_NEAR(seen, expected, 5.0 * std::sqrt(expected) + 1.0) << "mean " << mean << ", k = " << k;
        }
    }
}

TEST(NoiseTest, PoissonTotalIsThePhotonCountAndUnitsAreKept) {
    std::vector<double> slice(1000);
    for (std::size_t i = 0; i < slice.size(); ++i) slice[i] = 1e-3 * double(i % 17);  // some zeros
    double total = 0.0;
    for (double v : slice) total += v;
    const auto noisy = add_noise(slice, Noise{NoiseKind::Poisson, 1e6}, 3);
    double noisy_total = 0.0;
    for (std::size_t i = 0; i < slice.size(); ++i) {
        noisy_total += noisy[i];
        if (slice[i] == 0.0) {
            EXPECT_EQ(noisy[i], 0.0);  // no light, no photons
        }
    }
    // Σ counts ~ Poisson(N): relative spread 1e-3.
    EXPECT_NEAR(noisy_total / total, 1.0, 5e-3);
}

TEST(NoiseTest, GaussianNoiseHasTheRequestedSigmaAndIsClampedAtZero) {
    const std::vector<double> slice(50000, 10.0);
    const auto noisy = add_noise(slice, Noise{NoiseKind::Gaussian, 0.02}, 5);  // σ = 0.2
    double sum = 0.0, sum_sq = 0.0;
    for (double v : noisy) sum += v - 10.0;
    const double mean = sum / double(noisy.size());
    for (double v : noisy) sum_sq += (v - 10.0 - mean) * (v - 10.0 - mean);
    EXPECT_NEAR(mean, 0.0, 5.0 * 0.2 / std::sqrt(50000.0));
    EXPECT_NEAR(std::sqrt(sum_sq / double(noisy.size() - 1)), 0.2, 0.01 * 0.2 * 5.0);
    const auto clamped = add_noise(std::vector<double>{0.0, 0.0, 0.0, 0.0, 1.0}, Noise{NoiseKind::Gaussian, 1.0}, 9);
    for (double v : clamped) EXPECT_GE(v, 0.0);
}

TEST(NoiseTest, SameSeedSameNoiseOtherSeedOtherNoise) {
    const std::vector<double> slice(64, 1.0);
    for (const Noise& noise : {Noise{NoiseKind::Poisson, 500.0}, Noise{NoiseKind::Gaussian, 0.1}}) {
        EXPECT_EQ(add_noise(slice, noise, 1), add_noise(slice, noise, 1));
        EXPECT_NE(add_noise(slice, noise, 1), add_noise(slice, noise, 2));
    }
    EXPECT_EQ(add_noise(slice, Noise{}, 1), slice);
}

TEST(NoiseTest, ObservationsGetIndependentNoisePerIndex) {
    Observation o;
    o.lambdas_um = {0.5};
    o.resolution = 8;
    o.reference.assign(64, 1.0);
    std::vector<Observation> two = {o, o}, three = {o, o, o};
    add_noise(two, Noise{NoiseKind::Poisson, 200.0}, 4);
    add_noise(three, Noise{NoiseKind::Poisson, 200.0}, 4);
    EXPECT_NE(two[0].reference, two[1].reference);
    EXPECT_EQ(two[1].reference, three[1].reference);  // adding an observation changes no other
}

TEST(NoiseTest, ParsesAndRoundTrips) {
    EXPECT_EQ(parse_noise("none").kind, NoiseKind::None);
    EXPECT_EQ(parse_noise("poisson:1e4").kind, NoiseKind::Poisson);
    EXPECT_EQ(parse_noise("poisson:1e4").level, 1e4);
    EXPECT_EQ(parse_noise("gaussian:0.01").level, 0.01);
    for (const char* text : {"none", "poisson:10000", "gaussian:0.01", "gaussian:0"})
        EXPECT_EQ(to_string(parse_noise(text)), text);
    EXPECT_EQ(matched_loss(parse_noise("poisson:1e4"), Loss{}).kind, LossKind::Poisson);
    EXPECT_EQ(matched_loss(parse_noise("poisson:1e4"), Loss{}).photons, 1e4);
    EXPECT_EQ(matched_loss(parse_noise("gaussian:0.1"), Loss{}).kind, LossKind::MSE);
    EXPECT_EQ(matched_loss(parse_noise("none"), Loss{LossKind::Amplitude}).kind, LossKind::Amplitude);
}

TEST(NoiseTest, ParseErrorsNameTheText) {
    for (const char* text : {"poisson:0", "poisson:-1", "gaussian:-0.1", "poisson:inf", "gaussian:nan"}) {
        try {
            parse_noise(text);
            ADD_FAILURE() << text;
        } catch (const std::domain_error& e) {
            EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
        }
    }
    for (const char* text : {"", "poisson", "poisson:", "poisson: 5", "Poisson:5", "gauss:1", "none:1", "poisson:5x"}) {
        try {
            parse_noise(text);
            ADD_FAILURE() << text;
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(std::string("'") + text + "'"), std::string::npos) << e.what();
        }
    }
}
