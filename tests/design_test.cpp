// The design engine against independent evaluations: a direct sum of the Kirchhoff integral,
// a mirror, a λ/4 grating, energy, and the loop's gradient against finite differences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include "design/engine.h"
#include "design/relief.h"
#include "design/evaluator.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"
#include <nlohmann/json.hpp>

#include "design_util.h"

namespace wavebrdf {
namespace {

std::vector<double> random_levels(int size, int levels, double step_um, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::vector<double> h(static_cast<std::size_t>(size * size));
    for (double& x : h) x = step_um * static_cast<double>(rng() % static_cast<std::uint64_t>(levels));
    return h;
}

TEST(Design, ExactOrdersMatchADirectSumOfTheKirchhoffIntegral) {
    // 4 levels on a 6 × 6 tile under oblique light: every propagating order's power, FFT identity
    // against the midpoint rule with 48² points per texel (its aperture error is (π m/(N S))²/6
    // of the amplitude, below 1e-3 for every order here).
    const int size = 6;
    const std::vector<double> h = random_levels(size, 4, 0.13, 7);
    const std::array<double, 2> light{0.2, -0.1};
    const std::vector<double> lambdas{0.45, 0.62};
    const auto fast = exact_orders(h, size, 0.5, light, lambdas);
    const auto slow = direct_orders(h, size, 0.5, light, lambdas, 48);
    for (std::size_t w = 0; w < lambdas.size(); ++w) {
        double peak = 0.0;
        for (double p : slow[w].power) peak = std::max(peak, p);
        // The direct sum lists every propagating order, the fast one leaves out the aperture's zeros.
        std::size_t matched = 0;
        for (std::size_t o = 0; o < slow[w].m.size(); ++o) {
            std::size_t f = 0;
            while (f < fast[w].m.size() && (fast[w].m[f] != slow[w].m[o] || fast[w].n[f] != slow[w].n[o])) ++f;
            const double fast_power = f < fast[w].m.size() ? fast[w].power[f] : 0.0;
            if (f < fast[w].m.size()) ++matched;
            EXPECT_NEAR(fast_power, slow[w].power[o], 2e-3 * peak) << "order " << slow[w].m[o] << "," << slow[w].n[o];
        }
        EXPECT_EQ(matched, fast[w].m.size());
        EXPECT_NEAR(fast[w].kirchhoff_total, slow[w].kirchhoff_total, 2e-3);
    }
}

TEST(Design, OneLevelIsAPerfectMirror) {
    const std::vector<double> h(64, 0.37);
    const auto orders = exact_orders(h, 8, 0.5, {0.3, 0.1}, {0.4, 0.55, 0.7});
    for (const auto& w : orders) {
        EXPECT_NEAR(w.kirchhoff_total, 1.0, 1e-12);
        for (std::size_t o = 0; o < w.m.size(); ++o) {
            const bool mirror = w.m[o] == 0 && w.n[o] == 0;
            EXPECT_NEAR(w.power[o], mirror ? 1.0 : 0.0, 1e-12);
            if (mirror) {
                EXPECT_NEAR(w.omega_x[o], -0.3, 1e-15);
                EXPECT_NEAR(w.omega_y[o], -0.1, 1e-15);
            }
        }
    }
}

TEST(Design, QuarterWaveBinaryGratingHasNoZerothOrder) {
    // Normal light, lines of 0 and λ/4 (50 % duty): the two halves' mirror fields are in
    // antiphase (2 k λ/4 = π), so the zeroth order vanishes; the ±1 orders carry the most power.
    const int size = 16;
    const double lambda = 0.6;
    std::vector<double> h(static_cast<std::size_t>(size * size));
    for (int i = 0; i < size; ++i)
        for (int j = 0; j < size; ++j) h[static_cast<std::size_t>(i * size + j)] = (i < size / 2) ? 0.0 : lambda / 4;
    const auto w = exact_orders(h, size, 0.5, {0.0, 0.0}, {lambda})[0];
    double zero = -1.0, first = 0.0, best_other = 0.0;
    for (std::size_t o = 0; o < w.m.size(); ++o) {
        if (w.m[o] == 0 && w.n[o] == 0) {
            zero = w.power[o];
        } else if (std::abs(w.m[o]) == 1 && w.n[o] == 0) {
            first += w.power[o];
        } else {
            best_other = std::max(best_other, w.power[o]);
        }
    }
    EXPECT_NEAR(zero, 0.0, 1e-15);
    EXPECT_GT(first, 0.5);
    EXPECT_LT(best_other, first / 2);
    // The same lines of depth λ/2 are a mirror for the zeroth order (2 k λ/2 = 2π) but not
    // exactly: an order leaving at θ_o sees the step's phase k (λ/2)(1 + cos θ_o) ≠ 2π, so the
    // first orders (sin θ = λ/L = 0.075) keep (π (1 − cos θ)/2)² / 4 ≈ 0.2 % between them.
    for (double& x : h) x *= 2.0;
    const auto v = exact_orders(h, size, 0.5, {0.0, 0.0}, {lambda})[0];
    for (std::size_t o = 0; o < v.m.size(); ++o)
        if (v.m[o] == 0 && v.n[o] == 0) {
            EXPECT_GT(v.power[o], 0.99);
            EXPECT_LT(v.power[o], 1.0 - 1e-6);
        }
}

TEST(Design, ShallowReliefConservesEnergy) {
    // Energy: for a shallow relief the thin-element field is nearly a plane wave, and the orders'
    // flux sums to the incident power to second order in k h; evanescent orders carry none (the
    // orders listed are the propagating ones only, and their directions lie inside the disk).
    const int size = 16;
    const std::vector<double> h = random_levels(size, 8, 0.0005, 3);
    const auto orders = exact_orders(h, size, 0.5, {0.1, 0.2}, {0.5});
    EXPECT_NEAR(orders[0].kirchhoff_total, 1.0, 2e-3);
    for (std::size_t o = 0; o < orders[0].m.size(); ++o)
        EXPECT_LT(std::hypot(orders[0].omega_x[o], orders[0].omega_y[o]), 1.0);
}

TEST(Design, LevelSpectraAdjointIsItsTranspose) {
    // ⟨F p, B⟩ = ⟨p, Fᵀ B⟩ in the real inner product the loop uses (dL = Σ Re conj(B) dF).
    const int size = 8, levels = 3;
    detail::LevelSpectra spectra(size, levels);
    std::mt19937_64 rng(5);
    std::normal_distribution<double> normal;
    std::vector<double> p(static_cast<std::size_t>(size * size * levels));
    for (double& x : p) x = normal(rng);
    std::vector<detail::Complex> b(p.size());
    for (auto& x : b) x = {normal(rng), normal(rng)};
    spectra.forward(p);
    double lhs = 0.0;
    for (std::size_t i = 0; i < b.size(); ++i) lhs += (std::conj(b[i]) * spectra.spectra()[i]).real();
    std::vector<double> g;
    spectra.adjoint(b, g);
    double rhs = 0.0;
    for (std::size_t i = 0; i < p.size(); ++i) rhs += p[i] * g[i];
    EXPECT_NEAR(lhs, rhs, 1e-12 * std::abs(lhs) + 1e-12);
}

// The loop's loss and gradient (with the softmax weights as the loop feeds them) against
// central finite differences, for each target kind.
void check_gradient(const DesignOptions& options) {
    const PreparedDesign prepared = prepare_design(options);
    detail::Evaluator evaluator(prepared, {0.97, 1.0, 1.03});
    const std::size_t total = static_cast<std::size_t>(options.size * options.size * options.levels);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uniform(0.1, 1.0);
    std::vector<double> w(total);
    for (double& x : w) x = uniform(rng);
    std::vector<double> g;
    evaluator.evaluate(w, &g);
    const double step = 1e-6;
    for (int trial = 0; trial < 6; ++trial) {
        const std::size_t i = static_cast<std::size_t>(rng() % total);
        std::vector<double> plus = w, minus = w;
        plus[i] += step;
        minus[i] -= step;
        const double fd = (evaluator.evaluate(plus, nullptr) - evaluator.evaluate(minus, nullptr)) / (2 * step);
        EXPECT_NEAR(g[i], fd, 1e-5 * std::max(1.0, std::abs(fd))) << to_string(options.target.kind) << " weight " << i;
    }
}

// An anti-mirror on an 8 × 8 tile under oblique light at 4 wavelengths, the gradient tests' design.
DesignOptions oblique_anti_mirror(int levels) {
    DesignOptions o;
    o.size = 8;
    o.levels = levels;
    o.texel_um = 0.5;
    o.spectral = 4;
    o.band_um = {0.4, 0.7};
    o.omega_i = {0.1, 0.05};
    o.specular_cone = 0.2;
    o.region = "annulus:0.25,0.6";
    return o;
}

TEST(Design, LossGradientMatchesFiniteDifferences) {
    const DesignOptions o = oblique_anti_mirror(3);
    check_gradient(o);
    DesignOptions p = o;
    p.spectral = 0;
    p.lambda_um = 0.5;
    p.window = 0.5;
    p.target = pattern_target(3, 4, {0, 1, 0.5, 0.2, 1, 0, 0.3, 0.7, 0.9, 0.1, 0.4, 0.6});
    check_gradient(p);
    DesignOptions c = o;
    c.spectral = 6;
    c.band_um = {0.38, 0.78};
    c.view_cone = 0.2;
    c.target = parse_design_target("colour:#20c040");
    check_gradient(c);
    c.delta_uv_tolerance = 0.005;  // a tolerance the random weights' colour lies beyond
    check_gradient(c);
}

TEST(Design, LevelStepGradientMatchesFiniteDifferences) {
    // The anti-mirror's level step Δ is a design variable: the loss's derivative in Δ (one more
    // contraction of the level spectra) against central differences of the loss, for level
    // mixtures and for a relief on the levels, heights scaled by fabrication errors.
    const PreparedDesign prepared = prepare_design(oblique_anti_mirror(4));
    detail::Evaluator evaluator(prepared, {0.97, 1.0, 1.03});
    const std::size_t n2 = 64, total = n2 * 4;
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> uniform(0.1, 1.0);
    std::vector<double> mixture(total), relief(total, 0.0);
    for (double& x : mixture) x = uniform(rng);
    for (std::size_t t = 0; t < n2; ++t) relief[(rng() % 4) * n2 + t] = 1.0;
    for (const auto* w : {&mixture, &relief})
        for (double step : {0.12, 0.19, 0.31}) {
            evaluator.set_step_um(step);
            std::vector<double> g;
            double dstep = 0.0;
            evaluator.evaluate(*w, &g, nullptr, &dstep);
            const double h = 1e-6;
            evaluator.set_step_um(step + h);
            const double plus = evaluator.evaluate(*w, nullptr);
            evaluator.set_step_um(step - h);
            const double minus = evaluator.evaluate(*w, nullptr);
            const double fd = (plus - minus) / (2 * h);
            EXPECT_GT(std::abs(fd), 1e-3) << "step " << step;  // a derivative worth checking
            EXPECT_NEAR(dstep, fd, 1e-5 * std::max(1.0, std::abs(fd))) << "step " << step;
        }
}

TEST(Design, AntiMirrorLevelStepMovesWithinTheRangeAndTheExportMatchesTheLoop) {
    // Where no step survey runs (a start relief, more than 32 levels; here the survey taken out of
    // the prepared run) the anti-mirror's free step starts on the rule's and moves: the exported
    // heights lie on the final step's levels within the height range, and the loop's model of
    // them (on the step it ended with) is their exact scalar diffraction. With --level-step-um
    // the step stays where the user put it, and so does the survey's (design_step_survey_test).
    DesignOptions o = test::small_design("anti-mirror", 8, 60, 15);
    o.band_um = {0.4, 0.7};
    PreparedDesign p = prepare_design(o);
    ASSERT_FALSE(p.step_survey_um.empty());
    p.step_survey_um.clear();
    const DesignResult r = run_design(p);
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_TRUE(j.contains("level_step"));
    EXPECT_FALSE(j.contains("step_survey"));
    const double start = j["level_step"]["start_um"].get<double>(), end = j["level_step"]["final_um"].get<double>();
    EXPECT_DOUBLE_EQ(start, p.levels_um[1]);
    EXPECT_NE(end, start);
    EXPECT_NEAR(r.levels_um[1], end, 1e-15);
    EXPECT_LE(r.levels_um.back(), o.height_range_um);
    EXPECT_EQ(j["levels_um"].get<std::vector<double>>(), r.levels_um);
    for (std::size_t t = 0; t < r.level.size(); ++t)
        EXPECT_EQ(r.heights_um[t], r.levels_um[static_cast<std::size_t>(r.level[t])]);
    EXPECT_LT(j["metrics"]["model_vs_exact_max_fraction_difference"].get<double>(), 1e-9);
    DesignOptions fixed = o;
    fixed.level_step_um = 0.16;
    const DesignResult rf = run_design(prepare_design(fixed));
    EXPECT_FALSE(nlohmann::json::parse(rf.metrics_json).contains("level_step"));
    EXPECT_DOUBLE_EQ(rf.levels_um[1], 0.16);
}

TEST(Design, BadOptionsFailBeforeAnyWork) {
    DesignOptions o;
    o.min_feature_um = 1.0;
    EXPECT_THROW(prepare_design(o), std::invalid_argument);  // levels with a grey min feature
    o = DesignOptions{};
    o.target = pattern_target(2, 2, {0, 1, 1, 0});
    o.window = 0.8;  // corner at |ω| = 1.13
    EXPECT_THROW(prepare_design(o), std::domain_error);
    o = DesignOptions{};
    o.region = "annulus:0.5,0.2";
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    o = DesignOptions{};
    o.omega_i = {0.7, 0.0};  // region reaches 1.2
    EXPECT_THROW(prepare_design(o), std::domain_error);
    o = DesignOptions{};
    o.levels = 1;
    EXPECT_THROW(prepare_design(o), std::domain_error);
    o = DesignOptions{};
    o.target = parse_design_target("colour:#ff0000");
    EXPECT_THROW(prepare_design(o), std::invalid_argument);  // colour without white light
    EXPECT_THROW(parse_design_target("colour:#ff00"), std::invalid_argument);
    EXPECT_THROW(parse_design_target("colour:#gg0000"), std::invalid_argument);
    EXPECT_THROW(parse_design_target("pattern:/nonexistent/x.png"), std::invalid_argument);
    EXPECT_THROW(parse_design_target("mirror"), std::invalid_argument);
    EXPECT_THROW(parse_fabrication_errors("scale:80%"), std::invalid_argument);
    EXPECT_THROW(parse_fabrication_errors("tilt:3"), std::invalid_argument);
    const FabricationErrors e = parse_fabrication_errors("scale:5%,blur:0.3um");
    EXPECT_DOUBLE_EQ(e.scale, 0.05);
    EXPECT_DOUBLE_EQ(e.blur_um, 0.3);
    o = DesignOptions{};
    o.max_memory_gb = 1e-6;
    EXPECT_THROW(prepare_design(o), std::bad_alloc);
}

// The shares a of K equally spaced levels of step Δ with least mean |Σ_ℓ a_ℓ e^{−iℓθ}|² over the
// phases θ = 4πΔ/λ of `lambdas` (normal light), by trying every subset of levels: on a subset,
// a ∝ G⁻¹1; the least over the subsets whose a is non-negative. Independent of the run's
// active-set solver (small K only).
std::vector<double> least_mirror_shares(double step, int K, const std::vector<double>& lambdas) {
    std::vector<double> c(static_cast<std::size_t>(K), 0.0);
    for (int d = 0; d < K; ++d) {
        for (double l : lambdas) c[static_cast<std::size_t>(d)] += std::cos(d * 4.0 * k_pi * step / l);
        c[static_cast<std::size_t>(d)] /= static_cast<double>(lambdas.size());
    }
    std::vector<double> best;
    double best_value = 1e300;
    for (int mask = 1; mask < (1 << K); ++mask) {
        std::vector<int> S;
        for (int l = 0; l < K; ++l)
            if (mask & (1 << l)) S.push_back(l);
        const std::size_t n = S.size();
        std::vector<double> A(n * (n + 1));
        for (std::size_t i = 0; i < n; ++i) {
            for (std::size_t j = 0; j < n; ++j)
                A[i * (n + 1) + j] = c[static_cast<std::size_t>(std::abs(S[i] - S[j]))] + (i == j ? 1e-13 : 0.0);
            A[i * (n + 1) + n] = 1.0;
        }
        for (std::size_t k = 0; k < n; ++k) {  // Gaussian elimination with partial pivoting
            std::size_t piv = k;
            for (std::size_t i = k + 1; i < n; ++i)
                if (std::abs(A[i * (n + 1) + k]) > std::abs(A[piv * (n + 1) + k])) piv = i;
            for (std::size_t j = 0; j <= n; ++j) std::swap(A[k * (n + 1) + j], A[piv * (n + 1) + j]);
            for (std::size_t i = k + 1; i < n; ++i) {
                const double f = A[i * (n + 1) + k] / A[k * (n + 1) + k];
                for (std::size_t j = k; j <= n; ++j) A[i * (n + 1) + j] -= f * A[k * (n + 1) + j];
            }
        }
        std::vector<double> x(n);
        for (std::size_t i = n; i-- > 0;) {
            double v = A[i * (n + 1) + n];
            for (std::size_t j = i + 1; j < n; ++j) v -= A[i * (n + 1) + j] * x[j];
            x[i] = v / A[i * (n + 1) + i];
        }
        double total = 0.0;
        for (double v : x) total += v;
        std::vector<double> a(static_cast<std::size_t>(K), 0.0);
        bool ok = true;
        for (std::size_t i = 0; i < n; ++i) {
            a[static_cast<std::size_t>(S[i])] = x[i] / total;
            ok = ok && x[i] / total >= 0.0;
        }
        if (!ok) continue;
        double value = 0.0;
        for (int l = 0; l < K; ++l)
            for (int m = 0; m < K; ++m)
                value += a[static_cast<std::size_t>(l)] * a[static_cast<std::size_t>(m)] * c[static_cast<std::size_t>(std::abs(l - m))];
        if (value < best_value) {
            best_value = value;
            best = a;
        }
    }
    return best;
}

double worst_mirror_power(const std::vector<double>& shares, double step, const std::vector<double>& lambdas) {
    double worst = 0.0;
    for (double l : lambdas) {
        std::complex<double> a(0.0, 0.0);
        for (std::size_t k = 0; k < shares.size(); ++k) a += shares[k] * std::polar(1.0, -4.0 * k_pi * step * static_cast<double>(k) / l);
        worst = std::max(worst, std::norm(a));
    }
    return worst;
}

TEST(Design, AntiMirrorLevelsCanCancelTheMirrorOrderAcrossTheBand) {
    // 8 levels spanning 2 µm (step 0.286 µm) are a mirror at λ = 2 · 0.286 µm, inside 0.4–0.7,
    // whatever the design: the anti-mirror's levels take the largest step on which some shares
    // of the levels darken the mirror order (power ≤ 1e-4) at every wavelength of the band.
    // Checked here by the exact evaluation of a relief with those shares (found by a solver of
    // this test's own), texel by texel in a random order; and that a step 3 % larger allows no
    // shares that dark: the step is the largest, not merely a safe one.
    DesignOptions o;
    o.spectral = 16;
    o.band_um = {0.4, 0.7};
    o.size = 64;
    const PreparedDesign p = prepare_design(o);
    const double step = p.levels_um[1];
    EXPECT_LT(step, 2.0 / 7.0);
    EXPECT_LE(p.levels_um.back(), 2.0);
    std::vector<double> dense;
    for (int d = 0; d <= 300; ++d) dense.push_back(p.lambdas_um.front() + (p.lambdas_um.back() - p.lambdas_um.front()) * d / 300.0);
    const std::vector<double> shares = least_mirror_shares(step, 8, dense);
    EXPECT_LT(worst_mirror_power(shares, step, dense), 1.2e-4);
    EXPECT_GT(worst_mirror_power(least_mirror_shares(1.03 * step, 8, dense), 1.03 * step, dense), 1e-4);
    std::vector<double> h;
    for (int l = 0; l < 8; ++l) {
        const auto count = static_cast<std::size_t>(std::lround(shares[static_cast<std::size_t>(l)] * 64 * 64));
        for (std::size_t k = 0; k < count && h.size() < 64 * 64; ++k) h.push_back(p.levels_um[static_cast<std::size_t>(l)]);
    }
    while (h.size() < 64 * 64) h.push_back(p.levels_um[3]);
    std::shuffle(h.begin(), h.end(), std::mt19937_64(3));
    for (const auto& w : exact_orders(h, 64, 0.5, {0.0, 0.0}, p.lambdas_um))
        for (std::size_t k = 0; k < w.m.size(); ++k)
            if (w.m[k] == 0 && w.n[k] == 0) {
                EXPECT_LT(w.power[k], 3e-4) << "lambda " << w.lambda_um;
            }
    // The full range's step: one wavelength of the band near 2Δ is nearly a mirror for the same shares.
    for (double& x : h) x *= (2.0 / 7.0) / step;
    double worst = 0.0;
    for (const auto& w : exact_orders(h, 64, 0.5, {0.0, 0.0}, p.lambdas_um))
        for (std::size_t k = 0; k < w.m.size(); ++k)
            if (w.m[k] == 0 && w.n[k] == 0) worst = std::max(worst, w.power[k]);
    EXPECT_GT(worst, 0.5);
}

TEST(Design, SmallAntiMirrorDesignBeatsItsStartAndKeepsTheConstraints) {
    DesignOptions o;
    o.size = 32;
    o.spectral = 4;
    o.band_um = {0.45, 0.65};
    o.region = "annulus:0.15,0.6";
    o.specular_cone = 0.1;
    o.iterations = 40;
    o.refine_passes = 20;
    o.height_range_um = 1.5;
    const PreparedDesign p = prepare_design(o);
    std::vector<DesignStep> steps;
    const DesignResult r = run_design(p, [&](const DesignStep& s) {
        steps.push_back(s);
        return true;
    });
    ASSERT_FALSE(steps.empty());
    EXPECT_LT(steps.back().loss, 0.5 * steps.front().loss);
    for (double h : r.heights_um) {
        EXPECT_GE(h, 0.0);
        EXPECT_LE(h, 1.5 + 1e-12);
        const double level = h / r.levels_um[1];
        EXPECT_NEAR(level, std::round(level), 1e-9);
    }
    // Scored here from the heights alone (exact_orders), against the loop's random start (the
    // same seed, no iterations): the mirror cone darker and the region brighter.
    auto score = [&](const std::vector<double>& heights) {
        std::array<double, 2> s{0.0, 0.0};
        for (const auto& w : exact_orders(heights, o.size, o.texel_um, o.omega_i, p.lambdas_um))
            for (std::size_t k = 0; k < w.m.size(); ++k) {
                const double r = std::hypot(w.omega_x[k], w.omega_y[k]);
                if (r <= 0.1) s[0] += w.power[k] / 4;
                if (r >= 0.15 && r <= 0.6) s[1] += w.power[k] / 4;
            }
        return s;
    };
    DesignOptions start = o;
    start.iterations = 0;
    start.refine_passes = 0;
    start.anneal_sweeps = 0;  // the random relief itself, not annealed
    const auto designed = score(r.heights_um);
    const auto random = score(run_design(prepare_design(start)).heights_um);
    EXPECT_LT(designed[0], random[0] / 3);
    EXPECT_GT(designed[1], random[1]);
}

TEST(Design, ColourOfAFlatWhiteReflectorIsTheWhitePoint) {
    // Reflectance 1 everywhere: Y = 1 and the chromaticity of D65 (the white the slices adapt to).
    std::vector<double> lambdas;
    for (int k = 0; k < 16; ++k) lambdas.push_back(0.36 + (k + 0.5) * 0.47 / 16);
    const auto xyz = reflectance_xyz(lambdas, std::vector<double>(16, 1.0));
    EXPECT_NEAR(xyz[1], 1.0, 1e-9);
    const auto uv = xyz_to_uv(xyz);
    const auto d65 = xyz_to_uv(linear_srgb_to_xyz({1.0, 1.0, 1.0}));
    EXPECT_NEAR(uv[0], d65[0], 1e-9);
    EXPECT_NEAR(uv[1], d65[1], 1e-9);
    // D65's u'v' from its xy (0.3127, 0.3290): u' = 4x/(−2x + 12y + 3).
    EXPECT_NEAR(d65[0], 4 * 0.3127 / (-2 * 0.3127 + 12 * 0.3290 + 3), 1e-4);
}

TEST(Design, AntiMirrorBinsAreEqualForAReliefWithQuarterTurnSymmetry) {
    // A relief unchanged by a quarter turn of the tile reflects a far field unchanged by a quarter
    // turn about the mirror direction (normal light): power(m, n) = power(−n, m). The region's 16
    // equal-area bins (4 rings × 4 quadrants) must then hold equal power within each ring, and
    // equally many orders, whatever the relief; bins that give a half-axis of orders to the wrong
    // quadrant do not.
    const int N = 32;
    const int K = 8;
    const double step = 0.13;
    std::mt19937_64 rng(11);
    std::vector<double> h(static_cast<std::size_t>(N * N), -1.0);
    auto at = [&](int i, int j) -> double& {
        return h[static_cast<std::size_t>(((i % N + N) % N) * N + ((j % N + N) % N))];
    };
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            if (at(i, j) >= 0.0) continue;
            const double v = step * static_cast<double>(rng() % K);
            at(i, j) = v;     // the orbit of (i, j) under quarter turns (i, j) → (−j, i)
            at(-j, i) = v;
            at(-i, -j) = v;
            at(j, -i) = v;
        }
    const std::vector<double> lambdas{0.41, 0.55, 0.69};
    const auto orders = exact_orders(h, N, 0.5, {0.0, 0.0}, lambdas);
    std::vector<detail::OrderSet> sets;
    for (double lambda : lambdas) sets.push_back(detail::make_order_set(N, 0.5, {0.0, 0.0}, lambda));
    const auto target = detail::make_anti_mirror({});
    target->assign(sets);
    for (std::size_t w = 0; w < lambdas.size(); ++w) {
        std::map<std::pair<int, int>, double> power;
        for (std::size_t o = 0; o < orders[w].m.size(); ++o) power[{orders[w].m[o], orders[w].n[o]}] = orders[w].power[o];
        std::vector<double> bin(16, 0.0), count(16, 0.0);
        double in_region = 0.0;
        for (std::size_t o = 0; o < sets[w].size(); ++o) {
            const int m = sets[w].m[o], n = sets[w].n[o];
            ASSERT_NEAR(power.at({m, n}), power.at({-n, m}), 1e-12) << m << "," << n;  // the premise
            const int q = target->members()[w][o][1];
            if (q < 1) continue;
            bin[static_cast<std::size_t>(q - 1)] += power.at({m, n});
            count[static_cast<std::size_t>(q - 1)] += 1.0;
            in_region += power.at({m, n});
        }
        ASSERT_GT(in_region, 0.1);
        for (int ring = 0; ring < 4; ++ring)
            for (int quadrant = 1; quadrant < 4; ++quadrant) {
                const auto a = static_cast<std::size_t>(ring * 4), b = static_cast<std::size_t>(ring * 4 + quadrant);
                EXPECT_EQ(count[b], count[a]) << "lambda " << lambdas[w] << " ring " << ring;
                EXPECT_NEAR(bin[b], bin[a], 1e-12) << "lambda " << lambdas[w] << " ring " << ring;
            }
        // The target's own uniformity of these fractions is the std/mean of the same 16 bins.
        detail::Fractions f(1, std::vector<double>(17, 0.0));
        for (std::size_t q = 0; q < 16; ++q) f[0][q + 1] = bin[q];
        double mean = in_region / 16.0, var = 0.0;
        for (double x : bin) var += (x - mean) * (x - mean) / 16.0;
        EXPECT_NEAR(target->metrics(f)["uniformity"][0].get<double>(), std::sqrt(var) / mean, 1e-12);
    }
}

TEST(Design, AntiMirrorMetricsSayWhereTheLightTheRegionMissesGoes) {
    // A random relief: the fractions inside the region's inner edge (the cone excepted) and beyond
    // its outer edge, against sums over exact_orders' powers by |ω_o − ω_mirror|; with the cone
    // and the region they hold every propagating order once (they sum to 1; a disk region holds the
    // cone's orders too, and has nothing inside it).
    const int N = 32;
    const std::vector<double> h = random_levels(N, 8, 0.15, 21);
    const std::vector<double> lambdas{0.41, 0.55, 0.69};
    const auto orders = exact_orders(h, N, 0.5, {0.0, 0.0}, lambdas);
    std::vector<detail::OrderSet> sets;
    for (double lambda : lambdas) sets.push_back(detail::make_order_set(N, 0.5, {0.0, 0.0}, lambda));
    const auto flux = detail::level_flux(detail::to_level_relief(h, 8), N, sets, 1.0);
    for (const bool disk : {false, true}) {
        detail::AntiMirrorSpec spec;
        if (disk) spec.r1 = 0.0;
        const auto target = detail::make_anti_mirror(spec);
        target->assign(sets);
        const nlohmann::json m = target->metrics(detail::group_fractions(*target, flux));
        ASSERT_TRUE(m.contains("beyond_fraction"));
        for (std::size_t w = 0; w < lambdas.size(); ++w) {
            double inside = 0.0, beyond = 0.0;
            for (std::size_t o = 0; o < orders[w].m.size(); ++o) {
                const double r = std::hypot(orders[w].omega_x[o], orders[w].omega_y[o]);
                if (r > spec.specular_cone && r < spec.r1) inside += orders[w].power[o];
                if (r > spec.r2) beyond += orders[w].power[o];
            }
            EXPECT_GT(beyond, 0.05);  // the premise: a random relief lights the whole disk
            EXPECT_NEAR(m["beyond_fraction"][w].get<double>(), beyond, 1e-12) << lambdas[w];
            EXPECT_NEAR(m["inside_fraction"][w].get<double>(), inside, 1e-12) << lambdas[w];
            if (disk) EXPECT_EQ(m["inside_fraction"][w].get<double>(), 0.0);
            else EXPECT_GT(inside, 0.005);
            const double all = m["specular_fraction"][w].get<double>() + m["region_fraction"][w].get<double>() +
                               m["inside_fraction"][w].get<double>() + m["beyond_fraction"][w].get<double>();
            EXPECT_NEAR(all, disk ? 1.0 + m["specular_fraction"][w].get<double>() : 1.0, 1e-12) << lambdas[w];
        }
    }
}

TEST(Design, RepeatedTileHasTheSameFarField) {
    // The view survey's premise: an s² tile repeated 2 × 2 reflects into exactly the orders of the
    // small tile (the even orders of the large one) with the same powers; the odd orders are dark.
    const int s = 8;
    const std::vector<double> small = random_levels(s, 4, 0.15, 21);
    std::vector<double> big(static_cast<std::size_t>(4 * s * s));
    for (int i = 0; i < 2 * s; ++i)
        for (int j = 0; j < 2 * s; ++j)
            big[static_cast<std::size_t>(i * 2 * s + j)] = small[static_cast<std::size_t>((i % s) * s + j % s)];
    const std::array<double, 2> light{0.1, -0.05};
    const auto a = exact_orders(small, s, 0.5, light, {0.45})[0];
    const auto b = exact_orders(big, 2 * s, 0.5, light, {0.45})[0];
    std::size_t matched = 0;
    for (std::size_t o = 0; o < b.m.size(); ++o) {
        if (b.m[o] % 2 != 0 || b.n[o] % 2 != 0) {
            EXPECT_NEAR(b.power[o], 0.0, 1e-12) << b.m[o] << "," << b.n[o];
            continue;
        }
        for (std::size_t k = 0; k < a.m.size(); ++k)
            if (a.m[k] == b.m[o] / 2 && a.n[k] == b.n[o] / 2) {
                EXPECT_NEAR(b.power[o], a.power[k], 1e-12);
                ++matched;
            }
    }
    EXPECT_EQ(matched, a.m.size());
}

TEST(Design, ColourOutOfReachIsSurveyedFromOtherViews) {
    // A colour the run misses (too little light into the cone, or the wrong chromaticity) is
    // designed for other views; each listed view's numbers are what a design for it reflects,
    // rescored here by exact diffraction of its relief.
    DesignOptions o;
    o.size = 16;
    o.levels = 16;
    o.height_range_um = 2.0;
    o.spectral = 6;
    o.iterations = 10;
    o.refine_passes = 3;
    o.target = parse_design_target("colour:#FF0000");
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    const auto& exact = j["metrics"]["exact"];
    ASSERT_TRUE(exact["delta_uv"].get<double>() > 0.04 || exact["luminous_efficiency"].get<double>() < 0.05);
    ASSERT_TRUE(j.contains("view_survey"));
    const auto& survey = j["view_survey"];
    EXPECT_EQ(survey["size"].get<int>(), 16);
    ASSERT_EQ(survey["views"].size(), 4u);  // offsets 0.1 … 0.4; not the run's own view
    for (const auto& v : survey["views"]) {
        EXPECT_GT(std::hypot(v["view"][0].get<double>(), v["view"][1].get<double>()), 0.05);
        // Each entry is what a design for that view reaches, scored by exact diffraction.
        DesignOptions w = o;
        w.iterations = survey["iterations"].get<int>();
        w.refine_passes = survey["refine_passes"].get<int>();
        w.view = std::array<double, 2>{v["view"][0].get<double>(), v["view"][1].get<double>()};
        const DesignResult rv = run_design(prepare_design(w));
        const auto e = exact_orders(rv.heights_um, o.size, o.texel_um, o.omega_i, rv.lambdas_um);
        std::vector<double> reflectance;
        for (const auto& op : e) {
            double in = 0.0;
            for (std::size_t k = 0; k < op.m.size(); ++k)
                if (std::hypot(op.omega_x[k] - (*w.view)[0], op.omega_y[k] - (*w.view)[1]) <= o.view_cone) in += op.power[k] * op.kirchhoff_total;
            reflectance.push_back(in);
        }
        const auto xyz = reflectance_xyz(rv.lambdas_um, reflectance);
        EXPECT_NEAR(v["luminous_efficiency"].get<double>(), xyz[1], 1e-9);
    }
    double least = 1e300;
    for (const auto& v : survey["views"]) least = std::min(least, v["loss"].get<double>());
    EXPECT_EQ(survey["best"]["loss"].get<double>(), least);
}

// A start relief (DesignOptions::start_heights_um) with no relaxed iterations and no discrete
// passes comes back as it was: the levels bit for bit and the heights exactly, on the run's own
// levels (a colour target: H/(K − 1)) and on the anti-mirror's free step (the start's own, which
// design.json reports as the step's start). Without the start the loop begins at random and the
// levels differ. With passes the loop starts there: its first curve point is the start's loss.
TEST(Design, AStartReliefIsKeptWhenTheLoopDoesNothingAndIsWhereTheLoopStarts) {
    std::mt19937_64 rng(11);
    std::vector<int> start(256);
    for (int& l : start) l = static_cast<int>(rng() % 4);
    DesignOptions o = test::small_design("colour:#80a0c0", 4, 0, 0);
    const double step = 1.0 / 3.0;  // --height-range-um 1 on 4 levels
    o.height_range_um = 1.0;
    for (int l : start) o.start_heights_um.push_back(step * l);
    DesignResult r = run_design(prepare_design(o));
    EXPECT_EQ(r.level, start);
    EXPECT_EQ(r.heights_um, o.start_heights_um);
    o.start_heights_um.clear();
    EXPECT_NE(run_design(prepare_design(o)).level, start);  // a random start is another relief

    DesignOptions a = test::small_design("anti-mirror", 4, 0, 0);
    for (int l : start) a.start_heights_um.push_back(0.13 * l);
    r = run_design(prepare_design(a));
    EXPECT_EQ(r.level, start);
    for (std::size_t t = 0; t < start.size(); ++t) EXPECT_NEAR(r.heights_um[t], a.start_heights_um[t], 1e-15);
    const auto j = nlohmann::json::parse(r.metrics_json);
    EXPECT_NEAR(j["level_step"]["start_um"].get<double>(), 0.13, 1e-15);
    EXPECT_EQ(j["start"].get<std::string>().rfind("the given relief", 0), 0u);

    a.refine_passes = 5;
    const PreparedDesign p = prepare_design(a);
    const double start_loss = run_design(p).curve.front().loss;
    a.refine_passes = 0;
    DesignResult kept = run_design(prepare_design(a));
    EXPECT_EQ(kept.curve.front().loss, start_loss);  // the refinement's first point: the start's loss
}

TEST(Design, ABadStartFailsBeforeAnyWorkNamingTheValue) {
    DesignOptions o = test::small_design("colour:#80a0c0", 4, 0, 0);
    o.height_range_um = 1.0;
    auto message = [&](const std::vector<double>& h) {
        o.start_heights_um = h;
        try {
            (void)prepare_design(o);
        } catch (const std::exception& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message(std::vector<double>(255, 0.0)).find("255 texels; expected 16 x 16"), std::string::npos);
    std::vector<double> h(256, 0.0);
    h[7] = 0.2;  // between 0 and 1/3
    EXPECT_NE(message(h).find("0.2 um is not on the levels"), std::string::npos);
    h[7] = 1.5;
    EXPECT_NE(message(h).find("1.5 um is outside"), std::string::npos);
    h[7] = std::nan("");
    EXPECT_NE(message(h).find("nan"), std::string::npos);
    DesignOptions a = test::small_design("anti-mirror", 4, 0, 0);
    a.height_range_um = 1.0;
    a.start_heights_um.assign(256, 0.0);
    a.start_heights_um[3] = 0.5;  // one height 0.5: level 1 of step 0.5, 4 levels reach 1.5 um
    EXPECT_THROW(prepare_design(a), std::domain_error);
    a.start_heights_um[3] = 0.25;
    a.start_heights_um[4] = 0.6;  // 0.6 is not a multiple of the smallest gap 0.25
    EXPECT_THROW(prepare_design(a), std::invalid_argument);
}

}  // namespace
}  // namespace wavebrdf
