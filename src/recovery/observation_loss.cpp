// The recovery's observation loss (observation_loss.h).
#include "recovery/observation_loss.h"

#include <algorithm>

#include "core/exact_sum.h"
#include "recovery/calibration_detail.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::detail {

Query calibrated_query(const Observation& o, double sigma_scale, const std::array<double, 2>* offset_um) {
    Query query = o.query;
    if (offset_um) {
        query.x_um += (*offset_um)[0];
        query.y_um += (*offset_um)[1];
    }
    query.sigma_p_um *= sigma_scale;
    return query;
}

double observation_exposure(const std::vector<float>& f, const Observation& o) {
    const std::size_t n = std::min(f.size(), o.reference.size());
    if (o.weights.empty()) return slice_exposure(f.data(), o.reference.data(), n);
    double r = 0.0, m = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double w = value_weight(o, k);
        if (w == 0.0) continue;  // its reference may be anything
        r += w * std::max(double(o.reference[k]), 0.0);
        m += w * std::max(double(f[k]), 0.0);
    }
    return m > 0.0 ? r / m : 1.0;
}

void observation_exposure_gradient(double exposure, const std::vector<float>& f, const Observation& o,
                                   std::vector<double>& d) {
    const std::size_t n = std::min(f.size(), o.reference.size());
    if (o.weights.empty()) {
        exposure_gradient(exposure, f.data(), n, d);
        return;
    }
    // a = Σ w R / Σ w f₊: ∂a/∂f_k = −a w_k / Σ w f₊ where f_k > 0.
    double m = 0.0, df = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double w = value_weight(o, k), fk = std::max(double(f[k]), 0.0);
        m += w * fk;
        df += d[k] * fk;
    }
    const double shift = m > 0.0 ? exposure * df / m : 0.0;
    for (std::size_t k = 0; k < n; ++k) d[k] = exposure * d[k] - (f[k] > 0.0f ? value_weight(o, k) * shift : 0.0);
}

double slice_misfit(const Loss& loss, const std::vector<float>& f, const Observation& o, bool calibrate_exposure,
                    std::vector<double>* d_f, double* exposure_out) {
    std::vector<double> model(f.begin(), f.end());
    double exposure = 1.0;
    if (calibrate_exposure) {
        exposure = observation_exposure(f, o);
        for (double& m : model) m *= exposure;
    }
    if (exposure_out) *exposure_out = exposure;
    const double v = observation_slice_loss(loss, model, o, d_f);
    if (d_f && calibrate_exposure) observation_exposure_gradient(exposure, f, o, *d_f);
    return v;
}

double observation_misfit(const Heightfield& heights, const Observation& o, const Loss& loss, double sigma_scale,
                          const std::array<double, 2>* offset_um, bool calibrate_exposure, bool differentiable) {
    SlicePlan<float> plan(heights, calibrated_query(o, sigma_scale, offset_um), o.lambdas_um, o.resolution,
                          o.channels(), {}, differentiable);
    return slice_misfit(loss, plan.forward(), o, calibrate_exposure);
}

double mean_observation_loss(const std::vector<Observation>& observations, double observations_total,
                             const Heightfield& heights, const Loss& loss, const Communicator& comm) {
    std::vector<double> no_gradient;
    ExactParallelSum exact(0);
    return exact.run(observations.size(), comm, no_gradient,
                     [&](std::size_t i, ExactScratch&) {
                         return observation_loss(heights, {observations[i]}, loss, nullptr);
                     }) /
           observations_total;
}

bool any_weights(const std::vector<Observation>& observations) {
    for (const Observation& o : observations)
        if (!o.weights.empty()) return true;
    return false;
}

std::vector<Observation> filled_observations(const std::vector<Observation>& observations) {
    std::vector<Observation> out = observations;
    for (Observation& o : out) {
        if (o.weights.empty()) continue;
        const int n = o.resolution, channels = o.channels();
        const std::vector<float>& w = o.weights;
        const std::vector<float> given = o.reference;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c) {
                if (w[std::size_t(r) * n + c] != 0.0f) continue;
                // The smallest window about (r, c) that holds a pixel of weight > 0 (one
                // exists: validate refuses all-zero weights).
                for (int reach = 1; reach < n; ++reach) {
                    std::vector<double> sum(std::size_t(channels), 0.0);
                    int count = 0;
                    for (int a = std::max(0, r - reach); a <= std::min(n - 1, r + reach); ++a)
                        for (int b = std::max(0, c - reach); b <= std::min(n - 1, c + reach); ++b) {
                            const std::size_t p = std::size_t(a) * n + b;
                            if (w[p] == 0.0f) continue;
                            for (int k = 0; k < channels; ++k)
                                sum[std::size_t(k)] += double(given[p * std::size_t(channels) + std::size_t(k)]);
                            ++count;
                        }
                    if (count == 0) continue;
                    const std::size_t p = std::size_t(r) * n + c;
                    for (int k = 0; k < channels; ++k)
                        o.reference[p * std::size_t(channels) + std::size_t(k)] = float(sum[std::size_t(k)] / count);
                    break;
                }
            }
    }
    return out;
}

}  // namespace wavebrdf::detail
