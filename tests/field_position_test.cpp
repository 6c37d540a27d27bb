// Position correction in the field stage (src/recovery/field_positions.h): the analytic
// gradient of the amplitude loss with respect to the footprint centre against central
// differences, the object's Fourier shift against an exact roll, and the gradient steps
// finding known offsets at the true object (the same bits on one and two threads).
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <random>

#include "recovery/field_positions.h"
#include "test_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;

namespace {

constexpr int kRows = 12, kCols = 12, kRefine = 3;
constexpr double kTexel = 2.0, kLambda = 0.5;

// A smooth pure-phase object e^{−i(4π/λ)H} on the refined grid, H a sum of eight random
// sinusoids of up to 4 periods per tile side (periodic on the tile), |H| ≤ height_um.
std::vector<std::complex<double>> smooth_object(std::uint64_t seed, double height_um) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> phase(0.0, 2.0 * k_pi);
    std::uniform_int_distribution<int> frequency(-4, 4);
    const int nr = kRows * kRefine, nc = kCols * kRefine, modes = 8;
    std::vector<std::array<double, 3>> mode;
    for (int m = 0; m < modes; ++m) mode.push_back({double(frequency(rng)), double(frequency(rng)), phase(rng)});
    std::vector<std::complex<double>> o(std::size_t(nr) * nc);
    for (int a = 0; a < nr; ++a)
        for (int b = 0; b < nc; ++b) {
            const double x = double(a) / nr, y = double(b) / nc;
            double h = 0.0;
            for (const auto& [fx, fy, ph] : mode) h += height_um / modes * std::sin(2 * k_pi * (fx * x + fy * y) + ph);
            o[std::size_t(a) * nc + b] = std::polar(1.0, -4.0 * k_pi / kLambda * h);
        }
    return o;
}

// An observation at `stated` whose reference is the field model of `object` at stated + error.
Observation observation_at(const std::vector<std::complex<double>>& object, std::array<double, 2> stated,
                           std::array<double, 2> error, int resolution = 24) {
    Observation o;
    o.query = test::make_query(Model::OHS, stated[0] + error[0], stated[1] + error[1], 3.0);
    o.lambdas_um = {kLambda};
    o.resolution = resolution;
    const FieldOperator op(kRows, kCols, kTexel, o.query, kLambda, resolution, kRefine);
    const std::vector<std::complex<double>> f = op.forward(object);
    const std::vector<double>& amp = op.amplitude_factor();
    o.reference.resize(f.size());
    for (std::size_t k = 0; k < f.size(); ++k) o.reference[k] = float(amp[k] * amp[k] * std::norm(f[k]));
    o.query.x_um = stated[0];
    o.query.y_um = stated[1];
    return o;
}

// A 4 × 4 grid of positions over the 24 µm object, each observed at its stated centre plus an
// error from `draw` (µm; called once per position, row-major), with the errors' mean and the
// group and position indices a retrieval takes (group points into obs: keep the case whole).
struct GridCase {
    std::vector<Observation> obs;
    std::vector<std::array<double, 2>> errors;
    std::array<double, 2> mean{0.0, 0.0};
    std::vector<const Observation*> group;
    std::vector<std::size_t> position;
};

template <class Draw>
GridCase grid_case(const std::vector<std::complex<double>>& object, Draw draw) {
    GridCase c;
    const int side = 4;
    for (int a = 0; a < side; ++a)
        for (int b = 0; b < side; ++b) {
            c.errors.push_back(draw());
            c.obs.push_back(
                observation_at(object, {(a + 0.5) * 24.0 / side, (b + 0.5) * 24.0 / side}, c.errors.back()));
        }
    for (const auto& e : c.errors)
        c.mean = {c.mean[0] + e[0] / double(c.errors.size()), c.mean[1] + e[1] / double(c.errors.size())};
    for (std::size_t k = 0; k < c.obs.size(); ++k) {
        c.group.push_back(&c.obs[k]);
        c.position.push_back(k);
    }
    return c;
}

}  // namespace

// With and without pixel weights (the weighted one: weights in [0.5, 1.5], every 7th pixel and
// the brightest at weight 0 holding NaN, which the loss never reads).
TEST(FieldPositions, CentreGradientMatchesCentralDifferences) {
    const auto object = smooth_object(5501, 0.3);
    const auto truth = smooth_object(5502, 0.3);
    for (const bool weighted : {false, true})
        for (const std::array<double, 2> centre : {std::array<double, 2>{11.3, 12.7}, {1.1, 22.9}}) {
            Observation o = observation_at(truth, centre, {0.7, -0.4});
            if (weighted) {
                const Observation unweighted = o;
                o.weights.resize(o.reference.size());
                for (std::size_t k = 0; k < o.weights.size(); ++k)
                    o.weights[k] = float(k % 7 ? 0.5 + 0.01 * double(k % 101) : 0.0);
                const std::size_t peak = std::size_t(std::max_element(o.reference.begin(), o.reference.end()) -
                                                     o.reference.begin());
                o.weights[peak] = 0.0f;
                for (std::size_t k = 0; k < o.weights.size(); ++k)
                    if (o.weights[k] == 0.0f) o.reference[k] = std::numeric_limits<float>::quiet_NaN();
                const double lw = detail::field_position_loss(o, {0.2, 0.1}, object, kLambda, kRows, kCols, kTexel,
                                                              kRefine, nullptr);
                EXPECT_TRUE(std::isfinite(lw));
                EXPECT_NE(lw, detail::field_position_loss(unweighted, {0.2, 0.1}, object, kLambda, kRows, kCols, kTexel,
                                                          kRefine, nullptr));
            }
            for (const std::array<double, 2> offset : {std::array<double, 2>{0.0, 0.0}, {0.37, -0.61}}) {
                std::array<double, 2> g{0.0, 0.0};
                const double l = detail::field_position_loss(o, offset, object, kLambda, kRows, kCols, kTexel, kRefine,
                                                             &g);
                ASSERT_GT(l, 0.0);
                const double h = 1e-4;  // µm: well inside one fine sample, no sample crosses the 3σ_p cut
                for (int c = 0; c < 2; ++c) {
                    std::array<double, 2> plus = offset, minus = offset;
                    plus[std::size_t(c)] += h;
                    minus[std::size_t(c)] -= h;
                    const double fd = (detail::field_position_loss(o, plus, object, kLambda, kRows, kCols, kTexel,
                                                                   kRefine, nullptr) -
                                       detail::field_position_loss(o, minus, object, kLambda, kRows, kCols, kTexel,
                                                                   kRefine, nullptr)) /
                                      (2.0 * h);
                    EXPECT_NEAR(g[std::size_t(c)], fd, 1e-5 * (std::abs(fd) + std::abs(g[0]) + std::abs(g[1])))
                        << "centre " << centre[0] << "," << centre[1] << " coordinate " << c;
                }
            }
        }
}

TEST(FieldPositions, ShiftingTheObjectByWholeSamplesIsARoll) {
    // Odd sizes (no Nyquist row): a whole-sample shift is exactly a periodic roll.
    const int rows = 5, cols = 7, refine = 3, nr = rows * refine, nc = cols * refine;
    std::mt19937_64 rng(5503);
    std::normal_distribution<double> normal;
    std::vector<std::complex<double>> o(std::size_t(nr) * nc);
    for (auto& v : o) v = {normal(rng), normal(rng)};
    const double d = kTexel / refine;
    const auto shifted = detail::shift_object(o, rows, cols, kTexel, refine, 2 * d, -3 * d);
    double worst = 0.0;
    for (int a = 0; a < nr; ++a)
        for (int b = 0; b < nc; ++b) {
            const int sa = ((a - 2) % nr + nr) % nr, sb = ((b + 3) % nc + nc) % nc;
            worst = std::max(worst, std::abs(shifted[std::size_t(a) * nc + b] - o[std::size_t(sa) * nc + sb]));
        }
    EXPECT_LT(worst, 1e-12);
    // A fractional shift and back is the identity.
    const auto back = detail::shift_object(detail::shift_object(o, rows, cols, kTexel, refine, 0.37, -0.81), rows, cols,
                                           kTexel, refine, -0.37, 0.81);
    for (std::size_t k = 0; k < o.size(); ++k) EXPECT_LT(std::abs(back[k] - o[k]), 1e-12);
}

TEST(FieldPositions, GradientStepsFindKnownOffsetsAtTheTrueObjectWithTheSameBitsOnAnyThreadCount) {
    const auto object = smooth_object(5504, 0.3);
    std::mt19937_64 rng(5505);
    std::normal_distribution<double> normal(0.0, 0.5 * kTexel);  // 0.5 texel rms
    GridCase c = grid_case(object, [&] { return std::array<double, 2>{normal(rng), normal(rng)}; });
    const auto& obs = c.obs;
    const auto& errors = c.errors;
    const auto& mean = c.mean;
    const auto run = [&](int threads, int steps) {
        const int before = omp_get_max_threads();
        omp_set_num_threads(threads);
        std::vector<double> offsets(2 * obs.size(), 0.0);
        // The object shifted by the errors' mean: the frame in which the mean-free offsets hold.
        std::vector<std::complex<double>> o = detail::shift_object(object, kRows, kCols, kTexel, kRefine, -mean[0],
                                                                   -mean[1]);
        detail::correct_positions(c.group, c.position, o, kLambda, kRows, kCols, kTexel, kRefine, steps, offsets,
                                  serial_communicator());
        omp_set_num_threads(before);
        return offsets;
    };
    const std::vector<double> one = run(1, 12);
    EXPECT_EQ(one, run(2, 12));
    // The offsets found have mean 0 (the gauge), as the errors minus their mean.
    double found_mean[2] = {0.0, 0.0};
    for (std::size_t k = 0; k < obs.size(); ++k)
        for (int c = 0; c < 2; ++c) found_mean[c] += one[2 * k + std::size_t(c)] / double(obs.size());
    EXPECT_NEAR(found_mean[0], 0.0, 1e-12);
    EXPECT_NEAR(found_mean[1], 0.0, 1e-12);
    double sum = 0.0, start = 0.0;
    for (std::size_t k = 0; k < obs.size(); ++k)
        for (int c = 0; c < 2; ++c) {
            const double truth = errors[k][std::size_t(c)] - mean[std::size_t(c)];
            sum += std::pow(one[2 * k + std::size_t(c)] - truth, 2);
            start += truth * truth;
        }
    const double rms = std::sqrt(sum / (2.0 * double(obs.size()))) / kTexel,
                 rms0 = std::sqrt(start / (2.0 * double(obs.size()))) / kTexel;
    RecordProperty("offset_rms_before_texels", std::to_string(rms0));
    RecordProperty("offset_rms_after_texels", std::to_string(rms));
    EXPECT_GT(rms0, 0.3);
    EXPECT_LT(rms, 0.02) << "from " << rms0;
}
