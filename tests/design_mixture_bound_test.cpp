// The mixture bound: the simplex against every vertex of small programmes, the bound exact where
// the relaxation is (two levels), never below a sampled mixture or convex combination of mixtures,
// its Δu′v′ never beaten by a sampled mixture with Y ≥ 5 %, and a design's check against an
// independent sum over exact_orders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "design/mixture_bound.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf {
namespace {

// max c·x over A x ≤ b, x ≥ 0 by every choice of n active constraints among the m rows and the
// n bounds x_j ≥ 0 (Gaussian elimination), the feasible ones compared.
double vertex_max(const std::vector<double>& c, const std::vector<double>& A, const std::vector<double>& b) {
    const std::size_t n = c.size(), m = b.size(), total = m + n;
    double best = -1e300;
    std::vector<std::size_t> pick(n);
    for (std::size_t i = 0; i < n; ++i) pick[i] = i;
    for (;;) {
        std::vector<double> M(n * (n + 1), 0.0);
        for (std::size_t r = 0; r < n; ++r) {
            const std::size_t k = pick[r];
            if (k < m) {
                for (std::size_t j = 0; j < n; ++j) M[r * (n + 1) + j] = A[k * n + j];
                M[r * (n + 1) + n] = b[k];
            } else {
                M[r * (n + 1) + (k - m)] = 1.0;
            }
        }
        bool singular = false;
        for (std::size_t col = 0; col < n && !singular; ++col) {
            std::size_t piv = col;
            for (std::size_t r = col + 1; r < n; ++r)
                if (std::abs(M[r * (n + 1) + col]) > std::abs(M[piv * (n + 1) + col])) piv = r;
            if (std::abs(M[piv * (n + 1) + col]) < 1e-12) {
                singular = true;
                break;
            }
            for (std::size_t j = 0; j <= n; ++j) std::swap(M[col * (n + 1) + j], M[piv * (n + 1) + j]);
            for (std::size_t r = 0; r < n; ++r) {
                if (r == col) continue;
                const double f = M[r * (n + 1) + col] / M[col * (n + 1) + col];
                for (std::size_t j = 0; j <= n; ++j) M[r * (n + 1) + j] -= f * M[col * (n + 1) + j];
            }
        }
        if (!singular) {
            std::vector<double> x(n);
            for (std::size_t j = 0; j < n; ++j) x[j] = M[j * (n + 1) + n] / M[j * (n + 1) + j];
            bool ok = true;
            for (double v : x) ok = ok && v >= -1e-9;
            for (std::size_t k = 0; k < m && ok; ++k) {
                double s = 0.0;
                for (std::size_t j = 0; j < n; ++j) s += A[k * n + j] * x[j];
                ok = s <= b[k] + 1e-9;
            }
            if (ok) {
                double v = 0.0;
                for (std::size_t j = 0; j < n; ++j) v += c[j] * x[j];
                best = std::max(best, v);
            }
        }
        // Next combination.
        std::size_t i = n;
        while (i > 0 && pick[i - 1] == total - n + i - 1) --i;
        if (i == 0) break;
        ++pick[i - 1];
        for (std::size_t k = i; k < n; ++k) pick[k] = pick[k - 1] + 1;
    }
    return best;
}

TEST(DesignMixtureBound, SimplexMatchesEveryVertex) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 40; ++trial) {
        const std::size_t n = 3 + trial % 2, m = 9;
        std::vector<double> c(n), A(m * n), b(m);
        for (double& x : c) x = u(rng);
        for (double& x : A) x = u(rng);
        // Degenerate rows (b = 0) as the bound's programmes have, and one row keeping it bounded.
        for (std::size_t k = 0; k < m; ++k) b[k] = k % 3 == 0 ? 0.0 : 0.5 + 0.5 * u(rng);
        for (std::size_t j = 0; j < n; ++j) A[(m - 1) * n + j] = 1.0;
        b[m - 1] = 1.0;
        const auto r = detail::lp_maximise(c, A, b);
        ASSERT_EQ(r.status, detail::LpResult::Status::Optimal);
        EXPECT_NEAR(r.value, vertex_max(c, A, b), 1e-9) << "trial " << trial;
    }
}

struct Band {
    std::vector<double> lambdas, weights, nu;
};

// The slices' white at W samples of 0.40–0.70 µm, K levels within 2 µm, normal light.
Band mixture_band(int W, int K) {
    Band b;
    for (int k = 0; k < W; ++k) b.lambdas.push_back(0.40 + (k + 0.5) * 0.30 / W);
    b.weights = detail::colour_xyz_weights(b.lambdas);
    const double step = K > 1 ? 2.0 / (K - 1) : 0.0;
    for (double l : b.lambdas) b.nu.push_back(2.0 * k_pi / l * step * 2.0);
    return b;
}

std::array<double, 3> xyz(const Band& b, const std::vector<double>& R) {
    const std::size_t W = R.size();
    std::array<double, 3> X{0.0, 0.0, 0.0};
    for (std::size_t c = 0; c < 3; ++c)
        for (std::size_t w = 0; w < W; ++w) X[c] += b.weights[c * W + w] * R[w];
    return X;
}

std::vector<double> random_shares(int K, std::mt19937_64& rng, double sparsity) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<double> p(static_cast<std::size_t>(K));
    double s = 0.0;
    for (double& x : p) s += x = u(rng) < sparsity ? 0.0 : -std::log(u(rng) + 1e-300);
    if (s == 0.0) p[0] = s = 1.0;
    for (double& x : p) x /= s;
    return p;
}

TEST(DesignMixtureBound, TwoLevelsAreExact) {
    // K = 2: the autocorrelations r_1 = a(1 − a) fill [0, 1/4], the programme's whole set, so the
    // bound at a mixture's own chromaticity is that mixture's Y.
    const Band b = mixture_band(12, 2);
    for (double a : {0.1, 0.3, 0.45}) {
        const auto R = detail::mixture_spectrum({a, 1.0 - a}, b.nu);
        const auto X = xyz(b, R);
        EXPECT_NEAR(detail::mixture_bound_y(b.weights, b.nu, 2, xyz_to_uv(X)), X[1], 1e-9) << a;
    }
}

TEST(DesignMixtureBound, NoMixtureOrPatchworkExceedsIt) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int K : {3, 8, 16}) {
        const Band b = mixture_band(16, K);
        for (int trial = 0; trial < 12; ++trial) {
            // One mixture, or patches of three (a convex combination of their spectra).
            std::vector<double> R(b.nu.size(), 0.0);
            const int patches = trial % 2 ? 3 : 1;
            double left = 1.0;
            for (int k = 0; k < patches; ++k) {
                const double share = k + 1 == patches ? left : left * u(rng);
                left -= share;
                const auto S = detail::mixture_spectrum(random_shares(K, rng, 0.5), b.nu);
                for (std::size_t w = 0; w < R.size(); ++w) R[w] += share * S[w];
            }
            const auto X = xyz(b, R);
            EXPECT_LE(X[1], detail::mixture_bound_y(b.weights, b.nu, K, xyz_to_uv(X)) + 1e-9) << K << " " << trial;
        }
    }
}

TEST(DesignMixtureBound, NoMixtureBeatsItsDeltaUvAtFivePercent) {
    const int K = 16;
    const Band b = mixture_band(16, K);
    const auto blue = xyz_to_uv(linear_srgb_to_xyz({0.0, 0.0, 1.0}));
    const auto bound = detail::mixture_bound(b.weights, b.nu, K, blue, 0.05);
    const auto one = detail::best_mixture(b.weights, b.nu, K, blue, 1e-3, 0.05, 3);
    std::mt19937_64 rng(9);
    int bright = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        const auto X = xyz(b, detail::mixture_spectrum(random_shares(K, rng, 0.8), b.nu));
        if (X[1] < 0.05) continue;
        ++bright;
        const auto uv = xyz_to_uv(X);
        if (bound.y_at_target < 0.05) {
            EXPECT_GE(std::hypot(uv[0] - blue[0], uv[1] - blue[1]), bound.delta_uv_at_min_y - 1e-9);
        }
    }
    EXPECT_GT(bright, 100);
    // What one mixture reaches lies within the bound: at its Y the Δu′v′ is no better.
    const auto own = detail::mixture_spectrum(one.shares, b.nu);
    const auto X = xyz(b, own);
    EXPECT_NEAR(X[1], one.y, 1e-12);
    EXPECT_LE(one.y, detail::mixture_bound_y(b.weights, b.nu, K, one.uv) + 1e-9);
    if (one.y >= 0.05 && bound.y_at_target < 0.05) {
        EXPECT_GE(one.delta_uv, bound.delta_uv_at_min_y - 1e-9);
    }
    if (bound.y_at_target >= 0.05) {
        EXPECT_EQ(bound.delta_uv_at_min_y, 0.0);
    }
}

// A colour design's options: an N² tile on K levels under `spectral` wavelengths, no view survey.
DesignOptions colour_run(const std::string& target, int size, int levels, int spectral, int iterations,
                         int refine_passes) {
    DesignOptions o;
    o.target = parse_design_target(target);
    o.size = size;
    o.levels = levels;
    o.spectral = spectral;
    o.iterations = iterations;
    o.refine_passes = refine_passes;
    o.survey_views = false;
    return o;
}

TEST(DesignMixtureBound, DesignJsonChecksTheDesignsConeLight) {
    // design.json's check of the run's own cone light, against exact_orders summed here.
    const DesignOptions o = colour_run("colour:#FF0000", 16, 4, 8, 20, 4);
    const DesignResult r = run_design(prepare_design(o));
    const auto j = nlohmann::json::parse(r.metrics_json);
    ASSERT_TRUE(j.contains("mixture_bound"));
    const auto& m = j["mixture_bound"];
    const auto orders = exact_orders(r.heights_um, o.size, o.texel_um, o.omega_i, r.lambdas_um);
    std::vector<double> normalised(orders.size(), 0.0), absolute(orders.size(), 0.0);
    for (std::size_t l = 0; l < orders.size(); ++l) {
        for (std::size_t q = 0; q < orders[l].power.size(); ++q)
            if (std::hypot(orders[l].omega_x[q], orders[l].omega_y[q]) <= o.view_cone)
                normalised[l] += orders[l].power[q];
        absolute[l] = normalised[l] * orders[l].kirchhoff_total;
    }
    EXPECT_NEAR(m["design_check"]["normalised"]["y"].get<double>(), reflectance_xyz(r.lambdas_um, normalised)[1], 1e-9);
    EXPECT_NEAR(m["design_check"]["absolute"]["y"].get<double>(), reflectance_xyz(r.lambdas_um, absolute)[1], 1e-9);
    // The target's bound from the recorded phase steps.
    const auto nu = m["phase_step_rad"].get<std::vector<double>>();
    const auto w = detail::colour_xyz_weights(r.lambdas_um);
    EXPECT_NEAR(m["y_at_target"].get<double>(),
                detail::mixture_bound_y(w, nu, 4, xyz_to_uv(linear_srgb_to_xyz({1.0, 0.0, 0.0}))), 1e-12);
    EXPECT_EQ(m["levels"].get<int>(), 4);
}

TEST(DesignMixtureBound, AboveSixtyFourLevelsTheRunSaysItIsNotComputed) {
    const auto j = nlohmann::json::parse(
        run_design(prepare_design(colour_run("colour:#0000FF", 4, 128, 4, 1, 0))).metrics_json);
    EXPECT_FALSE(j.contains("mixture_bound"));
    bool noted = false;
    for (const auto& n : j["notes"]) noted = noted || n.get<std::string>().find("up to 64 levels") != std::string::npos;
    EXPECT_TRUE(noted) << j["notes"].dump();
}

}  // namespace
}  // namespace wavebrdf
