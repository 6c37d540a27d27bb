#pragma once
// Acquisition planning for heightfield recovery (recover.h): where to put the footprints, how
// finely to sample each slice, and which wavelengths to measure, so that the slices determine
// the heights; and the check of given observations against the same rules.
//
// The rules (ptychography; ours to measure in docs/recovery.md):
//  - A footprint window has support D = 6σ_p (the model's 3σ_p cut). Neighbouring windows
//    overlap linearly by 1 − d/D at centre distance d; recovery needs ≥ 60 %. Positions are a
//    raster over the periodic tile, each jittered by up to ±jitter · step (a perfect raster
//    has ambiguities of its own), with the step chosen so the worst case still overlaps.
//  - A slice samples u = (ω_i + ω_o)/λ every Δu = 2/(nλ). The intensity of a window of support
//    D is band-limited to |Δx| ≤ D, so Nyquist asks Δu ≤ 1/(2D): n ≥ 4D/λ. Recovery works
//    down to 4× coarser (measured: 4.5× works, 6× fails), so the planner takes n ≥ D/λ at the
//    shortest wavelength, at least 48 (the size the accuracy tables were measured at, also
//    where Nyquist asks less).
//  - One wavelength determines the heights modulo λ/2. A pair (λ0, λj) has the synthetic
//    wavelength Λ = λ0λj/|λ0 − λj| and determines them modulo Λ/2. The planner builds a ladder
//    of synthetic wavelengths from one that spans the height range with a margin down to λ0,
//    each step at most `max_step_ratio` finer than the previous (each level's height estimate
//    must be good to a fraction of the next level's ambiguity).
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/model.h"
#include "wavebrdf/noise.h"

namespace wavebrdf {

class Heightfield;
class Progress;
struct Observation;

// The planned footprint's σ_p per µm (rms per coordinate) of position uncertainty. The position
// loop (recover.h) registers a footprint against heights that are themselves recovered at wrong
// positions; it converges when the positions are off by up to ~σ_p (rms per coordinate) and
// stalls at 2σ_p: positions 3 texels (6 µm) off stall at 12–13 % with σ_p = 3 µm and at ~7 % with
// 4.5 µm, and reach 0.01 % with 6 µm (experiments/2026-11-23-position-calibration.md).
constexpr double k_footprint_per_position_uncertainty = 1.0;

struct PlanRequest {
    int rows = 32, cols = 32;      // heightfield size (texels)
    double texel_um = 1.0;         // texel width w, µm
    double height_range_um = 0.0;  // expected peak-to-valley of the heights, µm (≥ 0)
    double sigma_p_um = 0.0;       // footprint σ_p, µm; 0: planned (below)
    // How far the stage may put a footprint from where it says, µm rms per coordinate (≥ 0).
    // With σ_p planned: σ_p = max(1.5 texels, k_footprint_per_position_uncertainty × this).
    double position_uncertainty_um = 0.0;
    double overlap = 0.6;          // worst-case linear overlap of neighbouring windows, 0.6 … 0.95
    double jitter = 0.2;           // position jitter, fraction of the raster step, 0 … 0.3
    double lambda_um = 0.5;        // base wavelength λ0, µm
    double lambda_min_um = 0.45;   // wavelengths available to the ladder, µm
    double lambda_max_um = 0.70;
    double max_step_ratio = 4.0;                // ladder: Λ_j / Λ_{j+1} ≤ this (≥ 1.5)
    std::vector<double> lambdas_um;             // given wavelengths (µm) instead of the ladder; empty: plan them
    int resolution = 0;                         // given slice size; 0: plan it (above)
    std::array<double, 2> omega_i{{0.0, 0.0}};  // projected light direction ω_i of every observation
    Model model = Model::OHS;
    std::uint64_t seed = 1;  // jitter
};

struct AcquisitionPlan {
    double sigma_p_um = 0.0;
    int resolution = 0;                               // slice pixels per side
    std::vector<double> lambdas_um;                   // λ0 first, then the ladder's partners
    std::vector<double> synthetic_um;                 // the ladder Λ_1 > Λ_2 > … (λ0 excluded)
    std::vector<std::array<double, 2>> positions_um;  // footprint centres (x, y)
    double step_x_um = 0.0, step_y_um = 0.0;          // raster steps
    double overlap = 0.0;                             // worst-case linear overlap of neighbours
    std::array<double, 2> omega_i{{0.0, 0.0}};        // projected light direction ω_i
    // Further light directions (projected ω_i): every position is observed under omega_i and
    // under each of these, at every wavelength (steep surfaces: add_oblique_lights in
    // roughness_plan.h). Empty: one light.
    std::vector<std::array<double, 2>> oblique_omega_i;
    Model model = Model::OHS;
    std::vector<std::string> notes;  // choices the caller should know about
    // White light: non-empty, one RGB observation per position, of a broadband source sampled
    // at these wavelengths (µm; spectral_mix_weights), instead of one per wavelength of
    // lambdas_um (which then only sized the slices).
    std::vector<double> white_lambdas_um;
};

// Throws std::invalid_argument / std::domain_error naming the field for sizes < 1, texel_um,
// σ_p, the position uncertainty, λ or ranges out of range, overlap outside 0.6 … 0.95, jitter
// outside 0 … 0.3, a base wavelength outside [lambda_min_um, lambda_max_um], or a height range
// the wavelength range cannot unwrap (names the largest range it can).
AcquisitionPlan plan_acquisition(const PlanRequest& request);

// One observation per (position, light, wavelength) of `plan`, in that order (position slowest),
// with empty references (render them with render_observation, or fill them with measurements).
std::vector<Observation> planned_observations(const AcquisitionPlan& plan);

// How many observations planned_observations(plan) makes per position (lights × wavelengths).
std::size_t observations_per_position(const AcquisitionPlan& plan);

// The planned observations of `truth`, rendered, with `noise` added (seeded per observation,
// noise.h), one observation per thread: the same bits for any thread count. `progress`, when
// given, advances by one per observation.
std::vector<Observation> simulate_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                               const Noise& noise, std::uint64_t seed, Progress* progress = nullptr);

// Only the planned observations `indices` (indices into planned_observations(plan), in any
// order, e.g. a rank's observation_share), with the same references and noise they have in the
// full set. Throws std::invalid_argument for an index out of range.
std::vector<Observation> simulate_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                               const Noise& noise, std::uint64_t seed,
                                               const std::vector<std::size_t>& indices, Progress* progress = nullptr);

// The synthetic-wavelength ladder for heights spanning `height_range_um` (see above): the
// partner wavelengths of λ0, coarsest first. Empty when λ0 alone suffices (range < λ0/4).
// Throws std::domain_error when the range needs a finer λ step than [λ_min, λ_max] offers.
std::vector<double> plan_wavelengths(double height_range_um, double lambda0_um, double lambda_min_um,
                                     double lambda_max_um, double max_step_ratio,
                                     std::vector<double>* synthetic_um = nullptr);

// Warnings (one line each) for observations that are too coarse or too sparse to determine the
// heights of a rows × cols tile of texel `texel_um`, at the limits measured in
// docs/recovery.md: neighbouring windows overlapping < 60 % (41 % failed), texels farther than
// 2σ_p from every footprint centre, slices sampling u more than 4× as coarsely as the rule
// above (6× failed), fewer measured values than heights, and (with `truth`) slopes that
// reflect light off the slice. Empty when all is well. (No warning about wrapping: the
// recovery unwraps spatially on its fine grid, and one wavelength recovered ±1 µm.)
std::vector<std::string> check_acquisition(const std::vector<Observation>& observations, int rows, int cols,
                                           double texel_um, const Heightfield* truth = nullptr);

}  // namespace wavebrdf
