#include "wavebrdf/loss.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "core/text.h"

namespace wavebrdf {

namespace {

void check_epsilon(double epsilon, const std::string& what) {
    if (!(std::isfinite(epsilon) && epsilon > 0.0))
        throw std::domain_error("CMSLE epsilon must be finite and > 0, got " + what);
}

void check_photons(double photons, const std::string& what) {
    if (!(std::isfinite(photons) && photons > 0.0))
        throw std::domain_error("Poisson photons per slice must be finite and > 0, got " + what);
}

// Validates a (estimate, reference, channels) triple; returns the number of pixels.
template <typename Ref>
std::size_t check_slices(const char* function, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                         int channels) {
    const std::string where = std::string(function) + ": ";
    if (channels < 1) throw std::invalid_argument(where + "channels must be >= 1, got " + std::to_string(channels));
    if (estimate.size() != reference.size())
        throw std::invalid_argument(where + "estimate has " + std::to_string(estimate.size()) +
                                    " values but reference has " + std::to_string(reference.size()));
    if (estimate.empty()) throw std::invalid_argument(where + "the slices are empty");
    const auto c = static_cast<std::size_t>(channels);
    if (estimate.size() % c != 0)
        throw std::invalid_argument(where + "size " + std::to_string(estimate.size()) +
                                    " is not a multiple of channels = " + std::to_string(channels));
    return estimate.size() / c;
}

// Shared body of rgb_mse and rgb_gamma_mse: mean over all values of (T(I) − T(R))².
template <typename Ref, typename ToneMap>
double tone_mapped_mse(const char* function, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                       int channels, ToneMap tone_map) {
    check_slices(function, estimate, reference, channels);
    if (channels != 1 && channels != 3)
        throw std::invalid_argument(std::string(function) + ": channels must be 1 (mono) or 3 (RGB), got " +
                                    std::to_string(channels));
    // A grey pixel (v, v, v) contributes three equal terms, so for mono slices the mean over
    // pixels and RGB channels equals the mean over the mono values: both cases divide by size.
    double sum = 0.0;
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        const double d = tone_map(std::max(estimate[i], 0.0)) - tone_map(std::max(double(reference[i]), 0.0));
        sum += d * d;
    }
    return sum / static_cast<double>(estimate.size());
}

// Shared body of loss_value: `residual(e, r)` is the per-value difference whose square is
// summed, `derivative(e, r, d)` is ∂(d²)/∂e. The residuals are computed once, in a loop of
// their own (no sum in it, so it vectorises: the square roots and divisions of the amplitude
// loss), into the gradient's storage or a per-thread scratch; then the sum in index order and
// the gradient from the stored residuals. The same code runs whether or not the gradient is
// asked for, so the value is bit-for-bit the same either way (and the same as the earlier
// form, which computed each residual twice).
template <typename Ref, typename Residual, typename Derivative>
double mean_over_pixels(const std::vector<double>& estimate, const std::vector<Ref>& reference, double inv_pixels,
                        std::vector<double>* gradient, Residual residual, Derivative derivative) {
    const std::size_t n = estimate.size();
    thread_local std::vector<double> scratch;
    std::vector<double>& d = gradient ? *gradient : scratch;
    d.resize(n);
    const double* e = estimate.data();
    const Ref* r = reference.data();
    double* out = d.data();
    for (std::size_t i = 0; i < n; ++i) out[i] = residual(e[i], double(r[i]));
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) sum += out[i] * out[i];
    if (gradient)
        for (std::size_t i = 0; i < n; ++i) out[i] = derivative(e[i], double(r[i]), out[i]) * inv_pixels;
    return sum * inv_pixels;
}

}  // namespace

Loss parse_loss(const std::string& text) {
    const auto bad = [&]() {
        return std::invalid_argument("unknown loss '" + text +
                                     "'; expected 'cmsle', 'cmsle:EPS' (EPS > 0, e.g. cmsle:0.01), "
                                     "'mse', 'amplitude' or 'poisson:N' (N photons per slice, e.g. poisson:1e4)");
    };
    if (text == "mse") return {LossKind::MSE, 1.0};
    if (text == "amplitude") return {LossKind::Amplitude, 1.0};
    if (text == "cmsle") return {LossKind::CMSLE, 1.0};
    const auto starts_with = [&](const std::string& prefix) { return text.compare(0, prefix.size(), prefix) == 0; };
    if (starts_with("cmsle:")) {
        const double epsilon = detail::parse_number_from(text, 6, bad);
        check_epsilon(epsilon, "'" + text + "'");
        return {LossKind::CMSLE, epsilon};
    }
    if (starts_with("poisson:")) {
        const double photons = detail::parse_number_from(text, 8, bad);
        check_photons(photons, "'" + text + "'");
        return {LossKind::Poisson, 1.0, photons};
    }
    throw bad();
}

std::string to_string(const Loss& loss) {
    switch (loss.kind) {
        case LossKind::CMSLE: return "cmsle:" + detail::format_shortest(loss.epsilon);
        case LossKind::MSE: return "mse";
        case LossKind::Amplitude: return "amplitude";
        case LossKind::Poisson: return "poisson:" + detail::format_shortest(loss.photons);
    }
    throw std::invalid_argument("to_string: invalid LossKind " + std::to_string(static_cast<int>(loss.kind)));
}

namespace {

// loss_value for a reference in double or float (each value read as double).
template <typename Ref>
double loss_value_of(const Loss& loss, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                     int channels, std::vector<double>* gradient) {
    const std::size_t pixels = check_slices("loss_value", estimate, reference, channels);
    // Definition 3.2 normalises by |P| only (not |P|·|C|): each pixel's channel vector is one sample.
    const double inv_pixels = 1.0 / static_cast<double>(pixels);
    switch (loss.kind) {
        case LossKind::CMSLE: {
            const double eps = loss.epsilon;
            check_epsilon(eps, detail::format_shortest(eps));
            return mean_over_pixels(
                estimate, reference, inv_pixels, gradient,
                [eps](double e, double r) {
                    e = std::max(e, 0.0);
                    r = std::max(r, 0.0);
                    // log(e + ε) − log(r + ε) as log1p of the relative difference: exact to a
                    // few ulps also when e ≈ r, where the difference of two logs would cancel.
                    return std::log1p((e - r) / (r + eps));
                },
                // ∂/∂e (d²) = 2 d / (e + ε); zero where the clamp is active (e < 0).
                [eps](double e, double, double d) { return e >= 0.0 ? 2.0 * d / (e + eps) : 0.0; });
        }
        case LossKind::MSE:
            return mean_over_pixels(
                estimate, reference, inv_pixels, gradient, [](double e, double r) { return e - r; },
                [](double, double, double d) { return 2.0 * d; });
        case LossKind::Amplitude: {
            constexpr double tiny = 1e-30;  // keeps 1/√e finite at e = 0
            return mean_over_pixels(
                estimate, reference, inv_pixels, gradient,
                [](double e, double r) {
                    e = std::max(e, 0.0);
                    r = std::max(r, 0.0);
                    // √(e + δ) − √(r + δ) = (e − r) / (√(e + δ) + √(r + δ)), without cancellation.
                    return (e - r) / (std::sqrt(e + tiny) + std::sqrt(r + tiny));
                },
                // ∂/∂e (d²) = 2 d / (2 √(e + δ)); zero where the clamp is active (e < 0).
                [](double e, double, double d) { return e >= 0.0 ? d / std::sqrt(e + tiny) : 0.0; });
        }
        case LossKind::Poisson: {
            check_photons(loss.photons, detail::format_shortest(loss.photons));
            double total = 0.0;
            for (const auto r : reference) total += std::max(double(r), 0.0);
            if (!(total > 0.0))
                throw std::invalid_argument(
                    "loss_value: the Poisson loss needs a reference with a positive sum "
                    "(its photon scale N / sum), got sum " +
                    detail::format_shortest(total));
            const double s = loss.photons / total;
            // 1e-9 counts added to both k and μ keep log μ and 1/μ finite where I = 0 and the
            // loss exactly 0 where I = R.
            constexpr double tiny = 1e-9;
            const auto term = [s](double e, double r) {
                const double k = s * std::max(r, 0.0) + tiny, mu = s * std::max(e, 0.0) + tiny;
                // k log(k/μ) − (k − μ), with log1p for k ≈ μ (no cancellation).
                return 2.0 * (k * std::log1p((k - mu) / mu) - (k - mu));
            };
            double sum = 0.0;
            for (std::size_t i = 0; i < estimate.size(); ++i) sum += term(double(estimate[i]), double(reference[i]));
            if (gradient) {
                gradient->resize(estimate.size());
                for (std::size_t i = 0; i < estimate.size(); ++i) {
                    const double e = estimate[i];
                    const double k = s * std::max(double(reference[i]), 0.0) + tiny, mu = s * std::max(e, 0.0) + tiny;
                    // ∂/∂e = 2 s (1 − k/μ); zero where the clamp is active (e < 0).
                    (*gradient)[i] = e >= 0.0 ? 2.0 * s * (1.0 - k / mu) * inv_pixels : 0.0;
                }
            }
            return sum * inv_pixels;
        }
    }
    throw std::invalid_argument("loss_value: invalid LossKind " + std::to_string(static_cast<int>(loss.kind)));
}

// weighted_loss_value: `value_and_derivative(e, r, &d)` returns a value's term and sets d to its
// derivative in e; pixels of weight 0 are skipped (their values may be anything, NaN included).
template <typename Ref, typename Term>
double weighted_sum(const std::vector<double>& estimate, const std::vector<Ref>& reference, std::size_t channels,
                    const std::vector<float>& weights, double inv_weight, std::vector<double>* gradient, Term term) {
    if (gradient) gradient->assign(estimate.size(), 0.0);
    double sum = 0.0;
    for (std::size_t p = 0; p < weights.size(); ++p) {
        const double w = static_cast<double>(weights[p]);
        if (w == 0.0) continue;
        for (std::size_t c = 0; c < channels; ++c) {
            const std::size_t i = p * channels + c;
            double d = 0.0;
            sum += w * term(estimate[i], double(reference[i]), d);
            if (gradient) (*gradient)[i] = d * w * inv_weight;
        }
    }
    return sum * inv_weight;
}

template <typename Ref>
double weighted_loss_of(const Loss& loss, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                        int channels, const std::vector<float>& weights, std::vector<double>* gradient) {
    const std::size_t pixels = check_slices("weighted_loss_value", estimate, reference, channels);
    if (weights.size() != pixels)
        throw std::invalid_argument("weighted_loss_value: " + std::to_string(weights.size()) +
                                    " weights; expected one per pixel, " + std::to_string(pixels));
    double total_weight = 0.0;
    for (std::size_t p = 0; p < pixels; ++p) {
        if (!(std::isfinite(weights[p]) && weights[p] >= 0.0f))
            throw std::invalid_argument("weighted_loss_value: weight " + std::to_string(p) + " is " +
                                        detail::format_shortest(double(weights[p])) +
                                        "; expected a finite weight >= 0");
        total_weight += double(weights[p]);
    }
    if (!(total_weight > 0.0))
        throw std::invalid_argument(
            "weighted_loss_value: every weight is 0; expected at least one pixel of weight > 0");
    const double inv_weight = 1.0 / total_weight;
    const std::size_t c = static_cast<std::size_t>(channels);
    switch (loss.kind) {
        case LossKind::CMSLE: {
            const double eps = loss.epsilon;
            check_epsilon(eps, detail::format_shortest(eps));
            return weighted_sum(
                estimate, reference, c, weights, inv_weight, gradient, [eps](double e, double r, double& de) {
                    const double d = std::log1p((std::max(e, 0.0) - std::max(r, 0.0)) / (std::max(r, 0.0) + eps));
                    de = e >= 0.0 ? 2.0 * d / (e + eps) : 0.0;
                    return d * d;
                });
        }
        case LossKind::MSE:
            return weighted_sum(estimate, reference, c, weights, inv_weight, gradient,
                                [](double e, double r, double& de) {
                                    de = 2.0 * (e - r);
                                    return (e - r) * (e - r);
                                });
        case LossKind::Amplitude: {
            constexpr double tiny = 1e-30;  // as loss_value's
            return weighted_sum(estimate, reference, c, weights, inv_weight, gradient,
                                [](double e, double r, double& de) {
                                    const double ec = std::max(e, 0.0), rc = std::max(r, 0.0);
                                    const double d = (ec - rc) / (std::sqrt(ec + tiny) + std::sqrt(rc + tiny));
                                    de = e >= 0.0 ? d / std::sqrt(e + tiny) : 0.0;
                                    return d * d;
                                });
        }
        case LossKind::Poisson: {
            check_photons(loss.photons, detail::format_shortest(loss.photons));
            double total = 0.0;
            for (std::size_t p = 0; p < pixels; ++p)
                if (weights[p] != 0.0f)
                    for (std::size_t k = 0; k < c; ++k) total += std::max(double(reference[p * c + k]), 0.0);
            if (!(total > 0.0))
                throw std::invalid_argument(
                    "weighted_loss_value: the Poisson loss needs a reference with a positive sum over the pixels of "
                    "weight > 0, got sum " +
                    detail::format_shortest(total));
            const double s = loss.photons / total;
            constexpr double tiny = 1e-9;  // as loss_value's
            return weighted_sum(estimate, reference, c, weights, inv_weight, gradient,
                                [s](double e, double r, double& de) {
                                    const double k = s * std::max(r, 0.0) + tiny, mu = s * std::max(e, 0.0) + tiny;
                                    de = e >= 0.0 ? 2.0 * s * (1.0 - k / mu) : 0.0;
                                    return 2.0 * (k * std::log1p((k - mu) / mu) - (k - mu));
                                });
        }
    }
    throw std::invalid_argument("weighted_loss_value: invalid LossKind " + std::to_string(static_cast<int>(loss.kind)));
}

double reinhard(double x) { return x / (1.0 + x); }
double reinhard_gamma(double x) { return std::pow(x / (1.0 + x), 1.0 / 2.2); }

}  // namespace

double loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<double>& reference,
                  int channels, std::vector<double>* gradient) {
    return loss_value_of(loss, estimate, reference, channels, gradient);
}

template <typename Ref, typename>
double loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<Ref>& reference,
                  int channels, std::vector<double>* gradient) {
    return loss_value_of(loss, estimate, reference, channels, gradient);
}
template double loss_value<float>(const Loss&, const std::vector<double>&, const std::vector<float>&, int,
                                  std::vector<double>*);

double weighted_loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<float>& reference,
                           int channels, const std::vector<float>& weights, std::vector<double>* gradient) {
    return weighted_loss_of(loss, estimate, reference, channels, weights, gradient);
}

double weighted_loss_value(const Loss& loss, const std::vector<double>& estimate, const std::vector<double>& reference,
                           int channels, const std::vector<float>& weights, std::vector<double>* gradient) {
    return weighted_loss_of(loss, estimate, reference, channels, weights, gradient);
}

double rgb_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels) {
    return tone_mapped_mse("rgb_mse", estimate, reference, channels, reinhard);
}

template <typename Ref, typename>
double rgb_mse(const std::vector<double>& estimate, const std::vector<Ref>& reference, int channels) {
    return tone_mapped_mse("rgb_mse", estimate, reference, channels, reinhard);
}
template double rgb_mse<float>(const std::vector<double>&, const std::vector<float>&, int);

double rgb_gamma_mse(const std::vector<double>& estimate, const std::vector<double>& reference, int channels) {
    return tone_mapped_mse("rgb_gamma_mse", estimate, reference, channels, reinhard_gamma);
}

template <typename Ref, typename>
double rgb_gamma_mse(const std::vector<double>& estimate, const std::vector<Ref>& reference, int channels) {
    return tone_mapped_mse("rgb_gamma_mse", estimate, reference, channels, reinhard_gamma);
}
template double rgb_gamma_mse<float>(const std::vector<double>&, const std::vector<float>&, int);

double height_mse(const std::vector<double>& estimate, const std::vector<double>& truth) {
    if (estimate.size() != truth.size())
        throw std::invalid_argument("height_mse: estimate has " + std::to_string(estimate.size()) +
                                    " heights but truth has " + std::to_string(truth.size()));
    if (estimate.empty()) throw std::invalid_argument("height_mse: the heightfields are empty");
    const double n = static_cast<double>(estimate.size());
    double mean_e = 0.0, mean_t = 0.0;
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        mean_e += estimate[i];
        mean_t += truth[i];
    }
    mean_e /= n;
    mean_t /= n;
    // Two passes: subtracting the means before squaring keeps large common offsets from
    // swamping the differences.
    double sum = 0.0;
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        const double d = (estimate[i] - mean_e) - (truth[i] - mean_t);
        sum += d * d;
    }
    return sum / n;
}

}  // namespace wavebrdf
