// Tests of the refinement's coarse space (src/recovery/coarse_correction.h): the adjoint
// identity, the coarse gradient against finite differences, the gauge (no piston), the levels,
// and on slices of a small surface that it removes a smooth undulation plain L-BFGS leaves.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "recover_util.h"
#include "recovery/coarse_correction.h"
#include "test_util.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"

using namespace wavebrdf;
using wavebrdf::detail::CoarseBasis;

namespace {

double dot(const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) s += a[k] * b[k];
    return s;
}

}  // namespace

// Levels: spacing doubled while both axes keep ≥ 4 nodes; sizes add up.
TEST(CoarseBasis, LevelsAndSizes) {
    const CoarseBasis b(128, 64, 8.0);
    ASSERT_EQ(b.levels(), 2);  // 16 × 8, 8 × 4 nodes (the next, 4 × 2, is too coarse)
    EXPECT_EQ(b.nodes_rows(0), 16);
    EXPECT_EQ(b.nodes_cols(0), 8);
    EXPECT_EQ(b.nodes_rows(1), 8);
    EXPECT_EQ(b.nodes_cols(1), 4);
    EXPECT_EQ(b.size(), std::size_t(16 * 8 + 8 * 4));
    EXPECT_EQ(CoarseBasis(12, 12, 8.0).size(), 0u);  // too small for 4 nodes: no levels
    EXPECT_THROW(CoarseBasis(0, 12, 8.0), std::invalid_argument);
    EXPECT_THROW(CoarseBasis(12, 12, 0.5), std::invalid_argument);
    EXPECT_THROW(CoarseBasis(12, 12, 8.0, 0.0), std::invalid_argument);
    EXPECT_THROW(CoarseBasis(12, 12, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

// ⟨B c, g⟩ = ⟨c, Bᵀ g⟩ for random c and g (a non-square surface, non-integer node spacing).
TEST(CoarseBasis, AdjointDotProductIdentity) {
    const int rows = 40, cols = 56;
    const CoarseBasis b(rows, cols, 5.0, 1.7);  // 8 × 11 and 4 × 6 nodes
    ASSERT_GE(b.levels(), 2);
    const std::vector<double> c = test::uniform_vector(b.size(), -1.0, 1.0, 3);
    const std::vector<double> g = test::uniform_vector(std::size_t(rows * cols), -1.0, 1.0, 4);
    std::vector<double> bc(std::size_t(rows * cols), 0.0);
    b.apply(c.data(), bc);
    std::vector<double> btg(b.size());
    b.adjoint(g, btg.data());
    const double lhs = dot(bc, g), rhs = dot(c, btg);
    EXPECT_NEAR(lhs, rhs, 1e-12 * (std::abs(lhs) + 1.0));
    EXPECT_GT(std::abs(lhs), 1e-3);
}

// The gauge: B c has mean 0 (the piston stays), and a constant gradient has Bᵀ g = 0. Each level's
// functions sum to 1: all coefficients 1 give a constant, i.e. 0 after the mean is removed.
TEST(CoarseBasis, MeanFreeAndPartitionOfUnity) {
    const int rows = 48, cols = 36;
    const CoarseBasis b(rows, cols, 9.0);
    const std::vector<double> c = test::uniform_vector(b.size(), -1.0, 1.0, 5);
    std::vector<double> h(std::size_t(rows * cols), 2.5);
    b.apply(c.data(), h);
    double mean = 0.0;
    for (double v : h) mean += v / double(h.size());
    EXPECT_NEAR(mean, 2.5, 1e-12);
    std::vector<double> ones(b.size(), 1.0), flat(std::size_t(rows * cols), 0.0);
    b.apply(ones.data(), flat);
    for (double v : flat) ASSERT_NEAR(v, 0.0, 1e-12);
    std::vector<double> gc(b.size());
    b.adjoint(std::vector<double>(std::size_t(rows * cols), 3.0), gc.data());
    for (double v : gc) ASSERT_NEAR(v, 0.0, 1e-9);
    // A smooth mode, cos(2π j / cols), is reproduced by one level of spacing ≤ cols / 4 (≈ 1 %).
    const CoarseBasis fine(rows, cols, 9.0);
    std::vector<double> g(std::size_t(rows * cols));
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) g[std::size_t(i * cols + j)] = std::cos(2.0 * M_PI * j / cols);
    std::vector<double> gcoef(fine.size());
    fine.adjoint(g, gcoef.data());
    double norm = 0.0;
    for (double v : gcoef) norm += v * v;
    EXPECT_GT(norm, 1.0);  // the smooth mode is seen by the coarse space
}

// The coarse objective's gradient (∇f, Bᵀ∇f) against central differences of f(x + B c) in
// x and in c, for a non-quadratic f.
TEST(CoarseBasis, CoarseGradientMatchesFiniteDifferences) {
    const int rows = 24, cols = 20;
    const CoarseBasis b(rows, cols, 5.0, 0.8);
    ASSERT_GE(b.size(), 16u);
    const std::vector<double> w = test::uniform_vector(std::size_t(rows * cols), 0.5, 1.5, 6);
    const detail::Objective f = [&](const std::vector<double>& h, std::vector<double>& g) {
        double v = 0.0;
        g.assign(h.size(), 0.0);
        for (std::size_t k = 0; k < h.size(); ++k) {
            // f = Σ w sin(h) + Σ (h_k − h_{k+1})⁴ (neighbours along the rows, periodic)
            const std::size_t n = (k + 1) % h.size();
            const double d = h[k] - h[n];
            v += w[k] * std::sin(h[k]) + d * d * d * d;
            g[k] += w[k] * std::cos(h[k]) + 4.0 * d * d * d;
            g[n] -= 4.0 * d * d * d;
        }
        return v;
    };
    const detail::Objective fz = detail::coarse_objective(f, b);
    std::vector<double> z = test::uniform_vector(std::size_t(rows * cols) + b.size(), -0.5, 0.5, 7);
    std::vector<double> gz;
    fz(z, gz);
    ASSERT_EQ(gz.size(), z.size());
    const double eps = 1e-5;
    std::vector<double> scratch;
    for (std::size_t k : {std::size_t(3), std::size_t(rows * cols - 1), std::size_t(rows * cols),
                          std::size_t(rows * cols) + 7, z.size() - 1}) {
        std::vector<double> zp = z, zm = z;
        zp[k] += eps;
        zm[k] -= eps;
        const double fd = (fz(zp, scratch) - fz(zm, scratch)) / (2.0 * eps);
        EXPECT_NEAR(gz[k], fd, 1e-6 * (std::abs(fd) + 1.0)) << "variable " << k;
    }
    // The coarse-only objective's gradient is the same Bᵀ∇f.
    const std::vector<double> x(z.begin(), z.begin() + rows * cols);
    const std::vector<double> c(z.begin() + rows * cols, z.end());
    std::vector<double> gc;
    detail::coarse_only_objective(f, b, x)(c, gc);
    for (std::size_t k = 0; k < c.size(); ++k) ASSERT_NEAR(gc[k], gz[std::size_t(rows * cols) + k], 1e-12);
}

// On the slices of a small surface: the truth plus a smooth undulation (one cycle across the
// surface) plus a small detail error. A few L-BFGS iterations on the heights alone leave most of
// the undulation; with the coarse variables they remove it.
TEST(CoarseBasis, RemovesASmoothUndulationWherePlainLbfgsDoesNot) {
    const int n = 32;
    const Heightfield truth = test::peak_scaled_surface(n, 8.0, 0.4, 41);  // 2 µm texels, 64 µm
    std::vector<Observation> observations;
    const double step = 4.0;  // σ_p = 3 µm
    for (int a = 0; a < 16; ++a)
        for (int b = 0; b < 16; ++b) {
            Observation o;
            o.query = test::make_query(Model::OHS, (a + 0.5) * step, (b + 0.5) * step, 3.0);
            o.lambdas_um.assign(1, 0.5);
            o.resolution = 32;
            o.reference = to_reference(render_observation(truth, o));
            observations.push_back(std::move(o));
        }
    std::vector<double> start = truth.values();
    const std::vector<double> detail = test::uniform_vector(start.size(), -0.002, 0.002, 42);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const std::size_t k = std::size_t(i * n + j);
            // 0.01 texel units = 20 nm: λ/25, well inside the basin.
            start[k] += 0.01 * std::cos(2.0 * M_PI * (i + 0.5 * j) / n) + detail[k];
        }
    const Loss loss{LossKind::Amplitude, 1.0};
    const detail::Objective f = [&](const std::vector<double>& h, std::vector<double>& g) {
        return observation_loss(truth.with_values(h), observations, loss, &g);
    };
    LbfgsOptions lo;
    lo.history = 20;
    lo.max_iterations = 8;
    lo.gradient_tolerance = 0.0;
    const double before = height_rel_rmse(truth.with_values(start), truth);

    std::vector<double> plain = start;
    lbfgs_minimize(f, plain, lo);
    const double plain_rmse = height_rel_rmse(truth.with_values(plain), truth);

    const CoarseBasis basis(n, n, 4.0);
    ASSERT_GE(basis.levels(), 2);
    std::vector<double> z(start.size() + basis.size(), 0.0);
    std::copy(start.begin(), start.end(), z.begin());
    lbfgs_minimize(detail::coarse_objective(f, basis), z, lo);
    const double coarse_rmse = height_rel_rmse(truth.with_values(detail::coarse_heights(z, basis)), truth);
    std::cout << "undulation: start " << before << ", plain " << plain_rmse << ", coarse " << coarse_rmse << "\n";
    EXPECT_GT(plain_rmse, 0.25 * before);  // measured 0.34
    EXPECT_LT(coarse_rmse, 0.1 * before);  // measured 0.03
}
