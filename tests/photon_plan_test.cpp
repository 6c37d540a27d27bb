// Photon-aware planning (photon_plan.h): the exposure count against its definition, the 1/N
// scaling of the error bars, the proxy tile's bars against those of the whole tile (an
// independent evaluation: another tile, other positions), the Monte Carlo's solver against the
// truth without noise and against the recovery's estimate, the plan's seed, and the recovery: a
// nm surface at 10⁴ photons misses the target with one exposure per slice and gets the exposures
// whose Monte Carlo meets it, its error over noise draws what the Monte Carlo said, while a µm
// surface keeps its plan bit for bit.
#include "wavebrdf/photon_plan.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <stdexcept>

#include "recover_util.h"
#include "core/random.h"
#include "recovery/photon_proxy.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/conditioning.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/surface_file.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {
namespace {

TEST(PhotonPlan, ExposuresAreTheFewestThatMeetTheTarget) {
    for (double single : {0.0, 0.3, 1.0, 1.0000001, 2.01, 2.5, 3.99, 7.0}) {
        // A variance alone (single / √k) and a variance with a bias that falls as 1/k.
        const std::function<double(int)> variance = [=](int k) { return single / std::sqrt(double(k)); };
        const std::function<double(int)> biased = [=](int k) {
            return std::sqrt(single * single / k + 0.25 * single * single / (double(k) * k));
        };
        for (const auto& rms : {variance, biased}) {
            // By the definition: the smallest k with rms(k) ≤ 1, by counting.
            int k = 1;
            while (rms(k) > 1.0) ++k;
            bool capped = true;
            EXPECT_EQ(exposures_for_target(rms, 1.0, 1000, &capped), k) << single;
            EXPECT_FALSE(capped);
            const int held = exposures_for_target(rms, 1.0, 3, &capped);
            EXPECT_EQ(held, std::min(k, 3)) << single;
            EXPECT_EQ(capped, k > 3) << single;
        }
    }
    const auto root = [](double single) { return [=](int k) { return single / std::sqrt(double(k)); }; };
    EXPECT_EQ(exposures_for_target(root(2.0), 0.5, 100), 16);  // (2 / 0.5)² exactly
    EXPECT_THROW(exposures_for_target(root(-1.0), 1.0, 4), std::domain_error);
    EXPECT_THROW(exposures_for_target(root(NAN), 1.0, 4), std::domain_error);
    EXPECT_THROW(exposures_for_target(root(1.0), 0.0, 4), std::domain_error);
    EXPECT_THROW(exposures_for_target(root(1.0), 1.0, 0), std::domain_error);
}

struct NmTile {
    Heightfield truth;
    AcquisitionPlan plan;
};

// A rows² nm-smooth tile (2 µm texels, max |H| 0.01 µm, correlation 6 µm) and the planner's
// acquisition for it with 32² slices.
NmTile nm_tile(int rows, std::uint64_t seed) {
    NmTile t{test::peak_scaled_surface(rows, 6.0, 0.01, seed), {}};
    PlanRequest request;
    request.rows = request.cols = rows;
    request.texel_um = 2.0;
    request.height_range_um = 0.02;
    request.resolution = 32;
    request.seed = seed;
    t.plan = plan_acquisition(request);
    return t;
}

// k exposures of N photons summed hold k·N: the Fisher information is k times, the predicted
// rms error 1/√k times (what exposures_for_target counts on).
TEST(PhotonPlan, ThePredictedErrorFallsAsOneOverTheRootOfThePhotons) {
    const NmTile t = nm_tile(16, 3);
    const double one = predict_photon_limited_rms_um(t.truth, t.plan, 1e4);
    const double four = predict_photon_limited_rms_um(t.truth, t.plan, 4e4);
    EXPECT_GT(one, 0.0);
    EXPECT_NEAR(four / one, 0.5, 1e-6);
    EXPECT_THROW(predict_photon_limited_rms_um(t.truth, t.plan, 0.0), std::domain_error);
    PhotonPlanSettings bad;
    bad.proxy_texels = 2;
    EXPECT_THROW(predict_photon_limited_rms_um(t.truth, t.plan, 1e4, bad), std::domain_error);
}

// The proxy (a 16² tile cut from the middle, made periodic, the raster's density) against the
// error bars of the whole 40² tile observed by the whole plan (289 observations against the
// proxy's 49): the same rms error within 20 % (measured 0.791 nm against 0.832 nm).
TEST(PhotonPlan, TheProxyTilePredictsTheErrorBarsOfTheWholeTile) {
    const NmTile t = nm_tile(40, 5);
    PhotonPlan details;
    const double proxy = predict_photon_limited_rms_um(t.truth, t.plan, 1e4, {}, &details);
    EXPECT_EQ(details.proxy_rows, 16);
    EXPECT_EQ(details.proxy_cols, 16);
    const std::vector<Observation> observations = simulate_observations(t.truth, t.plan, Noise{}, 1);
    const HeightUncertainty whole = height_uncertainty(observations, t.truth, Loss{LossKind::Poisson, 1.0, 1e4});
    double sum = 0.0;
    for (double s : whole.sigma_um) sum += s * s;
    const double bars = std::sqrt(sum / double(whole.sigma_um.size()));
    std::printf("proxy %.4g nm (%zu observations, density ratio %.3f), whole tile's bars %.4g nm (%zu)\n",
                1e3 * proxy, details.proxy_observations, details.density_ratio, 1e3 * bars, observations.size());
    EXPECT_NEAR(proxy / bars, 1.0, 0.2);
}

RecoveryOptions nm_run(double target) {
    RecoveryOptions options;
    options.rows = options.cols = 16;
    options.resolution = 32;
    options.height_range_um = 0.03;
    options.noise = parse_noise("poisson:1e4");
    options.seed = 4;
    options.target_error = target;
    return options;
}

// The rms (µm) of a − b over the texels, each mean removed, a and b in µm.
double rms_difference_um(const std::vector<double>& a, const std::vector<double>& b) {
    double mean = 0.0, square = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) mean += (a[i] - b[i]) / double(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) square += std::pow(a[i] - b[i] - mean, 2) / double(a.size());
    return std::sqrt(square);
}

std::vector<double> in_um(const Heightfield& h) {
    std::vector<double> v = h.values();
    for (double& x : v) x *= h.texel_um() * h.vscale();
    return v;
}

// A 16² surface of 30 nm peak to valley at 10⁴ photons per slice: one exposure per slice misses
// the 1 % target (1.29 %); the planner's Monte Carlo of the estimator takes the fewest exposures
// whose bound meets it, and the recovery's rms error over eight noise draws at those exposures
// (the truth fixed) is what the Monte Carlo said within 12 % (measured: 3 exposures, Monte Carlo
// 0.93-0.94 % over two sets of draws, the recovery 0.962 %; the Monte Carlo at one exposure 1.285 %). On this surface the error
// bars over-predict (2.59 % with one exposure: modes the photons do not resolve come back
// shrunk, below the bars): the closed-form rule that planned before (the bars' variance and a
// bias) took 7 exposures, where the recovery gave 0.70 % (the Monte Carlo at 7: 0.74 %).
TEST(PhotonPlan, ANanometreSurfaceGetsTheExposuresThatMeetTheTarget) {
    const PreparedRecovery off = prepare_recovery(nm_run(0.0));
    EXPECT_FALSE(off.photon_plan.has_value());
    EXPECT_EQ(off.noise.level, 1e4);
    const double error_off = height_rel_rmse(run_recovery(off), *off.truth);
    EXPECT_GT(error_off, 0.01);

    const PreparedRecovery on = prepare_recovery(nm_run(0.01));
    ASSERT_TRUE(on.photon_plan.has_value());
    const PhotonPlan& p = *on.photon_plan;
    EXPECT_GT(p.exposures, 1);
    EXPECT_FALSE(p.capped);
    EXPECT_LE(p.bound_um / p.range_um, 0.01);
    EXPECT_LE(p.rms_um, p.bound_um);
    // The fewest: one exposure less misses (its Monte Carlo was run by the search).
    bool fewer_tried = false;
    for (const PhotonPlan::MonteCarlo& m : p.tried)
        if (m.exposures == p.exposures - 1) {
            fewer_tried = true;
            EXPECT_GT(m.bound_um / p.range_um, 0.01);
        }
    EXPECT_TRUE(fewer_tried);
    EXPECT_EQ(on.noise.level, 1e4 * p.exposures);
    EXPECT_EQ(on.loss.kind, LossKind::Poisson);
    EXPECT_EQ(on.loss.photons, 1e4 * p.exposures);
    EXPECT_EQ(on.observations.size(), off.observations.size());
    EXPECT_NE(on.notes.back().find(std::to_string(p.exposures) + " exposures per slice, summed"), std::string::npos)
        << on.notes.back();

    // The recovery at the planned exposures over noise draws (k exposures summed: one draw of k·N).
    RecoveryOptions draws = nm_run(0.0);
    draws.noise.level = 1e4 * p.exposures;
    double sum = 0.0;
    const int n = 8;
    for (int d = 0; d < n; ++d) {
        draws.seed = std::uint64_t(11 + d);
        const PreparedRecovery r = prepare_recovery(draws, &*on.truth);
        const double e = height_rel_rmse(run_recovery(r), *on.truth);
        sum += e * e;
    }
    const double measured = std::sqrt(sum / n);
    std::printf("one exposure %.3f %%, %d exposures over %d draws %.3f %% (bars %.3f %% with one; Monte Carlo %.3f %%, "
                "bound %.3f %%; %d gradients, %.2f s)\n", 100.0 * error_off, p.exposures, n, 100.0 * measured,
                100.0 * p.bars_rms_um / p.range_um, 100.0 * p.rms_um / p.range_um, 100.0 * p.bound_um / p.range_um,
                p.gradients, p.seconds);
    EXPECT_NEAR(p.rms_um / p.range_um / measured, 1.0, 0.12);

    // Capped: the plan says so and takes the cap.
    RecoveryOptions capped = nm_run(0.01);
    capped.max_exposures = 2;
    const PreparedRecovery c = prepare_recovery(capped);
    ASSERT_TRUE(c.photon_plan.has_value());
    EXPECT_TRUE(c.photon_plan->capped);
    EXPECT_EQ(c.photon_plan->exposures, 2);
    EXPECT_NE(c.notes.back().find("the target is not met"), std::string::npos) << c.notes.back();
}

// The Monte Carlo's solver (recovery/photon_proxy.h) without noise, from the truth displaced
// (a) along one Fourier mode (3, 2 cycles per tile) by a fifth of the error bars: one step (G⁻¹
// times the deviance's gradient, nothing learnt yet) takes most of the way back without a
// halving (measured: 21 % left), so the gradient's and G's scales agree (G⁻¹ twice too large
// would need a halving, twice too small leave half); not all the way, since G⁻¹ is not the
// Hessian's inverse to the last digit in G's weakest directions (its forward differences, G's
// condition); (b) by a fifth of the bars at every texel, signs at random, the steps that follow
// go on to the truth (measured: 0.34 % left after 11 steps).
TEST(PhotonPlan, TheMonteCarloSolverStepsBackToTheTruthWithoutNoise) {
    const NmTile t = nm_tile(16, 3);
    const std::vector<Observation> noiseless = simulate_observations(t.truth, t.plan, Noise{}, 1);
    const detail::PhotonProxy proxy = detail::photon_proxy(t.truth, noiseless, 1e4, 1.0);
    const double sd_um = std::sqrt(detail::proxy_bars_variance_um2(proxy));
    const double to_raw = 1.0 / (t.truth.texel_um() * t.truth.vscale());
    const auto solve = [&](const std::vector<double>& start, double tolerance_um, const char* what) {
        ObservationPlans plans;
        const detail::ProxySolve s = detail::proxy_maximum_likelihood(proxy, noiseless, 1e4, start, tolerance_um, plans);
        const double displaced = rms_difference_um(in_um(t.truth.with_values(start)), in_um(t.truth));
        const double left = rms_difference_um(in_um(t.truth.with_values(s.heights)), in_um(t.truth));
        std::printf("%s: displaced %.4g nm, left %.4g nm (%d steps, %d halvings)\n", what, 1e3 * displaced, 1e3 * left,
                    s.steps, s.halvings);
        return std::array<double, 4>{{displaced, left, double(s.steps), double(s.halvings)}};
    };
    std::vector<double> mode = t.truth.values(), white = t.truth.values();
    std::mt19937_64 rng(7);
    for (int r = 0; r < 16; ++r)
        for (int c = 0; c < 16; ++c) {
            mode[t.truth.index(r, c)] += 0.2 * std::sqrt(2.0) * sd_um * to_raw * std::cos(2.0 * k_pi * (3.0 * r + 2.0 * c) / 16.0);
            white[t.truth.index(r, c)] += 0.2 * sd_um * to_raw * (detail::uniform01(rng) < 0.5 ? -1.0 : 1.0);
        }
    const std::array<double, 4> one = solve(mode, 1e9, "mode, one step");
    EXPECT_EQ(one[2], 1.0);
    EXPECT_EQ(one[3], 0.0);
    EXPECT_LT(one[1], 0.3 * one[0]);
    const std::array<double, 4> all = solve(white, 1e-3 * sd_um, "white, to 0.1 % of the bars");
    EXPECT_LT(all[1], 0.02 * all[0]);
}

// The solver against the recovery (an independent path: the whole pipeline from no knowledge of
// the truth) on the recovery's own noisy slices, one exposure: the solver, started at the truth,
// finds the recovery's estimate (their difference a small part of the error).
TEST(PhotonPlan, TheMonteCarloSolverFindsTheRecoverysEstimate) {
    const PreparedRecovery r = prepare_recovery(nm_run(0.0));
    const Heightfield estimate = run_recovery(r);
    std::vector<Observation> noiseless = r.observations;
    for (Observation& o : noiseless) o.reference = to_reference(render_observation(*r.truth, o));
    const detail::PhotonProxy proxy = detail::photon_proxy(*r.truth, noiseless, 1e4, 1.0);
    const double sd_um = std::sqrt(detail::proxy_bars_variance_um2(proxy));
    ObservationPlans plans;
    const detail::ProxySolve s =
        detail::proxy_maximum_likelihood(proxy, r.observations, 1e4, r.truth->values(), 0.01 * sd_um, plans);
    const std::vector<double> truth = in_um(*r.truth), mc = in_um(r.truth->with_values(s.heights));
    const double error_recovery = rms_difference_um(in_um(estimate), truth);
    const double error_mc = rms_difference_um(mc, truth);
    const double apart = rms_difference_um(mc, in_um(estimate));
    std::printf("recovery %.4g nm, solver %.4g nm (%d steps, %d gradients), apart %.4g nm\n", 1e3 * error_recovery,
                1e3 * error_mc, s.steps, s.gradients, 1e3 * apart);
    EXPECT_LT(apart, 0.25 * error_recovery);
    EXPECT_NEAR(error_mc / error_recovery, 1.0, 0.1);
}

// The same seed gives the same plan, bit for bit; another seed draws other noise. A small proxy
// (8²) keeps it quick.
TEST(PhotonPlan, ThePlanDependsOnTheSeedAlone) {
    const NmTile t = nm_tile(16, 3);
    PhotonPlanSettings settings;
    settings.proxy_texels = 8;
    const PhotonPlan a = plan_exposures(t.truth, t.plan, 1e4, 0.05, settings);
    const PhotonPlan b = plan_exposures(t.truth, t.plan, 1e4, 0.05, settings);
    settings.seed = 2;
    const PhotonPlan c = plan_exposures(t.truth, t.plan, 1e4, 0.05, settings);
    EXPECT_EQ(a.exposures, b.exposures);
    EXPECT_EQ(a.rms_um, b.rms_um);
    EXPECT_EQ(a.bound_um, b.bound_um);
    EXPECT_EQ(a.note, b.note);
    EXPECT_NE(a.rms_um, c.rms_um);
    std::printf("seed 1: %d exposures, %.4g nm; seed 2: %d exposures, %.4g nm\n", a.exposures, 1e3 * a.rms_um,
                c.exposures, 1e3 * c.rms_um);
}

// ../shared/real-surfaces/ beside the repository (or beside the worktree's parent), else "".
std::filesystem::path shared_surfaces() {
    namespace fs = std::filesystem;
    for (const fs::path& p : {fs::path(WAVEBRDF_SOURCE_DIR) / ".." / "shared" / "real-surfaces",
                              fs::path(WAVEBRDF_SOURCE_DIR) / ".." / ".." / "shared" / "real-surfaces"})
        if (fs::is_directory(p)) return fs::canonical(p);
    return {};
}

// The prediction against the truth over noise draws (an independent evaluation: the recovery
// itself, six draws of the noise and the raster's jitter): a 32² patch of the finely striated
// scan plu-1 (42.7 nm peak to valley; its power reaches the highest frequencies, where the error
// bars alone fell short), one exposure of 10⁴ photons per slice. The planner's Monte Carlo on its
// 16² proxy within 15 % of the draws' rms error (their own spread over six draws: about ± 4 %;
// measured 2.78 % against 3.14 %; 24 draws measured 3.15 %: the Monte Carlo from the truth is
// about 10 % low here, on a 32² proxy too, 2.85 %: the recovery ends in another maximum of the
// likelihood than the one by the truth); the bars alone below the draws.
// Skipped without the shared scans.
TEST(PhotonPlan, ThePredictionMatchesTheErrorOverNoiseDraws) {
    const std::filesystem::path dir = shared_surfaces();
    if (dir.empty()) GTEST_SKIP() << "../shared/real-surfaces/ not found";
    ConditioningOptions c;
    c.crop = std::array<int, 4>{{300, 200, 32, 32}};
    c.detrend_order = 1;
    c.periodic = PeriodicMethod::Smooth;
    const std::string path = (dir / "SurfaceTopography__plu-1.plu").string();
    const Heightfield truth = to_heightfield(condition(read_surface(path), c), path);
    RecoveryOptions options = nm_run(0.01);
    options.resolution = 48;
    options.max_exposures = 1;
    double sum = 0.0;
    PhotonPlan plan;
    const int draws = 6;
    for (int d = 0; d < draws; ++d) {
        options.seed = std::uint64_t(1 + d);
        const PreparedRecovery r = prepare_recovery(options, &truth);
        ASSERT_TRUE(r.photon_plan.has_value());
        ASSERT_EQ(r.photon_plan->exposures, 1);
        plan = *r.photon_plan;
        const double e = height_rel_rmse(run_recovery(r), truth);
        sum += e * e;
    }
    const double measured = std::sqrt(sum / draws);
    const double predicted = plan.rms_um / plan.range_um;
    const double bars = plan.bars_rms_um / plan.range_um;
    std::printf("draws %.3f %%, predicted %.3f %% (bars %.3f %%)\n", 100.0 * measured, 100.0 * predicted, 100.0 * bars);
    EXPECT_NEAR(predicted / measured, 1.0, 0.15);
    EXPECT_LT(bars, measured);
}

// A 2 µm surface at the same photons meets the target with one exposure: the plan, the noise,
// the loss and every simulated slice are those of a run without photon planning.
TEST(PhotonPlan, ASurfaceThatMeetsTheTargetKeepsItsPlan) {
    RecoveryOptions options = nm_run(0.01);
    options.height_range_um = 2.0;
    const PreparedRecovery on = prepare_recovery(options);
    options.target_error = 0.0;
    const PreparedRecovery off = prepare_recovery(options);
    ASSERT_TRUE(on.photon_plan.has_value());
    EXPECT_EQ(on.photon_plan->exposures, 1);
    EXPECT_LT(on.photon_plan->bound_um / on.photon_plan->range_um, 0.01);
    EXPECT_EQ(on.noise.level, 1e4);
    EXPECT_EQ(on.loss.photons, off.loss.photons);
    ASSERT_EQ(on.observations.size(), off.observations.size());
    for (std::size_t k = 0; k < on.observations.size(); ++k)
        ASSERT_EQ(on.observations[k].reference, off.observations[k].reference) << k;
}

TEST(PhotonPlan, OptionsOutOfRangeAreRefused) {
    RecoveryOptions options = nm_run(1.5);
    EXPECT_THROW(check_recovery_options(options, {}), std::invalid_argument);
    options.target_error = NAN;
    EXPECT_THROW(check_recovery_options(options, {}), std::invalid_argument);
    options.target_error = 0.01;
    options.max_exposures = 0;
    try {
        check_recovery_options(options, {});
        ADD_FAILURE() << "max_exposures 0 accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("--max-exposures 0"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace wavebrdf
