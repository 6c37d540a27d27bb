// The point-evaluation engine against independent evaluations: render_slice's direct sum at
// slice pixel centres (every model), central finite differences and the dot-product identity for
// its adjoint, and the stated pruning bound against the unpruned sum.
#include "wavebrdf/point_eval.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/gabor.h"

namespace wavebrdf {
namespace {

using test::random_heightfield;

const Model k_models[] = {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff};

// Samples at the centres of slice pixels (row p, column q) of an n × n slice, with random
// footprints and lights.
struct SliceSample {
    PointSample sample;
    int p, q;
};

std::vector<SliceSample> random_slice_samples(int count, int n, double period_um, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<SliceSample> out;
    while (static_cast<int>(out.size()) < count) {
        SliceSample s;
        s.p = static_cast<int>(uni(rng) * n);
        s.q = static_cast<int>(uni(rng) * n);
        const double ox = slice_omega(s.p, n), oy = slice_omega(s.q, n);
        if (ox * ox + oy * oy > 0.9) continue;
        s.sample.omega_o = {ox, oy};
        s.sample.omega_i = {0.6 * (uni(rng) - 0.5), 0.6 * (uni(rng) - 0.5)};
        s.sample.x_um = uni(rng) * period_um * 3.0 - period_um;  // also outside the first tile
        s.sample.y_um = uni(rng) * period_um;
        s.sample.sigma_p_um = 1.5 + 4.0 * uni(rng);
        out.push_back(s);
    }
    return out;
}

TEST(PointEval, EqualsRenderSliceAtPixelCentresForEveryModel) {
    const Heightfield hf = random_heightfield(24, 20, 0.3, 11, 0.8, 1.0);
    const int n = 33;
    const std::vector<double> lambdas = {0.45, 0.63};
    RenderOptions direct;
    direct.path = RenderPath::Direct;
    direct.prune_tolerance = 0.0;
    for (Model model : k_models) {
        const auto samples = random_slice_samples(12, n, hf.period_x_um(), 5 + static_cast<int>(model));
        PointEvalOptions options;
        options.model = model;
        const PointEvaluator eval(hf, lambdas, options);
        std::vector<PointSample> points;
        for (const auto& s : samples) points.push_back(s.sample);
        std::vector<double> values(points.size() * lambdas.size());
        eval.evaluate(points.data(), points.size(), values.data());
        for (std::size_t s = 0; s < samples.size(); ++s) {
            Query q;
            q.model = model;
            q.x_um = points[s].x_um;
            q.y_um = points[s].y_um;
            q.sigma_p_um = points[s].sigma_p_um;
            q.omega_i = points[s].omega_i;
            for (std::size_t l = 0; l < lambdas.size(); ++l) {
                const std::vector<double> slice = render_slice<double>(hf, q, lambdas[l], n, direct);
                const double expected = slice[static_cast<std::size_t>(samples[s].p) * n + samples[s].q];
                const double got = values[s * lambdas.size() + l];
                ASSERT_GT(expected, 0.0);
                EXPECT_LE(std::abs(got - expected), 1e-6 * expected)
                    << to_string(model) << " sample " << s << " lambda " << lambdas[l] << ": " << got << " vs "
                    << expected;
            }
        }
    }
}

// A loss Σ W f over samples and wavelengths, for the gradient checks.
double weighted_sum(const PointEvaluator& eval, const std::vector<PointSample>& points, const std::vector<double>& w) {
    std::vector<double> values(w.size());
    eval.evaluate(points.data(), points.size(), values.data());
    double sum = 0.0;
    for (std::size_t i = 0; i < w.size(); ++i) sum += w[i] * values[i];
    return sum;
}

TEST(PointEval, AdjointMatchesFiniteDifferencesAndTangent) {
    const Heightfield hf = random_heightfield(12, 14, 0.25, 3, 1.0, 1.0);
    const std::vector<double> lambdas = {0.5, 0.7};
    for (Model model : k_models) {
        PointEvalOptions options;
        options.model = model;
        const auto samples = random_slice_samples(5, 17, hf.period_x_um(), 40 + static_cast<int>(model));
        std::vector<PointSample> points;
        for (const auto& s : samples) points.push_back(s.sample);
        const std::vector<double> w = test::uniform_vector(points.size() * lambdas.size(), 0.2, 1.0, 9);
        const PointEvaluator eval(hf, lambdas, options);
        std::vector<double> gradient;
        eval.adjoint(points.data(), points.size(), w.data(), gradient);
        ASSERT_EQ(gradient.size(), hf.values().size());
        // Central differences on a few texels, the ones with the largest gradient among them.
        const double h = 1e-5;
        double scale = test::max_abs(gradient);
        ASSERT_GT(scale, 0.0);
        for (std::size_t t : {std::size_t(0), std::size_t(17), std::size_t(55), std::size_t(100), std::size_t(167)}) {
            std::vector<double> up = hf.values(), down = hf.values();
            up[t] += h;
            down[t] -= h;
            const double fd = (weighted_sum(PointEvaluator(hf.with_values(up), lambdas, options), points, w) -
                               weighted_sum(PointEvaluator(hf.with_values(down), lambdas, options), points, w)) /
                              (2.0 * h);
            EXPECT_NEAR(gradient[t], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << to_string(model) << " texel " << t;
        }
        // Dot-product identity ⟨J x, W⟩ = ⟨x, Jᵀ W⟩ for a random direction x.
        const std::vector<double> x = test::uniform_vector(hf.values().size(), -1.0, 1.0, 21);
        std::vector<double> jx(w.size());
        eval.tangent(points.data(), points.size(), x, jx.data());
        double lhs = 0.0, rhs = 0.0;
        for (std::size_t i = 0; i < w.size(); ++i) lhs += jx[i] * w[i];
        for (std::size_t i = 0; i < x.size(); ++i) rhs += x[i] * gradient[i];
        EXPECT_NEAR(lhs, rhs, 1e-10 * (std::abs(lhs) + std::abs(rhs))) << to_string(model);
        // Shifting every height by one constant changes no value: the gradient sums to zero.
        double total = 0.0;
        for (double g : gradient) total += g;
        EXPECT_NEAR(total, 0.0, 1e-9 * scale * static_cast<double>(gradient.size())) << to_string(model);
    }
}

TEST(PointEval, PrunedValuesWithinTheirStatedBound) {
    const Heightfield hf = random_heightfield(64, 64, 0.8, 8, 1.0, 1.0);
    const std::vector<double> lambdas = {0.4, 0.55, 0.7};
    for (Model model : {Model::OHS, Model::Kirchhoff}) {
        std::vector<PointSample> points;
        for (int p = 0; p < 40; ++p)
            for (const double ox : {-0.6, -0.2, 0.3, 0.7}) {
                PointSample s;
                s.x_um = 1.7 * p;
                s.y_um = 3.1 * p;
                s.sigma_p_um = 6.0;
                s.omega_i = {0.3, -0.2};
                s.omega_o = {ox, 0.1};
                points.push_back(s);
            }
        PointEvalOptions exact;
        exact.model = model;
        const PointEvaluator full(hf, lambdas, exact);
        std::vector<double> reference(points.size() * lambdas.size());
        full.evaluate(points.data(), points.size(), reference.data());
        for (double tau : {1e-2, 1e-4}) {
            PointEvalOptions pruned = exact;
            pruned.prune_tolerance = tau;
            const PointEvaluator eval(hf, lambdas, pruned);
            std::vector<double> values(reference.size()), bound(reference.size());
            eval.evaluate(points.data(), points.size(), values.data(), bound.data());
            double differs = 0.0;
            for (std::size_t i = 0; i < values.size(); ++i) {
                EXPECT_LE(std::abs(values[i] - reference[i]), bound[i] * (1.0 + 1e-9) + 1e-300)
                    << to_string(model) << " tau " << tau << " value " << i;
                differs = std::max(differs, std::abs(values[i] - reference[i]));
            }
            // The pruning must actually skip something at these directions, or the test tests nothing.
            EXPECT_GT(differs, 0.0) << to_string(model) << " tau " << tau;
        }
    }
}

TEST(PointEval, SinglePrecisionWithinItsStatedError) {
    const Heightfield hf = random_heightfield(64, 64, 0.8, 8, 1.0, 1.0);
    const std::vector<double> lambdas = {0.4, 0.55, 0.7};
    for (Model model : {Model::OHS, Model::GHS, Model::Kirchhoff}) {
        std::vector<PointSample> points;
        for (int p = 0; p < 60; ++p) {
            PointSample s;
            s.x_um = 1.7 * p + 300.0;  // far from the origin: large offsets, large phases
            s.y_um = 3.1 * p - 200.0;
            s.sigma_p_um = 8.0;
            s.omega_i = {0.3, -0.2};
            s.omega_o = {-0.6 + 0.02 * p, 0.1};
            points.push_back(s);
        }
        PointEvalOptions options;
        options.model = model;
        const PointEvaluator full(hf, lambdas, options);
        options.single_precision = true;
        const PointEvaluator single(hf, lambdas, options);
        std::vector<double> a(points.size() * lambdas.size()), b(a.size());
        full.evaluate(points.data(), points.size(), a.data());
        single.evaluate(points.data(), points.size(), b.data());
        // Relative to c1 A², the footprint's largest possible value: for OHS-type c1 ≤ 1/(λ² cos θ_i)
        // and A = Σ c_k w² over a footprint away from the tile's seams (|C2| ≤ 2 + 2|s| for Kirchhoff).
        double amplitude = 0.0;
        for (double w : footprint_kernels(hf, 32.0, 32.0, 8.0).weight) amplitude += w;
        for (std::size_t i = 0; i < a.size(); ++i) {
            const double lambda = lambdas[i % lambdas.size()];
            const double scale = (model == Model::Kirchhoff ? 9.0 : 1.0) * amplitude * amplitude /
                                 (lambda * lambda * std::sqrt(1 - 0.13));
            EXPECT_LE(std::abs(a[i] - b[i]), 1e-5 * scale) << to_string(model) << " value " << i;
        }
        EXPECT_NE(a, b);  // it did run in float
    }
}

TEST(PointEval, RefusesBadInput) {
    const Heightfield hf = random_heightfield(8, 8, 0.1, 1);
    test::expect_throw_naming<std::domain_error>(
        [&] {
            PointEvaluator(hf, {0.5}, {Model::OHS, 0.5});
        },
        "prune tolerance 0.5");
    test::expect_throw_naming<std::domain_error>([&] { PointEvaluator(hf, {-1.0}, {}); }, "wavelength -1");
    test::expect_throw_naming<std::invalid_argument>([&] { PointEvaluator(hf, {}, {}); }, "0 wavelengths");
    PointSample s;
    s.sigma_p_um = 2.0;
    s.omega_o = {0.9, 0.5};
    test::expect_throw_naming<std::domain_error>([&] { validate(s, hf); }, "view direction (0.9, 0.5)");
    s.omega_o = {0.0, 0.0};
    s.sigma_p_um = 1000.0;
    test::expect_throw_naming<std::domain_error>([&] { validate(s, hf); }, "too large for the tile");
}

}  // namespace
}  // namespace wavebrdf
