// The shared per-slice amplitude loss (src/recovery/amplitude_loss.h): its value against a
// direct evaluation and its gradient against central finite differences.

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include "recovery/amplitude_loss.h"

namespace wavebrdf {
namespace {

using Field = Eigen::MatrixXcd;

struct Box {
    Field psi;
    Eigen::MatrixXd amp, sqrt_ref;
};

// A 5 × 4 box with two pixels outside the disk (c = 0) and one zero field value.
Box random_box(std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0), pos(0.2, 1.5);
    Box box{Field(5, 4), Eigen::MatrixXd(5, 4), Eigen::MatrixXd(5, 4)};
    for (Eigen::Index b = 0; b < 4; ++b)
        for (Eigen::Index a = 0; a < 5; ++a) {
            box.psi(a, b) = {u(rng), u(rng)};
            box.amp(a, b) = pos(rng);
            box.sqrt_ref(a, b) = pos(rng);
        }
    box.amp(0, 0) = 0.0;
    box.amp(4, 3) = 0.0;
    box.psi(2, 1) = 0.0;
    return box;
}

// The loss written out directly, as the header states it.
double direct(const Box& box, double outside, bool calibrate) {
    double s2 = 1.0;
    if (calibrate) {
        double r = 0.0, m = 0.0;
        for (Eigen::Index k = 0; k < box.psi.size(); ++k)
            if (box.amp(k) != 0.0) {
                r += box.sqrt_ref(k) * box.sqrt_ref(k);
                m += std::pow(box.amp(k) * std::abs(box.psi(k)), 2);
            }
        s2 = r / m;
    }
    double v = outside;
    for (Eigen::Index k = 0; k < box.psi.size(); ++k) {
        if (box.amp(k) == 0.0)
            v += box.sqrt_ref(k) * box.sqrt_ref(k);
        else
            v += std::pow(std::sqrt(s2) * box.amp(k) * std::abs(box.psi(k)) - box.sqrt_ref(k), 2);
    }
    return v;
}

TEST(AmplitudeLoss, ValueIsTheDirectSumAndGradientMatchesFiniteDifferences) {
    for (const bool calibrate : {false, true}) {
        SCOPED_TRACE(calibrate ? "calibrated exposure" : "exposure 1");
        const Box box = random_box(calibrate ? 11 : 12);
        const double outside = 0.37, scale = 0.25;
        Field g;
        const double v = detail::amplitude_box_loss(box.psi, box.amp, box.sqrt_ref, outside, calibrate, scale, g);
        EXPECT_NEAR(v, direct(box, outside, calibrate), 1e-12 * v);
        ASSERT_EQ(g.rows(), 5);
        ASSERT_EQ(g.cols(), 4);
        EXPECT_EQ(g(0, 0), std::complex<double>(0.0));  // outside the disk
        EXPECT_EQ(g(4, 3), std::complex<double>(0.0));
        double largest = 0.0;
        for (Eigen::Index k = 0; k < g.size(); ++k) largest = std::max(largest, std::abs(g(k)));
        ASSERT_GT(largest, 0.0);
        const double h = 1e-6;
        for (Eigen::Index k = 0; k < box.psi.size(); ++k) {
            if (std::abs(box.psi(k)) == 0.0) continue;  // |Ψ| is not differentiable at 0
            for (const std::complex<double> step : {std::complex<double>(h, 0.0), std::complex<double>(0.0, h)}) {
                Box plus = box, minus = box;
                plus.psi(k) += step;
                minus.psi(k) -= step;
                Field unused;
                const double fd = (detail::amplitude_box_loss(plus.psi, plus.amp, plus.sqrt_ref, outside, calibrate,
                                                              scale, unused) -
                                   detail::amplitude_box_loss(minus.psi, minus.amp, minus.sqrt_ref, outside, calibrate,
                                                              scale, unused)) /
                                  (2.0 * h);
                // g = scale · (∂L/∂Re Ψ + i ∂L/∂Im Ψ)
                const double analytic = (step.real() != 0.0 ? g(k).real() : g(k).imag()) / scale;
                EXPECT_NEAR(analytic, fd, 1e-6 * (1.0 + std::abs(fd))) << "pixel " << k;
            }
        }
    }
}

TEST(AmplitudeLoss, FloatFieldGivesTheDoubleFieldsValueToFloatRounding) {
    const Box box = random_box(13);
    const Eigen::MatrixXcf psi = box.psi.cast<std::complex<float>>();
    Eigen::MatrixXcf g;
    Field gd;
    const double vf = detail::amplitude_box_loss(psi, box.amp, box.sqrt_ref, 0.0, true, 1.0, g);
    const double vd = detail::amplitude_box_loss(box.psi, box.amp, box.sqrt_ref, 0.0, true, 1.0, gd);
    EXPECT_NEAR(vf, vd, 1e-6 * vd);
    for (Eigen::Index k = 0; k < g.size(); ++k) EXPECT_NEAR(std::abs(std::complex<double>(g(k)) - gd(k)), 0.0, 1e-5);
}

}  // namespace
}  // namespace wavebrdf
