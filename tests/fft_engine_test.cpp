// The FFT engine (src/forward/fft_engine.h) against an independent slow evaluation of the sum
//   F_v[p,q] = Σ_k w_vk exp(−2π²σ²|u + b_k|²) e^{−i2π u·δ_k},  b_k = shift_scale (2/λ) s_k,
// its adjoint against the transpose of that sum and against finite differences, and the
// separable path (detail::SeparableEngine) for OHS.
#include <cmath>
#include <complex>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "forward/fft_engine.h"
#include "forward/separable_engine.h"
#include "forward/path_cost.h"
#include "forward/separable.h"
#include "test_util.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {
namespace {

using detail::ComplexMatrix;
using detail::FftEngine;
using detail::FieldGradient;
using detail::KernelWeights;
using detail::SliceGrid;
using Cd = std::complex<double>;

struct EngineCase {
    int n = 40;
    double lambda_um = 0.5;
    double sigma_p_um = 4.0;
    double amplitude = 0.3;  // heights, texel units
    double wx = 0.0, wy = 0.0;
    double shift_scale = 1.0;
    int views = 1;
    int rows = 48;
};

struct Fixture {
    Heightfield heightfield;
    FootprintKernels kernels;
    Query query;
    KernelWeights weights;
};

Fixture make_setup(const EngineCase& c, std::uint64_t seed = 7) {
    Heightfield hf = test::random_heightfield(c.rows, c.rows, c.amplitude, seed);
    Query query = test::make_query(Model::OHS, 11.0, 17.0, c.sigma_p_um, c.wx, c.wy);
    FootprintKernels kernels = footprint_kernels(hf, query.x_um, query.y_um, query.sigma_p_um);
    KernelWeights weights(static_cast<std::size_t>(c.views));
    std::mt19937_64 rng(seed + 1);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    for (int v = 0; v < c.views; ++v)
        for (std::size_t k = 0; k < kernels.size(); ++k)
            weights[std::size_t(v)].push_back(v == 0 ? detail::kernel_weight(kernels, k, c.lambda_um)
                                                     : Cd(uni(rng), uni(rng)) * kernels.weight[k]);
    return {std::move(hf), std::move(kernels), query, std::move(weights)};
}

// The slow sum: one exp and one phase per kernel and pixel.
std::vector<std::vector<Cd>> slow_fields(const FootprintKernels& k, const SliceGrid& grid, const KernelWeights& w,
                                         double lambda_um, double shift_scale) {
    const std::size_t n = grid.ux.size();
    const double s2 = k.sigma_um * k.sigma_um;
    std::vector<std::vector<Cd>> out(w.size(), std::vector<Cd>(n * n, 0.0));
    for (std::size_t i = 0; i < k.size(); ++i) {
        const double bx = shift_scale * 2.0 / lambda_um * k.slope_x[i],
                     by = shift_scale * 2.0 / lambda_um * k.slope_y[i];
        for (std::size_t p = 0; p < n; ++p)
            for (std::size_t q = 0; q < n; ++q) {
                const double ax = grid.ux[p] + bx, ay = grid.uy[q] + by;
                const Cd g = std::exp(-2.0 * k_pi * k_pi * s2 * (ax * ax + ay * ay)) *
                             std::polar(1.0, -2.0 * k_pi * (grid.ux[p] * k.dx_um[i] + grid.uy[q] * k.dy_um[i]));
                for (std::size_t v = 0; v < w.size(); ++v) out[v][p * n + q] += w[v][i] * g;
            }
    }
    return out;
}

// max |F_fft − F_slow| / max |F_slow| over the views (the worst view).
template <typename Float>
double relative_error(const std::vector<ComplexMatrix<Float>>& fast, const std::vector<std::vector<Cd>>& slow) {
    double worst = 0.0;
    for (std::size_t v = 0; v < slow.size(); ++v) {
        const Eigen::Index n = fast[v].rows();
        double peak = 0.0, err = 0.0;
        for (Eigen::Index p = 0; p < n; ++p)
            for (Eigen::Index q = 0; q < n; ++q) {
                const Cd s = slow[v][std::size_t(p * n + q)];
                peak = std::max(peak, std::abs(s));
                err = std::max(err, std::abs(Cd(fast[v](p, q)) - s));
            }
        EXPECT_GT(peak, 0.0);
        worst = std::max(worst, err / peak);
    }
    return worst;
}

double engine_error(const EngineCase& c, double tolerance, detail::FftGridInfo* info = nullptr) {
    const Fixture s = make_setup(c);
    const SliceGrid grid(s.query, c.lambda_um, c.n);
    FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, tolerance);
    std::vector<ComplexMatrix<double>> fields;
    engine.forward(s.weights, c.shift_scale, fields);
    if (info) *info = engine.last_grid();
    EXPECT_EQ(fields.size(), s.weights.size());
    return relative_error(fields, slow_fields(s.kernels, grid, s.weights, c.lambda_um, c.shift_scale));
}

TEST(FftEngineTest, MatchesTheSlowSumForThreeViewsObliqueLightAndAShiftScale) {
    EngineCase c;
    c.views = 3;
    c.shift_scale = 0.7;
    c.wx = 0.3;
    c.wy = -0.45;
    EXPECT_LE(engine_error(c, 1e-6), 1e-6);
}

TEST(FftEngineTest, MatchesTheSlowSumWithSteepSlopesWhoseSpectraLeaveTheWindow) {
    EngineCase c;
    c.amplitude = 6.0;  // slopes of order 1–3: many spectra partly or wholly outside
    c.wx = -0.5;
    detail::FftGridInfo info;
    EXPECT_LE(engine_error(c, 1e-6, &info), 1e-6);
    EXPECT_LT(info.kept, make_setup(c).kernels.size());  // some kernels skipped by the bound
}

TEST(FftEngineTest, FoldsAFootprintLargerThanThePeriod) {
    EngineCase c;
    c.n = 12;  // period P = nλ/2 = 3 µm, footprint ±3σ_p = ±15 µm
    c.sigma_p_um = 5.0;
    c.views = 2;
    EXPECT_LE(engine_error(c, 1e-6), 1e-6);
}

TEST(FftEngineTest, OddSliceSize) {
    EngineCase c;
    c.n = 37;
    c.wy = 0.2;
    EXPECT_LE(engine_error(c, 1e-6), 1e-6);
}

TEST(FftEngineTest, ErrorFollowsTheTolerance) {
    EngineCase c;
    c.wx = 0.2;
    const double loose = engine_error(c, 1e-3), tight = engine_error(c, 1e-10);
    EXPECT_LE(loose, 1e-3);
    EXPECT_LE(tight, 1e-10);
    EXPECT_GT(loose, 1e3 * tight);  // the loose grid is really coarser
}

TEST(FftEngineTest, FloatEngineWithinFloatAccuracy) {
    EngineCase c;
    c.views = 2;
    c.wx = 0.1;
    const Fixture s = make_setup(c);
    const SliceGrid grid(s.query, c.lambda_um, c.n);
    FftEngine<float> engine(s.kernels, grid, c.lambda_um, c.n, 1e-6);
    std::vector<ComplexMatrix<float>> fields;
    engine.forward(s.weights, 1.0, fields);
    EXPECT_LE(relative_error(fields, slow_fields(s.kernels, grid, s.weights, c.lambda_um, 1.0)), 2e-6);
}

TEST(FftEngineTest, MatchesTheSeparablePathForOhs) {
    for (const double wx : {0.0, 0.4}) {
        EngineCase c;
        c.n = 64;
        c.wx = wx;
        const Fixture s = make_setup(c);
        const SliceGrid grid(s.query, c.lambda_um, c.n);
        detail::SeparableEngine<double> product(s.kernels, grid, c.lambda_um, c.n);
        std::vector<ComplexMatrix<double>> products;
        product.forward(s.weights, 1.0, products);
        const ComplexMatrix<double>& separable = products[0];
        FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, 1e-6);
        std::vector<ComplexMatrix<double>> fields;
        engine.forward(s.weights, 1.0, fields);
        EXPECT_LE((fields[0] - separable).cwiseAbs().maxCoeff(), 1e-6 * separable.cwiseAbs().maxCoeff());
    }
}

// L = 2 Re Σ_v Σ_pq B_v F_v, so B_v = ∂L/∂F_v in the FieldEngine's convention.
double engine_loss(FftEngine<double>& engine, const KernelWeights& w, double shift_scale,
            const std::vector<ComplexMatrix<double>>& b) {
    std::vector<ComplexMatrix<double>> fields;
    engine.forward(w, shift_scale, fields);
    double sum = 0.0;
    for (std::size_t v = 0; v < b.size(); ++v) sum += 2.0 * (b[v].cwiseProduct(fields[v])).sum().real();
    return sum;
}

std::vector<ComplexMatrix<double>> random_cotangents(int views, int n, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    std::vector<ComplexMatrix<double>> b(static_cast<std::size_t>(views), ComplexMatrix<double>(n, n));
    for (auto& m : b)
        for (Eigen::Index i = 0; i < m.size(); ++i) m(i) = Cd(normal(rng), normal(rng));
    return b;
}

TEST(FftEngineTest, AdjointIdentityForTheWeights) {
    EngineCase c;
    c.views = 2;
    c.wx = 0.3;
    c.shift_scale = 1.3;
    const Fixture s = make_setup(c);
    const SliceGrid grid(s.query, c.lambda_um, c.n);
    FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, 1e-8);
    const auto b = random_cotangents(c.views, c.n, 3);
    FieldGradient gradient;
    engine.adjoint(s.weights, c.shift_scale, b, gradient);
    // ⟨J x, B⟩ = ⟨x, Jᵀ B⟩ for random weight vectors x (the forward is linear in them).
    KernelWeights x = s.weights;
    std::mt19937_64 rng(5);
    std::normal_distribution<double> normal;
    for (auto& v : x)
        for (auto& e : v) e = Cd(normal(rng), normal(rng));
    std::vector<ComplexMatrix<double>> fields;
    engine.forward(x, c.shift_scale, fields);
    Cd lhs = 0.0, rhs = 0.0;
    double scale = 0.0;
    for (std::size_t v = 0; v < x.size(); ++v) {
        lhs += b[v].cwiseProduct(fields[v]).sum();
        for (std::size_t k = 0; k < x[v].size(); ++k) {
            rhs += gradient.weight[v][k] * x[v][k];
            scale += std::abs(gradient.weight[v][k] * x[v][k]);
        }
    }
    EXPECT_LE(std::abs(lhs - rhs), 1e-12 * scale);
    // And the gradient against the transpose of the slow sum, Σ_pq B G_k.
    const double s2 = s.kernels.sigma_um * s.kernels.sigma_um;
    double err = 0.0, peak = 0.0;
    for (std::size_t k = 0; k < s.kernels.size(); k += 7) {
        const double bx = c.shift_scale * 2.0 / c.lambda_um * s.kernels.slope_x[k];
        const double by = c.shift_scale * 2.0 / c.lambda_um * s.kernels.slope_y[k];
        Cd sum = 0.0, sum_dx = 0.0;
        for (int p = 0; p < c.n; ++p)
            for (int q = 0; q < c.n; ++q) {
                const double ax = grid.ux[std::size_t(p)] + bx, ay = grid.uy[std::size_t(q)] + by;
                const Cd g = std::exp(-2.0 * k_pi * k_pi * s2 * (ax * ax + ay * ay)) *
                             std::polar(1.0, -2.0 * k_pi *
                                                 (grid.ux[std::size_t(p)] * s.kernels.dx_um[k] +
                                                  grid.uy[std::size_t(q)] * s.kernels.dy_um[k]));
                sum += b[0](p, q) * g;
                sum_dx += b[0](p, q) * (-4.0 * k_pi * k_pi * s2 * ax) * g;
            }
        double shift = 0.0;  // views 0 and 1 both contribute
        for (std::size_t v = 0; v < x.size(); ++v) {
            Cd dv = 0.0;
            for (int p = 0; p < c.n; ++p)
                for (int q = 0; q < c.n; ++q) {
                    const double ax = grid.ux[std::size_t(p)] + bx, ay = grid.uy[std::size_t(q)] + by;
                    dv += b[v](p, q) * (-4.0 * k_pi * k_pi * s2 * ax) *
                          std::exp(-2.0 * k_pi * k_pi * s2 * (ax * ax + ay * ay)) *
                          std::polar(1.0, -2.0 * k_pi *
                                              (grid.ux[std::size_t(p)] * s.kernels.dx_um[k] +
                                               grid.uy[std::size_t(q)] * s.kernels.dy_um[k]));
                }
            shift += 2.0 * std::real(s.weights[v][k] * dv);
        }
        peak = std::max(peak, std::abs(sum));
        err = std::max(err, std::abs(gradient.weight[0][k] - sum));
        EXPECT_NEAR(gradient.shift_x[k], shift, 1e-6 * (std::abs(shift) + 1.0)) << "kernel " << k;
        (void)sum_dx;
    }
    EXPECT_LE(err, 1e-7 * peak);
}

TEST(FftEngineTest, ShiftGradientMatchesFiniteDifferences) {
    EngineCase c;
    c.views = 2;
    c.wy = 0.25;
    c.shift_scale = 0.8;
    c.amplitude = 1.0;
    Fixture s = make_setup(c);
    const SliceGrid grid(s.query, c.lambda_um, c.n);
    FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, 1e-10);
    const auto b = random_cotangents(c.views, c.n, 9);
    FieldGradient gradient;
    engine.adjoint(s.weights, c.shift_scale, b, gradient);
    // A random direction in the slopes; the engine reads them at every call.
    const std::vector<double> dx = test::uniform_vector(s.kernels.size(), -1.0, 1.0, 21);
    const std::vector<double> dy = test::uniform_vector(s.kernels.size(), -1.0, 1.0, 22);
    const double db_ds = c.shift_scale * 2.0 / c.lambda_um;
    double predicted = 0.0;
    for (std::size_t k = 0; k < s.kernels.size(); ++k)
        predicted += (gradient.shift_x[k] * dx[k] + gradient.shift_y[k] * dy[k]) * db_ds;
    const double eps = 1e-5;
    const FootprintKernels original = s.kernels;
    auto at = [&](double t) {
        for (std::size_t k = 0; k < s.kernels.size(); ++k) {
            s.kernels.slope_x[k] = original.slope_x[k] + t * dx[k];
            s.kernels.slope_y[k] = original.slope_y[k] + t * dy[k];
        }
        return engine_loss(engine, s.weights, c.shift_scale, b);
    };
    const double fd = (at(eps) - at(-eps)) / (2.0 * eps);
    EXPECT_NEAR(fd, predicted, 1e-6 * std::abs(predicted));
}

TEST(FftEngineTest, RefusesBadArgumentsAndHostileSizesBeforeAllocating) {
    EngineCase c;
    Fixture s = make_setup(c);
    const SliceGrid grid(s.query, c.lambda_um, c.n);
    EXPECT_THROW(FftEngine<double>(s.kernels, grid, c.lambda_um, c.n, 0.5), std::domain_error);
    EXPECT_THROW(FftEngine<double>(s.kernels, grid, -1.0, c.n, 1e-6), std::domain_error);
    EXPECT_THROW(FftEngine<double>(s.kernels, grid, c.lambda_um, c.n + 1, 1e-6), std::invalid_argument);
    FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, 1e-6);
    std::vector<ComplexMatrix<double>> fields;
    KernelWeights short_weights{std::vector<Cd>(3, 1.0)};
    EXPECT_THROW(engine.forward(short_weights, 1.0, fields), std::invalid_argument);
    EXPECT_THROW(engine.forward(s.weights, std::numeric_limits<double>::infinity(), fields), std::domain_error);
    // A tiny σ makes every spectrum wide: the grid it needs is refused before any allocation.
    s.kernels.sigma_um = 1e-5;
    const int n = 4096;
    const SliceGrid big(s.query, c.lambda_um, n);
    FftEngine<double> hostile(s.kernels, big, c.lambda_um, n, 1e-6);
    EXPECT_THROW(hostile.forward(s.weights, 1.0, fields), OutOfMemory);
    // A huge σ against a tiny period: kernel vectors of ~1e9 points are refused too.
    s.kernels.sigma_um = 1e6;
    const SliceGrid one(s.query, 0.01, 1);
    FftEngine<double> wide(s.kernels, one, 0.01, 1, 1e-6);
    EXPECT_THROW(wide.forward(s.weights, 1.0, fields), OutOfMemory);
}

TEST(FftEngineTest, GoodFftSizes) {
    EXPECT_EQ(detail::good_fft_size(1), 1);
    EXPECT_EQ(detail::good_fft_size(7), 8);
    EXPECT_EQ(detail::good_fft_size(1025), 1080);
    EXPECT_EQ(detail::good_fft_size(1024), 1024);
    EXPECT_EQ(detail::good_fft_size(121), 125);
}

// The cost model's grid bounds the engine's (it assumes the steepest slope on both axes), and
// its choice follows the costs: the product for small slices, the FFT for large footprints.
TEST(FftEngineTest, CostModelGridBoundsTheEnginesAndPicksByCost) {
    for (const double amplitude : {0.3, 3.0}) {
        EngineCase c;
        c.amplitude = amplitude;
        c.wx = 0.3;
        const Fixture s = make_setup(c);
        const SliceGrid grid(s.query, c.lambda_um, c.n);
        FftEngine<double> engine(s.kernels, grid, c.lambda_um, c.n, 1e-6);
        const detail::FftGridInfo info = engine.plan_grid(1.0);
        detail::FieldPathInputs in;
        in.n = c.n;
        in.lambda_um = c.lambda_um;
        in.kernels = s.kernels.size();
        in.texel_um = 1.0;
        for (std::size_t k = 0; k < s.kernels.size(); ++k)
            in.max_slope = std::max({in.max_slope, std::abs(s.kernels.slope_x[k]), std::abs(s.kernels.slope_y[k])});
        in.omega_ix = c.wx;
        const detail::FieldPathCost cost = detail::field_path_cost(in);
        EXPECT_GE(cost.fft_grid, std::max(info.mx, info.my)) << amplitude;
        EXPECT_LE(cost.fft_grid, 2 * std::max(info.mx, info.my)) << amplitude;
        EXPECT_GE(cost.fft_span, info.span_x);
    }
    detail::FieldPathInputs small;
    small.n = 16;
    small.kernels = 10;
    small.max_slope = 0.1;
    EXPECT_EQ(detail::choose_field_path(small), RenderPath::Separable);
    detail::FieldPathInputs large = small;
    large.n = 1024;
    large.kernels = 70000;
    EXPECT_EQ(detail::choose_field_path(large), RenderPath::Fft);
    large.n = 0;
    EXPECT_THROW(detail::field_path_cost(large), std::invalid_argument);
}

}  // namespace
}  // namespace wavebrdf
