#pragma once
// Internal: what mixtures of K equally spaced levels can send into the mirror direction.
//
// A patch of texels holding level ℓ in share p_ℓ, finely arranged, sends into the mirror
// direction its mean phasor, power R(ν) = |Σ_ℓ p_ℓ e^{−iℓν}|² per unit incident power at the
// phase step ν_λ = (2π/λ) Δh (cos θ_i + cos θ_o); the rest scatters away. A relief made of such
// patches, each coarser than the view cone's resolution, sends a convex combination of these
// spectra into the cone. R(ν) = r_0 + 2 Σ_{m ≥ 1} r_m cos(mν) with r the autocorrelation of p:
// r_m ≥ 0, r_m ≤ r_0, r_0 + 2 Σ r_m = 1 and R ≥ 0 at every ν. Those conditions are linear in r
// and every convex combination of autocorrelations meets them, so the largest Y at a chromaticity
// over them (a linear programme) is an upper bound on every such relief: the mixture bound. It
// covers nothing else: detail that diffracts light into the cone, or a normalisation of the
// cone's power by less than the incident power, are outside it (docs/design.md).
#include <array>
#include <cstdint>
#include <vector>

namespace wavebrdf::detail {

// max c·x subject to A x ≤ b, x ≥ 0, with b ≥ 0 (x = 0 feasible); A row-major, rows × c.size().
// Dense tableau simplex, largest-coefficient rule on right-hand sides raised by ~1e-12 of each
// row's scale (a relaxation that breaks the degeneracy of the bound's b = 0 rows).
struct LpResult {
    enum class Status { Optimal, Unbounded, IterationLimit } status = Status::Optimal;
    double value = 0.0;
    std::vector<double> x;
};
LpResult lp_maximise(const std::vector<double>& c, const std::vector<double>& A, const std::vector<double>& b);

// |Σ_ℓ p_ℓ e^{−iℓν}|² at each ν.
std::vector<double> mixture_spectrum(const std::vector<double>& shares, const std::vector<double>& nu);

struct MixtureBound {
    int levels = 0;
    int grid = 0;  // the ν grid on [0, π] where R ≥ 0 is imposed (with the samples' own ν)
    // The largest Y at the target chromaticity (0 when no mixture's colour has it).
    double y_at_target = 0.0;
    // The smallest Δu′v′ from the target any convex combination of mixtures has with Y ≥ min_y
    // (a lower bound: the disk is circumscribed by a polygon), and that programme's solution's
    // chromaticity; 0 and the target when y_at_target ≥ min_y. Infinity when no Y ≥ min_y at all.
    double min_y = 0.05;
    double delta_uv_at_min_y = 0.0;
    std::array<double, 2> uv_at_min_y{};
    std::vector<double> autocorrelation;  // r of the y_at_target programme
};

// xyz_weights: 3 × W (colour_xyz_weights); nu: ν_λ per wavelength; K ≥ 1 levels.
MixtureBound mixture_bound(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                           const std::array<double, 2>& target_uv, double min_y);

// The largest Y of any convex combination of mixtures whose chromaticity is `uv` (the bound at a
// given colour, for checking a spectrum against it).
double mixture_bound_y(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                       const std::array<double, 2>& uv);

// What one mixture reaches (a local search over the shares, seeded starts): the shares with the
// largest Y within `tolerance` of the target chromaticity, or else the closest chromaticity.
struct BestMixture {
    std::vector<double> shares;
    double y = 0.0;
    double delta_uv = 0.0;
    std::array<double, 2> uv{};
};
BestMixture best_mixture(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                         const std::array<double, 2>& target_uv, double tolerance, double min_y, std::uint64_t seed);

}  // namespace wavebrdf::detail
