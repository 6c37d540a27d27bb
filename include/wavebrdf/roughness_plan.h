#pragma once
// What a surface's stated roughness asks of the recovery (docs/recovery.md, "Rough surfaces"):
// from the peak-to-valley height range and the correlation length a caller states (not from
// the truth), the expected slopes, and for rough surfaces (steep slopes, or correlation close
// to the texel) a note, and for a correlation close to the texel the pipeline's longer
// schedule: more field-retrieval iterations (the field stage, started far from the heights,
// stops at the default 50 while still descending; steep slopes gain from it only with the long
// wavelengths below). The recovery's schedule applies the plan (recover.h, scheduled_settings,
// from RecoverSettings::surface); smooth surfaces (the common case, ±1 µm at correlation 4
// texels) get its smooth schedule.
//
// Slopes of a Gaussian-correlated surface (generate.h: autocorrelation σ_h² e^{−r²/ℓ²}):
// E[(∂H/∂x)²] = −C''(0) = 2σ_h²/ℓ², so |∇H| has rms 2σ_h/ℓ; the peak-to-valley range of a
// tile of ~10³ texels is ≈ 6σ_h, so rms |∇H| ≈ range / (3ℓ). A facet of slope s reflects
// normal light towards |ω_o| ≈ 2s: beyond the slice's rim (|ω_o| > 1) from s > 0.5, i.e. for
// the 3σ tail from an rms slope of ≈ 0.17 (a wavelength, a σ_p or a slice size cannot bring it
// back: the slice already spans the whole hemisphere; a light tilted along the slope can:
// oblique_omega_i below).
//
// Long wavelengths for steep or fine surfaces (docs/recovery.md, "Rough surfaces"): the blurred
// fit ends ≈ 17 % of the range off (rms) on rough surfaces, more than λ/4 at every visible
// wavelength, so every visible field settles in a wrong basin. The plan then asks the acquisition
// for a ladder of long wavelengths (an infrared source), the longest 4× that expected error (so
// its phase error stays within a quarter turn), each next one at most 4× shorter, all longer
// than the visible ladder; the field stage runs at these only (their heights start the
// refinement, which fits every wavelength's slices: first the longest wavelength's slices,
// then each shorter long one's added, then every slice, RecoverSettings::refine_ladder_min_um). The model holds at any λ (the Gabor
// kernels' tangent planes are better approximations the longer λ is; the slices' Nyquist size
// 4D/λ falls with λ, so the visible wavelengths' slice size covers them).
#include <array>
#include <string>
#include <vector>

namespace wavebrdf {

struct AcquisitionPlan;
class Heightfield;

struct RoughnessPlan {
    double rms_slope = 0.0;           // expected rms |∇H| (dimensionless)
    double rim_fraction = 0.0;        // expected fraction of texels whose light leaves the slice (|∇H| > 0.5)
    double correlation_texels = 0.0;  // stated correlation length, texels
    bool rough = false;               // the longer schedule below applies
    int field_iterations = 0;         // field retrieval iterations per wavelength (0: the default)
    double blur_error_um = 0.0;       // expected rms error of the blurred fit (µm; rough surfaces)
    // Rough surfaces: long wavelengths (µm, longest first) the acquisition adds and the field
    // stage runs at (empty: none; a smooth surface, or a range the visible ladder already covers).
    std::vector<double> long_lambdas_um;
    // Rough surfaces with long wavelengths: the refinement's wavelength ladder
    // (RecoverSettings::refine_ladder_min_um; 0: none): the shortest long wavelength, so the
    // refinement runs on the longest wavelength's slices, then adds each shorter long one, then
    // every slice at once: from the unwrapped fields the refinement on every slice at once
    // stalls (experiments/2026-11-23-rough-surfaces.md).
    double refine_ladder_min_um = 0.0;
    // Steep surfaces: further light directions (projected ω_i, a ring around normal incidence)
    // under which the acquisition observes every position as well (empty: one light). A facet
    // of slope s sends light ω_i towards ω_o ≈ −ω_i − 2s, so a light tilted along a slope
    // brings its reflection back onto the slice: with the ring, slopes up to 0.85 along the
    // lights' azimuths (0.63 in any direction; normal light alone: 0.45) reflect inside the rim
    // 0.9 of some slice (experiments/2026-11-23-rough-surfaces.md).
    std::vector<std::array<double, 2>> oblique_omega_i;
    std::vector<std::string> notes;  // the choice, one line each
};

// The expected rms slope |∇H| ≈ range / (3ℓ) of a Gaussian-correlated surface (see above).
// Throws std::domain_error for a range < 0 or a correlation length ≤ 0 (µm, finite).
double expected_rms_slope(double height_range_um, double correlation_um);

// The plan for a surface of peak-to-valley `height_range_um` (µm, ≥ 0) and correlation length
// `correlation_um` (µm, > 0) on texels of `texel_um` (µm, > 0): rough when the expected rms
// slope exceeds 0.2 (light of the tail beyond the rim) or the correlation is shorter than
// 2.5 texels (roughness_plan.cpp: between the measured limits of docs/recovery.md, "Where it
// fails"). Throws std::domain_error naming a bad value.
RoughnessPlan plan_for_roughness(double height_range_um, double correlation_um, double texel_um);

// A known surface's measured roughness (a measured or given truth), for the plan instead of the
// stated range and correlation: what the surface has, not what a Gaussian-correlated one of
// its range would have.
struct MeasuredRoughness {
    double range_um = 0.0;        // peak to valley, µm
    double rms_slope = 0.0;       // rms |∇H|, central differences across the periodic tile (the model's slopes)
    double rim_fraction = 0.0;    // fraction of texels with |∇H| > 0.5 (their light leaves the slice)
    double correlation_um = 0.0;  // Sal (ISO 25178-2): the shortest lag at which the ACF falls to 0.2, µm
    double aspect = 1.0;          // Str: shortest over longest such lag (an upper bound when a lay is longer than half the tile)
    double lay_deg = 0.0;         // Std: the lay's direction from x towards y, degrees
};

// The measured roughness of `heightfield` (surface_stats.h's Sal, Str, Std; the slopes and range
// directly). Throws as surface_parameters does.
MeasuredRoughness measure_roughness(const Heightfield& heightfield);

// The plan for a surface of measured roughness `m` on texels of `texel_um`: as
// plan_for_roughness, with the measured rms slope and rim fraction for the expected ones and
// Sal (the fastest decay, across a lay) for the correlation length; Sal is taken as at least
// one texel (a surface whose ACF falls within a texel is as fine as the grid). A surface with a
// lay (Str < 0.5) whose blurred fit is expected off by more than a quarter of the longest visible
// wavelength (0.17 × range > 0.7 µm / 4) is rough as well: striated surfaces of a few µm end
// the blurred fit as far off as rough ones. Its first note says what was measured; a strongly
// anisotropic surface (Str < 0.3) is named there.
RoughnessPlan plan_for_measured_roughness(const MeasuredRoughness& m, double texel_um);

// `acquisition` with the plan's long wavelengths appended to its wavelengths (those not longer
// than every planned one left out) and a note saying the source they need. Returns how many
// were added (0 for a smooth surface: the acquisition is unchanged).
int add_long_wavelengths(const RoughnessPlan& plan, AcquisitionPlan& acquisition);

// `acquisition` with the plan's oblique lights (AcquisitionPlan::oblique_omega_i) and a note
// saying what they cost. Returns how many were added (0 for a surface that is not steep, and for
// GHS-type models, whose field stage takes one light direction: a note says so).
int add_oblique_lights(const RoughnessPlan& plan, AcquisitionPlan& acquisition);

}  // namespace wavebrdf
