#include "wavebrdf/convergence.h"

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "recovery/observation_loss.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// 2 [k log(k/μ) − (k − μ)], 0 log 0 = 0.
double deviance_term(double k, double mu) {
    if (k <= 0.0) return 2.0 * mu;
    if (mu <= 0.0) return 2.0 * (k * std::log(k / 1e-300) - k);
    return 2.0 * (k * std::log1p((k - mu) / mu) - (k - mu));
}

double thread_cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

double process_cpu_seconds() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

SliceDeviance slice_photon_deviance(const Observation& o, const std::vector<double>& model, double photons) {
    if (model.size() != o.reference.size())
        throw std::invalid_argument("slice_photon_deviance: the model slice has " + std::to_string(model.size()) +
                                    " values; expected " + std::to_string(o.reference.size()));
    if (!(std::isfinite(photons) && photons > 0.0))
        throw std::invalid_argument("slice_photon_deviance: photons " + std::to_string(photons) +
                                    " is invalid; expected > 0");
    SliceDeviance d;
    double total = 0.0;
    for (std::size_t p = 0; p < model.size(); ++p)
        if (detail::value_weight(o, p) != 0.0) total += std::max(double(o.reference[p]), 0.0);
    if (!(total > 0.0)) return d;
    const double s = photons / total;
    for (std::size_t p = 0; p < model.size(); ++p) {
        const double w = detail::value_weight(o, p);
        if (w == 0.0) continue;
        const double mu = s * std::max(model[p], 0.0), k = s * std::max(double(o.reference[p]), 0.0);
        double e = 0.0, v = 0.0;
        poisson_deviance_moments(mu, e, v);
        const double term = deviance_term(k, mu);
        d.deviance += w * term;
        d.expected += w * e;
        d.variance += w * w * v;
        if (mu >= k_slice_bright_photons) {
            d.bright_deviance += w * term;
            d.bright_expected += w * e;
            d.bright_variance += w * w * v;
        }
    }
    return d;
}

double slice_deviance_limit(double expected, double variance, double slices) {
    if (!(expected > 0.0 && variance > 0.0 && slices >= 1.0) || !std::isfinite(expected) || !std::isfinite(variance))
        return HUGE_VAL;
    // The normal quantile z of 1 − α/M by bisection on the upper tail ½ erfc(z/√2).
    const double p = k_slice_false_alarm / slices;
    double lo = 0.0, hi = 40.0;
    for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
    }
    const double z = 0.5 * (lo + hi);
    // Gamma of shape k = E²/Var: (X/E)^(1/3) ≈ normal, mean 1 − 1/(9k), variance 1/(9k).
    const double c = variance / (9.0 * expected * expected);
    const double root = 1.0 - c + z * std::sqrt(c);
    return expected * root * root * root;
}

bool misfit_on_photon_floor(double deviance, double expected, double sd) {
    return !(deviance > k_misfit_ratio_limit * expected && deviance - expected > k_misfit_sd_limit * sd);
}

void poisson_deviance_moments(double mu, double& mean, double& variance) {
    if (!(std::isfinite(mu) && mu >= 0.0))
        throw std::domain_error("poisson_deviance_moments: mean " + std::to_string(mu) + " is invalid; expected >= 0");
    if (mu == 0.0) {
        mean = variance = 0.0;
        return;
    }
    // The counts within 12 standard deviations (and 40 counts) of μ carry all but ~1e-30 of
    // the probability; the pmf in logs (no overflow at large μ).
    const double reach = 12.0 * std::sqrt(mu) + 40.0;
    const long long lo = std::max(0LL, static_cast<long long>(std::floor(mu - reach)));
    const long long hi = static_cast<long long>(std::ceil(mu + reach));
    // The pmf at lo in logs (no overflow at large μ), then p(k + 1) = p(k) μ / (k + 1): one exp
    // and lgamma per pixel instead of per count (the check and the model check evaluate every
    // pixel of every slice, most of them dim). At lo the pmf is above e^−217 for any μ, far from
    // the underflow. Past the mode the terms fall faster than geometrically, so the counts
    // after the first of probability below 1e−40 of the sum so far add below 1e−35 of a moment.
    double p = std::exp(double(lo) * std::log(mu) - mu - std::lgamma(double(lo) + 1.0));
    double m1 = 0.0, m2 = 0.0, total = 0.0;
    for (long long k = lo; k <= hi; ++k) {
        const double kd = double(k);
        const double d = deviance_term(kd, mu);
        total += p;
        m1 += p * d;
        m2 += p * d * d;
        if (kd > mu && p < 1e-40 * total) break;
        p *= mu / (kd + 1.0);
    }
    mean = m1 / total;
    variance = std::max(m2 / total - mean * mean, 0.0);
}

std::string ConvergenceCheck::warning() const {
    if (converged) return "";
    std::string line = misfit_failed ? "the recovery did not converge: " : "the recovery is likely inaccurate: ";
    for (std::size_t i = 0; i < reasons.size(); ++i) line += (i ? "; " : "") + reasons[i];
    return line;
}

ConvergenceCheck check_convergence(const std::vector<Observation>& observations, const Heightfield& estimate,
                                   double photons, bool noiseless, const Calibration* calibration,
                                   const Communicator& comm) {
    if (observations.empty() && comm.size() == 1)
        throw std::invalid_argument("check_convergence: no observations given; expected at least one");
    const std::size_t n = observations.size();
    const bool positions = calibration && calibration->position_offsets_um.size() == n;
    const bool exposures = calibration && calibration->exposures.size() == n;
    const double sigma_scale = calibration ? calibration->sigma_p_scale : 1.0;
    if (!(std::isfinite(photons) && photons >= 0.0))
        throw std::invalid_argument("check_convergence: photons " + std::to_string(photons) +
                                    " is invalid; expected >= 0 (0: unknown)");
    const bool poisson = photons > 0.0;
    // Per observation, summed in order afterwards (the same bits for any thread count):
    // deviance, its expectation and variance, Σ(√I − √R)², Σ R.
    std::vector<double> dev(n, 0.0), mean(n, 0.0), var(n, 0.0), amp(n, 0.0), energy(n, 0.0);
    std::vector<double> bright_dev(n, 0.0), bright_mean(n, 0.0), bright_var(n, 0.0);
    std::vector<std::string> errors(n);
    std::vector<double> forward_seconds(n, 0.0);  // each observation's slice plan built and rendered
#pragma omp parallel for schedule(dynamic, 1)
    for (std::size_t i = 0; i < n; ++i) {
        try {
            const Observation& o = observations[i];
            SlicePlan<double> plan(estimate,
                                   detail::calibrated_query(o, sigma_scale,
                                                            positions ? &calibration->position_offsets_um[i] : nullptr),
                                   o.lambdas_um, o.resolution, o.channels());
            plan.forward();
            // Timed again once built, as the error bars' forward differences run it (the cost rule).
            const double forward_start = thread_cpu_seconds();
            std::vector<double> model = plan.forward();
            forward_seconds[i] = thread_cpu_seconds() - forward_start;
            if (model.size() != o.reference.size())
                throw std::invalid_argument("observation " + std::to_string(i) + " has " +
                                            std::to_string(o.reference.size()) + " reference values; expected " +
                                            std::to_string(model.size()));
            if (exposures)
                for (double& m : model) m *= calibration->exposures[i];
            // Only the values of weight > 0 count, each with its weight (a value of weight 0
            // may hold anything); the photons are those of the counted values, as the weighted
            // Poisson loss's.
            double total = 0.0, weighted = 0.0;
            for (std::size_t p = 0; p < model.size(); ++p) {
                const double w = detail::value_weight(o, p);
                if (w == 0.0) continue;
                total += std::max(double(o.reference[p]), 0.0);
                weighted += w * std::max(double(o.reference[p]), 0.0);
                const double r = std::max(double(o.reference[p]), 0.0), m = std::max(model[p], 0.0);
                const double d = std::sqrt(m) - std::sqrt(r);
                amp[i] += w * d * d;
            }
            energy[i] = weighted;
            if (poisson && total > 0.0) {
                const SliceDeviance d = slice_photon_deviance(o, model, photons);
                dev[i] = d.deviance;
                mean[i] = d.expected;
                var[i] = d.variance;
                bright_dev[i] = d.bright_deviance;
                bright_mean[i] = d.bright_expected;
                bright_var[i] = d.bright_variance;
            }
        } catch (const std::exception& e) {
            errors[i] = e.what();
        }
    }
    // The forwards' CPU time (the deviance's exact moments excluded: the error bars' cost rule
    // needs a forward's cost); rank 0's, the same on every rank.
    double pass_seconds = 0.0;
    for (const double t : forward_seconds) pass_seconds += t;
    for (const std::string& e : errors)
        if (!e.empty()) throw std::invalid_argument("check_convergence: " + e);
    comm.broadcast(&pass_seconds, 1);
    std::vector<double> sums(5, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        sums[0] += dev[i];
        sums[1] += mean[i];
        sums[2] += var[i];
        sums[3] += amp[i];
        sums[4] += energy[i];
    }
    comm.allreduce_sum(sums);
    ConvergenceCheck check;
    check.pass_seconds = pass_seconds;
    check.relative_misfit = sums[4] > 0.0 ? sums[3] / sums[4] : 0.0;
    if (poisson && sums[1] > 0.0) {
        check.floor = "poisson";
        check.deviance = sums[0];
        check.expected_deviance = sums[1];
        check.deviance_sd = std::sqrt(sums[2]);
        check.misfit_ratio = sums[0] / sums[1];
        if (!misfit_on_photon_floor(check.deviance, check.expected_deviance, check.deviance_sd)) {
            check.converged = false;
            check.misfit_failed = true;
            check.reasons.push_back("the slices' misfit is " + format_number(check.misfit_ratio, "%.3g") +
                                    "x what photon noise leaves (deviance " + format_number(check.deviance, "%.4g") +
                                    ", expected " + format_number(check.expected_deviance, "%.4g") + " +- " +
                                    format_number(check.deviance_sd, "%.2g") + ")");
        }
        // Each slice against its own floor (k_slice_false_alarm): the count over every rank,
        // and the worst slice (each rank's worst in its own slot, then summed).
        std::vector<double> slices{double(n)};
        comm.allreduce_sum(slices);
        std::vector<double> worst(3 * std::size_t(comm.size()) + 1, 0.0);
        double& off = worst.back();
        double local_worst = -1.0;
        for (std::size_t i = 0; i < n; ++i) {
            const double limit = slice_deviance_limit(bright_mean[i], bright_var[i], slices[0]);
            if (!std::isfinite(limit)) continue;
            const double excess = bright_dev[i] / limit;
            if (excess > 1.0) off += 1.0;
            if (excess > local_worst) {
                local_worst = excess;
                double* slot = worst.data() + 3 * std::size_t(comm.rank());
                slot[0] = excess;
                slot[1] = observations[i].query.x_um;
                slot[2] = observations[i].query.y_um;
            }
        }
        comm.allreduce_sum(worst);
        check.slices_off_floor = int(off);
        for (int r = 0; r < comm.size(); ++r) {
            const double* slot = worst.data() + 3 * std::size_t(r);
            if (slot[0] > check.worst_slice_excess) {
                check.worst_slice_excess = slot[0];
                check.worst_slice_x_um = slot[1];
                check.worst_slice_y_um = slot[2];
            }
        }
        if (check.slices_off_floor >= k_slices_off_floor_min) {
            check.converged = false;
            check.misfit_failed = true;
            check.reasons.push_back(
                std::to_string(check.slices_off_floor) + " of " + format_number(slices[0], "%.0f") +
                " slices are above their own photon-noise floor (the worst, centred at x " +
                format_number(check.worst_slice_x_um, "%.1f") + " um, y " + format_number(check.worst_slice_y_um, "%.1f") + " um, " +
                format_number(check.worst_slice_excess, "%.3g") + "x its limit on the pixels of >= 1 expected photon): the "
                "heights under those footprints are not explained (a pit, spike or step the fit did not resolve)");
        }
    } else if (noiseless) {
        check.floor = "noiseless";
        if (check.relative_misfit > k_noiseless_misfit_limit) {
            check.converged = false;
            check.misfit_failed = true;
            check.reasons.push_back("the slices were simulated without noise, yet the estimate's relative misfit is " +
                                    format_number(check.relative_misfit, "%.3g") + " (a converged estimate: below " +
                                    format_number(k_noiseless_misfit_limit, "%.0e") + ")");
        }
    }
    return check;
}

void add_model_check(ConvergenceCheck& check, double misfit_gabor, double misfit_field, const std::string& selected) {
    check.model_misfit_gabor = misfit_gabor;
    check.model_misfit_field = misfit_field;
    check.model_selected = selected;
}

void add_error_bars(ConvergenceCheck& check, double median_sigma_um, double height_range_um) {
    if (!(median_sigma_um >= 0.0) || !(height_range_um > 0.0)) return;
    check.median_sigma_relative = median_sigma_um / height_range_um;
    if (2.0 * check.median_sigma_relative > k_error_bar_limit) {
        check.converged = false;
        check.reasons.push_back("the error bars are wide: 2 sigma (median) is " +
                                format_number(200.0 * check.median_sigma_relative, "%.3g") +
                                " % of the height range (target " + format_number(100.0 * k_error_bar_limit, "%.0f") + " %)");
    }
}

bool needs_error_bars(const ConvergenceCheck& check) {
    return (check.floor == "poisson" || check.floor == "none") && check.converged;
}

std::string to_string(CheckErrorBars mode) {
    return mode == CheckErrorBars::Always ? "always" : mode == CheckErrorBars::Off ? "off" : "auto";
}

CheckErrorBars parse_check_error_bars(const std::string& text) {
    if (text == "auto") return CheckErrorBars::Auto;
    if (text == "always") return CheckErrorBars::Always;
    if (text == "off") return CheckErrorBars::Off;
    throw std::invalid_argument("check error bars '" + text + "' is invalid; expected auto, always or off");
}

bool check_error_bars_affordable(CheckErrorBars mode, double predicted_seconds, double run_seconds) {
    if (mode == CheckErrorBars::Always) return true;
    if (mode == CheckErrorBars::Off) return false;
    if (!(std::isfinite(predicted_seconds) && predicted_seconds >= 0.0)) return false;
    if (!(std::isfinite(run_seconds) && run_seconds >= 0.0)) return false;
    return predicted_seconds <= k_check_error_bars_budget * run_seconds;
}

bool check_error_bars_fit(double needed_bytes, double limit_bytes) {
    if (!(std::isfinite(needed_bytes) && needed_bytes >= 0.0)) return false;
    return needed_bytes <= limit_bytes;
}

void add_error_lower_bound(ConvergenceCheck& check, double bound_um, double height_range_um) {
    if (!(bound_um >= 0.0) || !(height_range_um > 0.0)) return;
    check.error_lower_bound_relative = bound_um / height_range_um;
    if (!(check.error_lower_bound_relative > k_predicted_error_limit)) return;
    check.converged = false;
    const std::string bound = std::isfinite(check.error_lower_bound_relative)
                                  ? "at least " + format_number(100.0 * check.error_lower_bound_relative, "%.3g") + " %"
                                  : "no bound (some texel no slice value depends on)";
    check.reasons.push_back(std::string(check.misfit_failed ? "" : "the misfit is on the photon-noise floor, but ") +
                            "the slices' Fisher information bounds the rms height error the error bars would predict "
                            "from below: " +
                            bound + " of the height range (target " + format_number(100.0 * k_predicted_error_limit, "%.0f") +
                            " %): the slices do not determine the heights that well at this photon count "
                            "(more photons, slices or wavelengths would)");
}

void add_predicted_error(ConvergenceCheck& check, const std::vector<double>& sigma_um, double height_range_um) {
    if (sigma_um.empty() || !(height_range_um > 0.0)) return;
    double sum = 0.0;
    for (const double s : sigma_um) sum += s * s;
    check.predicted_error_relative = std::sqrt(sum / double(sigma_um.size())) / height_range_um;
    if (!(check.predicted_error_relative > k_predicted_error_limit)) return;
    const bool wide_bars_said = !check.converged && check.median_sigma_relative >= 0.0 &&
                                2.0 * check.median_sigma_relative > k_error_bar_limit;
    check.converged = false;
    if (wide_bars_said) return;
    const std::string predicted = "the error bars predict an rms height error of " +
                                  format_number(100.0 * check.predicted_error_relative, "%.3g") +
                                  " % of the height range (target " + format_number(100.0 * k_predicted_error_limit, "%.0f") +
                                  " %)";
    if (check.floor == "none") {
        // No noise level stated: the bars' noise is the residuals' variance, so they are wide
        // both where the slices carry too little information and where the estimate leaves them
        // unexplained; either way the heights are not known to the target.
        check.reasons.push_back("the misfit is not judged (the loss states no noise level), but with the noise "
                                "estimated from the residuals " +
                                predicted +
                                ": the slices' noise, or what the estimate leaves unexplained, is too large for "
                                "the heights");
        return;
    }
    check.reasons.push_back(std::string(check.misfit_failed ? "" : "the misfit is on the photon-noise floor, but ") +
                            predicted +
                            ": the slices do not determine the heights that well at this photon count "
                            "(more photons, slices or wavelengths would)");
}

}  // namespace wavebrdf
