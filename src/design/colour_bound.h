#pragma once
// Internal: how luminous a colour of a given chromaticity can be at all (the optimal-colour or
// MacAdam limit) on the wavelengths a design samples. A view cone's share of the reflected
// power at each wavelength is some R_λ ∈ [0, 1], whatever the relief, so no surface, on any
// levels or from any view, reflects a colour of that chromaticity with a larger Y. The bound is
// the value of the Lagrangian dual at a point found by a search; weak duality makes it an upper
// bound wherever the search stops, and it meets the largest Y (strong duality) when the search
// converges.
#include <array>
#include <vector>

namespace wavebrdf::detail {

struct OptimalColourBound {
    // The largest Y of any R ∈ [0, 1]^W with u′v′ exactly the target's.
    double y_at_target = 0.0;
    // The largest Y of any R ∈ [0, 1]^W with Δu′v′ ≤ tolerance from the target.
    double tolerance = 0.0;
    double y_within = 0.0;
    // The spectrum of the within-tolerance dual's step: R_λ = 1 where its reduced cost is
    // positive, else 0 (1 where the optimal colour reflects): says which part of the band the
    // brightest colour of that chromaticity uses.
    std::vector<int> reflects;
};

// xyz_weights: 3 × W (colour_xyz_weights: row c holds X, Y or Z per unit reflectance at each
// wavelength); target_uv the target chromaticity (CIE 1976 u′v′); tolerance ≥ 0.
OptimalColourBound optimal_colour_bound(const std::vector<double>& xyz_weights, const std::array<double, 2>& target_uv,
                                        double tolerance);

// The dual function itself (for tests): F(μ) = Σ_λ max(0, y_λ − μ·b_λ + s d_λ), b_λ = (4x_λ, 9y_λ) −
// target·d_λ, d_λ = x_λ + 15y_λ + 3z_λ, s = ± tolerance·|μ| (the larger sum): an upper bound on
// the largest Y for every μ.
double optimal_colour_dual(const std::vector<double>& xyz_weights, const std::array<double, 2>& target_uv,
                           double tolerance, const std::array<double, 2>& mu);

}  // namespace wavebrdf::detail
