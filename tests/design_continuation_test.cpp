// Tile continuation (DesignOptions::continuation): the anti-mirror designed on a smaller tile
// first, the tile's relief repeated and continued on the run's tile.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "design_util.h"

namespace wavebrdf {
namespace {

// A 16² anti-mirror at 4 wavelengths whose orders lie off the cone's and the region's edges;
// the continuation alone, every tile designed by the loop (no annealed last stage, which
// design_anneal_test.cpp covers).
DesignOptions small_anti_mirror(int iterations, int refine_passes) {
    DesignOptions o = test::small_design("anti-mirror", 8, iterations, refine_passes);
    o.spectral = 4;
    o.band_um = {0.41, 0.69};
    o.anneal_sweeps = 0;
    return o;
}

// Per wavelength, the fractions of the reflected power in the specular cone and in the region
// (|ω_o| ≤ 0.05 and 0.1 ≤ |ω_o| ≤ 0.5, normal light) of these orders.
std::vector<std::array<double, 2>> cone_and_region(const std::vector<OrderPowers>& orders) {
    std::vector<std::array<double, 2>> f;
    for (const OrderPowers& w : orders) {
        std::array<double, 2> s{0.0, 0.0};
        for (std::size_t k = 0; k < w.power.size(); ++k) {
            const double r = std::hypot(w.omega_x[k], w.omega_y[k]);
            if (r <= 0.05) s[0] += w.power[k];
            if (r >= 0.1 && r <= 0.5) s[1] += w.power[k];
        }
        f.push_back(s);
    }
    return f;
}

TEST(DesignContinuation, TheContinuedAntiMirrorKeepsItsLevelsAndItsMetricsAreTheExportsExactDiffraction) {
    // auto on 16²: the 8² tile first (the step survey's, designed at the run's budget: the same run
    // as that tile's design alone), then 16² from it. The export keeps the levels and the range, and design.json's
    // exact metrics are the exact scalar diffraction of the exported heights.
    const DesignOptions o = small_anti_mirror(10, 3);
    const PreparedDesign p = prepare_design(o);
    ASSERT_EQ(p.stages.size(), 1u);
    EXPECT_EQ(p.stages[0].size, 8);
    EXPECT_EQ(p.stages[0].iterations, 40);
    EXPECT_EQ(p.stages[0].refine_passes, 12);
    const DesignResult r = run_design(p);
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_EQ(j["continuation"]["schedule"].size(), 2u);
    EXPECT_EQ(j["continuation"]["schedule"][0]["size"].get<int>(), 8);
    EXPECT_EQ(j["continuation"]["schedule"][1]["size"].get<int>(), 16);
    ASSERT_EQ(r.heights_um.size(), 256u);
    ASSERT_EQ(r.levels_um.size(), 8u);
    const double step = r.levels_um[1];
    for (std::size_t k = 0; k < r.levels_um.size(); ++k) EXPECT_NEAR(r.levels_um[k], static_cast<double>(k) * step, 1e-12);
    EXPECT_LE(r.levels_um.back(), o.height_range_um + 1e-12);
    for (std::size_t t = 0; t < r.heights_um.size(); ++t)
        EXPECT_EQ(r.heights_um[t], r.levels_um[static_cast<std::size_t>(r.level[t])]);
    const auto exact = cone_and_region(exact_orders(r.heights_um, 16, o.texel_um, o.omega_i, r.lambdas_um));
    const auto& m = j["metrics"]["exact"];
    for (std::size_t w = 0; w < exact.size(); ++w) {
        EXPECT_NEAR(m["specular_fraction"][w].get<double>(), exact[w][0], 1e-9);
        EXPECT_NEAR(m["region_fraction"][w].get<double>(), exact[w][1], 1e-9);
    }
    // The 8² stage is the tile the run's survey designed on the step it chose (at the run's budget,
    // not the stage's 40:12: the survey's tile is the first): that tile's own design, the same
    // relief's metrics.
    ASSERT_TRUE(p.step_survey_first_tile);
    EXPECT_EQ(j["continuation"]["schedule"][0]["iterations"].get<int>(), o.iterations);
    DesignOptions tile = o;
    tile.size = 8;
    tile.continuation = "off";
    tile.level_step_um = j["step_survey"]["chosen_um"].get<double>();
    const auto jt = nlohmann::json::parse(run_design(prepare_design(tile)).metrics_json);
    const auto& stage = j["continuation"]["schedule"][0]["exact"];
    EXPECT_DOUBLE_EQ(stage["region_fraction_mean"].get<double>(), jt["metrics"]["exact"]["region_fraction_mean"].get<double>());
    // off: the 16² tile alone from a random start, another relief.
    DesignOptions off = o;
    off.continuation = "off";
    const DesignResult ro = run_design(prepare_design(off));
    EXPECT_EQ(nlohmann::json::parse(ro.metrics_json)["continuation"]["schedule"].size(), 1u);
    EXPECT_NE(ro.heights_um, r.heights_um);
}

TEST(DesignContinuation, AutoHalvesWhileTheHalfHoldsAnOrderBesidesTheMirrorInTheConeAtEveryWavelength) {
    // The acceptance tile (256² of 0.5 µm, 0.40–0.70 µm): the orders lie λ/(n·0.5 µm) apart, so a
    // 32² tile holds one inside the cone 0.05 at 0.69 µm (0.043) and a 16² one does not (0.086):
    // 32 -> 64 -> 128 -> 256. The three earlier tiles share one tile's budget, each times (256/n)².
    DesignOptions o = test::small_design("anti-mirror", 8, 200, 60);
    o.size = 256;
    o.spectral = 16;
    o.band_um = {0.40, 0.70};
    const auto sizes = [](const DesignOptions& d) {
        std::vector<std::array<int, 3>> s;
        for (const DesignStage& t : prepare_design(d).stages) s.push_back({t.size, t.iterations, t.refine_passes});
        return s;
    };
    EXPECT_EQ(sizes(o), (std::vector<std::array<int, 3>>{{32, 4266, 1280}, {64, 1066, 320}, {128, 266, 80}}));
    // To 0.83 µm: 0.051 apart on 32², outside the cone: 64 -> 128 -> 256, each earlier tile at half.
    o.band_um = {0.40, 0.83};
    EXPECT_EQ(sizes(o), (std::vector<std::array<int, 3>>{{64, 1600, 480}, {128, 400, 120}}));
    // A wider cone lets the tile halve further; the 64² docs tile (16² holds no order in the cone) once.
    o.specular_cone = 0.11;
    EXPECT_EQ(sizes(o).front()[0], 16);
    o.specular_cone = 0.05;
    o.size = 64;
    o.band_um = {0.40, 0.70};
    EXPECT_EQ(sizes(o), (std::vector<std::array<int, 3>>{{32, 800, 240}}));
    // Coarse texels hold orders in the cone on every tile: the halving stops at the smallest
    // tile a design takes (2²) rather than asking for a 1² one.
    // (20 µm texels: λ/(1 · 20 µm) ≤ 0.035 would let a 1² tile hold one.)
    o.size = 16;
    o.texel_um = 20.0;
    o.spectral = 2;
    const auto coarse = sizes(o);
    ASSERT_FALSE(coarse.empty());
    EXPECT_EQ(coarse.front()[0], 2);
    EXPECT_EQ(coarse.back()[0], 8);
}

TEST(DesignContinuation, AutoContinuesAColourWhenHalfItsOptimalColourLimitIsBelowTheLossesY) {
    // The colour acceptance's tile (128², 0.5 µm texels, 16 samples of the white, the mirror
    // view's cone 0.05). A design on its tile alone reaches at most about half of its colour's
    // optimal-colour limit; auto continues a colour when that half is below the Y the colour loss
    // counts up to (10 %): of the six blue alone (limit 7.8 %; red 23.8 % and the others above),
    // and the lighter blues #0040FF (12.1 %), #0060FF (17.3 %) and #2060FF (17.6 %), not #0080FF
    // (25.0 %) or #4080FF (26.2 %); from the halves whose view cone holds an order besides the
    // central one at every wavelength: 64² alone (the longest sample, 0.815 µm, lies
    // 0.815 / (64 · 0.5) = 0.025 apart on 64² and 0.051 > 0.05 apart on 32²).
    DesignOptions o = test::small_design("colour:#0000FF", 16, 10, 3);
    o.size = 128;
    o.spectral = 16;
    o.height_range_um = 2.0;
    const auto sizes = [&](const std::string& colour) {
        o.target = parse_design_target("colour:" + colour);
        std::vector<int> s;
        for (const DesignStage& stage : prepare_design(o).stages) s.push_back(stage.size);
        return s;
    };
    for (const char* colour : {"#0000FF", "#0040FF", "#0060FF", "#2060FF"})
        EXPECT_EQ(sizes(colour), (std::vector<int>{64})) << colour;
    for (const char* colour : {"#FF0000", "#00FF00", "#00FFFF", "#FF00FF", "#FFFF00", "#0080FF", "#4080FF"})
        EXPECT_TRUE(sizes(colour).empty()) << colour;
    // The rule reads the limit under the run's light, not the colour's name: under a white cut to
    // 0.40-0.50 µm #4080FF's limit is 12.6 % and it is continued, from 32² (the longest sample,
    // 0.497 µm, lets the halving go on: 0.031 <= 0.05 < 0.062).
    o.band_um = {0.40, 0.50};
    EXPECT_EQ(sizes("#4080FF"), (std::vector<int>{32, 64}));
    o.band_um = {0.38, 0.78};
    // A view off the mirror, whose cone may hold no order of the half tile: under 0.38-0.78 µm
    // (longest sample 0.7675 µm) 64²'s orders lie up to 0.024 apart and 32²'s 0.048, within the
    // cone 0.05, so blue is continued as at the mirror; with the cone 0.02, 64²'s are not, and blue
    // runs alone there, while at the mirror it is continued (the mirror order is in every mirror cone).
    o.view = std::array<double, 2>{0.2, 0.0};
    EXPECT_EQ(sizes("#0000FF"), (std::vector<int>{32, 64}));
    o.view_cone = 0.02;
    EXPECT_TRUE(sizes("#0000FF").empty());
    o.view.reset();
    EXPECT_EQ(sizes("#0000FF"), (std::vector<int>{64}));
    o.continuation = "off";
    EXPECT_TRUE(sizes("#0000FF").empty());
}

TEST(DesignContinuation, AutoContinuesAnIridescentTargetWhenAnyPairIsInTheLossesCompetingRegime) {
    // docs/design.md's example (64², 16 samples of 0.40-0.70 µm, view cones 0.08): the pairs'
    // optimal-colour limits are 41.8, 81.1 and 17.7 % (#2060FF); half of the last is below 10 %, so
    // auto continues, from 32² (0.69 µm lies 0.043 <= 0.08 apart on 32², 0.086 on 16²); without
    // that pair the target runs on its tile alone.
    const auto sizes = [](DesignOptions o, std::vector<IridescentPair> pairs) {
        o.target.kind = DesignKind::Iridescent;
        o.target.text = "iridescent";
        for (auto& pair : pairs)
            for (std::size_t c = 0; c < 3; ++c) pair.linear_rgb[c] = srgb_decode(pair.srgb8[c] / 255.0);
        o.target.pairs = pairs;
        std::vector<int> s;
        for (const DesignStage& stage : prepare_design(o).stages) s.push_back(stage.size);
        return s;
    };
    DesignOptions o = test::small_design("colour:#0000FF", 16, 10, 3);
    o.size = 64;
    o.spectral = 16;
    o.band_um = {0.40, 0.70};
    o.height_range_um = 2.0;
    o.view_cone = 0.08;
    const IridescentPair orange{{0.3, 0.0}, {255, 96, 0}, {}}, green{{0.0, 0.3}, {32, 192, 64}, {}};
    EXPECT_EQ(sizes(o, {orange, green, {{-0.3, 0.0}, {32, 96, 255}, {}}}), (std::vector<int>{32}));
    EXPECT_TRUE(sizes(o, {orange, green}).empty());
    // A pair's cone off the mirror may hold orders of the tile and none of its half: on 16² at
    // 0.445-0.655 µm a cone of 0.05 about (0, 0.06) holds (0, λ/8 µm) at 0.445 µm, while on 8² the
    // orders lie λ/4 µm >= 0.111 apart and none is within 0.05 of it. A half given by hand is refused;
    // auto, whose half's orders lie 0.164 > 0.05 apart, leaves the target on its tile, where it runs.
    DesignOptions small = small_anti_mirror(2, 0);
    small.view_cone = 0.05;
    const IridescentPair near_mirror{{0.0, 0.06}, {32, 96, 255}, {}};
    EXPECT_TRUE(sizes(small, {near_mirror}).empty());
    small.target = parse_design_target("colour:#2060FF");
    small.target.kind = DesignKind::Iridescent;
    small.target.pairs = {near_mirror};
    for (std::size_t c = 0; c < 3; ++c) small.target.pairs[0].linear_rgb[c] = small.target.linear_rgb[c];
    EXPECT_NO_THROW(run_design(prepare_design(small)));
    small.continuation = "8";
    EXPECT_THROW(run_design(prepare_design(small)), std::invalid_argument);
}

TEST(DesignContinuation, ATiledReliefScoresAsItsTileByADirectSum) {
    // With no iterations and no passes the continuation's last tile is its first tile's random
    // relief repeated 2 × 2, scored as it is: its exact metrics are the tile's. The premise, by
    // the direct Kirchhoff sum (independent of the FFT identity): the tiled relief sends the
    // tile's power into the cone and the region at every wavelength.
    DesignOptions o = small_anti_mirror(0, 0);
    o.continuation = "8";
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    std::vector<double> tile(64);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            const double h = r.heights_um[static_cast<std::size_t>(y * 16 + x)];
            if (y < 8 && x < 8) tile[static_cast<std::size_t>(y * 8 + x)] = h;
            else EXPECT_EQ(h, tile[static_cast<std::size_t>((y % 8) * 8 + x % 8)]) << y << "," << x;
        }
    const auto& stage = j["continuation"]["schedule"][0]["exact"];
    const auto& last = j["metrics"]["exact"];
    for (const char* key : {"specular_fraction", "region_fraction", "uniformity"})
        for (std::size_t w = 0; w < 4; ++w)
            EXPECT_NEAR(last[key][w].get<double>(), stage[key][w].get<double>(), 1e-12) << key;
    const auto small = cone_and_region(direct_orders(tile, 8, o.texel_um, o.omega_i, r.lambdas_um, 4));
    const auto big = cone_and_region(direct_orders(r.heights_um, 16, o.texel_um, o.omega_i, r.lambdas_um, 4));
    for (std::size_t w = 0; w < 4; ++w) {
        EXPECT_GT(small[w][1], 0.2);  // a random relief lights the region
        EXPECT_NEAR(big[w][0], small[w][0], 1e-9);
        EXPECT_NEAR(big[w][1], small[w][1], 1e-9);
    }
}

TEST(DesignContinuation, AColourContinuesAndATiledReliefScoresAsItsTile) {
    // A colour's view cone holds the same orders of a tiled relief as of its tile, so with no
    // iterations and no passes the 16² result (the 8² tile's random relief repeated) has its tile's
    // chromaticity and luminous efficiency; the two earlier tiles share one tile's budget.
    DesignOptions o = small_anti_mirror(0, 0);
    o.target = parse_design_target("colour:#80a0c0");
    o.delta_uv_ceiling = 0.0;  // no brightness trade after the (empty) schedule
    o.continuation = "4,8";
    o.iterations = 10;
    const PreparedDesign p = prepare_design(o);
    ASSERT_EQ(p.stages.size(), 2u);
    EXPECT_EQ(p.stages[0].iterations, 10 * 16 / 2);  // (16/4)², over two earlier tiles
    EXPECT_EQ(p.stages[1].iterations, 10 * 4 / 2);
    o.continuation = "8";
    o.iterations = 0;
    const auto j = nlohmann::json::parse(run_design(prepare_design(o)).metrics_json);
    ASSERT_EQ(j["continuation"]["schedule"].size(), 2u);
    const auto& stage = j["continuation"]["schedule"][0]["exact"];
    for (const char* key : {"delta_uv", "luminous_efficiency"}) {
        ASSERT_TRUE(stage.contains(key)) << key;
        EXPECT_NEAR(j["metrics"]["exact"][key].get<double>(), stage[key].get<double>(), 1e-12) << key;
    }
    EXPECT_GT(stage["luminous_efficiency"].get<double>(), 0.0);
}

TEST(DesignContinuation, AnIridescentTargetContinuesAndItsTiledReliefScoresAsItsTileByADirectSum) {
    // Each pair's view cone holds the same orders of a tiled relief as of its tile: with no
    // iterations and no passes the 16² result (the 8² tile's random relief repeated) has each
    // pair's chromaticity and Y of its tile, and the direct Kirchhoff sum (no FFT) puts the same
    // power into each cone from both reliefs, the Y design.json reports.
    DesignOptions o = small_anti_mirror(0, 0);
    o.target.kind = DesignKind::Iridescent;
    o.target.text = "iridescent";
    o.target.pairs = {{{0.2, 0.0}, {255, 128, 0}, {}}, {{0.0, -0.25}, {0, 128, 255}, {}}};
    for (auto& pair : o.target.pairs)
        for (std::size_t c = 0; c < 3; ++c) pair.linear_rgb[c] = srgb_decode(pair.srgb8[c] / 255.0);
    o.view_cone = 0.08;
    o.delta_uv_ceiling = 0.0;
    o.continuation = "8";
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_EQ(j["continuation"]["schedule"].size(), 2u);
    const auto& stage = j["continuation"]["schedule"][0]["exact"];
    const auto& last = j["metrics"]["exact"];
    std::vector<double> tile(64);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) tile[static_cast<std::size_t>(y * 8 + x)] = r.heights_um[static_cast<std::size_t>(y * 16 + x)];
    const auto small = direct_orders(tile, 8, o.texel_um, o.omega_i, r.lambdas_um, 8);
    const auto big = direct_orders(r.heights_um, 16, o.texel_um, o.omega_i, r.lambdas_um, 8);
    auto cone = [&](const OrderPowers& w, const IridescentPair& pair) {
        double in = 0.0;
        for (std::size_t k = 0; k < w.power.size(); ++k)
            if (std::hypot(w.omega_x[k] - pair.view[0], w.omega_y[k] - pair.view[1]) <= o.view_cone) in += w.power[k];
        return in * w.kirchhoff_total;
    };
    for (std::size_t q = 0; q < 2; ++q) {
        for (const char* key : {"delta_uv", "luminous_efficiency"})
            EXPECT_NEAR(last[key][q].get<double>(), stage[key][q].get<double>(), 1e-12) << key << " pair " << q;
        std::vector<double> reflectance;
        for (std::size_t w = 0; w < small.size(); ++w) {
            EXPECT_NEAR(cone(big[w], o.target.pairs[q]), cone(small[w], o.target.pairs[q]), 1e-9) << "pair " << q;
            reflectance.push_back(cone(small[w], o.target.pairs[q]));
        }
        const double y = reflectance_xyz(r.lambdas_um, reflectance)[1];
        EXPECT_GT(y, 0.001) << "pair " << q;  // a random relief lights each cone
        EXPECT_NEAR(last["luminous_efficiency"][q].get<double>(), y, 2e-3) << "pair " << q;
    }
}

TEST(DesignContinuation, ABadScheduleFailsBeforeAnyWorkNamingTheValue) {
    DesignOptions o = small_anti_mirror(10, 3);
    auto message = [&](const std::string& schedule) {
        DesignOptions b = o;
        b.continuation = schedule;
        try {
            prepare_design(b);
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message("fast").find("--continuation fast is not a schedule"), std::string::npos);
    EXPECT_NE(message("4,,8").find("not a schedule"), std::string::npos);
    EXPECT_NE(message("6").find("tile 6 does not divide 16"), std::string::npos);
    EXPECT_NE(message("8,4").find("tile 8 does not divide 4"), std::string::npos);
    EXPECT_NE(message("16").find("tile 16 does not divide 16"), std::string::npos);
    o.target = pattern_target(2, 2, {0.0, 1.0, 1.0, 0.0});
    EXPECT_NE(message("8").find("for the anti-mirror, colour and iridescent"), std::string::npos);
    o.continuation = "8";
    o.target = parse_design_target("anti-mirror");
    o.start_heights_um.assign(256, 0.0);
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    // auto: a start relief, an odd size or another target run on their tile alone.
    o.continuation = "auto";
    EXPECT_TRUE(prepare_design(o).stages.empty());
    o.start_heights_um.clear();
    o.size = 15;
    EXPECT_TRUE(prepare_design(o).stages.empty());
    o.size = 16;
    o.target = parse_design_target("colour:#80a0c0");
    EXPECT_TRUE(prepare_design(o).stages.empty());
}

}  // namespace
}  // namespace wavebrdf
