#pragma once
// Internal: the largest luminous efficiency, in incident power, that any relief on K equally spaced
// levels sends into a view cone about the mirror direction under normal light.
//
// With F_ℓ(b) the DFT of level ℓ's mask over N², the order (m, n) in the cone carries the flux
// env |Σ_ℓ F_ℓ(b) e^{−iℓν}|², ν = (2π/λ) Δh (1 + cos θ_o), env = sinc²(m/N) sinc²(n/N) cos θ_o.
// The orders {(±m, ±n), (±n, ±m)} share one ν and one env per wavelength: a class. A class's power
// S_c(ν) = Σ_b |Σ_ℓ F_ℓ(b) e^{−iℓν}|² is a non-negative cosine polynomial g_0 + 2 Σ g_k cos kν of
// degree K − 1 (the class is closed under negation and the masks are real); the classes and the
// rest of the tile sum to 1 at every ν (Parseval at a fixed phase step); the mirror order's
// coefficients are the autocorrelation of the level shares (r_k ≥ 0, r_k ≤ r_0, S_0(0) = 1, of
// which the programme keeps S_0(0) ≤ 1).
// Every relief is a point of that set with its own cone power, so the largest Y over the set at a
// chromaticity bounds every relief's cone light at that chromaticity, in incident power.
//
// It is computed as the dual: a cosine-coefficient vector π, a multiplier ρ ≥ 0 for S_0(0) ≤ 1,
// multipliers for the colour conditions and non-negative ones for r's conditions, such that for
// every class the Toeplitz matrix of π − ℓ_c is positive semidefinite (ℓ_c the class's share of
// the objective): then π_0 + ρ ≥ Y for every point of the set (weak duality). A log-barrier Newton
// method finds such a point; the bound returned is that strictly feasible point's value, checked
// by Cholesky factorisations, so it is an upper bound whether or not the method converged.
// It does not cover the metrics' division by the reflected propagating power (docs/design.md).
#include <array>
#include <vector>

namespace wavebrdf::detail {

struct ConeProgramme {
    int levels = 0;
    int wavelengths = 0;
    std::vector<std::array<int, 2>> classes;  // (m, n), m ≥ n ≥ 0; class 0 the mirror order
    // Cone power per wavelength: P_w = Σ_c Σ_k power[(w · C + c) · K + k] g_{c,k}.
    std::vector<double> power;
};

// Throws std::invalid_argument when the largest cone reaches half the tile (its orders would alias).
ConeProgramme cone_programme(int size, double texel_um, double view_cone, const std::vector<double>& lambdas_um,
                             double level_step_um, int levels);

// An upper bound on Y (incident power) of every relief whose cone colour has chromaticity `uv`
// (delta 0) or lies within the 32-gon circumscribing the disk of radius delta about it.
// stop_below / stop_above: the search may end once the bound is below stop_below, or once it
// cannot go below stop_above (the value is still a valid bound).
double cone_bound_y(const ConeProgramme& p, const std::vector<double>& xyz_weights, const std::array<double, 2>& uv,
                    double delta = 0.0, double stop_below = -1.0, double stop_above = 1e300);

struct ConeBound {
    int classes = 0;
    double y_at_target = 0.0;
    double min_y = 0.05;
    // The largest radius about the target within which the bound proves Y < min_y (0 when the
    // target itself is not ruled out).
    double delta_uv_ruled_out = 0.0;
};
ConeBound cone_bound(const ConeProgramme& p, const std::vector<double>& xyz_weights,
                     const std::array<double, 2>& target_uv, double min_y);

// The class coefficients g (class-major, K each) of a relief given as level indices (N² values),
// by the DFT of its masks: for tests, which compare P = power · g with independent sums.
std::vector<double> cone_relief_point(const ConeProgramme& p, const std::vector<int>& level, int size);

}  // namespace wavebrdf::detail
