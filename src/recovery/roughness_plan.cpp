#include "wavebrdf/roughness_plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "core/text.h"
#include "wavebrdf/recover.h"

namespace wavebrdf {

namespace {

using detail::format_shortest;

// Rough from here (docs/recovery.md, "Rough surfaces"): ±2 µm at correlation 4 texels (rms
// slope 0.17 by the rule below, measured 0.018 %) and correlation 3 texels (0.009 %) still
// recover with the defaults; ±4 µm (0.33) and correlation 2 texels did not.
constexpr double kRoughSlope = 0.2;
constexpr double kRoughCorrelationTexels = 2.5;
// The longer schedule (measured there: a second cascade pass, more blurred-fit iterations or
// stages and more refinement iterations did not help).
constexpr int kRoughFieldIterations = 200;

std::string fixed(double v, int digits) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

void require(bool ok, const char* name, double value, const char* expected) {
    if (!ok)
        throw std::domain_error(std::string(name) + " = " + format_shortest(value) + " is out of range; expected " +
                                expected);
}

}  // namespace

double expected_rms_slope(double height_range_um, double correlation_um) {
    require(std::isfinite(height_range_um) && height_range_um >= 0.0, "height range (um)", height_range_um,
            "a finite value >= 0");
    require(std::isfinite(correlation_um) && correlation_um > 0.0, "correlation length (um)", correlation_um,
            "a finite value > 0");
    return height_range_um / (3.0 * correlation_um);
}

RoughnessPlan plan_for_roughness(double height_range_um, double correlation_um, double texel_um) {
    require(std::isfinite(texel_um) && texel_um > 0.0, "texel_um", texel_um, "a finite value > 0");
    RoughnessPlan plan;
    plan.rms_slope = expected_rms_slope(height_range_um, correlation_um);
    plan.correlation_texels = correlation_um / texel_um;
    // |∇H| of an isotropic Gaussian field is Rayleigh distributed with E|∇H|² = s²:
    // P(|∇H| > 0.5) = exp(−0.25 / s²).
    plan.rim_fraction = plan.rms_slope > 0.0 ? std::exp(-0.25 / (plan.rms_slope * plan.rms_slope)) : 0.0;
    const bool steep = plan.rms_slope > kRoughSlope;
    const bool fine = plan.correlation_texels < kRoughCorrelationTexels;
    plan.rough = steep || fine;
    if (plan.rough) {
        // Only a short correlation gains from the longer field stage (≈ 30 %); steep slopes do
        // not (±4 µm: 4.98 % before, 5.49 % after on seed 6301, at 2–3× the field stage's cost).
        plan.field_iterations = fine ? kRoughFieldIterations : 0;
        plan.notes.push_back(
            std::string("rough surface (") +
            (steep ? "expected rms slope " + fixed(plan.rms_slope, 2) + " > " + fixed(kRoughSlope, 2) + ", " +
                         fixed(100.0 * plan.rim_fraction, 1) + " % of texels reflect beyond the slice's rim"
                   : "") +
            (steep && fine ? "; " : "") +
            (fine
                 ? "correlation " + fixed(plan.correlation_texels, 2) + " texels < " + fixed(kRoughCorrelationTexels, 1)
                 : "") +
            (fine ? "): field retrieval up to " + std::to_string(plan.field_iterations) + " iterations per wavelength"
                  : "): the default schedule; expect errors of several % (docs/recovery.md, Rough surfaces)"));
    }
    return plan;
}

void apply_roughness_plan(const RoughnessPlan& plan, RecoverSettings& settings) {
    if (!plan.rough) return;
    settings.field.iterations = std::max(settings.field.iterations, plan.field_iterations);
}

}  // namespace wavebrdf
