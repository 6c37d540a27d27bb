// Tests of the losses and metrics: values on hand-computed inputs, gradients against central
// finite differences (double), zeros at equality, invariances, and parse/validation errors.
#include <gtest/gtest.h>

#include "test_util.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/loss.h"

using namespace wavebrdf;
using wavebrdf::test::expect_throw_naming;
using wavebrdf::test::uniform_vector;

namespace {

// ∂loss/∂estimate[i] by central differences with one Richardson extrapolation,
// (4 D(h/2) − D(h)) / 3, whose O(h⁴) error lets a relative tolerance of 1e-7 test the
// analytic gradient to far below the loss's own curvature.
double finite_difference(const Loss& loss, std::vector<double> estimate, const std::vector<double>& reference,
                         int channels, std::size_t i, double h) {
    const double x0 = estimate[i];
    const auto central = [&](double step) {
        estimate[i] = x0 + step;
        const double plus = loss_value(loss, estimate, reference, channels);
        estimate[i] = x0 - step;
        const double minus = loss_value(loss, estimate, reference, channels);
        return (plus - minus) / (2.0 * step);
    };
    const double d_h = central(h), d_half = central(0.5 * h);
    return (4.0 * d_half - d_h) / 3.0;
}

const Loss kLosses[] = {{LossKind::CMSLE, 1.0},
                        {LossKind::CMSLE, 0.01},
                        {LossKind::MSE, 1.0},
                        {LossKind::Amplitude, 1.0},
                        {LossKind::Poisson, 1.0, 1e4}};

}  // namespace

TEST(LossTest, ParsesEveryForm) {
    EXPECT_EQ(parse_loss("cmsle").kind, LossKind::CMSLE);
    EXPECT_EQ(parse_loss("cmsle").epsilon, 1.0);
    EXPECT_EQ(parse_loss("cmsle:0.01").kind, LossKind::CMSLE);
    EXPECT_EQ(parse_loss("cmsle:0.01").epsilon, 0.01);
    EXPECT_EQ(parse_loss("cmsle:1e-3").epsilon, 1e-3);
    EXPECT_EQ(parse_loss("mse").kind, LossKind::MSE);
    EXPECT_EQ(parse_loss("amplitude").kind, LossKind::Amplitude);
    EXPECT_EQ(parse_loss("poisson:1e4").kind, LossKind::Poisson);
    EXPECT_EQ(parse_loss("poisson:1e4").photons, 1e4);
}

TEST(LossTest, ToStringRoundTrips) {
    EXPECT_EQ(to_string(Loss{LossKind::CMSLE, 1.0}), "cmsle:1");
    EXPECT_EQ(to_string(Loss{LossKind::CMSLE, 0.01}), "cmsle:0.01");
    EXPECT_EQ(to_string(Loss{LossKind::MSE, 1.0}), "mse");
    EXPECT_EQ(to_string(Loss{LossKind::Amplitude, 1.0}), "amplitude");
    EXPECT_EQ(to_string(Loss{LossKind::Poisson, 1.0, 10000.0}), "poisson:10000");
    EXPECT_EQ(parse_loss(to_string(Loss{LossKind::Poisson, 1.0, 1.0 / 3.0})).photons, 1.0 / 3.0);
    for (double eps : {1.0, 0.001, 0.1 + 0.2, 1.0 / 3.0, 5e-300, 1e300}) {
        const Loss back = parse_loss(to_string(Loss{LossKind::CMSLE, eps}));
        EXPECT_EQ(back.kind, LossKind::CMSLE);
        EXPECT_EQ(back.epsilon, eps) << to_string(Loss{LossKind::CMSLE, eps});
    }
}

TEST(LossTest, ParseErrorsNameTheText) {
    for (const char* text :
         {"cmsle:0", "cmsle:-1", "cmsle:-0", "cmsle:inf", "cmsle:nan", "poisson:0", "poisson:-5", "poisson:inf"})
        expect_throw_naming<std::domain_error>([&] { parse_loss(text); }, text);
    for (const char* text : {"cmsle:abc", "foo", "", "cmsle:", "cmsle:1x", "cmsle: 1", "CMSLE", "mse:1", "cmsle0.1",
                             "poisson", "poisson:", "poisson:1e4x"})
        expect_throw_naming<std::invalid_argument>([&] { parse_loss(text); }, std::string("'") + text + "'");
}

TEST(LossTest, HandComputedValues) {
    const Loss mse{LossKind::MSE, 1.0};
    // (0² + 1² + 2²) / 3 pixels.
    EXPECT_DOUBLE_EQ(loss_value(mse, {1, 2, 3}, {1, 1, 1}, 1), 5.0 / 3.0);
    // Two channels: the sum over channels is divided by the 2 pixels, not by the 4 values.
    EXPECT_DOUBLE_EQ(loss_value(mse, {1, 2, 3, 4}, {0, 0, 0, 0}, 2), 15.0);

    const double e = std::exp(1.0);
    const Loss cmsle1{LossKind::CMSLE, 1.0};
    // log(e − 1 + 1) − log(0 + 1) = 1; the second pixel matches.
    EXPECT_DOUBLE_EQ(loss_value(cmsle1, {e - 1.0, 0.0}, {0.0, 0.0}, 1), 0.5);
    // log(e² − 1 + 1) − log(e − 1 + 1) = 1, one pixel of three channels.
    EXPECT_NEAR(loss_value(cmsle1, {e * e - 1.0, 5.0, 0.0}, {e - 1.0, 5.0, 0.0}, 3), 1.0, 1e-15);
    const Loss cmsle_small{LossKind::CMSLE, 0.5};
    // log(1.5 / 0.5)² = log(3)².
    EXPECT_NEAR(loss_value(cmsle_small, {1.0}, {0.0}, 1), std::log(3.0) * std::log(3.0), 1e-15);

    const Loss amplitude{LossKind::Amplitude, 1.0};
    // (√4 − √1)² + (√9 − √1)² = 1 + 4, one pixel of two channels.
    EXPECT_NEAR(loss_value(amplitude, {4, 9}, {1, 1}, 2), 5.0, 1e-14);

    // N = 10 photons over R = (1, 1): s = 5, counts k = (5, 5), rates μ = s·I = (10, 2.5):
    // 2[5 log(1/2) + 5] + 2[5 log 2 − 2.5] = 5 over 2 pixels.
    const Loss poisson{LossKind::Poisson, 1.0, 10.0};
    EXPECT_NEAR(loss_value(poisson, {2.0, 0.5}, {1.0, 1.0}, 1), 2.5, 1e-9);
    // The scale comes from the reference's sum: the same counts at another brightness.
    EXPECT_NEAR(loss_value(poisson, {6.0, 1.5}, {3.0, 3.0}, 1), 2.5, 1e-9);
}

TEST(LossTest, NegativeValuesAreClampedToZero) {
    const Loss cmsle{LossKind::CMSLE, 1.0}, amplitude{LossKind::Amplitude, 1.0};
    std::vector<double> gradient;
    EXPECT_EQ(loss_value(cmsle, {-0.5}, {0.0}, 1, &gradient), 0.0);
    EXPECT_EQ(gradient[0], 0.0);
    EXPECT_EQ(loss_value(amplitude, {-0.5}, {-2.0}, 1, &gradient), 0.0);
    EXPECT_EQ(gradient[0], 0.0);
    // At exactly 0 the amplitude gradient is large but finite and pulls the estimate up.
    loss_value(amplitude, {0.0}, {1.0}, 1, &gradient);
    EXPECT_TRUE(std::isfinite(gradient[0]));
    EXPECT_LT(gradient[0], 0.0);
}

TEST(LossTest, GradientsMatchFiniteDifferences) {
    const std::size_t pixels = 7;
    for (const Loss& loss : kLosses) {
        for (int channels : {1, 2, 3, 5}) {
            SCOPED_TRACE(to_string(loss) + ", channels = " + std::to_string(channels));
            const std::size_t n = pixels * static_cast<std::size_t>(channels);
            const auto estimate = uniform_vector(n, 0.2, 3.0, 100 + static_cast<std::uint64_t>(channels));
            const auto reference = uniform_vector(n, 0.2, 3.0, 200 + static_cast<std::uint64_t>(channels));
            std::vector<double> gradient;
            const double value = loss_value(loss, estimate, reference, channels, &gradient);
            ASSERT_EQ(gradient.size(), n);
            // Asking for the gradient does not change the value.
            EXPECT_EQ(value, loss_value(loss, estimate, reference, channels));
            for (std::size_t i = 0; i < n; ++i) {
                const double fd = finite_difference(loss, estimate, reference, channels, i, 1e-3);
                EXPECT_NEAR(gradient[i], fd, 1e-7 * std::abs(gradient[i]) + 1e-13) << "index " << i;
            }
        }
    }
}

TEST(LossTest, ZeroAtEquality) {
    const auto slice = uniform_vector(3 * 11, 0.0, 5.0, 7);
    for (const Loss& loss : kLosses) {
        for (int channels : {1, 3}) {
            std::vector<double> gradient;
            EXPECT_EQ(loss_value(loss, slice, slice, channels, &gradient), 0.0) << to_string(loss);
            for (double g : gradient) EXPECT_EQ(g, 0.0) << to_string(loss);
        }
    }
    EXPECT_EQ(rgb_mse(slice, slice, 3), 0.0);
    EXPECT_EQ(rgb_gamma_mse(slice, slice, 1), 0.0);
    EXPECT_EQ(height_mse(slice, slice), 0.0);
}

TEST(LossTest, SizeAndChannelErrorsThrow) {
    const Loss loss;
    const std::vector<double> a(6, 1.0), b(5, 1.0), empty;
    expect_throw_naming<std::invalid_argument>([&] { loss_value(loss, a, b, 1); }, "6");
    expect_throw_naming<std::invalid_argument>([&] { loss_value(loss, a, a, 0); }, "channels");
    expect_throw_naming<std::invalid_argument>([&] { loss_value(loss, a, a, 4); }, "multiple");
    EXPECT_THROW(loss_value(loss, empty, empty, 1), std::invalid_argument);
    EXPECT_THROW(loss_value(Loss{LossKind::CMSLE, 0.0}, a, a, 1), std::domain_error);
    EXPECT_THROW(loss_value(Loss{LossKind::CMSLE, std::nan("")}, a, a, 1), std::domain_error);
    EXPECT_THROW(loss_value(Loss{LossKind::Poisson, 1.0, 0.0}, a, a, 1), std::domain_error);
    expect_throw_naming<std::invalid_argument>(
        [&] {
            loss_value(Loss{LossKind::Poisson, 1.0, 1e4}, a, std::vector<double>(6, 0.0), 1);
        },
        "positive sum");
    EXPECT_THROW(rgb_mse(a, b, 3), std::invalid_argument);
    EXPECT_THROW(rgb_mse(a, a, 2), std::invalid_argument);
    EXPECT_THROW(rgb_gamma_mse(a, b, 1), std::invalid_argument);
    EXPECT_THROW(height_mse(a, b), std::invalid_argument);
    EXPECT_THROW(height_mse(empty, empty), std::invalid_argument);
}

TEST(LossTest, RgbMetricsHandComputed) {
    // T(1) = 1/2, T(3) = 3/4, T(0) = 0.
    EXPECT_DOUBLE_EQ(rgb_mse({1.0}, {0.0}, 1), 0.25);
    EXPECT_DOUBLE_EQ(rgb_mse({1.0, 3.0, 0.0}, {0.0, 1.0, 0.0}, 3), (0.25 + 0.0625) / 3.0);
    EXPECT_DOUBLE_EQ(rgb_gamma_mse({1.0}, {0.0}, 1), std::pow(0.5, 2.0 / 2.2));
    // A mono slice is grey RGB: the same as its triplicated RGB slice.
    const auto mono_e = uniform_vector(9, 0.0, 4.0, 1), mono_r = uniform_vector(9, 0.0, 4.0, 2);
    std::vector<double> rgb_e, rgb_r;
    for (std::size_t i = 0; i < mono_e.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            rgb_e.push_back(mono_e[i]);
            rgb_r.push_back(mono_r[i]);
        }
    EXPECT_NEAR(rgb_mse(mono_e, mono_r, 1), rgb_mse(rgb_e, rgb_r, 3), 1e-15);
    EXPECT_NEAR(rgb_gamma_mse(mono_e, mono_r, 1), rgb_gamma_mse(rgb_e, rgb_r, 3), 1e-15);
    // Gamma lifts the dark values, so it weighs a difference there more (the thesis's Fig. 5.3).
    EXPECT_GT(rgb_gamma_mse({0.01}, {0.02}, 1), rgb_mse({0.01}, {0.02}, 1));
}

// A float reference (Observation::reference) gives the double reference's values and
// gradients when its values are exact in float; a braced list selects the double overload.
TEST(LossTest, FloatReferenceMatchesTheDoubleOne) {
    const std::vector<float> ref{0.5f, 0.25f, 2.0f, 0.0f, 1.5f, 3.0f};
    const std::vector<double> ref_double(ref.begin(), ref.end());
    const std::vector<double> estimate{1.0, 0.0, 3.0, 0.125, 1.5, 2.0};
    for (const Loss& loss : {Loss{LossKind::MSE, 1.0}, Loss{LossKind::CMSLE, 0.01}, Loss{LossKind::Amplitude, 1.0},
                             Loss{LossKind::Poisson, 1.0, 100.0}}) {
        std::vector<double> g_float, g_double;
        // Equal up to the compiler's contraction of a * b + c, which may differ between the
        // two instantiations (a few ulps).
        EXPECT_DOUBLE_EQ(loss_value(loss, estimate, ref, 3, &g_float),
                         loss_value(loss, estimate, ref_double, 3, &g_double))
            << to_string(loss);
        ASSERT_EQ(g_float.size(), g_double.size());
        for (std::size_t i = 0; i < g_float.size(); ++i) EXPECT_DOUBLE_EQ(g_float[i], g_double[i]) << to_string(loss);
    }
    EXPECT_DOUBLE_EQ(rgb_mse(estimate, ref, 3), rgb_mse(estimate, ref_double, 3));
    EXPECT_DOUBLE_EQ(rgb_gamma_mse(estimate, ref, 3), rgb_gamma_mse(estimate, ref_double, 3));
    EXPECT_DOUBLE_EQ(rgb_mse({0.0, 1.0, 3.0}, {0.0, 0.0, 0.0}, 1), (0.25 + 0.5625) / 3.0);
    EXPECT_GT(rgb_gamma_mse({1.0}, {0.0}, 1), 0.0);
}

TEST(LossTest, HeightMseHandComputedAndOffsetInvariant) {
    EXPECT_DOUBLE_EQ(height_mse({1, 2, 3}, {0, 0, 0}), 2.0 / 3.0);
    EXPECT_DOUBLE_EQ(height_mse({1, 2, 3}, {3, 2, 1}), 8.0 / 3.0);
    const auto a = uniform_vector(64, -0.5, 0.5, 3), b = uniform_vector(64, -0.5, 0.5, 4);
    const double base = height_mse(a, b);
    EXPECT_GT(base, 0.0);
    for (double offset : {1.0, -7.25, 123.5}) {
        std::vector<double> a_shift = a, b_shift = b;
        for (double& x : a_shift) x += offset;
        for (double& x : b_shift) x -= 2.0 * offset;
        EXPECT_NEAR(height_mse(a_shift, b), base, 1e-12 * base) << offset;
        EXPECT_NEAR(height_mse(a, b_shift), base, 1e-12 * base) << offset;
        EXPECT_NEAR(height_mse(a_shift, b_shift), base, 1e-12 * base) << offset;
    }
}
