// The cone bound: a relief's point in the programme against a direct sum over texels (its cone
// power) and against the programme's conditions, and no relief of a small tile, all 3^9 of them,
// above the bound at its own chromaticity.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <random>

#include "design/cone_bound.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"

namespace wavebrdf {
namespace {

// Σ over the orders in the cone of |(1/L²) ∫ e^{−ikh(1 + cos θ_o)} e^{−2πi f·x} dx|² cos θ_o, each
// texel's integral in closed form.
std::vector<double> direct_cone_power(const std::vector<int>& level, int N, double texel, double cone, double step,
                                      const std::vector<double>& lambdas) {
    const double L = N * texel;
    std::vector<double> out;
    for (double lam : lambdas) {
        const double k = 2.0 * k_pi / lam;
        const int R = static_cast<int>(cone * L / lam) + 1;
        double total = 0.0;
        for (int m = -R; m <= R; ++m)
            for (int n = -R; n <= R; ++n) {
                const double dx = lam * m / L, dy = lam * n / L;
                if (dx * dx + dy * dy > cone * cone) continue;
                const double cos_o = std::sqrt(1.0 - dx * dx - dy * dy);
                auto edge = [&](int f, int i) {
                    if (f == 0) return std::complex<double>(texel, 0.0);
                    const double a = 2.0 * k_pi * f / L;
                    return (std::polar(1.0, -a * (i + 1) * texel) - std::polar(1.0, -a * i * texel)) /
                           std::complex<double>(0.0, -a);
                };
                std::complex<double> amp = 0.0;
                for (int i = 0; i < N; ++i)
                    for (int j = 0; j < N; ++j)
                        amp += std::polar(1.0, -k * level[static_cast<std::size_t>(i * N + j)] * step * (1.0 + cos_o)) *
                               edge(m, i) * edge(n, j);
                total += std::norm(amp / (L * L)) * cos_o;
            }
        out.push_back(total);
    }
    return out;
}

std::vector<double> programme_cone_power(const detail::ConeProgramme& p, const std::vector<double>& g) {
    const std::size_t C = p.classes.size(), K = static_cast<std::size_t>(p.levels);
    std::vector<double> P(static_cast<std::size_t>(p.wavelengths), 0.0);
    for (std::size_t w = 0; w < P.size(); ++w)
        for (std::size_t i = 0; i < C * K; ++i) P[w] += p.power[w * C * K + i] * g[i];
    return P;
}

TEST(DesignConeBound, AReliefIsAPointOfTheProgrammeWithTheDirectSumsConePower) {
    const std::vector<double> lambdas{0.41, 0.52, 0.66};
    const int N = 12, K = 4;
    const double texel = 0.5, cone = 0.3, step = 0.21;
    const auto p = detail::cone_programme(N, texel, cone, lambdas, step, K);
    ASSERT_GE(p.classes.size(), 4u);
    std::mt19937 rng(5);
    for (int trial = 0; trial < 3; ++trial) {
        std::vector<int> level(N * N);
        for (int t = 0; t < N * N; ++t)
            level[static_cast<std::size_t>(t)] = trial == 2 ? ((t / N + t % N) / 3) % K : static_cast<int>(rng() % K);
        const auto g = detail::cone_relief_point(p, level, N);
        const auto P = programme_cone_power(p, g);
        const auto direct = direct_cone_power(level, N, texel, cone, step, lambdas);
        for (std::size_t w = 0; w < P.size(); ++w) EXPECT_NEAR(P[w], direct[w], 1e-12 + 1e-9 * direct[w]);
        // Every class's polynomial and the rest's are non-negative; the mirror order's is a mixture's.
        const std::size_t C = p.classes.size();
        for (std::size_t c = 0; c <= C; ++c)
            for (int j = 0; j <= 2048; ++j) {
                const double nu = k_pi * j / 2048;
                double s = g[c * K];
                for (int m = 1; m < K; ++m) s += 2.0 * g[c * K + static_cast<std::size_t>(m)] * std::cos(m * nu);
                EXPECT_GE(s, -1e-12) << "class " << c << " at " << nu;
            }
        double s0 = g[0];
        for (int m = 1; m < K; ++m) {
            s0 += 2.0 * g[static_cast<std::size_t>(m)];
            EXPECT_GE(g[static_cast<std::size_t>(m)], -1e-15);
            EXPECT_LE(g[static_cast<std::size_t>(m)], g[0] + 1e-15);
        }
        EXPECT_NEAR(s0, 1.0, 1e-12);
    }
}

TEST(DesignConeBound, NoReliefOfASmallTileExceedsItAtItsOwnChromaticity) {
    const std::vector<double> lambdas{0.42, 0.55, 0.68};
    const int N = 3, K = 3;
    const auto p = detail::cone_programme(N, 0.5, 0.45, lambdas, 0.3, K);
    ASSERT_EQ(p.classes.size(), 3u);  // the mirror order, (1, 0) and (1, 1): nested cones
    const auto w = detail::colour_xyz_weights(lambdas);
    struct Colour {
        double y;
        std::array<double, 2> uv;
    };
    std::vector<Colour> all;
    std::vector<int> level(9, 0);
    for (int code = 0; code < 19683; ++code) {
        for (int t = 0, c = code; t < 9; ++t, c /= 3) level[static_cast<std::size_t>(t)] = c % 3;
        const auto P = programme_cone_power(p, detail::cone_relief_point(p, level, N));
        std::array<double, 3> X{};
        for (int c = 0; c < 3; ++c)
            for (std::size_t l = 0; l < 3; ++l) X[static_cast<std::size_t>(c)] += w[static_cast<std::size_t>(c) * 3 + l] * P[l];
        all.push_back({X[1], xyz_to_uv(X)});
    }
    // The direct sum on one of them, so that the brute force rests on it too.
    for (int t = 0, c = 12345; t < 9; ++t, c /= 3) level[static_cast<std::size_t>(t)] = c % 3;
    const auto direct = direct_cone_power(level, N, 0.5, 0.45, 0.3, lambdas);
    const auto P = programme_cone_power(p, detail::cone_relief_point(p, level, N));
    for (std::size_t l = 0; l < 3; ++l) EXPECT_NEAR(P[l], direct[l], 1e-12);
    std::sort(all.begin(), all.end(), [](const Colour& a, const Colour& b) { return a.y > b.y; });
    int tight = 0;
    for (std::size_t i = 0; i < all.size(); i += all.size() / 40) {
        const double bound = detail::cone_bound_y(p, w, all[i].uv);
        EXPECT_LE(all[i].y, bound + 1e-9) << "relief " << i << " at u'v' " << all[i].uv[0] << ", " << all[i].uv[1];
        if (all[i].y >= 0.8 * bound) ++tight;
    }
    EXPECT_GE(tight, 1);  // the bound is attained, or nearly, somewhere
}

}  // namespace
}  // namespace wavebrdf
