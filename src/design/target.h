#pragma once
// Internal: the appearance targets as functions of the orders' power fractions. Every order of
// every wavelength belongs to at most two groups (a cone, a region's bin, an image pixel); a
// target sees only each group's fraction of the wavelength's reflected power,
// f[w][q] = Σ_{o ∈ q} Φ_o / Σ_o Φ_o, and maps them to a loss (with its gradient) and to metrics.
// The colour targets see fractions of the incident power instead, f[w][q] = Σ_{o ∈ q} Φ_o (the
// fluxes are per unit incident power): the luminous efficiency is the fraction of the white
// light's luminous power that reaches the view cone, and no design can raise it by reflecting
// less elsewhere.
#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "design/engine.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

// A number in the design stage's messages and notes (format_shortest).
inline std::string num(double v) { return format_shortest(v); }

using Fractions = std::vector<std::vector<double>>;  // [wavelength][group]

class Target {
public:
    virtual ~Target() = default;
    // The groups of every order (-1: none), for these order sets; called once, before the rest.
    virtual void assign(const std::vector<OrderSet>& sets) = 0;
    virtual int groups() const = 0;
    // Whether the fractions are of the incident power (true) or of the reflected propagating power.
    virtual bool incident_power() const { return false; }
    // The loss of the fractions; with `gradient`, ∂loss/∂f (same shape).
    virtual double loss(const Fractions& f, Fractions* gradient) const = 0;
    // The target's metrics (design.json), from the fractions.
    virtual nlohmann::json metrics(const Fractions& f) const = 0;
    // The Δu′v′ the colour loss of view cone `cone` does not count (colour_loss; colour: cone 0,
    // iridescent: one per pair, in order); other targets have none.
    virtual void set_delta_uv_tolerance(std::size_t /*cone*/, double /*tolerance*/) {}
    // A constrained target (the anti-mirror) maximises one metric subject to limits on others.
    // Each constraint g ≤ 0 enters the loss as the augmented-Lagrangian term
    // (max(0, λ + ρ g)² − λ²) / (2ρ), whose multiplier λ the loop moves between blocks of the
    // optimisation (update_multipliers: λ ← max(0, λ + ρ g) at the block's fractions), so that it
    // grows while the constraint is violated and falls while it holds: the design settles on the
    // limits rather than at a fixed trade against them. Other targets have no constraints.
    virtual bool constrained() const { return false; }
    virtual void reset_multipliers() {}
    virtual void update_multipliers(const Fractions& /*f*/) {}
    // Doubles ρ (a repair block: the relief still breaks a limit).
    virtual void stiffen() {}
    // Which user limits the fractions break, one line each (empty: all met).
    virtual std::vector<std::string> broken_limits(const Fractions& /*f*/) const { return {}; }
    // The constraints' state for design.json (null for an unconstrained target).
    virtual nlohmann::json constraints_json() const { return nullptr; }
    // What the target picture holds on a size × size grid of ω_o about the mirror direction
    // (target.exr): rows along ω_x.
    const std::vector<std::vector<std::array<int, 2>>>& members() const { return m_members; }

protected:
    std::vector<std::vector<std::array<int, 2>>> m_members;  // [wavelength][order]
};

// Each group's fraction (of the incident or the reflected power, as the target counts) and each
// wavelength's total flux Σ Φ (the reflected propagating power per unit incident power).
Fractions group_fractions(const Target& target, const std::vector<std::vector<double>>& flux,
                          std::vector<double>* totals = nullptr);
// ∂loss/∂Φ_o from ∂loss/∂f (the fractions' quotient rule; the identity for incident power).
void flux_gradient(const Target& target, const std::vector<std::vector<double>>& flux, const Fractions& f,
                   const Fractions& df, std::vector<std::vector<double>>& gradient);

// The anti-mirror maximises the region's mean fraction over the wavelengths subject to, at every
// wavelength, the cone's fraction ≤ cone_limit and the region's uniformity ≤ uniformity_limit; the
// loop aims a margin inside each limit (k_anti_mirror_aim of it), since the relaxed mixtures it
// moves the multipliers on are not quite the final relief.
struct AntiMirrorSpec {
    double specular_cone = 0.05;  // sin of the cone's half-angle about the mirror direction
    double r1 = 0.1, r2 = 0.5;    // the region: r1 ≤ |ω_o − ω_mirror| ≤ r2 (disk: r1 = 0)
    double cone_limit = 0.002;     // fraction of the reflected power in the cone, per wavelength
    double uniformity_limit = 0.25;  // std/mean of the region's 16 bins, per wavelength
};
constexpr double k_anti_mirror_aim = 0.95;
std::unique_ptr<Target> make_anti_mirror(const AntiMirrorSpec& spec);

struct PatternSpec {
    double window = 0.3;        // half-width of the square window about the mirror direction
    int rows = 0, cols = 0;     // the image
    std::vector<double> image;  // grey values (relative intensity), row-major
};
std::unique_ptr<Target> make_pattern(const PatternSpec& spec);

// The colour targets' pieces (colour, iridescent): the weights that turn a cone's reflectance
// per wavelength into CIE XYZ under the white light sampled at `lambdas_um` (3 × n, row c
// holding X, Y or Z), that XYZ, and the loss of one cone's XYZ against a target u′v′:
// (max(0, Δu′v′ − tolerance) / 0.01)² + 4 · (max(0, 0.1 − Y) / 0.1)², with ∂loss/∂XYZ when
// `d_xyz` is given. A tolerance lets the design trade chromaticity within it for luminous
// efficiency, which the second term alone asks for.
std::vector<double> colour_xyz_weights(const std::vector<double>& lambdas_um);
// The luminous efficiency below which colour_loss counts Y (its 0.1 above).
constexpr double k_colour_loss_min_y = 0.10;
std::array<double, 3> cone_xyz(const std::vector<double>& xyz_weights, const Fractions& f, std::size_t group);
double colour_loss(const std::array<double, 3>& xyz, const std::array<double, 2>& target_uv,
                   std::array<double, 3>* d_xyz, double tolerance = 0.0);

struct ColourSpec {
    std::array<double, 2> view_offset{{0.0, 0.0}};  // view direction − mirror direction
    double view_cone = 0.05;
    std::array<double, 3> rgb{{1.0, 1.0, 1.0}};      // target, linear sRGB
    std::vector<double> lambdas_um;                  // the white light's samples
    double delta_uv_tolerance = 0.0;                 // Δu′v′ the loss does not count
};
std::unique_ptr<Target> make_colour(const ColourSpec& spec);

}  // namespace wavebrdf::detail
