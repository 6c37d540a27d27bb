#include "wavebrdf/spectrum.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

using wavebrdf::cie1931_xyz;
using wavebrdf::spectral_to_srgb_weights;
using wavebrdf::spectral_wavelengths_um;
using wavebrdf::xyz_to_linear_srgb;

namespace {

// RGB of the spectrum values f_k under a 3 × N row-major weight matrix.
std::array<double, 3> apply_weights(const std::vector<double>& weights, const std::vector<double>& f) {
    const std::size_t n = f.size();
    std::array<double, 3> rgb{0.0, 0.0, 0.0};
    for (std::size_t c = 0; c < 3; ++c)
        for (std::size_t k = 0; k < n; ++k) rgb[c] += weights[c * n + k] * f[k];
    return rgb;
}

Eigen::Matrix3d srgb_matrix() {
    const std::array<double, 9> m = xyz_to_linear_srgb();
    Eigen::Matrix3d out;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out(r, c) = m[static_cast<std::size_t>(3 * r + c)];
    return out;
}

std::size_t nearest(const std::vector<double>& lambdas, double target) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < lambdas.size(); ++k)
        if (std::abs(lambdas[k] - target) < std::abs(lambdas[best] - target)) best = k;
    return best;
}

}  // namespace

TEST(SpectrumTest, TableSpotValues) {
    EXPECT_NEAR(cie1931_xyz(0.555)[1], 1.0, 1e-9);
    EXPECT_NEAR(cie1931_xyz(0.600)[0], 1.0622, 1e-9);
    EXPECT_NEAR(cie1931_xyz(0.450)[2], 1.7721, 1e-4);
    EXPECT_NEAR(cie1931_xyz(0.500)[1], 0.3230, 1e-9);
    EXPECT_NEAR(cie1931_xyz(0.360)[0], 0.0001299, 1e-12);
    EXPECT_NEAR(cie1931_xyz(0.830)[1], 4.5181e-07, 1e-12);
    // ȳ peaks at 555 nm.
    for (double nm = 360.0; nm <= 830.0; nm += 1.0) EXPECT_LE(cie1931_xyz(nm / 1000.0)[1], 1.0 + 1e-12) << nm;
}

TEST(SpectrumTest, TableIsEqualEnergyBalanced) {
    // CIE 1931 is normalised so that the equal-energy illuminant E has X = Y = Z; the sums of
    // the 5 nm table over 380-780 nm are (21.371524, 21.371327, 21.371540) (CIE 015:2004).
    std::array<double, 3> sum{0.0, 0.0, 0.0};
    for (int nm = 380; nm <= 780; nm += 5)
        for (std::size_t c = 0; c < 3; ++c) sum[c] += cie1931_xyz(nm / 1000.0)[c];
    EXPECT_NEAR(sum[0], 21.371524, 2e-6);
    EXPECT_NEAR(sum[1], 21.371327, 2e-6);
    EXPECT_NEAR(sum[2], 21.371540, 2e-6);
}

TEST(SpectrumTest, InterpolatesLinearlyAndIsZeroOutside) {
    const auto a = cie1931_xyz(0.550);
    const auto b = cie1931_xyz(0.555);
    const auto mid = cie1931_xyz(0.5525);
    for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(mid[c], 0.5 * (a[c] + b[c]), 1e-12) << c;
    const auto quarter = cie1931_xyz(0.60125);
    const auto p600 = cie1931_xyz(0.600);
    const auto p605 = cie1931_xyz(0.605);
    EXPECT_NEAR(quarter[0], 0.75 * p600[0] + 0.25 * p605[0], 1e-12);
    for (double lambda : {0.0, 0.3599, 0.8301, 2.0, -0.5, std::nan("")})
        for (double v : cie1931_xyz(lambda)) EXPECT_EQ(v, 0.0) << lambda;
}

TEST(SpectrumTest, WavelengthGrid) {
    const std::vector<double> l8 = spectral_wavelengths_um(8);
    ASSERT_EQ(l8.size(), 8u);
    for (int k = 0; k < 8; ++k) EXPECT_NEAR(l8[k], 0.36 + (k + 0.5) * 0.47 / 8, 1e-15);
    const std::vector<double> l1 = spectral_wavelengths_um(1);
    ASSERT_EQ(l1.size(), 1u);
    EXPECT_NEAR(l1[0], 0.595, 1e-15);
    EXPECT_THROW(spectral_wavelengths_um(0), std::invalid_argument);
    EXPECT_THROW(spectral_wavelengths_um(-3), std::invalid_argument);
    try {
        spectral_wavelengths_um(-3);
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("-3"), std::string::npos) << e.what();
    }
}

TEST(SpectrumTest, XyzToSrgbMatrix) {
    const Eigen::Matrix3d m = srgb_matrix();
    const Eigen::Vector3d d65(0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290);
    const Eigen::Vector3d rgb = m * d65;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(rgb(c), 1.0, 1e-12) << c;
    EXPECT_NEAR(m(0, 0), 3.2406, 1e-3);
    EXPECT_NEAR(m(0, 1), -1.5372, 1e-3);
    EXPECT_NEAR(m(0, 2), -0.4986, 1e-3);
    EXPECT_NEAR(m(1, 0), -0.9689, 1e-3);
    EXPECT_NEAR(m(1, 1), 1.8758, 1e-3);
    EXPECT_NEAR(m(2, 2), 1.0570, 1e-3);
    // The luminance row of the inverse is Rec. 709's (0.2126, 0.7152, 0.0722).
    const Eigen::Matrix3d inv = m.inverse();
    EXPECT_NEAR(inv(1, 0), 0.2126, 1e-4);
    EXPECT_NEAR(inv(1, 1), 0.7152, 1e-4);
    EXPECT_NEAR(inv(1, 2), 0.0722, 1e-4);
}

TEST(SpectrumTest, ConstantSpectrumIsWhite) {
    for (int n : {1, 2, 3, 8, 16, 32, 100}) {
        const std::vector<double> lambdas = spectral_wavelengths_um(n);
        const std::vector<double> w = spectral_to_srgb_weights(lambdas);
        ASSERT_EQ(w.size(), 3u * static_cast<std::size_t>(n));
        const auto rgb = apply_weights(w, std::vector<double>(static_cast<std::size_t>(n), 1.0));
        for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(rgb[c], 1.0, 1e-12) << "N=" << n;
        const auto half = apply_weights(w, std::vector<double>(static_cast<std::size_t>(n), 0.5));
        for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(half[c], 0.5, 1e-12) << "N=" << n;
    }
}

TEST(SpectrumTest, NarrowBandHues) {
    const std::vector<double> lambdas = spectral_wavelengths_um(32);
    const std::vector<double> w = spectral_to_srgb_weights(lambdas);
    auto rgb_at = [&](double target) {
        std::vector<double> f(lambdas.size(), 0.0);
        f[nearest(lambdas, target)] = 1.0;
        return apply_weights(w, f);
    };
    const auto blue = rgb_at(0.45);
    EXPECT_GT(blue[2], blue[0]);
    EXPECT_GT(blue[2], blue[1]);
    const auto green = rgb_at(0.53);
    EXPECT_GT(green[1], green[0]);
    EXPECT_GT(green[1], green[2]);
    const auto red = rgb_at(0.65);
    EXPECT_GT(red[0], red[1]);
    EXPECT_GT(red[0], red[2]);
}

TEST(SpectrumTest, WeightsConvergeWithSampleCount) {
    const Eigen::Matrix3d to_xyz = srgb_matrix().inverse();
    const std::vector<double> l200 = spectral_wavelengths_um(200);
    const std::vector<double> w200 = spectral_to_srgb_weights(l200);
    const auto flat = apply_weights(w200, std::vector<double>(l200.size(), 1.0));
    const double y_flat = to_xyz.row(1).dot(Eigen::Vector3d(flat[0], flat[1], flat[2]));
    EXPECT_NEAR(y_flat, 1.0, 1e-12);

    // A smooth spectrum, f(λ) = λ, seen with 8 and with 200 samples.
    const std::vector<double> l8 = spectral_wavelengths_um(8);
    const auto rgb8 = apply_weights(spectral_to_srgb_weights(l8), l8);
    const auto rgb200 = apply_weights(w200, l200);
    for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_GT(rgb200[c], 0.3) << c;
        EXPECT_NEAR(rgb8[c], rgb200[c], 0.05 * rgb200[c]) << c;
    }
    // Longer wavelengths weigh more, so f(λ) = λ is reddish.
    EXPECT_GT(rgb200[0], rgb200[2]);
}

TEST(SpectrumTest, OrderAndSpacingOfArbitraryLists) {
    // A permuted list gives the permuted weights.
    const std::vector<double> sorted = {0.40, 0.45, 0.52, 0.60, 0.70};
    const std::vector<double> permuted = {0.60, 0.40, 0.70, 0.52, 0.45};
    const std::vector<std::size_t> where = {3, 0, 4, 2, 1};
    const auto ws = spectral_to_srgb_weights(sorted);
    const auto wp = spectral_to_srgb_weights(permuted);
    for (std::size_t c = 0; c < 3; ++c)
        for (std::size_t k = 0; k < 5; ++k) EXPECT_NEAR(wp[c * 5 + k], ws[c * 5 + where[k]], 1e-14);
    // Unequal spacing still maps a constant to white.
    const auto rgb = apply_weights(ws, std::vector<double>(5, 2.0));
    for (double v : rgb) EXPECT_NEAR(v, 2.0, 1e-12);
    // A repeated wavelength shares its Δλ: splitting one sample in two changes nothing.
    const std::vector<double> split = {0.40, 0.45, 0.52, 0.52, 0.60, 0.70};
    const auto wsplit = spectral_to_srgb_weights(split);
    for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_NEAR(wsplit[c * 6 + 2] + wsplit[c * 6 + 3], ws[c * 5 + 2], 1e-14);
        EXPECT_NEAR(wsplit[c * 6 + 4], ws[c * 5 + 3], 1e-14);
    }
    // Samples outside 360–830 nm get no weight.
    const auto wout = spectral_to_srgb_weights({0.30, 0.50, 0.60, 0.90});
    for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_EQ(wout[c * 4 + 0], 0.0);
        EXPECT_EQ(wout[c * 4 + 3], 0.0);
    }
}

TEST(SpectrumTest, BadInputsThrow) {
    EXPECT_THROW(spectral_to_srgb_weights({}), std::invalid_argument);
    EXPECT_THROW(spectral_to_srgb_weights({0.5, 0.0}), std::domain_error);
    EXPECT_THROW(spectral_to_srgb_weights({-0.5}), std::domain_error);
    EXPECT_THROW(spectral_to_srgb_weights({0.5, std::nan("")}), std::domain_error);
    EXPECT_THROW(spectral_to_srgb_weights({std::numeric_limits<double>::infinity()}), std::domain_error);
    // No sample where the eye sees anything: the sampled white is black.
    EXPECT_THROW(spectral_to_srgb_weights({0.2, 0.3, 1.0}), std::domain_error);
    try {
        spectral_to_srgb_weights({0.5, -0.25});
        FAIL() << "expected std::domain_error";
    } catch (const std::domain_error& e) {
        EXPECT_NE(std::string(e.what()).find("-0.25"), std::string::npos) << e.what();
    }
}
