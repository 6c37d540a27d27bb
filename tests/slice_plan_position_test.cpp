// The footprint centre's gradient (SlicePlan::position_gradient) against central finite
// differences of the plan's own output when the query's centre moves, on every path and model,
// oblique light, one and several wavelengths; float plans against the double ones.
#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;
using test::make_query;
using test::random_heightfield;
using test::uniform_vector;

namespace {

struct PositionCase {
    Model model;
    RenderPath path;
    std::vector<double> lambdas;
    double light_x, light_y;
};

std::vector<PositionCase> position_cases() {
    return {{Model::OHS, RenderPath::Auto, {0.5}, 0.0, 0.0},
            {Model::OHS, RenderPath::Separable, {0.5}, 0.3, -0.2},
            {Model::ROHS, RenderPath::Separable, {0.45, 0.61}, -0.25, 0.1},
            {Model::OHS, RenderPath::Direct, {0.55}, 0.2, 0.15},
            {Model::ROHS, RenderPath::Fft, {0.5}, 0.1, 0.3},
            {Model::OHS, RenderPath::Auto, spectral_wavelengths_um(3), 0.15, 0.0},
            {Model::GHS, RenderPath::Auto, {0.5}, 0.3, 0.1},
            {Model::Kirchhoff, RenderPath::Separable, {0.6}, -0.2, 0.2}};
}

template <typename Float>
double weighted_output(const Heightfield& hf, const PositionCase& c, double x, double y, double sigma_p, int n,
                       const std::vector<double>& weights, std::size_t* kernels = nullptr) {
    RenderOptions options;
    options.path = c.path;
    const int channels = c.lambdas.size() == 1 ? 1 : 3;
    SlicePlan<Float> plan(hf, make_query(c.model, x, y, sigma_p, c.light_x, c.light_y), c.lambdas, n, channels,
                          options);
    const std::vector<Float>& f = plan.forward();
    if (kernels) *kernels = plan.kernels();
    double sum = 0.0;
    for (std::size_t p = 0; p < f.size(); ++p) sum += weights[p] * double(f[p]);
    return sum;
}

template <typename Float>
std::array<double, 2> analytic(const Heightfield& hf, const PositionCase& c, double x, double y, double sigma_p, int n,
                               const std::vector<double>& weights) {
    RenderOptions options;
    options.path = c.path;
    const int channels = c.lambdas.size() == 1 ? 1 : 3;
    SlicePlan<Float> plan(hf, make_query(c.model, x, y, sigma_p, c.light_x, c.light_y), c.lambdas, n, channels,
                          options);
    plan.forward();
    // The combined call gives the same centre gradient and the same height gradient as adjoint.
    std::vector<double> g1, g2;
    plan.adjoint(weights, g1, 0.5);
    const std::array<double, 2> both = plan.adjoint_with_position(weights, g2, 0.5);
    EXPECT_EQ(g1, g2);
    const std::array<double, 2> alone = plan.position_gradient(weights);
    EXPECT_NEAR(both[0], 0.5 * alone[0], 1e-12 * (std::abs(alone[0]) + std::abs(alone[1])));
    EXPECT_NEAR(both[1], 0.5 * alone[1], 1e-12 * (std::abs(alone[0]) + std::abs(alone[1])));
    return alone;
}

}  // namespace

TEST(SlicePlanPosition, GradientMatchesCentralDifferences) {
    const Heightfield hf = random_heightfield(16, 14, 0.25, 41, 0.8, 1.0);
    const int n = 16;
    const double sigma_p = 2.7;
    // Centres away from the seam and with no kernel near the 3σ_p cut at ±h (checked below).
    const std::vector<std::array<double, 2>> centres{{6.13, 5.37}, {3.71, 8.29}, {11.9, 1.23}};
    const double h = 1e-4;  // µm
    for (const PositionCase& c : position_cases()) {
        SCOPED_TRACE(std::string(to_string(c.model)) + " path " + std::to_string(int(c.path)) + " lambdas " +
                     std::to_string(c.lambdas.size()));
        const std::size_t values = std::size_t(n) * n * (c.lambdas.size() == 1 ? 1 : 3);
        const std::vector<double> weights = uniform_vector(values, -1.0, 1.0, 7);
        for (const auto& centre : centres) {
            const double x = centre[0], y = centre[1];
            const std::array<double, 2> g = analytic<double>(hf, c, x, y, sigma_p, n, weights);
            std::array<double, 2> fd{};
            for (int axis = 0; axis < 2; ++axis) {
                const double dx = axis == 0 ? h : 0.0, dy = axis == 1 ? h : 0.0;
                std::size_t k_plus = 0, k_minus = 0, k_mid = 0;
                const double plus = weighted_output<double>(hf, c, x + dx, y + dy, sigma_p, n, weights, &k_plus);
                const double minus = weighted_output<double>(hf, c, x - dx, y - dy, sigma_p, n, weights, &k_minus);
                weighted_output<double>(hf, c, x, y, sigma_p, n, weights, &k_mid);
                ASSERT_EQ(k_plus, k_mid);  // the cut is held fixed by the derivative
                ASSERT_EQ(k_minus, k_mid);
                fd[axis] = (plus - minus) / (2.0 * h);
            }
            const double scale = std::abs(fd[0]) + std::abs(fd[1]);
            ASSERT_GT(scale, 0.0);
            EXPECT_NEAR(g[0], fd[0], 1e-5 * scale) << "x " << x << " y " << y;
            EXPECT_NEAR(g[1], fd[1], 1e-5 * scale) << "x " << x << " y " << y;
            // Single precision: the same gradient to float accuracy.
            const std::array<double, 2> gf = analytic<float>(hf, c, x, y, sigma_p, n, weights);
            EXPECT_NEAR(gf[0], g[0], 2e-3 * scale);
            EXPECT_NEAR(gf[1], g[1], 2e-3 * scale);
        }
    }
}

// The centre's gradient needs a forward and weights of the output's size; zero weights give 0.
TEST(SlicePlanPosition, NeedsForwardAndRejectsWrongWeights) {
    const Heightfield hf = random_heightfield(12, 12, 0.2, 3, 1.0, 1.0);
    SlicePlan<double> plan(hf, make_query(Model::OHS, 5.5, 6.5, 2.0), {0.5}, 12, 1);
    EXPECT_THROW(plan.position_gradient(std::vector<double>(144, 1.0)), std::logic_error);
    plan.forward();
    EXPECT_THROW(plan.position_gradient(std::vector<double>(100, 1.0)), std::invalid_argument);
    const std::array<double, 2> g = plan.position_gradient(std::vector<double>(144, 0.0));
    EXPECT_EQ(g[0], 0.0);
    EXPECT_EQ(g[1], 0.0);
}
