// Oblique light and GHS-type observations in the recovery (recovery/field_proxy.h;
// experiments/2026-11-23-oblique-light-and-models.md): the separable proxy against the
// renderer, and end-to-end recoveries of a small tile.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include "recovery/field_proxy.h"
#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/recover.h"

namespace wavebrdf {
namespace {

// A 12² tile of max |H| = 0.5 µm (2 µm texels, correlation 8 µm), as recover_test's small case.
Heightfield small_surface(std::uint64_t seed) { return test::peak_scaled_surface(12, 8.0, 0.5, seed); }

// 6 × 6 jittered positions (σ_p = 3 µm, 78 % overlap) at λ = 0.5 and 0.6 µm, `model` under `omega_i`.
std::vector<Observation> small_oblique_observations(const Heightfield& truth, Model model, std::array<double, 2> omega_i,
                                            std::uint64_t seed, int resolution) {
    std::vector<Observation> observations;
    std::mt19937_64 rng(seed + 100);
    std::uniform_real_distribution<double> jitter(-0.2, 0.2);
    const double step = 4.0;
    for (double lambda : {0.5, 0.6})
        for (int a = 0; a < 6; ++a)
            for (int b = 0; b < 6; ++b) {
                Observation o;
                o.query = test::make_query(model, (a + 0.5 + jitter(rng)) * step, (b + 0.5 + jitter(rng)) * step, 3.0,
                                           omega_i[0], omega_i[1]);
                o.lambdas_um.assign(1, lambda);
                o.resolution = resolution;
                o.reference = to_reference(render_observation(truth, o));
                observations.push_back(std::move(o));
            }
    return observations;
}

RecoverSettings quick_settings() {
    RecoverSettings s;
    s.blurred.blur_widths = {12.0, 4.0};
    s.blurred.iterations = 15;
    s.field.iterations = 40;
    s.field_wavelengths = 0;  // every wavelength's field (the smooth schedule's is the longest's alone)
    s.refine_iterations = 15;
    return s;
}

// Each stage's last height_rel_rmse and the final estimate's.
struct SmallRun {
    std::map<std::string, double> stage_rmse;
    double rmse = 0.0;
};
SmallRun recover_small(const Heightfield& truth, const std::vector<Observation>& observations) {
    SmallRun run;
    const Heightfield estimate = recover_heights(
        observations, 12, 12, 2.0, 1.0, quick_settings(),
        [&](const StageMetrics& m) {
            if (m.height_rel_rmse >= 0.0) run.stage_rmse[m.stage] = m.height_rel_rmse;
            return true;
        },
        &truth);
    run.rmse = height_rel_rmse(estimate, truth);
    return run;
}

TEST(FieldProxy, MapsModelsAndScales) {
    EXPECT_EQ(detail::field_proxy_model(Model::OHS), Model::OHS);
    EXPECT_EQ(detail::field_proxy_model(Model::GHS), Model::OHS);
    EXPECT_EQ(detail::field_proxy_model(Model::ROHS), Model::ROHS);
    EXPECT_EQ(detail::field_proxy_model(Model::RGHS), Model::ROHS);
    EXPECT_THROW(detail::field_proxy_model(Model::Kirchhoff), std::invalid_argument);
    EXPECT_FALSE(detail::has_field_stage(Model::Kirchhoff));
    EXPECT_TRUE(detail::has_field_stage(Model::GHS));
    EXPECT_EQ(detail::field_height_scale(test::make_query(Model::OHS, 0, 0, 3, 0.6, 0.0)), 1.0);
    EXPECT_NEAR(detail::field_height_scale(test::make_query(Model::GHS, 0, 0, 3, 0.6, 0.0)), 0.8, 1e-15);
    EXPECT_NEAR(detail::field_height_scale(test::make_query(Model::RGHS, 0, 0, 3, 0.0, -0.6)), 0.8, 1e-15);
}

// The proxy against the renderer: where cos θ_o = cos θ_i (|ω_o| = |ω_i|, C3/2 = cos θ_i), a
// GHS slice of H is the OHS slice of cos θ_i · H; the OHS slice of H itself is far from it.
TEST(FieldProxy, GhsSliceIsTheOhsSliceOfScaledHeightsWhereCosThetaOIsCosThetaI) {
    const Heightfield truth = small_surface(6401);
    const int n = 16;
    const double a = slice_omega(10, n), b = slice_omega(6, n);  // 0.3125, −0.1875: pixel centres
    for (Model model : {Model::GHS, Model::RGHS}) {
        const Query ghs = test::make_query(model, 12.0, 10.0, 3.0, a, b);
        Query proxy = ghs;
        proxy.model = detail::field_proxy_model(model);
        const double s = detail::field_height_scale(ghs);
        std::vector<double> scaled = truth.values();
        for (double& v : scaled) v *= s;
        const std::vector<double> f_ghs = render_slice<double>(truth, ghs, 0.5, n);
        const std::vector<double> f_proxy = render_slice<double>(truth.with_values(scaled), proxy, 0.5, n);
        const std::vector<double> f_unscaled = render_slice<double>(truth, proxy, 0.5, n);
        const double peak = *std::max_element(f_ghs.begin(), f_ghs.end());
        ASSERT_GT(peak, 0.0);
        int matched = 0;
        double worst = 0.0, unscaled = 0.0;
        for (int p = 0; p < n; ++p)
            for (int q = 0; q < n; ++q) {
                const double ox = slice_omega(p, n), oy = slice_omega(q, n);
                if (std::abs(ox * ox + oy * oy - (a * a + b * b)) > 1e-12) continue;
                const std::size_t at = std::size_t(p) * n + q;
                ++matched;
                worst = std::max(worst, std::abs(f_ghs[at] - f_proxy[at]) / peak);
                unscaled = std::max(unscaled, std::abs(f_ghs[at] - f_unscaled[at]) / peak);
            }
        EXPECT_EQ(matched, 8);  // (±a, ±b) and (±b, ±a)
        EXPECT_LT(worst, 1e-4) << to_string(model);
        EXPECT_GT(unscaled, 1e-2) << to_string(model);
    }
}

TEST(RecoverOblique, OhsUnderObliqueLightRecoversASmallTile) {
    const Heightfield truth = small_surface(6402);
    const SmallRun run = recover_small(truth, small_oblique_observations(truth, Model::OHS, {0.4, 0.2}, 6402, 32));
    ASSERT_TRUE(run.stage_rmse.count("unwrap"));
    EXPECT_LT(run.stage_rmse.at("unwrap"), 0.02);
    EXPECT_LT(run.rmse, 0.01);
}

// GHS slices under oblique light (cos θ_i = 0.866: the heights' scale 13 % off without the
// proxy's correction): the field stage through the proxy, the refinement in GHS.
TEST(RecoverOblique, GhsSlicesRecoverThroughTheSeparableProxy) {
    const Heightfield truth = small_surface(6403);
    const SmallRun run = recover_small(truth, small_oblique_observations(truth, Model::GHS, {0.5, 0.0}, 6403, 32));
    ASSERT_TRUE(run.stage_rmse.count("unwrap"));
    // Measured: 2.6 % with the proxy's scale, 3.8 % without it (the proxy at s = 1), Release;
    // 3.5 % with the proxy in the sanitizer build (RelWithDebInfo: other rounding, other field
    // iterations on this 12² tile). The unwrapped stage only guards against a gross failure here;
    // the proxy's scale itself is checked against the renderer (FieldProxy.*), and the final bound
    // below is the recovery's.
    EXPECT_LT(run.stage_rmse.at("unwrap"), 0.045);
    EXPECT_LT(run.rmse, 0.01);
}

TEST(RecoverOblique, RefusesGhsSlicesUnderDifferentLights) {
    const Heightfield truth = small_surface(6404);
    std::vector<Observation> observations = small_oblique_observations(truth, Model::GHS, {0.3, 0.0}, 6404, 8);
    observations.back().query.omega_i = {0.0, 0.2};
    RecoverSettings s = quick_settings();
    s.blurred.iterations = 0;
    try {
        recover_heights(observations, 12, 12, 2.0, 1.0, s);
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("one light direction"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace wavebrdf
