// The optimal-colour bound on a colour's luminous efficiency against brute force: every vertex
// of the reflectance box that meets the chromaticity (a linear programme's basic solutions: at
// most two reflectances strictly between 0 and 1), and for a Δu′v′ disk the best of those over a
// grid of chromaticities in the disk.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "design/colour_bound.h"
#include "design/target.h"
#include "design_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

std::vector<double> band(int n, double a, double b) {
    std::vector<double> l(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) l[static_cast<std::size_t>(k)] = a + (k + 0.5) * (b - a) / n;
    return l;
}

// The largest Y of R ∈ [0, 1]^n with u′v′ = p exactly: every basic solution (two free
// reflectances i < j solving the two chromaticity equations, every other one 0 or 1).
double brute_force_y(const std::vector<double>& w, const std::array<double, 2>& p) {
    const std::size_t n = w.size() / 3;
    std::vector<std::array<double, 2>> b(n);
    for (std::size_t l = 0; l < n; ++l) {
        const double x = w[l], y = w[n + l], z = w[2 * n + l], d = x + 15.0 * y + 3.0 * z;
        b[l] = {4.0 * x - p[0] * d, 9.0 * y - p[1] * d};
    }
    double best = 0.0;  // R = 0
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = i + 1; j < n; ++j) {
            const double det = b[i][0] * b[j][1] - b[j][0] * b[i][1];
            if (std::abs(det) < 1e-14) continue;
            std::vector<std::size_t> rest;
            for (std::size_t l = 0; l < n; ++l)
                if (l != i && l != j) rest.push_back(l);
            for (std::size_t mask = 0; mask < (std::size_t{1} << rest.size()); ++mask) {
                double r0 = 0.0, r1 = 0.0, y = 0.0;
                for (std::size_t k = 0; k < rest.size(); ++k)
                    if (mask >> k & 1U) {
                        r0 -= b[rest[k]][0];
                        r1 -= b[rest[k]][1];
                        y += w[n + rest[k]];
                    }
                const double ri = (r0 * b[j][1] - b[j][0] * r1) / det;
                const double rj = (b[i][0] * r1 - r0 * b[i][1]) / det;
                if (ri < -1e-12 || ri > 1.0 + 1e-12 || rj < -1e-12 || rj > 1.0 + 1e-12) continue;
                best = std::max(best, y + ri * w[n + i] + rj * w[n + j]);
            }
        }
    return best;
}

std::array<double, 2> uv_of(const std::array<double, 3>& rgb) { return xyz_to_uv(linear_srgb_to_xyz(rgb)); }

const std::vector<std::array<double, 3>> k_six{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 1, 1}, {1, 0, 1}, {1, 1, 0}};

TEST(DesignColourBound, EqualsTheBestBasicSolutionAtTheTargetChromaticity) {
    const auto w = detail::colour_xyz_weights(band(9, 0.36, 0.83));
    for (const auto& rgb : k_six) {
        const auto t = uv_of(rgb);
        const double brute = brute_force_y(w, t);
        const auto b = detail::optimal_colour_bound(w, t, 0.0);
        EXPECT_GE(b.y_at_target, brute - 1e-12) << rgb[0] << rgb[1] << rgb[2];
        EXPECT_NEAR(b.y_at_target, brute, 1e-7) << rgb[0] << rgb[1] << rgb[2];
    }
}

TEST(DesignColourBound, WithinADiskItBoundsEveryChromaticityOfTheDiskAndIsNearlyMet) {
    const auto w = detail::colour_xyz_weights(band(8, 0.36, 0.83));
    const double r = 0.04;
    for (const auto& rgb : {k_six[0], k_six[2], k_six[4]}) {
        const auto t = uv_of(rgb);
        const auto b = detail::optimal_colour_bound(w, t, r);
        double grid = 0.0;
        for (int ri = 0; ri <= 10; ++ri)
            for (int ai = 0; ai < (ri == 0 ? 1 : 64); ++ai) {
                const double rr = r * ri / 10.0, a = 2.0 * k_pi * ai / 64.0;
                grid = std::max(grid, brute_force_y(w, {t[0] + rr * std::cos(a), t[1] + rr * std::sin(a)}));
            }
        EXPECT_GE(b.y_within, grid - 1e-12) << rgb[0] << rgb[1] << rgb[2];
        // The grid's points are 0.004 apart at most (the rim's: 2π 0.04 / 64); the bound is met
        // on the rim, between two of them.
        EXPECT_LE(b.y_within, grid * 1.03 + 1e-9) << rgb[0] << rgb[1] << rgb[2];
        EXPECT_GE(b.y_within, b.y_at_target);
    }
}

TEST(DesignColourBound, AnyMultiplierGivesAnUpperBoundAndWhiteIsReflectedWhole) {
    const auto w = detail::colour_xyz_weights(band(8, 0.36, 0.83));
    const auto t = uv_of({0.0, 0.0, 1.0});
    const double brute = brute_force_y(w, t);
    for (double m0 : {-3.0, -0.5, 0.0, 0.7, 4.0})
        for (double m1 : {-2.0, 0.0, 0.3, 5.0}) EXPECT_GE(detail::optimal_colour_dual(w, t, 0.0, {m0, m1}), brute - 1e-12);
    // White (the light's own colour) is met by reflecting everything: Y = 1.
    double white_y = 0.0;
    for (std::size_t l = 0; l < 8; ++l) white_y += w[8 + l];
    const auto white = detail::optimal_colour_bound(w, uv_of({1.0, 1.0, 1.0}), 0.0);
    EXPECT_NEAR(white_y, 1.0, 1e-6);
    EXPECT_NEAR(white.y_at_target, 1.0, 1e-6);
}

TEST(DesignColourBound, ADesignsConeColourNeverExceedsItsBound) {
    // A small colour design, scored by exact_orders: its Y is below the bound of its own
    // chromaticity (the bound holds for any reflectance spectrum), and design.json reports the
    // bound of the target's.
    const DesignOptions o = test::small_design("colour:#0000FF", 4, 30, 5);
    const PreparedDesign p = prepare_design(o);
    const DesignResult r = run_design(p);
    const auto xyz = reflectance_xyz(
        r.lambdas_um, test::cone_power(r.heights_um, o.size, o.texel_um, r.lambdas_um, {0.0, 0.0}, o.view_cone));
    const auto own = detail::optimal_colour_bound(detail::colour_xyz_weights(r.lambdas_um), xyz_to_uv(xyz), 0.0);
    EXPECT_LE(xyz[1], own.y_at_target + 1e-9);
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_TRUE(j.contains("optimal_colour_bound"));
    const auto target = detail::optimal_colour_bound(detail::colour_xyz_weights(r.lambdas_um), uv_of({0, 0, 1}), 0.04);
    EXPECT_NEAR(j["optimal_colour_bound"]["y_at_target"].get<double>(), target.y_at_target, 1e-12);
    EXPECT_NEAR(j["optimal_colour_bound"]["y_within_delta_uv"].get<double>(), target.y_within, 1e-12);
}

}  // namespace
}  // namespace wavebrdf
