#pragma once
// Analytic microfacet BRDF lobes (GGX and Beckmann, isotropic or anisotropic) tabulated in the
// BRDF table format of table.h, so that a lobe is a target wherever a `wavebrdf table` file is
// (docs/table.md, "Analytic lobes").
//
// Directions are projected on the surface plane as everywhere (docs/conventions.md): ω = (x,
// y), z = sqrt(1 − x² − y²); ω_i points to the light, ω_o to the viewer, and the mirror
// direction of ω_i is −ω_i. The lobe is the Cook–Torrance microfacet BRDF
//   f_r(ω_i, ω_o) = F(ω_i·h) D(h) G2(ω_i, ω_o) / (4 cos θ_i cos θ_o),   h = (ω_i + ω_o)/|ω_i + ω_o|,
// with the anisotropic GGX or Beckmann distribution of slopes (α_x along x = rows, α_y along y
// = columns; Walter et al. 2007, "Microfacet models for refraction", eqs. 33 and 25, stretched
// as in Heitz 2014, "Understanding the masking-shadowing function", eqs. 80 and 87), the
// height-correlated Smith masking-shadowing G2 = 1 / (1 + Λ(ω_i) + Λ(ω_o)) (Heitz 2014, eq. 99),
// which keeps f_r reciprocal, and Schlick's Fresnel F = F0 + (1 − F0)(1 − ω_i·h)^5, off (F =
// 1, a perfect reflector as the wave-optical models are) when F0 = 1.
#include <string>

#include "wavebrdf/table.h"

namespace wavebrdf {

enum class LobeDistribution { ggx, beckmann };

// "ggx" / "beckmann" (lower case; also accepts "GGX", "Beckmann"); std::invalid_argument
// naming the text otherwise.
LobeDistribution parse_lobe_distribution(const std::string& text);
const char* to_string(LobeDistribution distribution);

// One lobe.
struct Lobe {
    LobeDistribution distribution = LobeDistribution::ggx;
    double alpha_x = 0.2;     // roughness along x (rows): 1e-3 … 4 (RMS slope / √2 for Beckmann)
    double alpha_y = 0.2;     // along y (columns), same range; equal to alpha_x: isotropic
    double fresnel_f0 = 1.0;  // Schlick's F0, 0 … 1; 1: no Fresnel (F = 1)
};

// Throws std::invalid_argument naming the value unless the lobe's numbers are in range.
void validate(const Lobe& lobe);

// The microfacet distribution D(h) in 1/sr for a unit half vector with projected components
// (hx, hy) and hz = cos θ_h > 0; ∫ D(h) cos θ_h dω_h = 1 over the hemisphere. 0 for hz ≤ 0.
double lobe_distribution(const Lobe& lobe, double hx, double hy, double hz);

// Smith's Λ of a direction with projected components (x, y) and z = cos θ > 0 (Heitz 2014,
// eqs. 86 and 88 with the stretched roughness α(φ) = sqrt(x² α_x² + y² α_y²) / sin θ).
double lobe_lambda(const Lobe& lobe, double x, double y, double z);

// f_r(ω_i, ω_o) in 1/sr for projected directions (|ω| < 1): 0 when |ω| ≥ 1 for either.
double lobe_brdf(const Lobe& lobe, double omega_i_x, double omega_i_y, double omega_o_x, double omega_o_y);

// What lobe_table makes: the lobe, the light grid and the slice resolution as table.h's, and
// the one wavelength recorded in the file (the lobe itself does not depend on it).
struct LobeTableSpec {
    Lobe lobe;
    LightGrid lights;
    int resolution = 64;     // n: each slice n × n, 1 … 8192, rows · n and cols · n ≤ 16384
    double lambda_um = 0.5;  // recorded as wavebrdf:lambdas_um
};

// The lobe as a BRDF table (table.h) of point samples: entry (a, b, p, q) = f_r(light (a, b),
// ω_o of pixel (p, q)) in R = G = B, zero outside the unit disk and for lights outside
// max_sin, as render_brdf_table lays a rendered table out. The fields a table of a surface
// records but a lobe has not are set as follows: model Kirchhoff, footprint (0, 0) with
// σ_p 1 µm, a 1 × 1 heightfield of texel 1 µm and vscale 1, precision double; `source`
// says the table is an analytic lobe and names its parameters. A lobe narrower than the pixel
// spacing 2/n is undersampled (its peak falls between pixels): choose n ≳ 10/α.
// Throws std::invalid_argument naming the value for an invalid lobe or grid; OutOfMemory
// (memory.h), before allocating, when the table (its values and the mosaic written from them)
// would exceed max_memory_gb (0: the physical memory). The lights are spread over the threads.
BrdfTable lobe_table(const LobeTableSpec& spec, double max_memory_gb = 0.0);

// The bytes lobe_table and writing its table need: the values and the mosaic, 4 bytes each.
double estimate_lobe_table_bytes(const LobeTableSpec& spec);

// The text lobe_table puts in BrdfTable::source, e.g. "analytic lobe: ggx alpha_x 0.2 alpha_y
// 0.1 fresnel_f0 1".
std::string lobe_description(const Lobe& lobe);

}  // namespace wavebrdf
