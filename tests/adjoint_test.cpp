// Tests of the hand-derived adjoints: finite differences (double), the dot-product identity
// against the tangent of the direct sum, height-offset invariance, and path agreement.
#include <gtest/gtest.h>

#include <random>

#include "test_util.h"
#include "wavebrdf/adjoint.h"

using namespace wavebrdf;
using wavebrdf::test::make_query;
using wavebrdf::test::random_heightfield;
using wavebrdf::test::uniform_vector;

namespace {

const Model kModels[] = {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff};

RenderOptions with_path(RenderPath path) {
    RenderOptions o;
    o.path = path;
    o.prune_tolerance = 0.0;  // the exact sum, so finite differences see the same function
    return o;
}

double loss(const Heightfield& hf, const Query& q, double lambda, int n, const std::vector<double>& w,
            RenderPath path) {
    const auto f = render_slice<double>(hf, q, lambda, n, with_path(path));
    double sum = 0.0;
    for (std::size_t i = 0; i < f.size(); ++i) sum += w[i] * f[i];
    return sum;
}

std::vector<RenderPath> paths_for(Model m) {
    if (is_separable(m)) return {RenderPath::Separable, RenderPath::Direct};
    return {RenderPath::Direct};
}

}  // namespace

TEST(AdjointTest, GradientMatchesFiniteDifferences) {
    const Heightfield hf = random_heightfield(14, 12, 0.35, 17, 0.9, 1.2);
    const int n = 20;
    const double lambda = 0.6;
    const auto weights = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 3);
    for (Model m : kModels) {
        const Query q = make_query(m, 5.5, 6.0, 2.2, 0.15, -0.2);  // footprint wraps the tile
        for (RenderPath path : paths_for(m)) {
            std::vector<double> grad;
            slice_gradient<double>(hf, q, lambda, n, weights, grad, with_path(path));
            double scale = 0.0;
            for (double g : grad) scale = std::max(scale, std::abs(g));
            ASSERT_GT(scale, 0.0);
            const double h = 1e-5;
            for (std::size_t cell = 0; cell < grad.size(); cell += 7) {
                std::vector<double> plus = hf.values(), minus = hf.values();
                plus[cell] += h;
                minus[cell] -= h;
                const double fd = (loss(hf.with_values(plus), q, lambda, n, weights, path) -
                                   loss(hf.with_values(minus), q, lambda, n, weights, path)) /
                                  (2 * h);
                EXPECT_LE(std::abs(fd - grad[cell]), 1e-6 * scale)
                    << to_string(m) << " path " << int(path) << " cell " << cell;
            }
        }
    }
}

TEST(AdjointTest, DotProductIdentityWithTheTangent) {
    const Heightfield hf = random_heightfield(16, 18, 0.4, 23, 1.0, 1.0);
    const int n = 24;
    const double lambda = 0.5;
    const auto y = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 5);
    const auto x = uniform_vector(hf.values().size(), -1.0, 1.0, 6);
    for (Model m : kModels) {
        const Query q = make_query(m, 8.0, 9.0, 2.5, -0.1, 0.3);
        const auto jx = slice_tangent_direct(hf, q, lambda, n, x);
        double lhs = 0.0;
        for (std::size_t i = 0; i < jx.size(); ++i) lhs += jx[i] * y[i];
        for (RenderPath path : paths_for(m)) {
            std::vector<double> jty;
            slice_gradient<double>(hf, q, lambda, n, y, jty, with_path(path));
            double rhs = 0.0, mag = 0.0;
            for (std::size_t i = 0; i < jty.size(); ++i) {
                rhs += x[i] * jty[i];
                mag += std::abs(x[i] * jty[i]);
            }
            EXPECT_LE(std::abs(lhs - rhs), 1e-11 * mag) << to_string(m) << " path " << int(path);
        }
    }
}

TEST(AdjointTest, GradientSumsToZero) {
    // Adding a constant to every height changes no slice, so the gradient has zero sum.
    const Heightfield hf = random_heightfield(20, 20, 0.4, 29, 1.0, 1.0);
    const int n = 24;
    const auto w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 8);
    for (Model m : kModels) {
        const Query q = make_query(m, 10.0, 10.0, 3.0, 0.2, 0.1);
        std::vector<double> grad;
        slice_gradient<double>(hf, q, 0.55, n, w, grad);
        double sum = 0.0, mag = 0.0;
        for (double g : grad) {
            sum += g;
            mag += std::abs(g);
        }
        EXPECT_LE(std::abs(sum), 1e-10 * mag) << to_string(m);
    }
}

TEST(AdjointTest, SeparableAndDirectGradientsAgree) {
    const Heightfield hf = random_heightfield(40, 36, 0.4, 31, 1.0, 1.0);
    const int n = 32;
    const auto w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 9);
    for (Model m : {Model::OHS, Model::ROHS}) {
        const Query q = make_query(m, 3.0, 30.0, 4.0, 0.25, -0.3);
        std::vector<double> gs, gd;
        slice_gradient<double>(hf, q, 0.45, n, w, gs, with_path(RenderPath::Separable));
        slice_gradient<double>(hf, q, 0.45, n, w, gd, with_path(RenderPath::Direct));
        EXPECT_LT(test::max_abs_diff(gs, gd), 1e-10 * test::max_abs(gd)) << to_string(m);
    }
}

// With more kernels than one chunk of factors (> 2048), the adjoint rebuilds the factors chunk
// by chunk instead of reusing the forward's: that path must agree with the direct sum too.
TEST(AdjointTest, ChunkedSeparableGradientAgreesWithDirect) {
    const Heightfield hf = random_heightfield(100, 100, 0.3, 41, 1.0, 1.0);
    const int n = 24;
    const auto w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 12);
    const Query q = make_query(Model::OHS, 50.0, 40.0, 16.0, 0.1, 0.2);
    ASSERT_GT(footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um).size(), 4096u);
    std::vector<double> gs, gd;
    slice_gradient<double>(hf, q, 0.5, n, w, gs, with_path(RenderPath::Separable));
    slice_gradient<double>(hf, q, 0.5, n, w, gd, with_path(RenderPath::Direct));
    EXPECT_LT(test::max_abs_diff(gs, gd), 1e-10 * test::max_abs(gd));
}

TEST(AdjointTest, FloatGradientAgreesWithDouble) {
    const Heightfield hf = random_heightfield(48, 48, 0.4, 37, 1.0, 1.0);
    const int n = 32;
    const auto w = uniform_vector(static_cast<std::size_t>(n) * n, -1.0, 1.0, 10);
    const std::vector<float> wf(w.begin(), w.end());
    const Query q = make_query(Model::OHS, 20.0, 20.0, 5.0, 0.0, 0.1);
    std::vector<double> gd, gf;
    slice_gradient<double>(hf, q, 0.5, n, w, gd);
    slice_gradient<float>(hf, q, 0.5, n, wf, gf);
    EXPECT_LT(test::max_abs_diff(gd, gf), 1e-3 * test::max_abs(gd));
}

TEST(AdjointTest, WeightsOfSliceCallbackSeesTheSlice) {
    const Heightfield hf = random_heightfield(24, 24, 0.3, 41, 1.0, 1.0);
    const Query q = make_query(Model::ROHS, 12.0, 12.0, 3.0, 0.0, 0.0);
    const int n = 16;
    const auto expected = render_slice<double>(hf, q, 0.5, n);
    std::vector<double> grad;
    std::vector<double> seen;
    const auto slice = slice_gradient<double>(
        hf, q, 0.5, n,
        std::function<std::vector<double>(const std::vector<double>&)>([&](const std::vector<double>& f) {
            seen = f;
            return std::vector<double>(f.size(), 1.0);
        }),
        grad);
    EXPECT_LT(test::max_abs_diff(seen, expected), 1e-12 * test::max_abs(expected));
    EXPECT_EQ(slice, seen);
}

TEST(AdjointTest, BadInputThrows) {
    const Heightfield hf = random_heightfield(8, 8, 0.3, 1, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 0, 0, 2.0, 0, 0);
    std::vector<double> grad;
    EXPECT_THROW(slice_gradient<double>(hf, q, 0.5, 8, std::vector<double>(10, 1.0), grad), std::invalid_argument);
    std::vector<double> wrong(5, 0.0);
    EXPECT_THROW(slice_gradient<double>(hf, q, 0.5, 8, std::vector<double>(64, 1.0), wrong), std::invalid_argument);
    EXPECT_THROW(slice_gradient<double>(hf, q, -0.5, 8, std::vector<double>(64, 1.0), grad), std::domain_error);
}
