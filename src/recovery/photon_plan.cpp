#include "wavebrdf/photon_plan.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/random.h"
#include "core/text.h"
#include "wavebrdf/conditioning.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/surface_file.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {

namespace {

using detail::format_shortest;

std::string fixed(const char* format, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

void check_settings(const PhotonPlanSettings& s) {
    if (!(std::isfinite(s.target) && s.target >= 0.0 && s.target <= 1.0))
        throw std::domain_error("target error " + format_shortest(s.target) +
                                " is out of range; expected 0 (off) to 1 (a fraction of the peak to valley)");
    if (s.max_exposures < 1 || s.max_exposures > 10000)
        throw std::domain_error("max exposures " + std::to_string(s.max_exposures) +
                                " is out of range; expected 1 to 10000");
    if (s.proxy_texels < 4 || s.proxy_texels > 64)
        throw std::domain_error("photon proxy tile " + std::to_string(s.proxy_texels) +
                                " texels is out of range; expected 4 to 64");
}

// The middle rows × cols of `surface`, made periodic (periodic-plus-smooth decomposition), or
// the surface itself where it is no larger.
Heightfield proxy_tile(const Heightfield& surface, int rows, int cols) {
    if (rows == surface.rows() && cols == surface.cols()) return surface;
    MeasuredSurface m = from_heightfield(surface);  // transposed: m.rows = surface.cols()
    ConditioningOptions c;
    c.crop = std::array<int, 4>{{(m.rows - cols) / 2, (m.cols - rows) / 2, cols, rows}};
    c.periodic = PeriodicMethod::Smooth;
    return to_heightfield(condition(m, c), "the photon plan's proxy tile", surface.texel_um(), surface.vscale());
}

// Positions per axis on the proxy's period nearest to the full plan's step (at least 1).
int proxy_steps(double period_um, double step_um) {
    if (!(step_um > 0.0)) return 1;
    return std::max(1, static_cast<int>(std::lround(period_um / step_um)));
}

}  // namespace

int exposures_for_target(double single_rms_um, double target_um, int max_exposures, bool* capped) {
    if (!(std::isfinite(single_rms_um) && single_rms_um >= 0.0))
        throw std::domain_error("predicted rms height error " + format_shortest(single_rms_um) +
                                " um is invalid; expected a finite value >= 0");
    if (!(std::isfinite(target_um) && target_um > 0.0))
        throw std::domain_error("target height error " + format_shortest(target_um) +
                                " um is invalid; expected a finite value > 0");
    if (max_exposures < 1)
        throw std::domain_error("max exposures " + std::to_string(max_exposures) + " is invalid; expected >= 1");
    const double ratio = single_rms_um / target_um;
    // The variance falls as 1/k: k ≥ ratio² (the 1e-9 keeps a ratio of exactly 1 at one exposure).
    const double needed = std::max(1.0, std::ceil(ratio * ratio - 1e-9));
    if (capped) *capped = needed > double(max_exposures);
    return static_cast<int>(std::min(needed, double(max_exposures)));
}

double predict_photon_limited_rms_um(const Heightfield& surface, const AcquisitionPlan& plan, double photons,
                                     const PhotonPlanSettings& settings, PhotonPlan* details) {
    check_settings(settings);
    if (!(std::isfinite(photons) && photons > 0.0))
        throw std::domain_error("photons per exposure " + format_shortest(photons) +
                                " is invalid; expected a finite value > 0");
    const auto start = std::chrono::steady_clock::now();
    const int rows = std::min(surface.rows(), settings.proxy_texels);
    const int cols = std::min(surface.cols(), settings.proxy_texels);
    const Heightfield tile = proxy_tile(surface, rows, cols);
    const double w = surface.texel_um();

    // The same acquisition on the proxy: the full raster's steps (as near as the proxy's period
    // allows), jittered as the planner does, every light and wavelength.
    AcquisitionPlan proxy = plan;
    proxy.notes.clear();
    proxy.positions_um.clear();
    const double full_step_x = plan.step_x_um > 0.0 ? plan.step_x_um : surface.rows() * w;
    const double full_step_y = plan.step_y_um > 0.0 ? plan.step_y_um : surface.cols() * w;
    const int nx = proxy_steps(rows * w, full_step_x), ny = proxy_steps(cols * w, full_step_y);
    proxy.step_x_um = rows * w / nx;
    proxy.step_y_um = cols * w / ny;
    constexpr double kJitter = 0.2;  // the planner's default (PlanRequest::jitter)
    std::mt19937_64 rng(detail::derive_seed(1, 17));
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j) {
            const double jx = (2.0 * detail::uniform01(rng) - 1.0) * kJitter * proxy.step_x_um;
            const double jy = (2.0 * detail::uniform01(rng) - 1.0) * kJitter * proxy.step_y_um;
            proxy.positions_um.push_back({(i + 0.5) * proxy.step_x_um + jx, (j + 0.5) * proxy.step_y_um + jy});
        }
    // σ² ∝ 1 / (positions per area): the proxy's density over the full plan's.
    const double density_ratio = (full_step_x * full_step_y) / (proxy.step_x_um * proxy.step_y_um);

    const std::vector<Observation> observations = simulate_observations(tile, proxy, Noise{}, 1);
    const Loss loss{LossKind::Poisson, 1.0, photons};
    const HeightUncertainty u = height_uncertainty(observations, tile, loss);
    double sum = 0.0;
    for (const double s : u.sigma_um) sum += s * s;
    const double rms = std::sqrt(sum / double(std::max<std::size_t>(u.sigma_um.size(), 1)) * density_ratio);
    if (details) {
        details->proxy_rows = rows;
        details->proxy_cols = cols;
        details->proxy_observations = observations.size();
        details->density_ratio = density_ratio;
        details->forwards = u.forwards;
        details->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return rms;
}

PhotonPlan plan_exposures(const Heightfield& surface, const AcquisitionPlan& plan, double photons, double range_um,
                          const PhotonPlanSettings& settings) {
    check_settings(settings);
    if (!(std::isfinite(range_um) && range_um > 0.0))
        throw std::domain_error("height range " + format_shortest(range_um) +
                                " um is invalid for the photon plan; expected a finite value > 0");
    PhotonPlan p;
    p.photons = photons;
    p.range_um = range_um;
    p.target = settings.target;
    p.single_rms_um = predict_photon_limited_rms_um(surface, plan, photons, settings, &p);
    if (settings.target > 0.0)
        p.exposures = exposures_for_target(p.single_rms_um, settings.target * range_um, settings.max_exposures,
                                           &p.capped);
    p.rms_um = p.single_rms_um / std::sqrt(double(p.exposures));
    const auto pct = [&](double rms_um) { return fixed("%.3g", 100.0 * rms_um / range_um) + " %"; };
    const std::string predicted = "photon-limited rms height error predicted " + pct(p.single_rms_um) +
                                  " of the peak to valley (" + fixed("%.3g", 1000.0 * p.single_rms_um) + " nm) at " +
                                  format_shortest(photons) + " photons per exposure";
    const std::string target = "target " + fixed("%.3g", 100.0 * settings.target) + " %";
    const std::string proxy = " (error bars on a " + std::to_string(p.proxy_rows) + "x" +
                              std::to_string(p.proxy_cols) + " proxy tile, " +
                              std::to_string(p.proxy_observations) + " observations)";
    if (settings.target <= 0.0)
        p.note = predicted + " (no target: one exposure per slice)" + proxy;
    else if (p.exposures == 1)
        p.note = predicted + ", within the " + target + ": one exposure per slice" + proxy;
    else
        p.note = predicted + " > " + target + ": " + std::to_string(p.exposures) +
                 " exposures per slice, summed, predicted " + pct(p.rms_um) +
                 (p.capped ? " (the cap, " + std::to_string(settings.max_exposures) +
                                 " exposures: the target is not met)"
                           : "") +
                 proxy;
    return p;
}

}  // namespace wavebrdf
