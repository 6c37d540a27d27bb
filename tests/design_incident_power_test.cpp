// The colour targets count the light into a view cone as a fraction of the incident power: a
// grating of known mirror efficiency, and a design's metrics against a slow direct sum of the
// Kirchhoff integral over its orders.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "design/engine.h"
#include "design/relief.h"
#include "design/target.h"
#include "design_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"
#include <nlohmann/json.hpp>

namespace wavebrdf {
namespace {

std::vector<double> white_samples() {
    std::vector<double> lambdas;
    for (int k = 0; k < 16; ++k) lambdas.push_back(0.36 + (k + 0.5) * 0.47 / 16);
    return lambdas;
}

TEST(DesignIncidentPower, ABinaryGratingsMirrorLightIsItsClosedFormEfficiency) {
    // Alternate columns of heights 0 and d, period 0.5 µm, normal light: the mirror order's
    // amplitude is (1 + e^{−2ikd})/2, so the cone about the mirror direction (which holds no other
    // order: the first ones lie at |ω| = λ/0.5 µm ≥ 0.72) receives cos²(2πd/λ) of the incident
    // power. Beyond λ = 0.5 µm the first orders are evanescent, the mirror order is all the
    // reflected propagating power, and a share of that would read 1 there.
    const double d = 0.1;
    const std::vector<double> lambdas = white_samples();
    const std::vector<double> heights{0.0, d, 0.0, d};
    detail::ColourSpec spec;
    spec.rgb = {0.0, 0.0, 1.0};
    spec.lambdas_um = lambdas;
    const auto target = detail::make_colour(spec);
    std::vector<detail::OrderSet> sets;
    for (double lambda : lambdas) sets.push_back(detail::make_order_set(2, 0.25, {0.0, 0.0}, lambda));
    target->assign(sets);
    const auto flux = detail::level_flux(detail::to_level_relief(heights, 256), 2, sets, 1.0);
    std::vector<double> totals;
    const detail::Fractions f = detail::group_fractions(*target, flux, &totals);
    std::vector<double> expected;
    bool some_evanescent = false;
    for (std::size_t w = 0; w < lambdas.size(); ++w) {
        const double c = std::cos(2.0 * k_pi * d / lambdas[w]);
        expected.push_back(c * c);
        EXPECT_NEAR(f[w][0], c * c, 1e-12) << lambdas[w];
        if (lambdas[w] > 0.5) {
            some_evanescent = true;
            EXPECT_NEAR(totals[w], c * c, 1e-12) << lambdas[w];  // only the mirror order propagates
        }
    }
    ASSERT_TRUE(some_evanescent);
    const nlohmann::json m = target->metrics(f);
    const auto xyz = reflectance_xyz(lambdas, expected);
    EXPECT_NEAR(m["luminous_efficiency"].get<double>(), xyz[1], 1e-12);
    const auto uv = xyz_to_uv(xyz);
    EXPECT_NEAR(m["uv"][0].get<double>(), uv[0], 1e-12);
    EXPECT_NEAR(m["uv"][1].get<double>(), uv[1], 1e-12);
    // The closed form is well below 1, so a share of the reflected power would not pass above.
    EXPECT_LT(xyz[1], 0.7);
}

TEST(DesignIncidentPower, ADesignsLuminousEfficiencyIsTheIncidentFractionOfADirectSum) {
    // A small colour design; design.json's Y and u′v′ against the slow direct sum of the Kirchhoff
    // integral (direct_orders: no FFT, no level identity): the cone's flux per unit incident power,
    // and the share of the reflected propagating power in its own field.
    DesignOptions o = test::small_design("colour:#00FF00", 4, 20, 4);
    o.size = 8;
    o.view_cone = 0.15;
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    const auto& e = j["metrics"]["exact"];
    const auto slow = direct_orders(r.heights_um, o.size, o.texel_um, o.omega_i, r.lambdas_um, 8);
    std::vector<double> incident, share;
    for (const auto& w : slow) {
        double in = 0.0;
        for (std::size_t k = 0; k < w.m.size(); ++k)
            if (std::hypot(w.omega_x[k], w.omega_y[k]) <= o.view_cone) in += w.power[k];
        share.push_back(in);
        incident.push_back(in * w.kirchhoff_total);
    }
    const auto xyz = reflectance_xyz(r.lambdas_um, incident);
    const auto uv = xyz_to_uv(xyz);
    EXPECT_NEAR(e["luminous_efficiency"].get<double>(), xyz[1], 2e-3);
    EXPECT_NEAR(e["uv"][0].get<double>(), uv[0], 2e-3);
    EXPECT_NEAR(e["uv"][1].get<double>(), uv[1], 2e-3);
    const double y_share = reflectance_xyz(r.lambdas_um, share)[1];
    // The share divides by every propagating order, the far ones too, where the midpoint rule's
    // error (∝ 1/samples²: 0.018 at 3, 0.0024 at 8) is largest.
    EXPECT_NEAR(e["luminous_efficiency_share_of_reflected"].get<double>(), y_share, 5e-3);
    // The two differ on this relief (the far orders carry their own phase, so the reflected
    // propagating power is not 1): the checks above tell them apart.
    EXPECT_GT(std::abs(y_share - xyz[1]), 0.02);
    EXPECT_EQ(e["luminous_efficiency_units"].get<std::string>(), "fraction of the incident white light's luminous power");
}

TEST(DesignIncidentPower, TheColourLossIgnoresChromaticityWithinItsToleranceAndItsGradientIsExact) {
    // colour_loss against the target u′v′ of sRGB blue: inside the tolerance only the Y hinge
    // counts; outside, (Δ − t)²/0.01²; the gradient against central differences on both sides.
    const auto target = xyz_to_uv(linear_srgb_to_xyz({0.0, 0.0, 1.0}));
    const double t = 0.02;
    auto xyz_at = [&](double du, double y) {
        // The XYZ with chromaticity target + (du, 0) and luminance y: X = 9uY/(4v), Z = (12 − 3u − 20v)Y/(4v).
        const double u = target[0] + du, v = target[1];
        return std::array<double, 3>{9.0 * u * y / (4.0 * v), y, (12.0 - 3.0 * u - 20.0 * v) * y / (4.0 * v)};
    };
    const double hinge = 4.0 * std::pow((0.1 - 0.04) / 0.1, 2);
    EXPECT_NEAR(detail::colour_loss(xyz_at(0.015, 0.04), target, nullptr, t), hinge, 1e-9);
    EXPECT_NEAR(detail::colour_loss(xyz_at(0.03, 0.04), target, nullptr, t), hinge + std::pow(0.01 / 0.01, 2), 1e-9);
    EXPECT_NEAR(detail::colour_loss(xyz_at(0.015, 0.04), target, nullptr, 0.0), hinge + std::pow(0.015 / 0.01, 2), 1e-9);
    for (double du : {0.005, 0.015, 0.025, 0.04}) {
        const auto X = xyz_at(du, 0.04);
        std::array<double, 3> g{};
        detail::colour_loss(X, target, &g, t);
        for (std::size_t c = 0; c < 3; ++c) {
            const double h = 1e-7;
            auto a = X, b = X;
            a[c] += h;
            b[c] -= h;
            const double fd = (detail::colour_loss(a, target, nullptr, t) - detail::colour_loss(b, target, nullptr, t)) / (2 * h);
            EXPECT_NEAR(g[c], fd, 1e-4 * std::max(1.0, std::abs(fd))) << du << " " << c;
        }
    }
}

}  // namespace
}  // namespace wavebrdf
