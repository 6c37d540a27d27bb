// The shared per-slice amplitude loss (src/recovery/amplitude_loss.h): its value against a
// direct evaluation and its gradient against central finite differences, without and with
// pixel weights (a pixel of weight 0, its reference NaN, enters nothing).

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <limits>
#include <random>
#include <string>

#include "recovery/amplitude_loss.h"

namespace wavebrdf {
namespace {

using Field = Eigen::MatrixXcd;

struct Box {
    Field psi;
    Eigen::MatrixXd amp, sqrt_ref;
    Eigen::MatrixXd weight;  // empty: none (UnitWeight)
};

// The loss through the weights' accessor the box has.
double box_loss(const Box& box, double outside, bool calibrate, double scale, Field& g) {
    if (box.weight.size() == 0)
        return detail::amplitude_box_loss(box.psi, box.amp, box.sqrt_ref, detail::UnitWeight{}, outside, calibrate,
                                          scale, g);
    return detail::amplitude_box_loss(box.psi, box.amp, box.sqrt_ref, box.weight, outside, calibrate, scale, g);
}

// random_box with weights in [0.3, 2], and weight 0 on one pixel inside the disk (its
// reference NaN) and on one outside it (c = 0).
Box weighted(Box box, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> w(0.3, 2.0);
    box.weight.resize(box.psi.rows(), box.psi.cols());
    for (Eigen::Index k = 0; k < box.weight.size(); ++k) box.weight(k) = w(rng);
    box.weight(3, 2) = 0.0;
    box.sqrt_ref(3, 2) = std::numeric_limits<double>::quiet_NaN();
    box.weight(0, 0) = 0.0;
    return box;
}

// A 5 × 4 box with two pixels outside the disk (c = 0) and one zero field value.
Box random_box(std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0), pos(0.2, 1.5);
    Box box{Field(5, 4), Eigen::MatrixXd(5, 4), Eigen::MatrixXd(5, 4), {}};
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

// The loss written out directly, as the header states it (each pixel × its weight, those of
// weight 0 skipped).
double direct(const Box& box, double outside, bool calibrate) {
    const auto w = [&](Eigen::Index k) { return box.weight.size() ? box.weight(k) : 1.0; };
    double s2 = 1.0;
    if (calibrate) {
        double r = 0.0, m = 0.0;
        for (Eigen::Index k = 0; k < box.psi.size(); ++k)
            if (box.amp(k) != 0.0 && w(k) != 0.0) {
                r += w(k) * box.sqrt_ref(k) * box.sqrt_ref(k);
                m += w(k) * std::pow(box.amp(k) * std::abs(box.psi(k)), 2);
            }
        s2 = r / m;
    }
    double v = outside;
    for (Eigen::Index k = 0; k < box.psi.size(); ++k) {
        if (w(k) == 0.0) continue;
        if (box.amp(k) == 0.0)
            v += w(k) * box.sqrt_ref(k) * box.sqrt_ref(k);
        else
            v += w(k) * std::pow(std::sqrt(s2) * box.amp(k) * std::abs(box.psi(k)) - box.sqrt_ref(k), 2);
    }
    return v;
}

TEST(AmplitudeLoss, ValueIsTheDirectSumAndGradientMatchesFiniteDifferences) {
    for (const bool weights : {false, true})
        for (const bool calibrate : {false, true}) {
            SCOPED_TRACE(std::string(calibrate ? "calibrated exposure" : "exposure 1") +
                         (weights ? ", weighted" : ""));
            const Box plain = random_box(calibrate ? 11 : 12);
            const Box box = weights ? weighted(plain, 14) : plain;
            const double outside = 0.37, scale = 0.25;
            Field g;
            const double v = box_loss(box, outside, calibrate, scale, g);
            EXPECT_NEAR(v, direct(box, outside, calibrate), 1e-12 * v);
            ASSERT_EQ(g.rows(), 5);
            ASSERT_EQ(g.cols(), 4);
            EXPECT_EQ(g(0, 0), std::complex<double>(0.0));  // outside the disk
            EXPECT_EQ(g(4, 3), std::complex<double>(0.0));
            if (weights) {
                EXPECT_EQ(g(3, 2), std::complex<double>(0.0));  // weight 0
            }
            double largest = 0.0;
            for (Eigen::Index k = 0; k < g.size(); ++k) largest = std::max(largest, std::abs(g(k)));
            ASSERT_GT(largest, 0.0);
            const double h = 1e-6;
            for (Eigen::Index k = 0; k < box.psi.size(); ++k) {
                if (std::abs(box.psi(k)) == 0.0) continue;  // |Ψ| is not differentiable at 0
                for (const std::complex<double> step :
                     {std::complex<double>(h, 0.0), std::complex<double>(0.0, h)}) {
                    Box plus = box, minus = box;
                    plus.psi(k) += step;
                    minus.psi(k) -= step;
                    Field unused;
                    const double fd = (box_loss(plus, outside, calibrate, scale, unused) -
                                       box_loss(minus, outside, calibrate, scale, unused)) /
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
    const double vf = detail::amplitude_box_loss(psi, box.amp, box.sqrt_ref, detail::UnitWeight{}, 0.0, true, 1.0, g);
    const double vd = box_loss(box, 0.0, true, 1.0, gd);
    EXPECT_NEAR(vf, vd, 1e-6 * vd);
    for (Eigen::Index k = 0; k < g.size(); ++k) EXPECT_NEAR(std::abs(std::complex<double>(g(k)) - gd(k)), 0.0, 1e-5);
}

}  // namespace
}  // namespace wavebrdf
