// convergence.h: the Poisson deviance's noise floor against draws of the noise (noise.h), and
// the check on slices rendered from a known surface: the surface itself sits on the floor, a
// wrong one far above it. roughness_plan.h's measured roughness against a sinusoid's slopes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf {
namespace {

// The deviance's mean and variance against the sample moments of Poisson draws (independent of
// the exact sums): within 4 standard errors.
TEST(Convergence, DevianceMomentsMatchPoissonDraws) {
    std::mt19937_64 rng(20261129);
    for (double mu : {0.05, 0.3, 2.0, 17.0, 400.0}) {
        double mean = 0.0, variance = 0.0;
        poisson_deviance_moments(mu, mean, variance);
        std::poisson_distribution<long long> draw(mu);
        const int n = 200000;
        double s1 = 0.0, s2 = 0.0;
        for (int i = 0; i < n; ++i) {
            const double k = double(draw(rng));
            const double d = k > 0.0 ? 2.0 * (k * std::log(k / mu) - (k - mu)) : 2.0 * mu;
            s1 += d;
            s2 += d * d;
        }
        const double m = s1 / n, v = s2 / n - m * m;
        EXPECT_NEAR(mean, m, 4.0 * std::sqrt(v / n)) << "mu " << mu;
        EXPECT_NEAR(variance, v, 0.05 * v + 1e-12) << "mu " << mu;
    }
    // Many photons: the chi-square limit, E ≈ 1 + 1/(6μ), Var ≈ 2.
    double mean = 0.0, variance = 0.0;
    poisson_deviance_moments(1e4, mean, variance);
    EXPECT_NEAR(mean, 1.0 + 1.0 / 6e4, 1e-5);
    EXPECT_NEAR(variance, 2.0, 0.01);
    poisson_deviance_moments(0.0, mean, variance);
    EXPECT_EQ(mean, 0.0);
    EXPECT_THROW(poisson_deviance_moments(-1.0, mean, variance), std::domain_error);
}

struct ConvergenceCase {
    Heightfield truth;
    std::vector<Observation> observations;
};

// A 16² surface of ±1 µm seen at 9 positions and two wavelengths, slices rendered by the model.
ConvergenceCase make_case(double photons) {
    SurfaceParams p;
    p.rows = p.cols = 16;
    p.texel_um = 2.0;
    p.correlation_um = 8.0;
    p.seed = 5;
    ConvergenceCase c{with_height_range(generate_heightfield(p).with_scale(2.0, 1.0), 2.0), {}};
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            for (double lambda : {0.5, 0.7}) {
                Observation o;
                o.query.x_um = 4.0 + 10.0 * a;
                o.query.y_um = 4.0 + 10.0 * b;
                o.query.sigma_p_um = 3.0;
                o.lambdas_um = {lambda};
                o.resolution = 32;
                o.reference = to_reference(render_observation(c.truth, o));
                c.observations.push_back(std::move(o));
            }
    if (photons > 0.0) add_noise(c.observations, Noise{NoiseKind::Poisson, photons}, 77);
    return c;
}

TEST(Convergence, TheTruthSitsOnThePhotonNoiseFloorAndAWrongSurfaceDoesNot) {
    const ConvergenceCase c = make_case(1e4);
    const ConvergenceCheck at_truth = check_convergence(c.observations, c.truth, 1e4, false);
    EXPECT_EQ(at_truth.floor, "poisson");
    EXPECT_TRUE(at_truth.converged) << at_truth.warning();
    EXPECT_TRUE(at_truth.warning().empty());
    // The truth leaves the noise alone: D within a few standard deviations of E[D].
    EXPECT_NEAR(at_truth.deviance, at_truth.expected_deviance, 5.0 * at_truth.deviance_sd);
    EXPECT_NEAR(at_truth.misfit_ratio, 1.0, 0.05);
    // Heights 5 % too large (a recovery stopped short of its scale): far above the floor.
    std::vector<double> scaled = c.truth.values();
    for (double& v : scaled) v *= 1.05;
    const Heightfield wrong(16, 16, scaled, 2.0, 1.0);
    const ConvergenceCheck off = check_convergence(c.observations, wrong, 1e4, false);
    EXPECT_FALSE(off.converged);
    EXPECT_GT(off.misfit_ratio, k_misfit_ratio_limit);
    EXPECT_NE(off.warning().find("did not converge"), std::string::npos) << off.warning();
    EXPECT_NE(off.warning().find("photon noise"), std::string::npos) << off.warning();
}

// A slice's limit against χ² quantiles (a χ²_ν is a Gamma of mean ν, variance 2ν; the values
// from scipy.stats.chi2.ppf): the 1 − 10⁻⁴ quantile of χ²₁₀₀ is 161.319, the 1 − 10⁻⁶ quantile
// of χ²₃₀ (10⁻⁴ over 100 slices) is 82.044. No light, no limit.
TEST(Convergence, TheSliceLimitIsTheGammaQuantileAtTheBonferroniLevel) {
    ASSERT_EQ(k_slice_false_alarm, 1e-4);
    EXPECT_NEAR(slice_deviance_limit(100.0, 200.0, 1.0), 161.319, 0.005 * 161.319);
    EXPECT_NEAR(slice_deviance_limit(30.0, 60.0, 100.0), 82.044, 0.01 * 82.044);
    EXPECT_GT(slice_deviance_limit(30.0, 60.0, 1e4), slice_deviance_limit(30.0, 60.0, 100.0));
    EXPECT_EQ(slice_deviance_limit(0.0, 0.0, 10.0), HUGE_VAL);
}

// A local error the whole misfit cannot see: a 64² tile of µm heights seen at 256 positions, and
// the truth with one pit of 2×2 texels 0.015 µm deep (a phase error of 0.38 rad at 0.5 µm, 2
// texels wide: a feature the footprints of a few positions hold). At the truth no slice is off its floor (five noise draws);
// with the pit the summed misfit stays on its floor (256 slices outweigh the few that hold it)
// while the slices over the pit are off theirs, the worst centred within 2 σ_p of it.
TEST(Convergence, ALocalErrorIsSeenSliceBySlice) {
    SurfaceParams sp;
    sp.rows = sp.cols = 64;
    sp.texel_um = 1.0;
    sp.correlation_um = 6.0;
    sp.seed = 9;
    const Heightfield truth = with_height_range(generate_heightfield(sp).with_scale(1.0, 1.0), 0.5);
    std::vector<Observation> clean;
    for (int a = 0; a < 16; ++a)
        for (int b = 0; b < 16; ++b) {
            Observation o;
            o.query.x_um = 2.0 + 4.0 * a;
            o.query.y_um = 2.0 + 4.0 * b;
            o.query.sigma_p_um = 2.0;
            o.lambdas_um = {0.5};
            o.resolution = 32;
            o.reference = to_reference(render_observation(truth, o));
            clean.push_back(std::move(o));
        }
    for (std::uint64_t seed : {11, 12, 13, 14, 15}) {
        std::vector<Observation> noisy = clean;
        add_noise(noisy, Noise{NoiseKind::Poisson, 1e4}, seed);
        const ConvergenceCheck at_truth = check_convergence(noisy, truth, 1e4, false);
        EXPECT_EQ(at_truth.slices_off_floor, 0) << "seed " << seed << ": " << at_truth.warning();
        EXPECT_TRUE(at_truth.converged) << at_truth.warning();
        EXPECT_LT(at_truth.worst_slice_excess, 1.0);
    }
    std::vector<Observation> noisy = clean;
    add_noise(noisy, Noise{NoiseKind::Poisson, 1e4}, 11);
    std::vector<double> pit = truth.values();
    const int r0 = 30, c0 = 41;
    for (int i = r0; i < r0 + 2; ++i)
        for (int j = c0; j < c0 + 2; ++j) pit[std::size_t(i) * 64 + std::size_t(j)] -= 0.015;
    const ConvergenceCheck off = check_convergence(noisy, truth.with_values(pit), 1e4, false);
    std::printf("with the pit: misfit %.4f x the floor (sd %.3g of %.4g), %d slices off their floor, the worst %.3g x "
                "its limit at (%.1f, %.1f) um\n",
                off.misfit_ratio, off.deviance_sd, off.expected_deviance, off.slices_off_floor,
                off.worst_slice_excess, off.worst_slice_x_um, off.worst_slice_y_um);
    EXPECT_TRUE(misfit_on_photon_floor(off.deviance, off.expected_deviance, off.deviance_sd));
    EXPECT_GE(off.slices_off_floor, k_slices_off_floor_min);
    EXPECT_FALSE(off.converged);
    EXPECT_TRUE(off.misfit_failed);
    EXPECT_LT(std::hypot(off.worst_slice_x_um - (r0 + 1.0), off.worst_slice_y_um - (c0 + 1.0)), 4.0);
    EXPECT_NE(off.warning().find("the recovery did not converge: "), std::string::npos) << off.warning();
    EXPECT_NE(off.warning().find("slices are above their own photon-noise floor"), std::string::npos)
        << off.warning();
}

TEST(Convergence, NoiselessSlicesAreJudgedByTheirRounding) {
    const ConvergenceCase c = make_case(0.0);
    const ConvergenceCheck at_truth = check_convergence(c.observations, c.truth, 0.0, true);
    EXPECT_EQ(at_truth.floor, "noiseless");
    EXPECT_TRUE(at_truth.converged);
    EXPECT_LT(at_truth.relative_misfit, 1e-10);
    const Heightfield flat(16, 16, std::vector<double>(256, 0.0), 2.0, 1.0);
    const ConvergenceCheck off = check_convergence(c.observations, flat, 0.0, true);
    EXPECT_FALSE(off.converged);
    // Without a stated noise level nothing is judged, whatever the misfit.
    const ConvergenceCheck unjudged = check_convergence(c.observations, flat, 0.0, false);
    EXPECT_EQ(unjudged.floor, "none");
    EXPECT_TRUE(unjudged.converged);
    EXPECT_GT(unjudged.relative_misfit, 1e-3);
}

TEST(Convergence, WideErrorBarsAreAReason) {
    ConvergenceCheck c;
    add_error_bars(c, 0.004, 2.0);  // 2σ = 0.4 % of the range
    EXPECT_TRUE(c.converged);
    add_error_bars(c, 0.02, 2.0);  // 2σ = 2 %
    EXPECT_FALSE(c.converged);
    EXPECT_NE(c.warning().find("error bars"), std::string::npos) << c.warning();
}

// The noise limit: √(mean σ²) over the range against 1 %, only where the misfit passed
// (needs_error_bars), the warning saying "likely inaccurate" unless the misfit failed too.
TEST(Convergence, TheErrorBarsPredictedRmsErrorIsJudgedAgainstTheTarget) {
    ConvergenceCheck on_floor;
    on_floor.floor = "poisson";
    EXPECT_TRUE(needs_error_bars(on_floor));
    ConvergenceCheck c = on_floor;
    // σ of 0.006 and 0.008 µm on a 1 µm range: √((0.006² + 0.008²) / 2) = 0.00707 → 0.71 %.
    add_predicted_error(c, {0.006, 0.008}, 1.0);
    EXPECT_NEAR(c.predicted_error_relative, std::sqrt(0.00005), 1e-12);
    EXPECT_TRUE(c.converged) << c.warning();
    // The same bars on half the range: 1.41 %, a miss the misfit could not see.
    c = on_floor;
    add_predicted_error(c, {0.006, 0.008}, 0.5);
    EXPECT_FALSE(c.converged);
    EXPECT_EQ(c.warning().rfind("the recovery is likely inaccurate: the misfit is on the photon-noise floor, but the "
                                "error bars predict an rms height error of 1.41 % of the height range",
                                0),
              0u)
        << c.warning();
    // The rms, not the median: one texel in four at 2.4 % of the range, the rest at 0.2 %.
    c = on_floor;
    add_predicted_error(c, {0.002, 0.002, 0.002, 0.024}, 1.0);
    EXPECT_NEAR(c.predicted_error_relative, std::sqrt((3 * 4e-6 + 5.76e-4) / 4.0), 1e-12);
    EXPECT_FALSE(c.converged);
    // Nothing to judge without bars or a range.
    c = on_floor;
    add_predicted_error(c, {}, 1.0);
    add_predicted_error(c, {0.5}, 0.0);
    EXPECT_TRUE(c.converged);
    EXPECT_LT(c.predicted_error_relative, 0.0);
    // Wide bars said already (add_error_bars): no second reason.
    c = on_floor;
    add_error_bars(c, 0.02, 1.0);
    add_predicted_error(c, {0.02, 0.02}, 1.0);
    EXPECT_EQ(c.reasons.size(), 1u);
    // A misfit above the floor, or noiseless slices (judged by their rounding): the bars are
    // not needed for the verdict.
    ConvergenceCheck off = on_floor;
    off.converged = false;
    off.misfit_failed = true;
    EXPECT_FALSE(needs_error_bars(off));
    ConvergenceCheck noiseless;
    noiseless.floor = "noiseless";
    EXPECT_FALSE(needs_error_bars(noiseless));
}

// A loss that states no noise level (amplitude, mse on measured slices): the misfit cannot be
// judged. Error bars, their noise estimated from the residuals, can fail such a run where even
// they exceed the target, but not pass it (narrow at a wrong basin's minimum too): within the
// target it stays reported, not judged.
TEST(Convergence, ALossWithoutANoiseLevelIsFailedByWideErrorBarsButNeverPassed) {
    ConvergenceCheck none;  // floor "none"
    EXPECT_TRUE(needs_error_bars(none));
    EXPECT_FALSE(none.judged());
    ConvergenceCheck c = none;
    add_predicted_error(c, {0.003, 0.004}, 1.0);  // 0.354 %
    EXPECT_TRUE(c.converged);
    EXPECT_FALSE(c.judged());
    c = none;
    add_predicted_error(c, {0.03, 0.04}, 1.0);  // 3.54 %
    EXPECT_FALSE(c.converged);
    EXPECT_TRUE(c.judged());
    EXPECT_EQ(c.warning().rfind("the recovery is likely inaccurate: the misfit is not judged (the loss states no "
                                "noise level), but with the noise estimated from the residuals the error bars "
                                "predict an rms height error of 3.54 % of the height range",
                                0),
              0u)
        << c.warning();
    // Photon counts and noiseless slices are judged by their floor, bars or not.
    ConvergenceCheck poisson;
    poisson.floor = "poisson";
    EXPECT_TRUE(poisson.judged());
}

// The cost rule for the check's own error bars: computed by default (auto) where predicted to
// take at most k_check_error_bars_budget of the recovery's CPU time; always / off override it;
// a prediction or a run time that is not a finite time is never taken as cheap.
TEST(Convergence, TheChecksErrorBarsAreComputedByDefaultOnlyWhereCheap) {
    EXPECT_DOUBLE_EQ(k_check_error_bars_budget, 1.0);
    EXPECT_TRUE(check_error_bars_affordable(CheckErrorBars::Auto, 9.9, 10.0));
    EXPECT_TRUE(check_error_bars_affordable(CheckErrorBars::Auto, 10.0, 10.0));
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Auto, 10.1, 10.0));
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Auto, 26.0, 10.0));  // a 64² dense solve's share
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Auto, std::nan(""), 10.0));
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Auto, 1.0, -1.0));
    const double inf = std::numeric_limits<double>::infinity();
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Auto, inf, inf));
    EXPECT_TRUE(check_error_bars_affordable(CheckErrorBars::Always, 1e9, 1.0));
    EXPECT_FALSE(check_error_bars_affordable(CheckErrorBars::Off, 0.0, 10.0));
    EXPECT_EQ(parse_check_error_bars("auto"), CheckErrorBars::Auto);
    EXPECT_EQ(parse_check_error_bars("always"), CheckErrorBars::Always);
    EXPECT_EQ(parse_check_error_bars("off"), CheckErrorBars::Off);
    for (const CheckErrorBars m : {CheckErrorBars::Auto, CheckErrorBars::Always, CheckErrorBars::Off})
        EXPECT_EQ(parse_check_error_bars(to_string(m)), m);
    try {
        parse_check_error_bars("sometimes");
        FAIL() << "accepted 'sometimes'";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("'sometimes'"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("auto, always or off"), std::string::npos) << e.what();
    }
}

// A sinusoid along x, h = A sin(2π x / L): central differences give the slope
// A sin(2π w / L) / w · cos(2π x / L), rms over whole periods that over √2; its ACF falls to
// 0.2 at the lag where cos(2π τ / L) = 0.2 along x and never along y (a lay along y).
TEST(MeasuredRoughness, ASinusoidsSlopesCorrelationAndLay) {
    const int n = 64;
    const double w = 1.5, L = 16.0 * w, A = 3.0;
    std::vector<double> values(std::size_t(n) * n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            values[std::size_t(i) * n + std::size_t(j)] = A * std::sin(2.0 * M_PI * i * w / L) / w;  // row i along x
    const Heightfield hf(n, n, values, w, 1.0);
    const MeasuredRoughness m = measure_roughness(hf);
    const double slope = A * std::sin(2.0 * M_PI * w / L) / w;
    EXPECT_NEAR(m.rms_slope, slope / std::sqrt(2.0), 1e-9);
    EXPECT_NEAR(m.range_um, 2.0 * A, 1e-9);
    EXPECT_NEAR(m.correlation_um, L * std::acos(0.2) / (2.0 * M_PI), 0.02 * L);
    EXPECT_LT(m.aspect, 0.3);
    EXPECT_NEAR(m.lay_deg, 90.0, 1.0);
    // |slope| > 0.5 where |cos| > 0.5 / slope: counted over the 16 phases a period samples.
    int beyond = 0;
    for (int k = 0; k < 16; ++k) beyond += std::abs(slope * std::cos(2.0 * M_PI * k / 16.0)) > 0.5 ? 1 : 0;
    EXPECT_DOUBLE_EQ(m.rim_fraction, beyond / 16.0);
    // Steep (rms slope over 0.2): oblique lights and long wavelengths; the note names the lay.
    const RoughnessPlan plan = plan_for_measured_roughness(m, w);
    EXPECT_TRUE(plan.rough);
    EXPECT_FALSE(plan.oblique_omega_i.empty());
    ASSERT_FALSE(plan.notes.empty());
    EXPECT_NE(plan.notes.front().find("strongly anisotropic"), std::string::npos) << plan.notes.front();
    // The same surface 10× lower: smooth, nothing added.
    std::vector<double> low = values;
    for (double& v : low) v *= 0.1;
    const RoughnessPlan smooth = plan_for_measured_roughness(measure_roughness(Heightfield(n, n, low, w, 1.0)), w);
    EXPECT_FALSE(smooth.rough);
    EXPECT_TRUE(smooth.oblique_omega_i.empty());
    // One period across the tile, 4 µm high: gentle slopes (rms 0.09) and a long correlation,
    // but a lay and a range beyond the blurred fit's reach at visible wavelengths: long
    // wavelengths, no oblique lights.
    std::vector<double> tall(values.size());
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) tall[std::size_t(i) * n + std::size_t(j)] = 2.0 * std::sin(2.0 * M_PI * i / n) / w;
    const MeasuredRoughness mt = measure_roughness(Heightfield(n, n, tall, w, 1.0));
    EXPECT_LT(mt.rms_slope, 0.2);
    EXPECT_GT(mt.correlation_um / w, 2.5);
    const RoughnessPlan layered = plan_for_measured_roughness(mt, w);
    EXPECT_TRUE(layered.rough);
    EXPECT_FALSE(layered.long_lambdas_um.empty());
    EXPECT_TRUE(layered.oblique_omega_i.empty());
}

}  // namespace
}  // namespace wavebrdf
