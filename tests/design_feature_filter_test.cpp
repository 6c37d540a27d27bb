// The grayscale relief's filtered parameterisation (src/design/feature_filter.h): no content
// above 1/F in the relief's spectrum (a direct DFT here, not FFTW), heights within [0, H], a
// non-negative kernel, and the adjoint equal to central finite differences.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include "design/feature_filter.h"
#include "wavebrdf/constants.h"

namespace wavebrdf::detail {
namespace {

std::vector<double> random_latent(std::size_t n, double scale, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, scale);
    std::vector<double> z(n);
    for (double& v : z) v = g(rng);
    return z;
}

TEST(DesignFeatureFilter, TheReliefHasNoSpatialFrequencyAboveOneOverTheMinimumFeature) {
    const int N = 32;
    const double w = 0.5, F = 2.0, H = 2.0, L = N * w;  // 1/F = 0.5 um^-1; Nyquist 1/(2w) = 1 um^-1
    const FeatureFilter filter(N, w, F);
    std::vector<double> h;
    filtered_heights(filter, H, random_latent(static_cast<std::size_t>(N * N), 3.0, 1), h);
    double above = 0.0, near = 0.0, dc = 0.0;
    for (int m = -N / 2; m < N / 2; ++m)
        for (int n = -N / 2; n < N / 2; ++n) {
            std::complex<double> s(0.0, 0.0);
            for (int i = 0; i < N; ++i)
                for (int j = 0; j < N; ++j)
                    s += h[static_cast<std::size_t>(i * N + j)] * std::polar(1.0, -2.0 * k_pi * (m * i + n * j) / N);
            const double nu = std::hypot(m, n) / L;
            if (m == 0 && n == 0) dc = std::abs(s);
            if (nu > 1.0 / F + 1e-9) above = std::max(above, std::abs(s));
            else if (nu > 0.75 / F) near = std::max(near, std::abs(s));
        }
    EXPECT_LT(above, 1e-11 * dc);
    EXPECT_GT(near, 1e-4 * dc);  // the band up to 1/F is passed, not only the lowest frequencies
}

TEST(DesignFeatureFilter, HeightsStayInRangeAndTheKernelIsNonNegative) {
    const int N = 24;
    const FeatureFilter filter(N, 0.5, 1.7);
    std::vector<double> h;
    filtered_heights(filter, 1.5, random_latent(static_cast<std::size_t>(N * N), 40.0, 2), h);
    for (double v : h) {
        EXPECT_GE(v, -1e-12);
        EXPECT_LE(v, 1.5 + 1e-12);
    }
    std::vector<double> delta(static_cast<std::size_t>(N * N), 0.0), kernel;
    delta[0] = 1.0;
    filter.apply(delta, kernel);
    double sum = 0.0;
    for (double k : kernel) {
        EXPECT_GE(k, -1e-15);
        sum += k;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_THROW(FeatureFilter(N, 0.5, 0.9), std::domain_error);  // below two texels
}

TEST(DesignFeatureFilter, AdjointEqualsCentralFiniteDifferences) {
    const int N = 16;
    const double H = 2.0;
    const FeatureFilter filter(N, 0.5, 2.5);
    const std::size_t n2 = static_cast<std::size_t>(N * N);
    const std::vector<double> c = random_latent(n2, 1.0, 3);
    std::vector<double> z = random_latent(n2, 1.0, 4);
    auto loss = [&](const std::vector<double>& zz) {
        std::vector<double> h;
        filtered_heights(filter, H, zz, h);
        double l = 0.0;
        for (std::size_t t = 0; t < n2; ++t) l += c[t] * h[t] * h[t];
        return l;
    };
    std::vector<double> h, dh(n2), dz;
    filtered_heights(filter, H, z, h);
    for (std::size_t t = 0; t < n2; ++t) dh[t] = 2.0 * c[t] * h[t];
    filtered_heights_adjoint(filter, H, z, dh, dz);
    for (std::size_t t : {std::size_t{0}, std::size_t{17}, std::size_t{100}, n2 - 1}) {
        const double e = 1e-5, keep = z[t];
        z[t] = keep + e;
        const double up = loss(z);
        z[t] = keep - e;
        const double down = loss(z);
        z[t] = keep;
        EXPECT_NEAR(dz[t], (up - down) / (2.0 * e), 1e-7 * (1.0 + std::abs(dz[t]))) << t;
    }
}

}  // namespace
}  // namespace wavebrdf::detail
