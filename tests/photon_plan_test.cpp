// Photon-aware planning (photon_plan.h): the exposure count against its definition, the 1/N
// scaling of the photon-limited variance it rests on, the proxy tile's prediction against the
// error bars of the whole tile (an independent evaluation: another tile, other positions), and
// the recovery: a nm surface at 10⁴ photons misses the target with one exposure per slice and
// meets it with the planned exposures (measured against the truth), while a µm surface keeps
// its plan bit for bit.
#include "wavebrdf/photon_plan.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <stdexcept>

#include "recover_util.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/conditioning.h"
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

// A 16² surface of 30 nm peak to valley at 10⁴ photons per slice: the planner predicts a miss
// with one exposure and takes the exposures that meet 1 %; the truth agrees on both sides
// (measured 1.29 % without the plan, 0.70 % with 7 exposures).
TEST(PhotonPlan, ANanometreSurfaceGetsTheExposuresThatMeetTheTarget) {
    const PreparedRecovery off = prepare_recovery(nm_run(0.0));
    EXPECT_FALSE(off.photon_plan.has_value());
    EXPECT_EQ(off.noise.level, 1e4);
    const double error_off = height_rel_rmse(run_recovery(off), *off.truth);
    EXPECT_GT(error_off, 0.01);

    const PreparedRecovery on = prepare_recovery(nm_run(0.01));
    ASSERT_TRUE(on.photon_plan.has_value());
    const PhotonPlan& p = *on.photon_plan;
    EXPECT_GT(p.single_rms_um / p.range_um, 0.01);
    EXPECT_GT(p.exposures, 1);
    EXPECT_FALSE(p.capped);
    EXPECT_LE(p.rms_um / p.range_um, 0.01);
    // The fewest: one exposure less misses (the variance and the bias at k − 1).
    const double single_variance = p.single_rms_um * p.single_rms_um - p.single_bias_um * p.single_bias_um;
    const double fewer_bias = photon_limited_bias_um(*on.truth, p, p.exposures - 1);
    EXPECT_GT(std::sqrt(single_variance / (p.exposures - 1) + fewer_bias * fewer_bias) / p.range_um, 0.01);
    EXPECT_EQ(on.noise.level, 1e4 * p.exposures);
    EXPECT_EQ(on.loss.kind, LossKind::Poisson);
    EXPECT_EQ(on.loss.photons, 1e4 * p.exposures);
    EXPECT_EQ(on.observations.size(), off.observations.size());
    EXPECT_NE(on.notes.back().find(std::to_string(p.exposures) + " exposures per slice, summed"), std::string::npos)
        << on.notes.back();
    const double error_on = height_rel_rmse(run_recovery(on), *on.truth);
    std::printf("one exposure %.3f %%, %d exposures %.3f %% (predicted %.3f %%, %.3f %%)\n", 100.0 * error_off,
                p.exposures, 100.0 * error_on, 100.0 * p.single_rms_um / p.range_um, 100.0 * p.rms_um / p.range_um);
    EXPECT_LE(error_on, 0.01);

    // Capped: the plan says so and takes the cap.
    RecoveryOptions capped = nm_run(0.01);
    capped.max_exposures = 2;
    const PreparedRecovery c = prepare_recovery(capped);
    ASSERT_TRUE(c.photon_plan.has_value());
    EXPECT_TRUE(c.photon_plan->capped);
    EXPECT_EQ(c.photon_plan->exposures, 2);
    EXPECT_NE(c.notes.back().find("the target is not met"), std::string::npos) << c.notes.back();
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
// bars alone fell short), one exposure of 10⁴ photons per slice. The predicted rms error (the
// bars' variance and the photon-limited bias) within 15 % of the draws' (their own spread over
// six draws: about ± 4 %; 24 draws measured 3.15 %, the bars alone 2.89 %); the bars alone below
// the draws: the bias is what they miss. Skipped without the shared scans.
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
    const double predicted = plan.single_rms_um / plan.range_um;
    const double bars = std::sqrt(predicted * predicted - std::pow(plan.single_bias_um / plan.range_um, 2));
    std::printf("draws %.3f %%, predicted %.3f %% (bars %.3f %%, bias %.3f %%)\n", 100.0 * measured,
                100.0 * predicted, 100.0 * bars, 100.0 * plan.single_bias_um / plan.range_um);
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
    EXPECT_LT(on.photon_plan->single_rms_um / on.photon_plan->range_um, 0.01);
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
