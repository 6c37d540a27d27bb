// The anti-mirror's constraints: the region is maximised subject to limits on the cone and the
// uniformity, by multipliers the loop moves between blocks (target.h). Checked here: the
// multipliers move only as the constraints say, the loss's gradient against finite differences on
// both sides of the augmented-Lagrangian kink, and a small design scored from its heights alone
// (exact_orders, binned here): it keeps the limits it is given, ends near them (the constraint is
// active, not slack) and lights the region more than a design given tighter limits.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "design/target.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

// Fractions of W wavelengths: cone `cone`, the region's 16 bins `region`/16 each, bin 1 scaled so
// that the uniformity is `u`.
detail::Fractions fractions(const std::vector<double>& cone, const std::vector<double>& u, double region = 0.8) {
    detail::Fractions f(cone.size(), std::vector<double>(19, 0.0));
    for (std::size_t w = 0; w < cone.size(); ++w) {
        f[w][0] = cone[w];
        const double mean = region / 16.0;
        for (std::size_t q = 1; q <= 16; ++q) f[w][q] = mean;
        // One bin raised by d and the rest lowered by d/15 (the mean stays): d by bisection on u.
        double lo = 0.0, hi = 15.0 * mean;
        for (int it = 0; it < 100; ++it) {
            const double d = 0.5 * (lo + hi);
            std::vector<double> b(16, mean - d / 15.0);
            b[0] = mean + d;
            double var = 0.0;
            for (double x : b) var += (x - mean) * (x - mean);
            (std::sqrt(var / 16.0) / mean < u[w] ? lo : hi) = d;
        }
        const double d = 0.5 * (lo + hi);
        for (std::size_t q = 1; q <= 16; ++q) f[w][q] = mean - d / 15.0;
        f[w][1] = mean + d;
    }
    return f;
}

std::vector<double> multipliers(const detail::Target& t, const char* which) {
    return t.constraints_json()[which].get<std::vector<double>>();
}

TEST(DesignConstraints, MultipliersRiseOnlyWhileALimitIsBrokenAndNeverFallBelowZero) {
    detail::AntiMirrorSpec spec;  // cone limit 0.002, uniformity limit 0.25
    const auto target = detail::make_anti_mirror(spec);
    target->reset_multipliers();
    const double aim_cone = detail::k_anti_mirror_aim * spec.cone_limit;
    const double aim_u = detail::k_anti_mirror_aim * spec.uniformity_limit;
    // Wavelength 0 breaks both aims, 1 keeps both.
    const detail::Fractions over = fractions({2.0 * aim_cone, 0.5 * aim_cone}, {1.5 * aim_u, 0.5 * aim_u});
    target->update_multipliers(over);
    auto lc = multipliers(*target, "cone_multipliers"), lu = multipliers(*target, "uniformity_multipliers");
    ASSERT_EQ(lc.size(), 2u);
    const double rho = target->constraints_json()["rho"].get<double>();
    EXPECT_NEAR(lc[0], rho * std::log(2.0), 1e-9);  // λ + ρ ln(cone / aim) from 0
    EXPECT_NEAR(lu[0], rho * std::log(1.5), 1e-3);
    EXPECT_EQ(lc[1], 0.0);
    EXPECT_EQ(lu[1], 0.0);
    // Still over: they rise again; then inside the aim: they fall, to 0 and no further.
    target->update_multipliers(over);
    EXPECT_GT(multipliers(*target, "cone_multipliers")[0], lc[0]);
    EXPECT_GT(multipliers(*target, "uniformity_multipliers")[0], lu[0]);
    const detail::Fractions inside = fractions({0.8 * aim_cone, 0.8 * aim_cone}, {0.8 * aim_u, 0.8 * aim_u});
    double previous = multipliers(*target, "cone_multipliers")[0];
    for (int k = 0; k < 20; ++k) {
        target->update_multipliers(inside);
        const double now = multipliers(*target, "cone_multipliers")[0];
        EXPECT_LE(now, previous);
        EXPECT_GE(now, 0.0);
        previous = now;
    }
    EXPECT_EQ(previous, 0.0);
    EXPECT_EQ(multipliers(*target, "uniformity_multipliers")[0], 0.0);
    // The limits, not the aims, decide what is broken.
    EXPECT_TRUE(target->broken_limits(inside).empty());
    EXPECT_EQ(target->broken_limits(fractions({1.01 * spec.cone_limit}, {0.1})).size(), 1u);
    EXPECT_EQ(target->broken_limits(fractions({0.0}, {1.01 * spec.uniformity_limit})).size(), 1u);
}

TEST(DesignConstraints, LossGradientMatchesFiniteDifferencesOnBothSidesOfTheKink) {
    const auto target = detail::make_anti_mirror({});
    target->reset_multipliers();
    const double aim_cone = detail::k_anti_mirror_aim * 0.002, aim_u = detail::k_anti_mirror_aim * 0.25;
    // Multipliers raised by fractions over the aims and lowered by fractions far inside, then the
    // gradient where each constraint's λ + ρ g is positive at some wavelengths and negative (its
    // term flat) at others.
    target->update_multipliers(fractions({3 * aim_cone, 3 * aim_cone, 3 * aim_cone}, {2 * aim_u, 2 * aim_u, 2 * aim_u}));
    target->update_multipliers(fractions({0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}));
    const detail::Fractions f = fractions({0.2 * aim_cone, 1.3 * aim_cone, 0.05 * aim_cone}, {1.4 * aim_u, 0.3 * aim_u, 0.02 * aim_u});
    const nlohmann::json c = target->constraints_json();
    const double rho = c["rho"].get<double>();
    int active = 0, flat = 0;
    for (std::size_t w = 0; w < 3; ++w) {
        const double pc = c["cone_multipliers"][w].get<double>() + rho * (f[w][0] / aim_cone - 1.0);
        const double pu = c["uniformity_multipliers"][w].get<double>() +
                          rho * (target->metrics(f)["uniformity"][w].get<double>() / aim_u - 1.0);
        (pc > 0.0 ? active : flat) += 1;
        (pu > 0.0 ? active : flat) += 1;
    }
    EXPECT_GE(active, 2);
    EXPECT_GE(flat, 2);
    detail::Fractions g;
    target->loss(f, &g);
    const double step = 1e-8;
    for (std::size_t w = 0; w < 3; ++w)
        for (std::size_t q = 0; q <= 16; ++q) {
            detail::Fractions plus = f, minus = f;
            plus[w][q] += step;
            minus[w][q] -= step;
            const double fd = (target->loss(plus, nullptr) - target->loss(minus, nullptr)) / (2 * step);
            EXPECT_NEAR(g[w][q], fd, 1e-5 * std::max(1.0, std::abs(fd))) << "wavelength " << w << " group " << q;
        }
}

// The anti-mirror metrics of a relief from exact_orders, binned here: per wavelength the cone's
// and the region's fractions and the uniformity of the 16 equal-area bins (4 rings × the
// quadrants [0, 90°), [90°, 180°), …).
struct Scored {
    std::vector<double> cone, region, uniformity;
    double worst(const std::vector<double>& v) const { return *std::max_element(v.begin(), v.end()); }
    double mean_region() const {
        double s = 0.0;
        for (double r : region) s += r;
        return s / static_cast<double>(region.size());
    }
};
Scored score(const std::vector<double>& heights, const DesignOptions& o, const std::vector<double>& lambdas, double r1,
             double r2) {
    Scored s;
    for (const auto& w : exact_orders(heights, o.size, o.texel_um, {0.0, 0.0}, lambdas)) {
        double cone = 0.0;
        std::array<double, 16> bins{};
        for (std::size_t k = 0; k < w.power.size(); ++k) {
            const double x = w.omega_x[k], y = w.omega_y[k];
            const double r = std::hypot(x, y);
            if (r <= o.specular_cone) cone += w.power[k];
            if (r < r1 || r > r2) continue;
            const int ring = std::clamp(static_cast<int>(4.0 * (r * r - r1 * r1) / (r2 * r2 - r1 * r1)), 0, 3);
            // The half-open quadrants by the signs (docs/design.md): each holds one half-axis.
            const int quadrant = x > 0.0 && y >= 0.0 ? 0 : x <= 0.0 && y > 0.0 ? 1 : x < 0.0 && y <= 0.0 ? 2 : 3;
            bins[static_cast<std::size_t>(ring * 4 + quadrant)] += w.power[k];
        }
        double region = 0.0;
        for (double b : bins) region += b;
        const double mean = region / 16.0;
        double var = 0.0;
        for (double b : bins) var += (b - mean) * (b - mean);
        s.cone.push_back(cone);
        s.region.push_back(region);
        s.uniformity.push_back(std::sqrt(var / 16.0) / mean);
    }
    return s;
}

TEST(DesignConstraints, SmallDesignKeepsItsLimitsEndsNearThemAndBeatsTighterLimits) {
    DesignOptions o;
    o.size = 32;
    o.spectral = 4;
    o.band_um = {0.45, 0.65};
    o.region = "annulus:0.15,0.6";
    o.specular_cone = 0.1;
    o.iterations = 40;
    o.refine_passes = 20;
    o.height_range_um = 1.5;
    o.seed = 7;
    o.cone_limit = 0.01;
    o.uniformity_limit = 0.25;
    const PreparedDesign p = prepare_design(o);
    const DesignResult r = run_design(p);
    const Scored s = score(r.heights_um, o, p.lambdas_um, 0.15, 0.6);
    const nlohmann::json j = nlohmann::json::parse(r.metrics_json);
    EXPECT_TRUE(j["warnings"].empty()) << j["warnings"].dump();
    EXPECT_LE(s.worst(s.cone), o.cone_limit);
    EXPECT_LE(s.worst(s.uniformity), o.uniformity_limit);
    // Active: at least one constraint ends within 25 % of its limit.
    EXPECT_GT(std::max(s.worst(s.cone) / o.cone_limit, s.worst(s.uniformity) / o.uniformity_limit), 0.75);

    DesignOptions tight = o;
    tight.cone_limit = 0.5 * o.cone_limit;
    tight.uniformity_limit = 0.5 * o.uniformity_limit;
    const PreparedDesign pt = prepare_design(tight);
    const Scored st = score(run_design(pt).heights_um, tight, pt.lambdas_um, 0.15, 0.6);
    EXPECT_GT(s.mean_region(), st.mean_region() + 0.005);
}

}  // namespace
}  // namespace wavebrdf
