#pragma once
// Self-calibration of the acquisition (docs/recovery.md, "Self-calibration"): what a real
// instrument does not record exactly, which recover_heights may refine together with the
// heights, as ptychography refines its probe positions; and the acquisition errors a study
// simulates to measure it.
//
//  - positions: each footprint centre (x, y) is off by an unknown offset (a stage that does
//    not go exactly where it was told);
//  - exposure: each slice carries an unknown scale (laser power, integration time, gain);
//  - sigma: every footprint's σ_p is off by one common unknown factor (the beam waist).
//
// The recovery is given the nominal (stated) acquisition and refines these with the heights;
// what it found is returned in a Calibration.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace wavebrdf {

// Which parts of the acquisition recover_heights refines with the heights (all off: the
// acquisition is taken as exact).
struct CalibrationSettings {
    bool positions = false;  // per observation: the footprint centre offset (x, y), µm
    bool exposure = false;   // per observation: a scale of the slice (closed form per slice)
    bool sigma = false;      // one factor on every observation's σ_p
    bool any() const { return positions || exposure || sigma; }
};

// Parses a comma-separated list of "positions", "exposure" and "sigma", or "all" or "none"
// (e.g. "positions,exposure"). Throws std::invalid_argument "NAME 'WORD' is unknown; expected
// positions, exposure, sigma, all or none" (`name` is the option, e.g. "--calibrate").
CalibrationSettings parse_calibration(const std::string& text, const std::string& name = "calibrate");
// "positions,exposure,sigma" (those set, in that order) or "none".
std::string to_string(const CalibrationSettings& settings);

// The acquisition as recover_heights refined it. Per-observation entries are in the order of
// the observations given (under MPI: this rank's share); empty when that part was not refined.
struct Calibration {
    std::vector<std::array<double, 2>> position_offsets_um;  // true centre − stated centre, µm
    std::vector<double> exposures;                           // reference ≈ exposure · model
    double sigma_p_scale = 1.0;                              // true σ_p = scale · stated σ_p
    double sigma_p_scale_fields = 1.0;  // the scale the field stage used (found at the blurred fit's heights)
};

// Errors of the acquisition a study simulates: the observations are rendered for the true
// (perturbed) acquisition and given to the recovery with the nominal one.
struct AcquisitionErrors {
    // Each footprint position (all its wavelengths alike) is off by a Gaussian offset with this
    // rms per coordinate, in texels.
    double position_rms_texels = 0.0;
    // Each observation's slice is scaled by a factor drawn log-uniformly in [min, max] (> 0).
    double exposure_min = 1.0, exposure_max = 1.0;
    // Every true σ_p is this factor times the stated one (> 0).
    double sigma_p_factor = 1.0;
    std::uint64_t seed = 1;  // the draws above
    bool any() const {
        return position_rms_texels != 0.0 || exposure_min != 1.0 || exposure_max != 1.0 || sigma_p_factor != 1.0;
    }
};

// Checks the bounds of simulated acquisition errors: position_rms_texels finite in [0, 10],
// exposure_min ≤ exposure_max, both finite in [1e-3, 1e3], sigma_p_factor finite in
// [0.25, 4]. Throws std::invalid_argument "NAME VALUE is invalid; expected …" naming the
// option (`prefix` + the field's name, e.g. "--simulate-" gives "--simulate-exposure").
void check_acquisition_errors(const AcquisitionErrors& errors, const std::string& prefix = "");

// The simulated errors of observation `observation` (its index among all the run's
// observations) at footprint position `position` (its position's index; every wavelength of
// a position shares its offset): the true centre − the stated one (µm, Gaussian of
// position_rms_texels · texel_um per coordinate) and the exposure (log-uniform in
// [exposure_min, exposure_max]). Each is seeded from errors.seed and its own index only, so
// the draws do not depend on how the observations are split over ranks.
std::array<double, 2> simulated_position_offset_um(const AcquisitionErrors& errors, std::size_t position,
                                                   double texel_um);
double simulated_exposure(const AcquisitionErrors& errors, std::size_t observation);

}  // namespace wavebrdf
