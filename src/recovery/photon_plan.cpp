#include "wavebrdf/photon_plan.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/cholesky.h"
#include "core/random.h"
#include "core/text.h"
#include "recovery/photon_proxy.h"
#include "wavebrdf/conditioning.h"
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

// The plan's acquisition on a rows × cols proxy of texel w: the full raster's steps (as near as
// the proxy's period allows), jittered as the planner does, every light and wavelength; *ratio
// receives the full plan's area per position over the proxy's.
AcquisitionPlan proxy_acquisition(const AcquisitionPlan& plan, const Heightfield& surface, int rows, int cols,
                                  double* ratio) {
    const double w = surface.texel_um();
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
    *ratio = (full_step_x * full_step_y) / (proxy.step_x_um * proxy.step_y_um);
    return proxy;
}

detail::PhotonProxy make_proxy(const Heightfield& surface, const AcquisitionPlan& plan, double photons,
                               const PhotonPlanSettings& settings) {
    const int rows = std::min(surface.rows(), settings.proxy_texels);
    const int cols = std::min(surface.cols(), settings.proxy_texels);
    const Heightfield tile = proxy_tile(surface, rows, cols);
    double ratio = 1.0;
    const AcquisitionPlan acquisition = proxy_acquisition(plan, surface, rows, cols, &ratio);
    return detail::photon_proxy(tile, simulate_observations(tile, acquisition, Noise{}, 1), photons, ratio);
}

// One-sided 95 % quantile of Student's t with k_photon_mc_draws − 1 = 15 degrees of freedom.
constexpr double kStudent95 = 1.753;
static_assert(k_photon_mc_draws == 16, "kStudent95 is the quantile for 15 degrees of freedom");
// A draw's solve stops when a step moves the heights by less than this fraction of the error
// bars' rms (or after k_photon_mc_steps steps).
constexpr double kStepTolerance = 0.01;
constexpr std::uint64_t kDrawStream = 0x70686f746f6e;  // "photon"

// The mean square error (µm², mean removed) of one noise draw's estimate: the proxy's slices
// with Poisson noise of k exposures (the full plan's photons per area), solved from the truth.
double draw_square_error(const detail::PhotonProxy& p, ObservationPlans& plans, int exposures, double sd_um,
                         std::uint64_t seed, int* gradients, int* steps) {
    const double photons = p.photons * exposures / p.density_ratio;
    std::vector<Observation> observations = p.observations;
    add_noise(observations, Noise{NoiseKind::Poisson, photons}, seed);
    const detail::ProxySolve s = detail::proxy_maximum_likelihood(p, observations, photons, p.tile.values(),
                                                                  kStepTolerance * sd_um, plans);
    *gradients += s.gradients;
    *steps = s.steps;
    const std::vector<double>& truth = p.tile.values();
    const std::size_t n = truth.size();
    const double to_um = p.tile.texel_um() * p.tile.vscale();
    double mean = 0.0, square = 0.0;
    for (std::size_t a = 0; a < n; ++a) mean += (s.heights[a] - truth[a]) / double(n);
    for (std::size_t a = 0; a < n; ++a) square += std::pow((s.heights[a] - truth[a] - mean) * to_um, 2) / double(n);
    return square;
}

// The estimator's rms error on the proxy with k exposures over k_photon_mc_draws noise draws
// (seeded from settings.seed and the draw's index, not k: the same draws' seeds for every k; a
// stream of their own, apart from the run's noise and jitter).
PhotonPlan::MonteCarlo estimator_error(const detail::PhotonProxy& p, ObservationPlans& plans, int exposures, double sd_um,
                                       std::uint64_t seed) {
    PhotonPlan::MonteCarlo m;
    m.exposures = exposures;
    std::vector<double> squares(k_photon_mc_draws);
    for (int d = 0; d < k_photon_mc_draws; ++d) {
        int steps = 0;
        squares[std::size_t(d)] = draw_square_error(p, plans, exposures, sd_um / std::sqrt(double(exposures)),
                                                    detail::derive_seed(detail::derive_seed(seed, kDrawStream), std::uint64_t(d)), &m.gradients, &steps);
        m.most_steps = std::max(m.most_steps, steps);
    }
    double mean = 0.0, spread = 0.0;
    for (double s : squares) mean += s / k_photon_mc_draws;
    for (double s : squares) spread += (s - mean) * (s - mean) / (k_photon_mc_draws - 1);
    m.rms_um = std::sqrt(mean);
    m.bound_um = std::sqrt(mean + kStudent95 * std::sqrt(spread / k_photon_mc_draws));
    return m;
}

}  // namespace

namespace detail {

PhotonProxy photon_proxy(const Heightfield& tile, std::vector<Observation> observations, double photons,
                         double density_ratio) {
    PhotonProxy p{tile, std::move(observations), photons, density_ratio, {}, 0.0, 0};
    const GaussNewtonBand band = GaussNewtonOperator(p.observations, p.tile, Loss{LossKind::Poisson, 1.0, photons}).band();
    p.forwards = band.forwards;
    p.factor = band.dense();
    const std::size_t n = p.tile.values().size();
    for (std::size_t a = 0; a < n; ++a) p.diagonal_mean += p.factor[a * n + a] / double(n);
    for (double& x : p.factor) x += p.diagonal_mean / double(n);
    const std::size_t singular = cholesky_in_place(p.factor, n, false);
    if (singular < n)
        throw std::domain_error("photon plan: the proxy's Gauss-Newton matrix is singular at texel " +
                                std::to_string(singular) + "; expected every texel seen by an observation");
    return p;
}

// The error bars' mean variance on the proxy, µm² (trace G⁺ / n = (trace A⁻¹ − 1/c) / n with
// trace A⁻¹ = ‖L⁻¹‖²_F, column by column), at the full plan's density, one exposure.
double proxy_bars_variance_um2(const PhotonProxy& p) {
    const std::size_t n = p.tile.values().size();
    double trace = 0.0;
    std::vector<double> x(n);
    for (std::size_t j = 0; j < n; ++j) {  // L x = e_j: x is 0 above row j
        for (std::size_t r = j; r < n; ++r) {
            const double* lr = p.factor.data() + r * n;
            double v = r == j ? 1.0 : 0.0;
            for (std::size_t k = j; k < r; ++k) v -= lr[k] * x[k];
            x[r] = v / lr[r];
            trace += x[r] * x[r];
        }
    }
    return std::max(0.0, trace - 1.0 / p.diagonal_mean) / double(n) * p.density_ratio;
}

ProxySolve proxy_maximum_likelihood(const PhotonProxy& p, const std::vector<Observation>& observations, double photons,
                                    std::vector<double> start, double tolerance_um, ObservationPlans& plans) {
    const std::size_t n = start.size();
    const double to_um = p.tile.texel_um() * p.tile.vscale();
    // observation_loss is the mean deviance over the slices and their pixels: −log L is half of
    // it times their count (up to a constant). Values and gradients below are of −log L, in µm.
    const double pixels = double(observations.front().reference.size()) / observations.front().channels();
    const double to_likelihood = 0.5 * double(observations.size()) * pixels;
    const double inverse_scale = p.photons / photons;  // G at `photons` = (photons / p.photons) · G
    const Loss loss{LossKind::Poisson, 1.0, photons};
    ProxySolve out{std::move(start), 0, 0, 0};
    const auto evaluate = [&](const std::vector<double>& raw, std::vector<double>& gradient) {
        gradient.clear();
        ++out.gradients;
        const double value = observation_loss(p.tile.with_values(raw), observations, loss, &gradient, {}, nullptr, &plans);
        for (double& g : gradient) g *= to_likelihood / to_um;
        return to_likelihood * value;
    };
    const auto dot = [](const std::vector<double>& a, const std::vector<double>& b) {
        double s = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
        return s;
    };
    constexpr std::size_t kMemory = 8;
    std::vector<std::vector<double>> s_history, y_history;  // steps and gradient changes, µm
    std::vector<double> gradient, trial_gradient, trial(n);
    double value = evaluate(out.heights, gradient);
    while (out.steps < k_photon_mc_steps) {
        // Two-loop recursion: d = −H g, H₀ = G⁻¹ at these photons.
        std::vector<double> d = gradient;
        std::vector<double> alpha(s_history.size());
        for (std::size_t i = s_history.size(); i-- > 0;) {
            alpha[i] = dot(s_history[i], d) / dot(y_history[i], s_history[i]);
            for (std::size_t a = 0; a < n; ++a) d[a] -= alpha[i] * y_history[i][a];
        }
        cholesky_solve(p.factor, n, d);
        for (double& v : d) v *= inverse_scale;
        for (std::size_t i = 0; i < s_history.size(); ++i) {
            const double beta = dot(y_history[i], d) / dot(y_history[i], s_history[i]);
            for (std::size_t a = 0; a < n; ++a) d[a] += (alpha[i] - beta) * s_history[i][a];
        }
        for (double& v : d) v = -v;
        const double slope = dot(gradient, d);
        if (!(slope < 0.0)) break;
        double fraction = 2.0, trial_value = value;
        bool accepted = false;
        for (int tries = 0; tries <= 4 && !accepted; ++tries) {
            fraction *= 0.5;
            out.halvings += tries > 0;
            for (std::size_t a = 0; a < n; ++a) trial[a] = out.heights[a] + fraction * d[a] / to_um;
            trial_value = evaluate(trial, trial_gradient);
            accepted = trial_value <= value + 1e-4 * fraction * slope;
        }
        if (!accepted) break;
        ++out.steps;
        std::vector<double> step(n), change(n);
        for (std::size_t a = 0; a < n; ++a) {
            step[a] = fraction * d[a];
            change[a] = trial_gradient[a] - gradient[a];
        }
        out.heights.swap(trial);
        gradient.swap(trial_gradient);
        value = trial_value;
        const double moved = std::sqrt(dot(step, step) / double(n));
        if (dot(step, change) > 0.0) {
            s_history.push_back(std::move(step));
            y_history.push_back(std::move(change));
            if (s_history.size() > kMemory) {
                s_history.erase(s_history.begin());
                y_history.erase(y_history.begin());
            }
        }
        if (moved <= tolerance_um) break;
    }
    return out;
}

}  // namespace detail

int exposures_for_target(const std::function<double(int)>& rms_um, double target_um, int max_exposures,
                         bool* capped) {
    if (capped) *capped = false;
    if (!(std::isfinite(target_um) && target_um > 0.0))
        throw std::domain_error("target height error " + format_shortest(target_um) +
                                " um is invalid; expected a finite value > 0");
    if (max_exposures < 1)
        throw std::domain_error("max exposures " + std::to_string(max_exposures) + " is invalid; expected >= 1");
    int lo = 0, hi = max_exposures + 1;  // rms_um(k) > target for k ≤ lo, ≤ target for k ≥ hi
    int k = 1;
    for (int tries = 1;; ++tries) {
        const double rms = rms_um(k);
        if (!(std::isfinite(rms) && rms >= 0.0))
            throw std::domain_error("predicted rms height error " + format_shortest(rms) + " um with " +
                                    std::to_string(k) + " exposures is invalid; expected a finite value >= 0");
        (rms > target_um ? lo : hi) = k;
        if (hi - lo <= 1) break;
        // Where rms · √(k / k') meets the target; after three guesses, bisection.
        const double guess = std::ceil(double(k) * (rms / target_um) * (rms / target_um));
        k = tries >= 3 ? lo + (hi - lo) / 2 : int(std::clamp(guess, double(lo + 1), double(hi - 1)));
    }
    if (hi > max_exposures) {
        if (capped) *capped = true;
        return max_exposures;
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
    const detail::PhotonProxy proxy = make_proxy(surface, plan, photons, settings);
    const double rms = std::sqrt(detail::proxy_bars_variance_um2(proxy));
    if (details) {
        details->proxy_rows = proxy.tile.rows();
        details->proxy_cols = proxy.tile.cols();
        details->proxy_observations = proxy.observations.size();
        details->density_ratio = proxy.density_ratio;
        details->forwards = proxy.forwards;
        details->bars_rms_um = rms;
        details->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return rms;
}

namespace {

// The plan's one-line note (PhotonPlan::note).
std::string plan_note(const PhotonPlan& p, const PhotonPlanSettings& settings) {
    const auto pct = [&](double rms_um) { return format_number(100.0 * rms_um / p.range_um, "%.3g") + " %"; };
    const auto with = [](int k) { return k == 1 ? std::string("one exposure") : std::to_string(k) + " exposures"; };
    const std::string bars = "photon-limited rms height error: the error bars " + pct(p.bars_rms_um) +
                             " of the peak to valley with one exposure of " + format_shortest(p.photons) + " photons";
    const std::string target = "target " + format_number(100.0 * settings.target, "%.3g") + " %";
    std::string mc = "the estimator by Monte Carlo on a " + std::to_string(p.proxy_rows) + "x" +
                     std::to_string(p.proxy_cols) + " proxy tile (" + std::to_string(p.proxy_observations) +
                     " observations, " + std::to_string(k_photon_mc_draws) + " noise draws, at most " +
                     std::to_string(k_photon_mc_steps) + " quasi-Newton steps each): " + pct(p.rms_um) + " with " +
                     with(p.exposures) + " (95 % upper bound " + pct(p.bound_um) + ")";
    for (const PhotonPlan::MonteCarlo& m : p.tried)
        if (m.exposures == p.exposures - 1) mc += ", " + pct(m.rms_um) + " (bound " + pct(m.bound_um) + ") with " + with(m.exposures);
    if (settings.target <= 0.0) return bars + "; " + mc + " (no target: one exposure per slice)";
    if (p.capped)
        return bars + "; " + mc + " > " + target + ": " + with(p.exposures) +
               " per slice, summed (the cap: the target is not met)";
    if (p.exposures == 1) return bars + "; " + mc + ", within the " + target + ": one exposure per slice";
    return bars + "; " + mc + ", within the " + target + ": " + with(p.exposures) + " per slice, summed";
}

}  // namespace

PhotonPlan plan_exposures(const Heightfield& surface, const AcquisitionPlan& plan, double photons, double range_um,
                          const PhotonPlanSettings& settings) {
    check_settings(settings);
    if (!(std::isfinite(range_um) && range_um > 0.0))
        throw std::domain_error("height range " + format_shortest(range_um) +
                                " um is invalid for the photon plan; expected a finite value > 0");
    if (!(std::isfinite(photons) && photons > 0.0))
        throw std::domain_error("photons per exposure " + format_shortest(photons) +
                                " is invalid; expected a finite value > 0");
    const auto start = std::chrono::steady_clock::now();
    PhotonPlan p;
    p.photons = photons;
    p.range_um = range_um;
    p.target = settings.target;
    const detail::PhotonProxy proxy = make_proxy(surface, plan, photons, settings);
    p.proxy_rows = proxy.tile.rows();
    p.proxy_cols = proxy.tile.cols();
    p.proxy_observations = proxy.observations.size();
    p.density_ratio = proxy.density_ratio;
    p.forwards = proxy.forwards;
    p.bars_rms_um = std::sqrt(detail::proxy_bars_variance_um2(proxy));
    ObservationPlans plans;
    const auto run = [&](int k) -> const PhotonPlan::MonteCarlo& {
        for (const PhotonPlan::MonteCarlo& m : p.tried)
            if (m.exposures == k) return m;
        p.tried.push_back(estimator_error(proxy, plans, k, p.bars_rms_um, settings.seed));
        return p.tried.back();
    };
    if (settings.target > 0.0)
        p.exposures = exposures_for_target([&](int k) { return run(k).bound_um; }, settings.target * range_um,
                                           settings.max_exposures, &p.capped);
    const PhotonPlan::MonteCarlo chosen = run(p.exposures);
    p.rms_um = chosen.rms_um;
    p.bound_um = chosen.bound_um;
    std::sort(p.tried.begin(), p.tried.end(), [](const auto& a, const auto& b) { return a.exposures < b.exposures; });
    for (const PhotonPlan::MonteCarlo& m : p.tried) p.gradients += m.gradients;
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    p.note = plan_note(p, settings);
    return p;
}

}  // namespace wavebrdf
