// The brightness trade of the colour targets (docs/design.md, "Brightness for chromaticity"):
// a dim colour whose schedule ends below Y 0.05 continues in blocks that give up Δu′v′ within
// the ceiling for luminous efficiency. Checked on the heights alone: exact_orders' power in the
// view cone (design_util.h cone_colour, an evaluation independent of the loop's model) must be
// brighter after the trade and within the ceiling of the target; the trade must start from the
// schedule's own relief (the same loss curve, bit for bit, up to the schedule's end), and the
// final loss must be the colour loss written out here at the tolerances it reports. A grayscale
// relief runs the same blocks; a trade that ends below the brightness is a design.json warning.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "design_util.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf {
namespace {

using test::cone_colour;

// docs/design.md's colour loss of one cone, written out independently of the library.
double colour_loss_of(double delta_uv, double y, double tolerance) {
    const double excess = tolerance > 0.0 ? std::max(0.0, delta_uv - tolerance) : delta_uv;
    const double hinge = std::max(0.0, 0.1 - y) / 0.1;
    return (excess / 0.01) * (excess / 0.01) + 4.0 * hinge * hinge;
}

std::array<double, 2> target_uv(const std::array<double, 3>& linear_rgb) { return xyz_to_uv(linear_srgb_to_xyz(linear_rgb)); }

// Δu′v′ from `target` and Y of the light the heights send into the cone (exact_orders).
std::array<double, 2> scored(const DesignResult& r, std::array<double, 2> view, double cone, std::array<double, 2> target) {
    const auto c = cone_colour(r.heights_um, r.size, r.texel_um, r.lambdas_um, view, cone);
    return {std::hypot(c[1] - target[0], c[2] - target[1]), c[0]};
}

// A 32² tile of 0.5 µm, 16 levels within 2 µm, white light at 6 wavelengths, a short schedule;
// with a minimum feature, a grayscale 16² tile. On its tile alone (no continuation: auto would
// continue a dim blue, whose earlier tile runs its own trade): the trade after one schedule.
DesignOptions small(const std::string& target, double min_feature_um = 0.0) {
    DesignOptions o = test::small_design(target, min_feature_um > 0.0 ? 0 : 16, 80, 20);
    o.min_feature_um = min_feature_um;
    o.size = min_feature_um > 0.0 ? 16 : 32;
    o.spectral = 8;
    o.height_range_um = 2.0;
    o.seed = 5;
    o.continuation = "off";
    return o;
}

TEST(DesignBrightness, DimBlueTradesChromaticityForBrightnessWithinTheCeiling) {
    DesignOptions o = small("colour:#0000FF");
    o.delta_uv_ceiling = 0.0;
    const DesignResult plain = run_design(prepare_design(o));
    o.delta_uv_ceiling = 0.04;
    const DesignResult traded = run_design(prepare_design(o));
    const auto jp = nlohmann::json::parse(plain.metrics_json), jt = nlohmann::json::parse(traded.metrics_json);

    const auto uv = target_uv(o.target.linear_rgb);
    const auto before = scored(plain, {0.0, 0.0}, o.view_cone, uv), after = scored(traded, {0.0, 0.0}, o.view_cone, uv);
    // The premise: blue's schedule ends dim, so the trade has something to do.
    ASSERT_LT(before[1], 0.05) << "blue's schedule reached Y " << before[1] << "; the test needs a dim colour";
    EXPECT_FALSE(jp.contains("brightness_trade"));  // ceiling 0: no trade

    const auto& t = jt.at("brightness_trade");
    ASSERT_GE(t.at("blocks").get<int>(), 1);
    const double tolerance = t.at("tolerance_used").get<double>();
    EXPECT_GT(tolerance, 0.0);
    EXPECT_LE(tolerance, 0.04);
    // It starts from the schedule's relief: the same curve up to the schedule's end (the refine
    // passes may stop early), the same Y; its blocks continue the curve.
    ASSERT_GE(plain.curve.size(), static_cast<std::size_t>(o.iterations));
    ASSERT_GT(traded.curve.size(), plain.curve.size());
    EXPECT_GT(traded.curve[plain.curve.size()].iteration, plain.curve.back().iteration);
    for (std::size_t k = 0; k < plain.curve.size(); ++k) EXPECT_EQ(traded.curve[k].loss, plain.curve[k].loss) << "step " << k;
    EXPECT_EQ(t.at("model_y_before").get<double>(), jp["metrics"]["model"]["luminous_efficiency"].get<double>());

    // Under exact scalar diffraction of the heights: brighter, at a Δu′v′ cost within the ceiling
    // (plus the model's disagreement with the exact orders, a few 1e-3 at most on such tiles).
    std::printf("blue, exact: Y %.4f -> %.4f, delta u'v' %.4f -> %.4f; %d block(s), tolerance %.3f\n", before[1], after[1],
                before[0], after[0], t.at("blocks").get<int>(), tolerance);
    EXPECT_GT(after[1], before[1] * 1.1) << "Y " << before[1] << " -> " << after[1];
    EXPECT_GT(after[0], before[0]) << "the brightness should cost some chromaticity";
    EXPECT_LE(after[0], tolerance + 0.005);
    // Stopped for a stated reason: bright enough, the block cap, or a block at the ceiling.
    EXPECT_TRUE(t.at("model_y_after").get<double>() >= 0.05 || t.at("blocks").get<int>() == t.at("max_blocks").get<int>() ||
                tolerance == 0.04);
    // The reported loss is the colour loss of the loop's own uv and Y at the trade's tolerance.
    const auto& m = jt["metrics"]["model"];
    EXPECT_NEAR(jt["metrics"]["final_loss"].get<double>(),
                colour_loss_of(m["delta_uv"].get<double>(), m["luminous_efficiency"].get<double>(), tolerance), 1e-9);
    EXPECT_EQ(t.at("model_y_after").get<double>(), m["luminous_efficiency"].get<double>());
}

TEST(DesignBrightness, BrightGreenAndCeilingAtTheToleranceAreTheScheduleBitForBit) {
    // Green ends its schedule bright: the trade looks, runs no block, and the heights are those
    // of the run without it.
    DesignOptions o = small("colour:#00FF00");
    o.delta_uv_ceiling = 0.0;
    const DesignResult plain = run_design(prepare_design(o));
    o.delta_uv_ceiling = 0.04;
    const DesignResult traded = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(traded.metrics_json);
    EXPECT_EQ(j.at("brightness_trade").at("blocks").get<int>(), 0);
    EXPECT_EQ(traded.heights_um, plain.heights_um);
    // A dim blue whose ceiling is its tolerance has nothing to trade: its schedule's heights.
    DesignOptions b = small("colour:#0000FF");
    b.delta_uv_tolerance = 0.01;
    b.delta_uv_ceiling = 0.0;
    const DesignResult off = run_design(prepare_design(b));
    b.delta_uv_ceiling = 0.01;
    const DesignResult level = run_design(prepare_design(b));
    EXPECT_FALSE(nlohmann::json::parse(level.metrics_json).contains("brightness_trade"));
    EXPECT_EQ(level.heights_um, off.heights_um);
}

TEST(DesignBrightness, IridescentPairsTradeOnlyWhereTheyAreDim) {
    // A dim blue pair beside a bright green one: the blue pair's tolerance rises, the green pair's
    // stays at the user's, and the blue cone is brighter under exact scalar diffraction.
    DesignOptions o = small("colour:#0000FF");  // its target replaced below
    o.target = DesignTarget{};
    o.target.kind = DesignKind::Iridescent;
    o.target.text = "iridescent";
    for (const auto& [view, rgb] : {std::pair<std::array<double, 2>, std::array<int, 3>>{{0.2, 0.0}, {0, 0, 255}},
                                    {{0.0, 0.2}, {0, 255, 0}}}) {
        IridescentPair p;
        p.view = view;
        p.srgb8 = rgb;
        for (std::size_t c = 0; c < 3; ++c) p.linear_rgb[c] = srgb_decode(rgb[c] / 255.0);
        o.target.pairs.push_back(p);
    }
    o.view_cone = 0.08;
    o.delta_uv_ceiling = 0.0;
    const DesignResult plain = run_design(prepare_design(o));
    o.delta_uv_ceiling = 0.04;
    const DesignResult traded = run_design(prepare_design(o));
    const auto jp = nlohmann::json::parse(plain.metrics_json), jt = nlohmann::json::parse(traded.metrics_json);
    EXPECT_FALSE(jp.contains("brightness_trade"));

    std::vector<std::array<double, 2>> before, after;
    for (const auto& p : o.target.pairs) {
        const auto uv = target_uv(p.linear_rgb);
        before.push_back(scored(plain, p.view, o.view_cone, uv));
        after.push_back(scored(traded, p.view, o.view_cone, uv));
    }
    ASSERT_LT(before[0][1], 0.05) << "the blue pair reached Y " << before[0][1] << "; the test needs it dim";
    ASSERT_GE(before[1][1], 0.05) << "the green pair is dim (Y " << before[1][1] << "); the test needs it bright";

    const auto& t = jt.at("brightness_trade");
    ASSERT_GE(t.at("blocks").get<int>(), 1);
    const auto tolerance = t.at("tolerance_used").get<std::vector<double>>();
    ASSERT_EQ(tolerance.size(), 2u);
    EXPECT_GT(tolerance[0], 0.0);
    EXPECT_LE(tolerance[0], 0.04);
    // The per-pair Y before the trade is the schedule's.
    const auto y_plain = jp["metrics"]["model"]["luminous_efficiency"].get<std::vector<double>>();
    EXPECT_EQ(t.at("model_y_before").get<std::vector<double>>(), y_plain);
    // Exact scalar diffraction: the blue cone brighter, within the ceiling.
    std::printf("iridescent, exact: blue Y %.4f -> %.4f, delta u'v' %.4f -> %.4f; green Y %.4f -> %.4f, delta u'v' "
                "%.4f -> %.4f; %d block(s), tolerances %.3f, %.3f\n", before[0][1], after[0][1], before[0][0], after[0][0],
                before[1][1], after[1][1], before[1][0], after[1][0], t.at("blocks").get<int>(), tolerance[0], tolerance[1]);
    EXPECT_GT(after[0][1], before[0][1] * 1.1) << "blue Y " << before[0][1] << " -> " << after[0][1];
    EXPECT_LE(after[0][0], tolerance[0] + 0.005);
    // The loss is the sum of the pairs' colour losses at their reported tolerances.
    const auto& m = jt["metrics"]["model"];
    const auto delta = m["delta_uv"].get<std::vector<double>>(), y = m["luminous_efficiency"].get<std::vector<double>>();
    EXPECT_NEAR(jt["metrics"]["final_loss"].get<double>(),
                colour_loss_of(delta[0], y[0], tolerance[0]) + colour_loss_of(delta[1], y[1], tolerance[1]), 1e-9);
    // A pair is raised only while it is dim: the green pair keeps the user's tolerance, 0.
    EXPECT_EQ(tolerance[1], 0.0);
    EXPECT_GE(t.at("model_y_after").get<std::vector<double>>()[1], 0.05);
}

// A grayscale relief (--min-feature-um 1, 16² texels of 0.5 µm, 256 evaluation levels) of
// magenta: its schedule ends far below Y 0.05 (about 1 %).
DesignOptions grey_magenta(double ceiling) {
    DesignOptions o = small("colour:#FF00FF", 1.0);
    o.delta_uv_ceiling = ceiling;
    return o;
}

TEST(DesignBrightness, AGrayscaleReliefRunsTheSameTradeAndReachesTheBrightnessWithinItsCeiling) {
    const DesignOptions o = grey_magenta(0.0);
    const DesignResult plain = run_design(prepare_design(o));
    const DesignResult traded = run_design(prepare_design(grey_magenta(0.08)));
    const auto jp = nlohmann::json::parse(plain.metrics_json), jt = nlohmann::json::parse(traded.metrics_json);
    const auto uv = target_uv(o.target.linear_rgb);
    const auto before = scored(plain, {0.0, 0.0}, o.view_cone, uv), after = scored(traded, {0.0, 0.0}, o.view_cone, uv);
    ASSERT_LT(before[1], 0.05) << "grey magenta's schedule reached Y " << before[1] << "; the test needs a dim colour";
    EXPECT_FALSE(jp.contains("brightness_trade"));
    const auto& t = jt.at("brightness_trade");
    ASSERT_GE(t.at("blocks").get<int>(), 1);
    const double tolerance = t.at("tolerance_used").get<double>();
    EXPECT_GT(tolerance, 0.0);
    EXPECT_LE(tolerance, 0.08);
    // It continues the schedule's own relief: the same curve up to the schedule's end.
    ASSERT_GT(traded.curve.size(), plain.curve.size());
    for (std::size_t k = 0; k < plain.curve.size(); ++k) EXPECT_EQ(traded.curve[k].loss, plain.curve[k].loss) << "step " << k;
    EXPECT_EQ(t.at("model_y_before").get<double>(), jp["metrics"]["model"]["luminous_efficiency"].get<double>());
    // Exact scalar diffraction of the heights (the relief as written, 256 levels): Y at least
    // 0.05, Δu′v′ within the tolerance the blocks reached (plus 0.005, as above).
    std::printf("grey magenta, exact: Y %.4f -> %.4f, delta u'v' %.4f -> %.4f; %d block(s), tolerance %.3f\n", before[1],
                after[1], before[0], after[0], t.at("blocks").get<int>(), tolerance);
    EXPECT_GE(after[1], 0.05);
    EXPECT_LE(after[0], tolerance + 0.005);
    EXPECT_NEAR(after[1], jt["metrics"]["exact"]["luminous_efficiency"].get<double>(), 2e-3);
    // Still grayscale: no detail finer than F is asked of the trade's relief either (its heights
    // lie on the 256 evaluation levels, whose rounding alone the filter does not remove).
    EXPECT_EQ(jt["constraints"]["min_feature_um"].get<double>(), 1.0);
    EXPECT_TRUE(jt["warnings"].empty()) << jt["warnings"].dump();
}

TEST(DesignBrightness, ATradeThatEndsDimIsAWarning) {
    // At the default ceiling 0.04 the same grey magenta stays below Y 0.05: design.json says so,
    // with the Y of the heights' exact scalar diffraction.
    const DesignResult r = run_design(prepare_design(grey_magenta(0.04)));
    const auto j = nlohmann::json::parse(r.metrics_json);
    const auto uv = target_uv(parse_design_target("colour:#FF00FF").linear_rgb);
    const auto exact = scored(r, {0.0, 0.0}, 0.05, uv);
    ASSERT_LT(exact[1], 0.05) << "the test needs the trade to end dim at ceiling 0.04";
    ASSERT_GE(j.at("brightness_trade").at("blocks").get<int>(), 1);
    ASSERT_EQ(j["warnings"].size(), 1u) << j["warnings"].dump();
    const std::string w = j["warnings"][0].get<std::string>();
    char y[32];
    std::snprintf(y, sizeof y, "Y %.3g %%", 100.0 * j["metrics"]["exact"]["luminous_efficiency"].get<double>());
    EXPECT_NE(w.find(y), std::string::npos) << w;
    EXPECT_NE(w.find("--delta-uv-ceiling 0.04"), std::string::npos) << w;
    EXPECT_NEAR(j["metrics"]["exact"]["luminous_efficiency"].get<double>(), exact[1], 2e-3);
}

TEST(DesignBrightness, IridescentToleranceAndCeilingAreChecked) {
    DesignOptions o = small("colour:#0000FF");
    o.target = DesignTarget{};
    o.target.kind = DesignKind::Iridescent;
    o.target.text = "iridescent";
    o.target.pairs.push_back(IridescentPair{});
    o.delta_uv_ceiling = 0.5;
    EXPECT_THROW(prepare_design(o), std::domain_error);
    o.delta_uv_ceiling = 0.04;
    o.delta_uv_tolerance = -0.01;
    EXPECT_THROW(prepare_design(o), std::domain_error);
}

}  // namespace
}  // namespace wavebrdf
