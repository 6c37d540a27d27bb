#include "wavebrdf/roughness_plan.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "core/text.h"
#include "wavebrdf/acquisition.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/surface_stats.h"
#include "wavebrdf/model.h"

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
// The blurred fit's rms error on rough surfaces, a fraction of the peak-to-valley range
// (measured 12–17 % on ±4 µm and correlation 2 texels, seeds 6301–6303 and 7301–7303).
constexpr double kBlurErrorFraction = 0.17;
// A field converges from a start within a quarter wavelength (phase error < π): the longest
// wavelength is this many times the expected start error, each next one this many times shorter.
constexpr double kLongLambdaFactor = 4.0;
// Steep surfaces: oblique lights at these azimuths (unit vectors: 0°, 90°, 180°, 270°) and this
// sin θ_i, a ring around normal incidence. Measured on ±4 µm (seeds 11922/11923, whose
// slopes reach 1.07/1.10): 2.22 / 1.52 % with one light, 0.0001 / 0.0000 % with 4 at 0.8; 3 at
// 0.8 gave 0.0027 % on 11922, 4 at 0.6 0.0053 %.
constexpr std::array<std::array<double, 2>, 4> kObliqueLightAzimuths{
    {{{1.0, 0.0}}, {{0.0, 1.0}}, {{-1.0, 0.0}}, {{0.0, -1.0}}}};
constexpr double kObliqueLightSin = 0.8;
// Long wavelengths only above the planner's visible range (PlanRequest::lambda_max_um).
constexpr double kVisibleMaxUm = 0.7;
// A measured surface's texture aspect ratio Str below which it has a lay (plan_for_measured_roughness).
constexpr double kLayeredAspect = 0.5;
// At most this many long wavelengths (a range of 8 µm needs 2).
constexpr int kMaxLongLambdas = 4;
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

namespace {

// The plan from its slopes: rms |∇H|, the fraction beyond the rim and the correlation in texels.
// `layered`: a measured surface with a lay, tall for the visible wavelengths (see
// plan_for_measured_roughness): rough although its slopes and correlation are not.
RoughnessPlan plan_from_slopes(double height_range_um, double rms_slope, double rim_fraction,
                               double correlation_texels, bool layered = false) {
    RoughnessPlan plan;
    plan.rms_slope = rms_slope;
    plan.correlation_texels = correlation_texels;
    plan.rim_fraction = rim_fraction;
    const bool steep = plan.rms_slope > kRoughSlope;
    const bool fine = plan.correlation_texels < kRoughCorrelationTexels;
    plan.rough = steep || fine || layered;
    if (plan.rough) {
        plan.blur_error_um = kBlurErrorFraction * height_range_um;
        // Rounded up to 0.1 µm (a source's nominal wavelength), coarsest first.
        for (double l = kLongLambdaFactor * plan.blur_error_um;
             l > kVisibleMaxUm && int(plan.long_lambdas_um.size()) < kMaxLongLambdas; l /= kLongLambdaFactor)
            plan.long_lambdas_um.push_back(std::ceil(10.0 * l - 1e-9) / 10.0);
        // Without long wavelengths only a short correlation gains from the longer field stage
        // (≈ 30 %); steep slopes do not (±4 µm: 4.98 % before, 5.49 % after on seed 6301).
        // With long wavelengths the longer schedule pays for steep slopes as well (±4 µm, seed 7301:
        // the 5.5 µm field 5.0 % after 50 iterations, 1.8 % after 150; final 2.6 → 1.5 %).
        plan.field_iterations = fine || !plan.long_lambdas_um.empty() ? kRoughFieldIterations : 0;
        // The refinement as a ladder over the long wavelengths, longest first, then every slice:
        // from the unwrapped fields (≈ 1–2 % of the range off, more than λ/4 at the visible
        // wavelengths) the refinement on every slice at once stalled at 1.1–1.5 % (±4 µm, seeds
        // 10302–10303); on the 5.5 µm slices alone it reaches 0.09–0.16 %, within a quarter wave of
        // every visible wavelength, which then join at once (experiments/2026-11-23-rough-surfaces.md).
        if (!plan.long_lambdas_um.empty())
            plan.refine_ladder_min_um = *std::min_element(plan.long_lambdas_um.begin(), plan.long_lambdas_um.end());
        if (steep)
            for (const auto& a : kObliqueLightAzimuths)
                plan.oblique_omega_i.push_back({{kObliqueLightSin * a[0], kObliqueLightSin * a[1]}});
        plan.notes.push_back(
            std::string("rough surface (") +
            (steep ? "expected rms slope " + format_fixed(plan.rms_slope, 2) + " > " + format_fixed(kRoughSlope, 2) + ", " +
                         format_fixed(100.0 * plan.rim_fraction, 1) + " % of texels reflect beyond the slice's rim"
                   : "") +
            (steep && fine ? "; " : "") +
            (fine
                 ? "correlation " + format_fixed(plan.correlation_texels, 2) + " texels < " + format_fixed(kRoughCorrelationTexels, 1)
                 : "") +
            (layered && !steep && !fine ? "a lay, and a range whose blurred fit is expected beyond a quarter wave "
                                          "at the visible wavelengths"
                                        : "") +
            (plan.field_iterations > 0
                 ? "): field retrieval up to " + std::to_string(plan.field_iterations) + " iterations per wavelength"
                 : "): the default field iterations") +
            (plan.long_lambdas_um.empty()
                 ? std::string()
                 : "; blurred fit expected " + format_fixed(plan.blur_error_um, 2) +
                       " um rms off: the field stage at long wavelengths only, the refinement from the longest "
                       "wavelength's slices down to every slice (docs/recovery.md, Rough surfaces)"));
    }
    return plan;
}

}  // namespace

RoughnessPlan plan_for_roughness(double height_range_um, double correlation_um, double texel_um) {
    require(std::isfinite(texel_um) && texel_um > 0.0, "texel_um", texel_um, "a finite value > 0");
    const double rms_slope = expected_rms_slope(height_range_um, correlation_um);
    // |∇H| of an isotropic Gaussian field is Rayleigh distributed with E|∇H|² = s²:
    // P(|∇H| > 0.5) = exp(−0.25 / s²).
    const double rim = rms_slope > 0.0 ? std::exp(-0.25 / (rms_slope * rms_slope)) : 0.0;
    return plan_from_slopes(height_range_um, rms_slope, rim, correlation_um / texel_um);
}

MeasuredRoughness measure_roughness(const Heightfield& hf) {
    MeasuredRoughness m;
    const SurfaceParameters p = surface_parameters(hf);
    m.range_um = p.Sz;
    m.correlation_um = p.Sal;
    m.aspect = p.Str;
    m.lay_deg = p.Std;
    // Central differences across the periodic tile, as the model sees the slopes (model.md §2).
    const int rows = hf.rows(), cols = hf.cols();
    const double w = 2.0 * hf.texel_um();
    double sum = 0.0;
    long long beyond = 0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const double gx = (hf.height_um((i + 1) % rows, j) - hf.height_um((i + rows - 1) % rows, j)) / w;
            const double gy = (hf.height_um(i, (j + 1) % cols) - hf.height_um(i, (j + cols - 1) % cols)) / w;
            const double g2 = gx * gx + gy * gy;
            sum += g2;
            if (g2 > 0.25) ++beyond;
        }
    const double n = double(rows) * double(cols);
    m.rms_slope = std::sqrt(sum / n);
    m.rim_fraction = double(beyond) / n;
    return m;
}

RoughnessPlan plan_for_measured_roughness(const MeasuredRoughness& m, double texel_um) {
    require(std::isfinite(texel_um) && texel_um > 0.0, "texel_um", texel_um, "a finite value > 0");
    require(std::isfinite(m.range_um) && m.range_um >= 0.0, "height range (um)", m.range_um, "a finite value >= 0");
    require(std::isfinite(m.rms_slope) && m.rms_slope >= 0.0, "rms slope", m.rms_slope, "a finite value >= 0");
    require(std::isfinite(m.correlation_um) && m.correlation_um >= 0.0, "correlation length (um)", m.correlation_um,
            "a finite value >= 0");
    const double correlation_texels = std::max(m.correlation_um / texel_um, 1.0);
    // A lay (Str below kLayeredAspect) on a surface whose blurred fit is expected off by more
    // than a quarter of the longest visible wavelength: the bullet land's 64² patch (Str 0.33,
    // 5.2 um peak to valley, rms slope 0.08, Sal 11 texels; smooth by slope and correlation)
    // ended its blurred fit 16–18 % of the range off, as rough surfaces do, and 3.2 % after the
    // smooth schedule; with the long wavelengths 0.033 % (docs/surfaces.md, Recovery).
    const bool layered =
        m.aspect < kLayeredAspect && kBlurErrorFraction * m.range_um > 0.25 * kVisibleMaxUm;
    RoughnessPlan plan = plan_from_slopes(m.range_um, m.rms_slope, m.rim_fraction, correlation_texels, layered);
    plan.notes.insert(plan.notes.begin(),
                      "planned for the truth's measured roughness: peak to valley " + format_fixed(m.range_um, 3) +
                          " um, rms slope " + format_fixed(m.rms_slope, 3) + " (" + format_fixed(100.0 * m.rim_fraction, 1) +
                          " % of texels beyond slope 0.5), correlation length Sal " + format_fixed(m.correlation_um, 2) +
                          " um (" + format_fixed(m.correlation_um / texel_um, 2) + " texels), Str " + format_fixed(m.aspect, 2) +
                          (m.aspect < 0.3 ? " (strongly anisotropic, lay at " + format_fixed(m.lay_deg, 0) + " deg)" : ""));
    return plan;
}

int add_long_wavelengths(const RoughnessPlan& plan, AcquisitionPlan& acquisition) {
    if (!plan.rough || plan.long_lambdas_um.empty()) return 0;
    const double longest = acquisition.lambdas_um.empty()
                               ? 0.0
                               : *std::max_element(acquisition.lambdas_um.begin(), acquisition.lambdas_um.end());
    std::string added;
    int count = 0;
    for (double l : plan.long_lambdas_um)
        if (l > longest) {
            acquisition.lambdas_um.push_back(l);
            added += (added.empty() ? "" : ", ") + format_fixed(l, 1);
            ++count;
        }
    if (count > 0)
        acquisition.notes.push_back(
            "rough surface: long wavelengths " + added + " um added (an infrared source is required): the longest is " +
            format_fixed(kLongLambdaFactor, 0) + "x the blurred fit's expected error (" + format_fixed(plan.blur_error_um, 2) +
            " um rms), so its field starts within a quarter wave; the field stage runs at "
            "these, every wavelength in the refinement");
    return count;
}

int add_oblique_lights(const RoughnessPlan& plan, AcquisitionPlan& acquisition) {
    if (plan.oblique_omega_i.empty()) return 0;
    if (!is_separable(acquisition.model)) {
        // The field stage takes GHS-type slices through the OHS proxy at one height scale cos θ_i
        // (field_proxy.h): every GHS slice must share one light direction.
        acquisition.notes.push_back(std::string("steep surface: no oblique lights for ") +
                                    to_string(acquisition.model) +
                                    " (its field stage takes one light direction): light beyond the slice's rim "
                                    "is not measured");
        return 0;
    }
    acquisition.oblique_omega_i.insert(acquisition.oblique_omega_i.end(), plan.oblique_omega_i.begin(),
                                       plan.oblique_omega_i.end());
    const int count = int(plan.oblique_omega_i.size());
    acquisition.notes.push_back(
        "steep surface: " + std::to_string(count) + " oblique lights at sin(theta_i) = " + format_fixed(kObliqueLightSin, 2) +
        " added (azimuths every " + format_fixed(360.0 / count, 0) +
        " deg): facets up to slope 0.63 in any direction (0.85 along the lights) reflect into a slice; "
        "every position is observed under each light, " +
        std::to_string(count + 1) + "x the slices");
    return count;
}

}  // namespace wavebrdf
