// Metrics under fabrication errors (`--fabrication-error scale:5%,blur:0.3um`) against an
// independent evaluation: the relief scaled or blurred here (a direct 2-D Gaussian on the periodic
// tile, not the run's separable one) and scored by exact_orders; for every kind of target, and
// for a plate's entries.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <nlohmann/json.hpp>

#include "design/blur_term.h"
#include "design/target.h"
#include "design_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

using namespace wavebrdf::test;

// Gaussian blur of σ texels on the periodic tile, a 2-D sum over the square |d| ≤ ceil(4σ) (at most
// size/2), normalised.
std::vector<double> blur2d(const std::vector<double>& h, int size, double sigma) {
    const int radius = std::min(size / 2, static_cast<int>(std::ceil(4.0 * sigma)));
    std::vector<double> out(h.size(), 0.0);
    double norm = 0.0;
    for (int di = -radius; di <= radius; ++di)
        for (int dj = -radius; dj <= radius; ++dj) norm += std::exp(-0.5 * (di * di + dj * dj) / (sigma * sigma));
    for (int i = 0; i < size; ++i)
        for (int j = 0; j < size; ++j) {
            double acc = 0.0;
            for (int di = -radius; di <= radius; ++di)
                for (int dj = -radius; dj <= radius; ++dj)
                    acc += std::exp(-0.5 * (di * di + dj * dj) / (sigma * sigma)) *
                           h[static_cast<std::size_t>(((i + di) % size + size) % size) * static_cast<std::size_t>(size) +
                             static_cast<std::size_t>(((j + dj) % size + size) % size)];
            out[static_cast<std::size_t>(i) * static_cast<std::size_t>(size) + static_cast<std::size_t>(j)] = acc / norm;
        }
    return out;
}

std::vector<double> scaled(std::vector<double> h, double s) {
    for (double& x : h) x *= s;
    return h;
}

TEST(DesignFabricationErrors, ColourMetricsUnderEachErrorMatchAnIndependentEvaluation) {
    DesignOptions o = small_design("colour:#00FFFF", 8, 30, 5);
    o.view_cone = 0.1;
    o.errors = parse_fabrication_errors("scale:5%,blur:0.3um");
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    const auto& fe = j["fabrication_errors"];
    ASSERT_EQ(fe.size(), 3U) << fe.dump();
    const std::vector<std::vector<double>> reliefs{scaled(r.heights_um, 0.95), scaled(r.heights_um, 1.05),
                                                   blur2d(r.heights_um, 16, 0.3 / 0.5)};
    for (std::size_t e = 0; e < 3; ++e) {
        const auto c = cone_colour(reliefs[e], 16, 0.5, r.lambdas_um, {0.0, 0.0}, 0.1);
        const auto& m = fe[e]["metrics"];
        EXPECT_NEAR(m["luminous_efficiency"].get<double>(), c[0], 1e-9) << fe[e]["error"];
        EXPECT_NEAR(m["uv"][0].get<double>(), c[1], 1e-9) << fe[e]["error"];
        EXPECT_NEAR(m["uv"][1].get<double>(), c[2], 1e-9) << fe[e]["error"];
    }
    // The errors change the colour (so the comparison above is not of the nominal relief).
    const auto nominal = cone_colour(r.heights_um, 16, 0.5, r.lambdas_um, {0.0, 0.0}, 0.1);
    EXPECT_GT(std::abs(fe[2]["metrics"]["luminous_efficiency"].get<double>() - nominal[0]), 1e-4);
}

TEST(DesignFabricationErrors, EveryKindReportsItsMetricsUnderEachError) {
    for (const char* target : {"anti-mirror", "colour:#FF00FF"}) {
        DesignOptions o = small_design(target, 4, 5, 2);
        o.size = 8;
        o.spectral = 4;
        o.band_um = {0.4, 0.7};
        o.errors = parse_fabrication_errors("scale:5%,blur:0.3um");
        const auto j = nlohmann::json::parse(run_design(prepare_design(o)).metrics_json);
        ASSERT_EQ(j["fabrication_errors"].size(), 3U) << target;
        for (const auto& e : j["fabrication_errors"])
            for (auto it = j["metrics"]["exact"].begin(); it != j["metrics"]["exact"].end(); ++it)
                EXPECT_TRUE(e["metrics"].contains(it.key())) << target << " " << it.key();
    }
}

TEST(DesignFabricationErrors, APlatesEntriesCarryTheirTilesMetricsUnderEachError) {
    PlateOptions o = small_plate(16, 6, 8, 20, 4);
    o.design.errors = parse_fabrication_errors("scale:5%,blur:0.3um");
    o.picture = picture(1, 2, {{{0, 255, 0}}, {{255, 0, 255}}});
    o.plate_pixel_um = 16.0;
    const PlateResult r = run_plate(prepare_plate(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_EQ(j["entries"].size(), 2U);
    for (std::size_t e = 0; e < 2; ++e) {
        const auto& fe = j["entries"][e]["fabrication_errors"];
        ASSERT_EQ(fe.size(), 3U) << j["entries"][e].dump();
        const auto& tile = r.tiles[e];
        const auto c = cone_colour(blur2d(tile.heights_um, 16, 0.6), 16, 0.5, tile.lambdas_um, {0.0, 0.0}, 0.1);
        EXPECT_NEAR(fe[2]["metrics"]["luminous_efficiency"].get<double>(), c[0], 1e-9);
        const auto s = cone_colour(scaled(tile.heights_um, 1.05), 16, 0.5, tile.lambdas_um, {0.0, 0.0}, 0.1);
        EXPECT_NEAR(fe[1]["metrics"]["luminous_efficiency"].get<double>(), s[0], 1e-9);
    }
}

DesignOptions small_colour(const std::string& errors) {
    DesignOptions o = small_design("colour:#FF00FF", 8, 40, 30);
    o.view_cone = 0.1;
    o.errors = parse_fabrication_errors(errors);
    return o;
}

TEST(DesignFabricationErrors, TheBlurIsItsOwnAdjointAndMatchesADirect2dSum) {
    std::mt19937_64 rng(3);
    std::normal_distribution<double> n(0.0, 1.0);
    for (int size : {5, 12}) {
        std::vector<double> x(static_cast<std::size_t>(size * size)), y(x.size());
        for (double& v : x) v = n(rng);
        for (double& v : y) v = n(rng);
        const auto bx = detail::periodic_blur(x, size, 0.9), by = detail::periodic_blur(y, size, 0.9);
        double a = 0.0, b = 0.0;
        for (std::size_t t = 0; t < x.size(); ++t) {
            a += bx[t] * y[t];
            b += x[t] * by[t];
        }
        EXPECT_NEAR(a, b, 1e-12 * std::max(1.0, std::abs(a)));
        const auto direct = blur2d(x, size, 0.9);
        for (std::size_t t = 0; t < x.size(); ++t) EXPECT_NEAR(bx[t], direct[t], 1e-12);
    }
}

TEST(DesignFabricationErrors, TheBlurredLossGradientMatchesFiniteDifferences) {
    const PreparedDesign p = prepare_design(small_colour("blur:0.4um"));
    detail::BlurTerm term(p, 0.8);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0.1, 0.9);
    const double top = p.levels_um.back();
    std::vector<double> h(16 * 16);
    for (double& x : h) x = top * u(rng);
    std::vector<double> g;
    term.evaluate_heights(h, &g);
    for (std::size_t t : {0UL, 37UL, 130UL, 255UL}) {
        const double e = 1e-6;
        std::vector<double> a = h, b = h;
        a[t] += e;
        b[t] -= e;
        const double fd = (term.evaluate_heights(a, nullptr) - term.evaluate_heights(b, nullptr)) / (2.0 * e);
        EXPECT_NEAR(g[t], fd, 1e-5 * std::max(1.0, std::abs(fd))) << t;
    }
}

TEST(DesignFabricationErrors, TheLoopsBlurredReliefAgreesWithExactDiffractionOfTheBlurredRelief) {
    // The loop's interpolated 256-level model of a blurred relief against exact_orders of the
    // relief blurred here: the cone's share per wavelength.
    const DesignOptions o = small_colour("blur:0.3um");
    const PreparedDesign p = prepare_design(o);
    detail::BlurTerm term(p, 0.6);
    std::mt19937_64 rng(9);
    std::vector<int> level(16 * 16);
    for (int& l : level) l = static_cast<int>(rng() % 8);
    std::vector<double> h(level.size());
    for (std::size_t t = 0; t < h.size(); ++t) h[t] = p.levels_um[static_cast<std::size_t>(level[t])];
    detail::Fractions f;
    term.evaluate(level, nullptr, &f);
    const auto cone = cone_power(blur2d(h, 16, 0.6), 16, 0.5, p.lambdas_um, {0.0, 0.0}, 0.1);
    for (std::size_t w = 0; w < cone.size(); ++w) {
        // (kqΔ)²/8 with Δ = top/255: below 1e-3 of the amplitude here.
        EXPECT_NEAR(f[w][0], cone[w], 3e-3) << p.lambdas_um[w];
    }
}

TEST(DesignFabricationErrors, DesigningForTheBlurBeatsIgnoringItUnderTheBlur) {
    // Same seed and relaxed phase; the refinement with the blur in the loop ends with a lower
    // loss of the blurred relief, scored by exact_orders of the relief blurred here.
    const DesignResult with = run_design(prepare_design(small_colour("blur:0.5um")));
    const DesignResult without = run_design(prepare_design(small_colour("none")));
    const auto target_uv = xyz_to_uv(linear_srgb_to_xyz({1.0, 0.0, 1.0}));
    auto blurred_loss = [&](const DesignResult& r) {
        const auto c = cone_colour(blur2d(r.heights_um, 16, 1.0), 16, 0.5, r.lambdas_um, {0.0, 0.0}, 0.1);
        const double d = std::hypot(c[1] - target_uv[0], c[2] - target_uv[1]);
        const double hinge = std::max(0.0, 0.1 - c[0]) / 0.1;
        return (d / 0.01) * (d / 0.01) + 4.0 * hinge * hinge;
    };
    EXPECT_LT(blurred_loss(with), blurred_loss(without));
    EXPECT_NE(with.heights_um, without.heights_um);
}

}  // namespace
}  // namespace wavebrdf
