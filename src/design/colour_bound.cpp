#include "design/colour_bound.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

#include "core/golden_section.h"

namespace wavebrdf::detail {

namespace {

// The primal: maximise Y = Σ y_λ R_λ over R ∈ [0, 1]^W and a chromaticity p with |p − t| ≤ r,
// subject to (4X, 9Y) = p D (u′v′ = p), D = X + 15Y + 3Z. Its Lagrangian with μ ∈ R² is
// Σ R_λ (y_λ − μ·(4x_λ, 9y_λ) + (μ·p) d_λ); the maximum over R ∈ box is Σ max(0, ·), convex in
// the scalar s = μ·p ∈ [μ·t − r|μ|, μ·t + r|μ|], so the larger of the two ends. (It is the second-
// order-cone dual of the disk constraint, with no gap when d_λ ≥ 0 and the disk holds a
// reachable chromaticity inside it.)
double dual_value(const std::vector<double>& w, std::size_t n, const std::array<double, 2>& t, double r,
                  const std::array<double, 2>& mu, std::vector<int>* reflects) {
    const double norm = std::hypot(mu[0], mu[1]);
    double best = -1.0;
    for (double sign : {1.0, -1.0}) {
        const double s = mu[0] * t[0] + mu[1] * t[1] + sign * r * norm;
        double sum = 0.0;
        for (std::size_t l = 0; l < n; ++l) {
            const double x = w[l], y = w[n + l], z = w[2 * n + l];
            const double d = x + 15.0 * y + 3.0 * z;
            const double c = y - mu[0] * 4.0 * x - mu[1] * 9.0 * y + s * d;
            if (c > 0.0) sum += c;
        }
        if (sum > best) {
            best = sum;
            if (reflects) {
                reflects->assign(n, 0);
                for (std::size_t l = 0; l < n; ++l) {
                    const double x = w[l], y = w[n + l], z = w[2 * n + l];
                    const double d = x + 15.0 * y + 3.0 * z;
                    (*reflects)[l] = y - mu[0] * 4.0 * x - mu[1] * 9.0 * y + s * d > 0.0 ? 1 : 0;
                }
            }
        }
        if (r == 0.0) break;
    }
    return best;
}

// min over μ of the dual: g(μ0) = min_μ1 F(μ0, μ1) is convex (a partial minimum of a convex
// function), so nested golden sections find the minimum; the bracket is wide enough that the
// minimiser of these small-magnitude weights lies well inside it (checked below: a minimum on the
// bracket's edge widens it).
double minimise_dual(const std::vector<double>& w, std::size_t n, const std::array<double, 2>& t, double r,
                     std::array<double, 2>& mu) {
    constexpr int k_iterations = 120;
    double bracket = 1e3;
    double value = 0.0;
    for (int widen = 0; widen < 6; ++widen) {
        auto inner = [&](double m0, double* m1) {
            double v = 0.0;
            *m1 = golden_section_minimum(
                [&](double x) {
                    return dual_value(w, n, t, r, {m0, x}, nullptr);
                },
                -bracket, bracket, k_iterations + 2, &v);
            return v;
        };
        double m1 = 0.0;
        const double m0 = golden_section_minimum(
            [&](double x) {
                double y;
                return inner(x, &y);
            },
            -bracket, bracket, k_iterations + 2, &value);
        inner(m0, &m1);
        mu = {m0, m1};
        if (std::max(std::abs(m0), std::abs(m1)) < 0.9 * bracket) break;
        bracket *= 100.0;
    }
    // F at μ = 0 is Y of white (every R = 1): a valid bound too, and never worse than 1.
    return std::min(value, dual_value(w, n, t, r, {0.0, 0.0}, nullptr));
}

}  // namespace

double optimal_colour_dual(const std::vector<double>& xyz_weights, const std::array<double, 2>& target_uv,
                           double tolerance, const std::array<double, 2>& mu) {
    if (xyz_weights.empty() || xyz_weights.size() % 3 != 0)
        throw std::invalid_argument("optimal_colour_dual: xyz weights are not 3 x wavelengths");
    return dual_value(xyz_weights, xyz_weights.size() / 3, target_uv, tolerance, mu, nullptr);
}

OptimalColourBound optimal_colour_bound(const std::vector<double>& xyz_weights, const std::array<double, 2>& target_uv,
                                        double tolerance) {
    if (xyz_weights.empty() || xyz_weights.size() % 3 != 0)
        throw std::invalid_argument("optimal_colour_bound: xyz weights are not 3 x wavelengths");
    if (!(tolerance >= 0.0 && std::isfinite(tolerance)))
        throw std::invalid_argument("optimal_colour_bound: tolerance is not a finite value >= 0");
    const std::size_t n = xyz_weights.size() / 3;
    OptimalColourBound b;
    b.tolerance = tolerance;
    std::array<double, 2> mu{};
    b.y_at_target = std::max(0.0, minimise_dual(xyz_weights, n, target_uv, 0.0, mu));
    b.y_within = std::max(0.0, minimise_dual(xyz_weights, n, target_uv, tolerance, mu));
    // The within-tolerance bound can only be larger; keep the pair consistent where the nested
    // search stopped a little above the exact-chromaticity one.
    b.y_within = std::max(b.y_within, b.y_at_target);
    dual_value(xyz_weights, n, target_uv, tolerance, mu, &b.reflects);
    return b;
}

}  // namespace wavebrdf::detail
