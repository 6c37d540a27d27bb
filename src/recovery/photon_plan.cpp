#include "wavebrdf/photon_plan.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cholesky.h"
#include "core/random.h"
#include "core/text.h"
#include "wavebrdf/conditioning.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/surface_file.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {

namespace {

using detail::format_shortest;

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

// Positions per axis on the proxy's period nearest to the full plan's step (at least 1).
int proxy_steps(double period_um, double step_um) {
    if (!(step_um > 0.0)) return 1;
    return std::max(1, static_cast<int>(std::lround(period_um / step_um)));
}

// The variance of every Fourier mode of the proxy's heights (row-major over its rows × cols
// frequencies, µm²: Λ(q) = f_qᴴ G⁺ f_q / n, f_q = e^{2πi q·x}; 0 at q = 0; the mean over the modes
// is the bars' mean σ²): A = G + c·11ᵀ/n = L Lᵀ (c the mean diagonal) has A⁻¹ = G⁺ + 11ᵀ/(n c)
// and f_q ⊥ 1, so Λ(q) = (‖L⁻¹ Re f_q‖² + ‖L⁻¹ Im f_q‖²) / n. Throws std::domain_error for a G
// that is not positive on the mean-free heights (a texel no observation sees).
std::vector<double> mode_variances(std::vector<double> g, int rows, int cols) {
    const std::size_t n = std::size_t(rows) * std::size_t(cols);
    double c = 0.0;
    for (std::size_t a = 0; a < n; ++a) c += g[a * n + a] / double(n);
    for (double& x : g) x += c / double(n);
    const std::size_t singular = detail::cholesky_in_place(g, n, false);
    if (singular < n)
        throw std::domain_error("photon plan: the proxy's Gauss-Newton matrix is singular at texel " +
                                std::to_string(singular) + "; expected every texel seen by an observation");
    const auto solved_norm = [&](std::vector<double> x) {  // ‖L⁻¹ x‖²
        double norm = 0.0;
        for (std::size_t r = 0; r < n; ++r) {
            const double* lr = g.data() + r * n;
            for (std::size_t k = 0; k < r; ++k) x[r] -= lr[k] * x[k];
            x[r] /= lr[r];
            norm += x[r] * x[r];
        }
        return norm;
    };
    std::vector<double> spectrum(n, 0.0), re(n), im(n);
    for (int qr = 0; qr < rows; ++qr)
        for (int qc = 0; qc < cols; ++qc) {
            if (qr == 0 && qc == 0) continue;
            for (int r = 0; r < rows; ++r)
                for (int cc = 0; cc < cols; ++cc) {
                    const double phase = 2.0 * k_pi * (double(qr * r) / rows + double(qc * cc) / cols);
                    re[std::size_t(r) * std::size_t(cols) + std::size_t(cc)] = std::cos(phase);
                    im[std::size_t(r) * std::size_t(cols) + std::size_t(cc)] = std::sin(phase);
                }
            spectrum[std::size_t(qr) * std::size_t(cols) + std::size_t(qc)] =
                (solved_norm(re) + solved_norm(im)) / double(n);
        }
    return spectrum;
}

// |X(q)|² of the mean-free heights in µm (X the unnormalised 2-D DFT), row-major: separable, a
// DFT along the rows then the columns (rows·cols·(rows + cols) complex multiply-adds).
std::vector<double> height_power(const Heightfield& surface) {
    const int rows = surface.rows(), cols = surface.cols();
    const std::size_t n = std::size_t(rows) * std::size_t(cols);
    const double to_um = surface.texel_um() * surface.vscale();
    double mean = 0.0;
    for (double v : surface.values()) mean += v / double(n);
    std::vector<std::complex<double>> x(n), y(n);
    for (std::size_t t = 0; t < n; ++t) x[t] = (surface.values()[t] - mean) * to_um;
    const auto twiddles = [](int size) {
        std::vector<std::complex<double>> e(static_cast<std::size_t>(size));
        for (int k = 0; k < size; ++k) e[std::size_t(k)] = std::polar(1.0, -2.0 * k_pi * k / size);
        return e;
    };
    const std::vector<std::complex<double>> er = twiddles(rows), ec = twiddles(cols);
    for (int r = 0; r < rows; ++r)  // along each row (over columns)
        for (int k = 0; k < cols; ++k) {
            std::complex<double> s = 0.0;
            for (int c = 0; c < cols; ++c) s += x[std::size_t(r) * std::size_t(cols) + std::size_t(c)] * ec[std::size_t((k * c) % cols)];
            y[std::size_t(r) * std::size_t(cols) + std::size_t(k)] = s;
        }
    std::vector<double> power(n);
    for (int c = 0; c < cols; ++c)
        for (int k = 0; k < rows; ++k) {
            std::complex<double> s = 0.0;
            for (int r = 0; r < rows; ++r) s += y[std::size_t(r) * std::size_t(cols) + std::size_t(c)] * er[std::size_t((k * r) % rows)];
            power[std::size_t(k) * std::size_t(cols) + std::size_t(c)] = std::norm(s);
        }
    return power;
}

// The proxy's frequency index (0 … proxy − 1) nearest the whole tile's index k of `size`.
int nearest_frequency(int k, int size, int proxy) {
    const double f = (k > size / 2 ? k - size : k) / double(size);  // cycles per texel, −½ … ½
    return ((int(std::lround(f * proxy)) % proxy) + proxy) % proxy;
}

// photon_limited_bias_um on the tile's power |X(q)|² (height_power).
double bias_of_power(const std::vector<double>& power, int rows, int cols, const PhotonPlan& details, int exposures) {
    const int pr = details.proxy_rows, pc = details.proxy_cols;
    const double n = double(rows) * double(cols);
    double bias2 = 0.0;
    for (int kr = 0; kr < rows; ++kr)
        for (int kc = 0; kc < cols; ++kc) {
            const double t = power[std::size_t(kr) * std::size_t(cols) + std::size_t(kc)];
            if ((kr == 0 && kc == 0) || !(t > 0.0)) continue;
            const std::size_t at = std::size_t(nearest_frequency(kr, rows, pr)) * std::size_t(pc) +
                                   std::size_t(nearest_frequency(kc, cols, pc));
            const double v = n * details.variance_spectrum[at] / double(exposures);
            const double shrink = std::min(1.0, v / (2.0 * t));
            bias2 += t * shrink * shrink;
        }
    return std::sqrt(bias2) / n;
}

// The predicted total with `exposures` and its bias: √(variance/k + bias²), the variance being
// the single exposure's total less its bias. One sum for plan_exposures and photon_plan_rms_um,
// so that a plan's rms_um is photon_plan_rms_um of its exposures to the bit.
double rms_with_bias(const PhotonPlan& p, int exposures, double bias_um) {
    const double variance = std::max(p.single_rms_um * p.single_rms_um - p.single_bias_um * p.single_bias_um, 0.0);
    return std::sqrt(variance / double(exposures) + bias_um * bias_um);
}

// The plan's note: the first-order prediction, the pilot's measurement where it ran, the
// exposures taken and the proxies (no times: the same every run).
std::string plan_note(const PhotonPlan& p, const PhotonPlanSettings& settings) {
    const auto pct = [&](double rms_um) { return format_number(100.0 * rms_um / p.range_um, "%.3g") + " %"; };
    const std::string predicted = "photon-limited rms height error predicted " + pct(p.single_rms_um) +
                                  " of the peak to valley (" + format_number(1000.0 * p.single_rms_um, "%.3g") +
                                  " nm, of which a bias of " + format_number(1000.0 * p.single_bias_um, "%.3g") +
                                  " nm rms: the high spatial frequencies shrunk) at " + format_shortest(p.photons) +
                                  " photons per exposure";
    const std::string target = "target " + format_number(100.0 * settings.target, "%.3g") + " %";
    const std::string proxy = " (error bars on a " + std::to_string(p.proxy_rows) + "x" +
                              std::to_string(p.proxy_cols) + " proxy tile, " +
                              std::to_string(p.proxy_observations) + " observations)";
    const PhotonPilot& q = p.pilot;
    std::string pilot;
    if (q.ran)
        pilot = "; a pilot of the recovery on " + std::to_string(q.tiles) + " " + std::to_string(q.rows) + "x" +
                std::to_string(q.cols) + " proxy tile" + (q.tiles == 1 ? "" : "s") + " (" +
                std::to_string(q.errors_um.size()) + " noise draws at " + std::to_string(q.exposures) +
                " exposures) measured " + format_number(q.ratio, "%.3f") + " +- " +
                format_number(q.ratio_sd, "%.3f") + " x the first-order prediction (" +
                format_number(1000.0 * q.measured_rms_um, "%.3g") + " nm against " +
                format_number(1000.0 * q.predicted_rms_um, "%.3g") + " nm), a draw's ratio scattering by " +
                format_number(q.draw_sd, "%.3f") + ", one run's on the full tile by " +
                format_number(q.run_sd, "%.3f") + ": the exposures are planned with " +
                format_number(q.upper_ratio, "%.3f") + " x the prediction (the ratio + " +
                format_number(k_photon_pilot_z, "%.3g") + " sd, one run's bound)";
    else if (!q.why_not.empty())
        pilot = "; no pilot: " + q.why_not;
    if (settings.target <= 0.0) return predicted + " (no target: one exposure per slice)" + proxy;
    if (p.exposures == 1 && !p.capped)
        return predicted + pilot + ", within the " + target + ": one exposure per slice" + proxy;
    return predicted + pilot + " > " + target + ": " + std::to_string(p.exposures) +
           " exposures per slice, summed, predicted " + pct(p.rms_um) +
           (p.capped ? " (the cap, " + std::to_string(settings.max_exposures) + " exposures: the target is not met)"
                     : "") +
           proxy;
}

}  // namespace

Heightfield photon_proxy_tile(const Heightfield& surface, int rows, int cols) {
    rows = std::min(rows, surface.rows());
    cols = std::min(cols, surface.cols());
    return photon_proxy_tile_at(surface, (surface.rows() - rows) / 2, (surface.cols() - cols) / 2, rows, cols);
}

Heightfield photon_proxy_tile_at(const Heightfield& surface, int row0, int col0, int rows, int cols) {
    rows = std::min(rows, surface.rows());
    cols = std::min(cols, surface.cols());
    if (rows == surface.rows() && cols == surface.cols()) return surface;
    row0 = std::clamp(row0, 0, surface.rows() - rows);
    col0 = std::clamp(col0, 0, surface.cols() - cols);
    MeasuredSurface m = from_heightfield(surface);  // transposed: m.rows = surface.cols()
    ConditioningOptions c;
    c.crop = std::array<int, 4>{{col0, row0, cols, rows}};
    c.periodic = PeriodicMethod::Smooth;
    return to_heightfield(condition(m, c), "the photon plan's proxy tile", surface.texel_um(), surface.vscale());
}

int exposures_for_target(const std::function<double(int)>& rms_um, double target_um, int max_exposures,
                         bool* capped) {
    if (capped) *capped = false;
    const double single = rms_um(1);
    if (!(std::isfinite(single) && single >= 0.0))
        throw std::domain_error("predicted rms height error " + format_shortest(single) +
                                " um is invalid; expected a finite value >= 0");
    if (!(std::isfinite(target_um) && target_um > 0.0))
        throw std::domain_error("target height error " + format_shortest(target_um) +
                                " um is invalid; expected a finite value > 0");
    if (max_exposures < 1)
        throw std::domain_error("max exposures " + std::to_string(max_exposures) + " is invalid; expected >= 1");
    if (single <= target_um) return 1;
    if (rms_um(max_exposures) > target_um) {
        if (capped) *capped = true;
        return max_exposures;
    }
    int lo = 1, hi = max_exposures;  // rms_um(lo) > target ≥ rms_um(hi)
    while (hi - lo > 1) {
        const int mid = lo + (hi - lo) / 2;
        (rms_um(mid) > target_um ? lo : hi) = mid;
    }
    return hi;
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
    const Heightfield tile = photon_proxy_tile(surface, rows, cols);
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
    // G on the proxy (uncertainty.h), its pseudo-inverse mode by mode: the bars' variance is the
    // modes' mean, its spectrum what photon_limited_bias_um weighs the truth's power against.
    const GaussNewtonBand band = GaussNewtonOperator(observations, tile, loss).band();
    std::vector<double> spectrum = mode_variances(band.dense(), tile.rows(), tile.cols());
    double sum = 0.0;
    for (double& v : spectrum) {
        v *= density_ratio;
        sum += v;
    }
    const double rms = std::sqrt(sum / double(std::max<std::size_t>(spectrum.size(), 1)));
    if (details) {
        details->proxy_rows = rows;
        details->proxy_cols = cols;
        details->proxy_observations = observations.size();
        details->density_ratio = density_ratio;
        details->forwards = band.forwards;
        details->variance_spectrum = std::move(spectrum);
        details->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return rms;
}

double photon_limited_bias_um(const Heightfield& surface, const PhotonPlan& details, int exposures) {
    const int pr = details.proxy_rows, pc = details.proxy_cols;
    if (pr < 1 || pc < 1 || details.variance_spectrum.size() != std::size_t(pr) * std::size_t(pc))
        throw std::invalid_argument("photon-limited bias: a variance spectrum of " +
                                    std::to_string(details.variance_spectrum.size()) + " values; expected " +
                                    std::to_string(pr) + "x" + std::to_string(pc));
    if (exposures < 1)
        throw std::domain_error("exposures " + std::to_string(exposures) + " is invalid; expected >= 1");
    return bias_of_power(height_power(surface), surface.rows(), surface.cols(), details, exposures);
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
    const double single_sd_um = predict_photon_limited_rms_um(surface, plan, photons, settings, &p);
    // √(variance/k + bias(k)²): both fall with k.
    const std::vector<double> power = height_power(surface);
    p.single_bias_um = bias_of_power(power, surface.rows(), surface.cols(), p, 1);
    p.single_rms_um = std::sqrt(single_sd_um * single_sd_um + p.single_bias_um * p.single_bias_um);
    const auto total_um = [&](int k, double* bias_um) {
        const double b = bias_of_power(power, surface.rows(), surface.cols(), p, k);
        if (bias_um) *bias_um = b;
        return rms_with_bias(p, k, b);
    };
    if (settings.target > 0.0)
        p.exposures = exposures_for_target([&](int k) { return total_um(k, nullptr); }, settings.target * range_um,
                                           settings.max_exposures, &p.capped);
    p.rms_um = total_um(p.exposures, &p.bias_um);
    p.note = plan_note(p, settings);
    return p;
}


double photon_plan_rms_um(const Heightfield& surface, const PhotonPlan& p, int exposures) {
    return rms_with_bias(p, exposures, photon_limited_bias_um(surface, p, exposures));
}

int photon_pilot_tile_texels(int rows, int cols) {
    if (rows < 1 || cols < 1)
        throw std::invalid_argument("surface " + std::to_string(rows) + "x" + std::to_string(cols) +
                                    " is invalid for the pilot; expected at least 1x1");
    const int side = std::min(rows, cols);
    return std::min(side, std::clamp(side / 2, k_photon_pilot_min_texels, k_photon_pilot_texels));
}

int photon_pilot_max_draws(int rows, int cols) {
    if (rows < 1 || cols < 1)
        throw std::invalid_argument("pilot tile " + std::to_string(rows) + "x" + std::to_string(cols) +
                                    " is invalid; expected at least 1x1");
    const long long draws = k_photon_pilot_budget_texels / (static_cast<long long>(rows) * cols);
    return int(std::clamp<long long>(draws, k_photon_pilot_min_draws, k_photon_pilot_max_draws));
}

void set_photon_pilot_spread(PhotonPilot& pilot, int rows, int cols) {
    const std::size_t n = std::min(pilot.errors_um.size(), pilot.predicted_um.size());
    double mean = 0.0, sum2 = 0.0;
    for (std::size_t d = 0; d < n; ++d) mean += pilot.errors_um[d] / pilot.predicted_um[d];
    mean /= double(std::max<std::size_t>(n, 1));
    for (std::size_t d = 0; d < n; ++d) {
        const double r = pilot.errors_um[d] / pilot.predicted_um[d] - mean;
        sum2 += r * r;
    }
    pilot.draw_sd = n > 1 ? std::sqrt(sum2 / double(n - 1)) : 0.0;
    const double tile = pilot.rows > 0 && pilot.cols > 0 ? double(pilot.rows) * double(pilot.cols)
                                                         : double(k_photon_pilot_texels) * k_photon_pilot_texels;
    const double cells = double(rows) * double(cols) / tile;
    pilot.run_sd = pilot.draw_sd / std::sqrt(std::max(1.0, cells));
    pilot.upper_ratio = std::max(1.0, pilot.ratio + k_photon_pilot_z * std::sqrt(pilot.ratio_sd * pilot.ratio_sd +
                                                                                  pilot.run_sd * pilot.run_sd));
}

void apply_photon_pilot(PhotonPlan& p, const Heightfield& surface, const PhotonPlanSettings& settings,
                        PhotonPilot pilot) {
    check_settings(settings);
    p.pilot = std::move(pilot);
    if (p.pilot.ran) set_photon_pilot_spread(p.pilot, surface.rows(), surface.cols());
    if (p.pilot.ran && settings.target > 0.0) {
        const double ratio = p.pilot.upper_ratio;
        p.exposures = exposures_for_target([&](int k) { return ratio * photon_plan_rms_um(surface, p, k); },
                                           settings.target * p.range_um, settings.max_exposures, &p.capped);
        p.bias_um = photon_limited_bias_um(surface, p, p.exposures);
        p.rms_um = ratio * photon_plan_rms_um(surface, p, p.exposures);
    }
    p.note = plan_note(p, settings);
}

}  // namespace wavebrdf
