// Error bars (uncertainty.h): the matrix-free Gauss–Newton product and the formed (band) G
// against the dense matrix from central differences of the renderer (no adjoint), the diagonal
// of its inverse (exact and probed) against the exact one, and the calibration: over Poisson
// noise draws the true error of a refined estimate lies within ±2σ for about 95 % of texels.
#include "wavebrdf/uncertainty.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/recover.h"

namespace wavebrdf {
namespace {

struct Tile {
    Heightfield truth;
    std::vector<Observation> observations;  // noiseless references
};

// A rows × rows tile (texel 2 µm, max |H| = 0.4 µm, correlation 6 µm) seen at a 4 µm raster of
// footprints σ_p = 3 µm (jittered), one wavelength, `resolution`² slices.
Tile make_tile(int rows, int resolution, std::uint64_t seed) {
    const Heightfield surface = test::peak_scaled_surface(rows, 6.0, 0.4, seed);
    Tile t{surface, {}};
    std::mt19937_64 rng(seed + 1);
    std::uniform_real_distribution<double> jitter(-0.3, 0.3);
    const int steps = rows * 2 / 4;
    for (int a = 0; a < steps; ++a)
        for (int b = 0; b < steps; ++b) {
            Observation o;
            o.query = test::make_query(Model::OHS, (a + 0.5 + jitter(rng)) * 4.0, (b + 0.5 + jitter(rng)) * 4.0, 3.0);
            o.lambdas_um = {0.5};
            o.resolution = resolution;
            o.reference = to_reference(render_observation(t.truth, o));
            t.observations.push_back(std::move(o));
        }
    return t;
}

// G in 1/µm² formed densely for the Poisson loss at N photons: J by central differences of
// render_observation (no adjoint), W = s² / (s I + 1e-9), s = N / Σ R.
std::vector<double> dense_gauss_newton(const std::vector<Observation>& observations, const Heightfield& at,
                                       double photons) {
    const std::size_t n = at.values().size();
    const double to_um = at.vscale() * at.texel_um(), delta = 1e-5;
    std::vector<double> g(n * n, 0.0);
    for (const Observation& o : observations) {
        const std::vector<double> f = render_observation(at, o);
        double total = 0.0;
        for (const float r : o.reference) total += static_cast<double>(r);
        const double s = photons / total;
        std::vector<std::vector<double>> j(n);
        for (std::size_t t = 0; t < n; ++t) {
            std::vector<double> plus = at.values(), minus = at.values();
            plus[t] += delta;
            minus[t] -= delta;
            const std::vector<double> fp = render_observation(at.with_values(plus), o);
            const std::vector<double> fm = render_observation(at.with_values(minus), o);
            j[t].resize(f.size());
            for (std::size_t p = 0; p < f.size(); ++p) j[t][p] = (fp[p] - fm[p]) / (2.0 * delta * to_um);
        }
        for (std::size_t p = 0; p < f.size(); ++p) {
            const double w = s * s / (s * std::max(f[p], 0.0) + 1e-9);
            for (std::size_t a = 0; a < n; ++a) {
                if (j[a][p] == 0.0) continue;
                const double wa = w * j[a][p];
                for (std::size_t b = 0; b < n; ++b) g[a * n + b] += wa * j[b][p];
            }
        }
    }
    return g;
}

// diag of G⁺ on the mean-free subspace: (G + c 11ᵀ/n)⁻¹ − 11ᵀ/(n c), by Gauss–Jordan.
std::vector<double> pseudo_inverse_diagonal(std::vector<double> g, std::size_t n) {
    double c = 0.0;
    for (std::size_t a = 0; a < n; ++a) c += g[a * n + a];
    c /= double(n);
    for (double& x : g) x += c / double(n);
    std::vector<double> inv(n * n, 0.0);
    for (std::size_t a = 0; a < n; ++a) inv[a * n + a] = 1.0;
    for (std::size_t k = 0; k < n; ++k) {
        std::size_t pivot = k;
        for (std::size_t a = k + 1; a < n; ++a)
            if (std::abs(g[a * n + k]) > std::abs(g[pivot * n + k])) pivot = a;
        for (std::size_t b = 0; b < n; ++b) {
            std::swap(g[k * n + b], g[pivot * n + b]);
            std::swap(inv[k * n + b], inv[pivot * n + b]);
        }
        const double d = g[k * n + k];
        for (std::size_t b = 0; b < n; ++b) {
            g[k * n + b] /= d;
            inv[k * n + b] /= d;
        }
        for (std::size_t a = 0; a < n; ++a) {
            if (a == k) continue;
            const double f = g[a * n + k];
            if (f == 0.0) continue;
            for (std::size_t b = 0; b < n; ++b) {
                g[a * n + b] -= f * g[k * n + b];
                inv[a * n + b] -= f * inv[k * n + b];
            }
        }
    }
    std::vector<double> diag(n);
    for (std::size_t a = 0; a < n; ++a) diag[a] = inv[a * n + a] - 1.0 / (double(n) * c);
    return diag;
}

const Loss k_poisson{LossKind::Poisson, 1.0, 1e4};

// The product G·v of the operator (forward difference + adjoint) equals the dense G's.
TEST(GaussNewtonOperator, ProductMatchesDenseMatrixFromForwardDifferences) {
    const Tile t = make_tile(8, 32, 5301);
    const std::size_t n = 64;
    const std::vector<double> g = dense_gauss_newton(t.observations, t.truth, k_poisson.photons);
    const GaussNewtonOperator op(t.observations, t.truth, k_poisson);
    EXPECT_EQ(op.noise_variance(), 1.0);
    const std::vector<double> v1 = test::uniform_vector(n, -1.0, 1.0, 5302);
    std::vector<double> v2(n, 0.0);
    v2[9] = 0.3;  // one column
    const auto out = op.apply({v1, v2});
    for (int k = 0; k < 2; ++k) {
        const std::vector<double>& v = k == 0 ? v1 : v2;
        std::vector<double> expect(n, 0.0);
        for (std::size_t a = 0; a < n; ++a)
            for (std::size_t b = 0; b < n; ++b) expect[a] += g[a * n + b] * v[b];
        EXPECT_LT(test::max_abs_diff(out[std::size_t(k)], expect), 1e-5 * test::max_abs(expect)) << "vector " << k;
    }
    // The piston is in the null space: G·1 = 0.
    const auto piston = op.apply({std::vector<double>(n, 1.0)});
    EXPECT_LT(test::max_abs(piston[0]), 1e-6 * test::max_abs(out[0]));
}

// G formed (band: one forward difference per box texel, Jᵀ W J) against the dense G from
// central differences of render_observation, and its sparse product against the matrix-free
// one (forward difference + adjoint). 8²: every axis full.
TEST(GaussNewtonOperator, FormedBandMatchesDenseMatrixAndMatrixFreeProduct) {
    const Tile t = make_tile(8, 32, 5805);
    const std::size_t n = 64;
    const std::vector<double> g = dense_gauss_newton(t.observations, t.truth, k_poisson.photons);
    const GaussNewtonOperator op(t.observations, t.truth, k_poisson);
    const GaussNewtonBand band = op.band();
    EXPECT_TRUE(band.full_rows && band.full_cols);
    EXPECT_GT(band.forwards, 0);
    const std::vector<double> formed = band.dense();
    ASSERT_EQ(formed.size(), n * n);
    EXPECT_LT(test::max_abs_diff(formed, g), 1e-5 * test::max_abs(g));
    const std::vector<double> v = test::uniform_vector(n, -1.0, 1.0, 5806);
    const std::vector<double> free = op.apply({v})[0];
    EXPECT_LT(test::max_abs_diff(band.multiply(v), free), 1e-5 * test::max_abs(free));
}

// A tile larger than twice the boxes stores a band of offsets (not every texel pair): its
// product still equals the matrix-free one, and it is symmetric.
TEST(GaussNewtonOperator, BandOfOffsetsOnALargerTile) {
    const Tile t = make_tile(24, 16, 5807);
    const std::size_t n = 576;
    const GaussNewtonOperator op(t.observations, t.truth, k_poisson);
    const GaussNewtonBand band = op.band();
    EXPECT_FALSE(band.full_rows || band.full_cols);
    EXPECT_LT(band.width(), n);
    const std::vector<double> v = test::uniform_vector(n, -1.0, 1.0, 5808);
    const std::vector<double> free = op.apply({v})[0];
    // Both are forward differences (step 1e-7 µm), the band's per texel, the free one along v:
    // they agree to 1.2e-5 of the largest value with clang 14, less with GCC 12; a wrong band
    // (an offset misplaced, a texel left out) is off by O(1).
    EXPECT_LT(test::max_abs_diff(band.multiply(v), free), 3e-5 * test::max_abs(free));
    const std::vector<double> dense = band.dense();
    double asymmetry = 0.0;
    for (std::size_t a = 0; a < n; ++a)
        for (std::size_t b = 0; b < n; ++b)
            asymmetry = std::max(asymmetry, std::abs(dense[a * n + b] - dense[b * n + a]));
    EXPECT_LT(asymmetry, 1e-12 * test::max_abs(dense));
}

// G's diagonal alone (one forward difference per box texel, each column dotted with itself)
// against the dense G's from central differences of render_observation, and the lower bound it
// gives: √(mean (1 − 1/n)² / G_ii) is at most the exact bars' √(mean σ²) (Cauchy–Schwarz; a
// bound without the (1 − 1/n)² or taken as 1 / mean G_ii the wrong way would not be a bound
// on every tile), and no trivial one (here within a factor of 10 of the bars). A texel no slice
// depends on has G_ii = 0: no bound.
TEST(GaussNewtonOperator, DiagonalMatchesDenseMatrixAndBoundsTheErrorBars) {
    const Tile t = make_tile(8, 32, 5809);
    const std::size_t n = 64;
    const std::vector<double> g = dense_gauss_newton(t.observations, t.truth, k_poisson.photons);
    const GaussNewtonOperator op(t.observations, t.truth, k_poisson);
    std::int64_t forwards = 0;
    const std::vector<double> diagonal = op.diagonal(&forwards);
    ASSERT_EQ(diagonal.size(), n);
    EXPECT_EQ(forwards, op.band().forwards);
    double largest = 0.0;
    for (std::size_t a = 0; a < n; ++a) largest = std::max(largest, g[a * n + a]);
    for (std::size_t a = 0; a < n; ++a) EXPECT_NEAR(diagonal[a], g[a * n + a], 1e-5 * largest) << "texel " << a;
    const std::vector<double> exact = pseudo_inverse_diagonal(g, n);
    double mean_variance = 0.0;
    for (double v : exact) mean_variance += v / double(n);
    const double bars = std::sqrt(mean_variance), bound = fisher_rms_error_lower_bound_um(diagonal);
    std::printf("rms error: the bars %.4g um, the bound from the diagonal %.4g um\n", bars, bound);
    EXPECT_GT(bound, 0.0);
    EXPECT_LE(bound, bars);
    EXPECT_GT(bound, 0.1 * bars);
    std::vector<double> unseen = diagonal;
    unseen[7] = 0.0;
    EXPECT_EQ(fisher_rms_error_lower_bound_um(unseen), HUGE_VAL);
    EXPECT_EQ(fisher_rms_error_lower_bound_um({3.0}), 0.0);
}

// The diagonal of G⁺ against the exact one (the dense G from central differences of the
// renderer, inverted by Gauss–Jordan). The default (formed G, Cholesky) is exact up to the
// forward differences: σ within 1e-4. Probing on the formed G (dense_max_texels 0) with one
// probe per texel (spacing 8 on 8²) is exact up to CG (σ within 0.1 %); spacing 4 errs by the
// covariances of texels 4 apart (8² tile: σ within 12 % on average, 35 % at worst; measured
// in docs/recovery.md, Error bars).
TEST(HeightUncertainty, MatchesTheExactDiagonalOfTheInverse) {
    const Tile t = make_tile(8, 32, 5303);
    const std::size_t n = 64;
    const std::vector<double> exact = pseudo_inverse_diagonal(dense_gauss_newton(t.observations, t.truth, 1e4), n);
    for (int spacing : {0, 8, 4}) {
        UncertaintySettings s;
        if (spacing > 0) {
            s.dense_max_texels = 0;
            s.probe_spacing = spacing;
        }
        const HeightUncertainty u = height_uncertainty(t.observations, t.truth, k_poisson, s);
        ASSERT_EQ(u.sigma_um.size(), n);
        EXPECT_EQ(u.exact, spacing == 0);
        double worst = 0.0, mean = 0.0;
        for (std::size_t a = 0; a < n; ++a) {
            const double rel = std::abs(u.sigma_um[a] / std::sqrt(exact[a]) - 1.0);
            worst = std::max(worst, rel);
            mean += rel / double(n);
        }
        std::printf("spacing %d: %d probes, %d products, CG <= %d iterations, sigma rel. error mean %.2e max %.2e\n",
                    spacing, u.probes, u.products, u.max_cg_iterations, mean, worst);
        if (spacing == 0) {
            EXPECT_LT(worst, 1e-4);
            EXPECT_EQ(u.filled, 0);
        } else if (spacing == 8) {
            EXPECT_LE(u.worst_relative_residual, s.cg_tolerance);
            EXPECT_LT(worst, 1e-3);
        } else {
            EXPECT_LT(mean, 0.12);
            EXPECT_LT(worst, 0.35);
        }
    }
}

// The error bars are calibrated: for Poisson noise of 10⁴ photons per slice, refinements
// started from the truth (the maximum-likelihood estimate near it) over kDraws noise draws put
// the true error (means removed) within ±2σ for about 95 % of the pooled texels. σ is computed
// once, at the first draw's estimate (it changes by far less than its own accuracy between
// draws). The band 88–99 %: kDraws · 144 pooled texels, correlated within a footprint (~30
// independent groups per draw), give a binomial standard deviation of about 1.3 % around 95 %;
// the band is ±5 of those below and the room to 99 % above. σ off by a factor of 2 fails it:
// with σ/2 the ±2σ band is ±1σ (68 %), with 2σ it is ±4σ (99.99 %), both outside (checked).
TEST(HeightUncertainty, TwoSigmaCoversAboutNinetyFivePercentOverNoiseDraws) {
    const Tile t = make_tile(12, 32, 5311);
    const Noise noise{NoiseKind::Poisson, 1e4};
    constexpr int kDraws = 12;
    std::vector<double> sigma, errors;
    for (int draw = 0; draw < kDraws; ++draw) {
        std::vector<Observation> noisy = t.observations;
        add_noise(noisy, noise, 5320 + std::uint64_t(draw));
        std::vector<double> h = t.truth.values();
        LbfgsOptions lo;
        lo.max_iterations = 60;
        lo.gradient_tolerance = 0.0;
        lbfgs_minimize(
            [&](const std::vector<double>& x, std::vector<double>& g) {
                return observation_loss(t.truth.with_values(x), noisy, k_poisson, &g);
            },
            h, lo);
        const Heightfield estimate = t.truth.with_values(h);
        if (draw == 0) sigma = height_uncertainty(noisy, estimate, k_poisson).sigma_um;
        double mean_e = 0.0, mean_t = 0.0;
        for (int i = 0; i < 12; ++i)
            for (int j = 0; j < 12; ++j) {
                mean_e += estimate.height_um(i, j) / 144.0;
                mean_t += t.truth.height_um(i, j) / 144.0;
            }
        for (int i = 0; i < 12; ++i)
            for (int j = 0; j < 12; ++j)
                errors.push_back((estimate.height_um(i, j) - mean_e) - (t.truth.height_um(i, j) - mean_t));
    }
    const auto coverage = [&](double k) {
        double inside = 0.0;
        for (std::size_t e = 0; e < errors.size(); ++e)
            if (std::abs(errors[e]) <= k * sigma[e % sigma.size()]) inside += 1.0;
        return inside / double(errors.size());
    };
    double rms = 0.0, mean_sigma2 = 0.0;
    for (double e : errors) rms += e * e / double(errors.size());
    for (double s : sigma) mean_sigma2 += s * s / double(sigma.size());
    std::printf("coverage 1 sigma %.3f, 2 sigma %.3f; rms error %.3g um, rms sigma %.3g um\n", coverage(1.0),
                coverage(2.0), std::sqrt(rms), std::sqrt(mean_sigma2));
    EXPECT_GT(coverage(2.0), 0.88);
    EXPECT_LT(coverage(2.0), 0.99);
    EXPECT_GT(coverage(1.0), 0.60);  // 68 %: measured 69.4 % (exact σ)
    EXPECT_LT(coverage(1.0), 0.76);
    // The same check with σ scaled by 0.5 or 2 fails.
    EXPECT_LT(coverage(2.0 * 0.5), 0.88);
    EXPECT_GT(coverage(2.0 * 2.0), 0.99);
}

// A study, not a check (run with --gtest_also_run_disabled_tests; docs/recovery.md, Error
// bars): on a UNC_STUDY_ROWS² tile (default 16) over UNC_STUDY_DRAWS Poisson 10⁴ draws (seeds
// 5801 …), each refined from the truth by L-BFGS on the Poisson loss, the pooled coverage of
// the exact σ (formed G) and of the probed one (spacing 4, the former default), the variance of
// the errors over the draws against σ² (the Gauss–Newton approximation) and the mean error
// against σ/√draws (bias).
TEST(HeightUncertainty, DISABLED_CoverageStudyExactVersusProbed) {
    const char* rows_env = std::getenv("UNC_STUDY_ROWS");
    const char* draws_env = std::getenv("UNC_STUDY_DRAWS");
    const int rows = rows_env ? std::max(8, std::min(32, std::atoi(rows_env))) : 16;
    const int draws = draws_env ? std::max(2, std::min(99, std::atoi(draws_env))) : 20;
    const std::size_t n = std::size_t(rows) * std::size_t(rows);
    const Tile t = make_tile(rows, 32, 5800);
    const Noise noise{NoiseKind::Poisson, 1e4};
    double in1[2] = {0, 0}, in2[2] = {0, 0}, kurt = 0.0, count = 0.0, sum_sigma2 = 0.0;
    std::vector<double> mean_e(n, 0.0), mean_e2(n, 0.0);
    for (int draw = 0; draw < draws; ++draw) {
        std::vector<Observation> noisy = t.observations;
        add_noise(noisy, noise, 5801 + std::uint64_t(draw));
        std::vector<double> h = t.truth.values();
        LbfgsOptions lo;
        lo.max_iterations = 150;
        lo.gradient_tolerance = 0.0;
        lbfgs_minimize(
            [&](const std::vector<double>& x, std::vector<double>& g) {
                return observation_loss(t.truth.with_values(x), noisy, k_poisson, &g);
            },
            h, lo);
        const Heightfield estimate = t.truth.with_values(h);
        const HeightUncertainty exact = height_uncertainty(noisy, estimate, k_poisson);
        UncertaintySettings probed_settings;
        probed_settings.dense_max_texels = 0;
        probed_settings.probe_spacing = 4;
        const HeightUncertainty probed = height_uncertainty(noisy, estimate, k_poisson, probed_settings);
        double me = 0.0, mt = 0.0;
        for (std::size_t a = 0; a < n; ++a) {
            me += h[a] / double(n);
            mt += t.truth.values()[a] / double(n);
        }
        const double to_um = t.truth.vscale() * t.truth.texel_um();
        for (std::size_t a = 0; a < n; ++a) {
            const double e = ((h[a] - me) - (t.truth.values()[a] - mt)) * to_um;
            for (int m = 0; m < 2; ++m) {
                const double sg = (m == 0 ? exact : probed).sigma_um[a];
                in1[m] += std::abs(e) <= sg ? 1.0 : 0.0;
                in2[m] += std::abs(e) <= 2.0 * sg ? 1.0 : 0.0;
            }
            const double z = e / exact.sigma_um[a];
            kurt += z * z * z * z;
            count += 1.0;
            sum_sigma2 += exact.sigma_um[a] * exact.sigma_um[a];
            mean_e[a] += e / draws;
            mean_e2[a] += e * e / draws;
        }
        std::printf("draw %d: exact %.3f / %.3f, probed %.3f / %.3f (pooled so far)\n", draw, in1[0] / count,
                    in2[0] / count, in1[1] / count, in2[1] / count);
    }
    double var = 0.0, bias = 0.0;
    for (std::size_t a = 0; a < n; ++a) {
        var += (mean_e2[a] - mean_e[a] * mean_e[a]) * draws / (draws - 1.0) / double(n);
        bias += mean_e[a] * mean_e[a] / double(n);
    }
    std::printf("%d^2, %d draws: within 1 sigma exact %.3f probed %.3f; within 2 sigma exact %.3f probed %.3f\n", rows,
                draws, in1[0] / count, in1[1] / count, in2[0] / count, in2[1] / count);
    std::printf(
        "E[(e/sigma)^4] %.2f (Gaussian 3); variance over draws / mean sigma^2 %.3f; "
        "rms mean error / (rms sigma / sqrt(draws)) %.2f (unbiased ~1)\n",
        kurt / count, var / (sum_sigma2 / count), std::sqrt(bias) / std::sqrt(sum_sigma2 / count / draws));
}

TEST(HeightUncertainty, RejectsBadSettings) {
    const Tile t = make_tile(8, 16, 5304);
    UncertaintySettings s;
    s.probe_spacing = 0;
    EXPECT_THROW(height_uncertainty(t.observations, t.truth, k_poisson, s), std::domain_error);
    s = {};
    s.cg_tolerance = 1.0;
    EXPECT_THROW(height_uncertainty(t.observations, t.truth, k_poisson, s), std::domain_error);
    // Noiseless slices fitted exactly leave no residual to estimate an amplitude noise from.
    EXPECT_THROW(height_uncertainty(t.observations, t.truth, Loss{LossKind::Amplitude}), std::domain_error);
    EXPECT_THROW(height_uncertainty({}, t.truth, k_poisson), std::invalid_argument);
    EXPECT_THROW(error_coverage(t.truth, t.truth, {1.0}, 2.0), std::invalid_argument);
}

// The cost the convergence check's rule predicts (predicted_uncertainty_cost) against what
// height_uncertainty does: the forward passes it counts itself (HeightUncertainty::forwards),
// on an 8² tile whose footprint boxes span it and a 40² tile where they do not (σ_p 3 µm on
// 2 µm texels), both solves; and the memory against the peak resident size of a child process
// that runs it (less a child that runs nothing), within a factor of two. The 40² dense solve
// holds ~20 MB of matrix and ~30 MB of band sums: a term left out or counted per observation
// instead of once fails it.
TEST(HeightUncertainty, PredictedCostCountsTheForwardsAndTheMemory) {
    for (const int rows : {8, 40}) {
        const Tile t = make_tile(rows, 16, 7100 + std::uint64_t(rows));
        for (const int dense : {4096, 0}) {
            if (rows == 40 && dense == 0) continue;  // the 40² probed solve: seconds for nothing new
            UncertaintySettings s;
            s.dense_max_texels = dense;
            const UncertaintyCost cost = predicted_uncertainty_cost(t.observations, t.truth, 1.0, s, 1);
            const HeightUncertainty u = height_uncertainty(t.observations, t.truth, k_poisson, s);
            std::printf("%d^2 %s: forwards predicted %.0f, counted %lld; bytes predicted %s\n", rows,
                        dense ? "dense" : "probed", cost.forwards, static_cast<long long>(u.forwards),
                        format_bytes(cost.bytes).c_str());
            EXPECT_NEAR(cost.forwards, double(u.forwards), 0.15 * double(u.forwards)) << rows << "^2";
            EXPECT_GT(cost.seconds, 0.0);
        }
    }
#ifdef WAVEBRDF_ASAN
    GTEST_SKIP() << "AddressSanitizer's shadow memory and quarantine inflate the resident size; "
                    "the estimate is checked in the plain build";
#endif
    const Tile t = make_tile(40, 16, 7140);
    const UncertaintyCost cost = predicted_uncertainty_cost(t.observations, t.truth, 1.0, UncertaintySettings{}, 1);
    const double idle = test::child_peak_memory_bytes([] { return true; });
    const double peak = test::child_peak_memory_bytes([&] {
        return !height_uncertainty(t.observations, t.truth, k_poisson).sigma_um.empty();
    });
    ASSERT_GT(idle, 0.0);
    ASSERT_GT(peak, 0.0) << "height_uncertainty failed in the child";
    test::expect_estimate_within_factor_of_two(cost.bytes, peak - idle, "height_uncertainty 40x40 dense");
}

// A study, not a check (run with --gtest_also_run_disabled_tests): the cost rule's prediction
// (predicted_uncertainty_cost, from check_convergence's timed forwards) against the CPU time
// height_uncertainty takes on one thread, on tiles of growing size seen as the planner sees
// them (make_tile: σ_p 1.5 texels, a footprint every 2 texels, here 48² slices), the dense
// solve and the probed one. Prints each part. A timing, hence not a check.
TEST(HeightUncertainty, DISABLED_CostStudy) {
    omp_set_num_threads(1);
    for (const int rows : {16, 24, 32}) {
        const Tile t = make_tile(rows, 48, 7200 + std::uint64_t(rows));
        const ConvergenceCheck check = check_convergence(t.observations, t.truth, 1e4, false);
        for (const int dense : {4096, 0}) {
            UncertaintySettings s;
            s.dense_max_texels = dense;
            const UncertaintyCost cost = predicted_uncertainty_cost(t.observations, t.truth, check.pass_seconds, s, 1);
            const double before = process_cpu_seconds();
            const HeightUncertainty u = height_uncertainty(t.observations, t.truth, k_poisson, s);
            const double took = process_cpu_seconds() - before;
            std::printf("%d^2 %s: %zu observations, pass %.3f s; forwards %.0f (counted %lld) products %.3g solve %.3g "
                        "madds; predicted %.2f CPU s, took %.2f (ratio %.2f)\n",
                        rows, dense ? "dense" : "probed", t.observations.size(), check.pass_seconds, cost.forwards,
                        static_cast<long long>(u.forwards), cost.product_madds, cost.solve_madds, cost.seconds, took,
                        took / cost.seconds);
        }
    }
}

}  // namespace
}  // namespace wavebrdf
