#pragma once
// What a surface's stated roughness asks of the recovery (docs/recovery.md, "Rough surfaces"):
// from the peak-to-valley height range and the correlation length a caller states (not from
// the truth), the expected slopes, and for rough surfaces (steep slopes, or correlation close
// to the texel) a note, and for a correlation close to the texel the pipeline's longer
// schedule: more field-retrieval iterations (the field stage, started far from the heights,
// stops at the default 50 while still descending; steep slopes gained nothing from it). Smooth surfaces (the common case, ±1 µm at correlation 4 texels) keep the
// library's defaults, so they cost what they did.
//
// Slopes of a Gaussian-correlated surface (generate.h: autocorrelation σ_h² e^{−r²/ℓ²}):
// E[(∂H/∂x)²] = −C''(0) = 2σ_h²/ℓ², so |∇H| has rms 2σ_h/ℓ; the peak-to-valley range of a
// tile of ~10³ texels is ≈ 6σ_h, so rms |∇H| ≈ range / (3ℓ). A facet of slope s reflects
// normal light towards |ω_o| ≈ 2s: beyond the slice's rim (|ω_o| > 1) from s > 0.5, i.e. for
// the 3σ tail from an rms slope of ≈ 0.17 (a wavelength, a σ_p or a slice size cannot bring it
// back: the slice already spans the whole hemisphere).
#include <string>
#include <vector>

namespace wavebrdf {

struct RecoverSettings;

struct RoughnessPlan {
    double rms_slope = 0.0;           // expected rms |∇H| (dimensionless)
    double rim_fraction = 0.0;        // expected fraction of texels whose light leaves the slice (|∇H| > 0.5)
    double correlation_texels = 0.0;  // stated correlation length, texels
    bool rough = false;               // the longer schedule below applies
    int field_iterations = 0;         // field retrieval iterations per wavelength (0: the default)
    std::vector<std::string> notes;   // the choice, one line each
};

// The expected rms slope |∇H| ≈ range / (3ℓ) of a Gaussian-correlated surface (see above).
// Throws std::domain_error for a range < 0 or a correlation length ≤ 0 (µm, finite).
double expected_rms_slope(double height_range_um, double correlation_um);

// The plan for a surface of peak-to-valley `height_range_um` (µm, ≥ 0) and correlation length
// `correlation_um` (µm, > 0) on texels of `texel_um` (µm, > 0): rough when the expected rms
// slope exceeds 0.15 (light of the 3σ tail beyond the rim) or the correlation is shorter than
// 3 texels (measured limits: docs/recovery.md). Throws std::domain_error naming a bad value.
RoughnessPlan plan_for_roughness(double height_range_um, double correlation_um, double texel_um);

// `settings` with the plan applied (field iterations raised to the plan's where it asks for
// more; nothing changed for a smooth surface).
void apply_roughness_plan(const RoughnessPlan& plan, RecoverSettings& settings);

}  // namespace wavebrdf
