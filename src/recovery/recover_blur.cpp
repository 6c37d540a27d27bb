// Stage 0 of the recovery: heights that match blurred slices.
//
// Blurring a slice in u by a Gaussian wider than its interference detail (the footprint's own
// lobe, std 1/(2√2 π σ_p) in u) leaves the distribution of reflected directions: the window-
// weighted histogram of slopes, the geometric-optics limit. Its loss is smooth in the heights
// (no λ/2 wrapping), so L-BFGS from a flat start finds the heights' shape; narrowing the blur
// step by step brings in finer detail. The result is close enough (a few % of the range) for
// the field stage to start from.
//
// The model slice is rendered at the observation's resolution and blurred there (a coarser
// rendering would alias: |I|² is band-limited only to the window's autocorrelation, 2·6σ_p).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "wavebrdf/adjoint.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/slice_plan.h"

#include "core/stall_rule.h"
#include "core/denormals.h"
#include "core/exact_sum.h"
#include "core/parallel.h"

namespace wavebrdf {

namespace {

// B[p, f] = G_β(u'_p − u_f) Δu_f: the Gaussian of std β (cycles/µm) from a grid of n_from slice
// pixels to one of n_to, both over the same disk at wavelength λ (u = (ω_i + ω_o)/λ; ω_i cancels).
Eigen::MatrixXd blur_matrix(int n_to, int n_from, double lambda_um, double beta) {
    Eigen::MatrixXd b(n_to, n_from);
    const double du = 2.0 / (n_from * lambda_um);
    const double norm = du / (std::sqrt(2.0 * k_pi) * beta);
    for (int p = 0; p < n_to; ++p)
        for (int f = 0; f < n_from; ++f) {
            const double d = (slice_omega(p, n_to) - slice_omega(f, n_from)) / lambda_um;
            b(p, f) = norm * std::exp(-0.5 * d * d / (beta * beta));
        }
    return b;
}

// Channel c of a row-major, channel-interleaved n × n slice of `channels` values per pixel.
template <typename T>
Eigen::MatrixXd as_matrix(const std::vector<T>& v, int n, int channels = 1, int c = 0) {
    Eigen::MatrixXd m(n, n);
    for (int p = 0; p < n; ++p)
        for (int q = 0; q < n; ++q) m(p, q) = double(v[(std::size_t(p) * n + q) * channels + c]);
    return m;
}

// The same for the model's float slice.
Eigen::MatrixXf channel_of(const std::vector<float>& v, int n, int channels, int c) {
    Eigen::MatrixXf m(n, n);
    for (int p = 0; p < n; ++p)
        for (int q = 0; q < n; ++q) m(p, q) = v[(std::size_t(p) * n + q) * channels + c];
    return m;
}

}  // namespace

double white_light_lambda_um(const std::vector<double>& lambdas_um) {
    if (lambdas_um.empty()) throw std::invalid_argument("white_light_lambda_um: no wavelength given");
    double sum = 0.0;
    for (double l : lambdas_um) sum += l;
    return sum / double(lambdas_um.size());
}

Heightfield fit_blurred(const std::vector<Observation>& observations, const Heightfield& initial,
                        const BlurredFitSettings& settings, const std::function<bool(int, int, double)>& on_iteration,
                        const Communicator& comm) {
    std::vector<const Observation*> all(observations.size());
    for (std::size_t i = 0; i < observations.size(); ++i) all[i] = &observations[i];
    return fit_blurred(all, initial, settings, on_iteration, comm);
}

namespace {

void check_blurred_settings(const BlurredFitSettings& settings) {
    if (settings.iterations < 0 || settings.history < 1)
        throw std::domain_error("fit_blurred: iterations " + std::to_string(settings.iterations) + " / history " +
                                std::to_string(settings.history) + " invalid; expected >= 0 / >= 1");
    if (!settings.width_iterations.empty() && settings.width_iterations.size() != settings.blur_widths.size())
        throw std::invalid_argument("fit_blurred: " + std::to_string(settings.width_iterations.size()) +
                                    " width iterations for " + std::to_string(settings.blur_widths.size()) +
                                    " blur widths; expected one per width (or none)");
    for (int k : settings.width_iterations)
        if (k < 0) throw std::domain_error("fit_blurred: width iterations " + std::to_string(k) + "; expected >= 0");
    if (settings.stall_window < 0 || !(settings.stall_tolerance >= 0.0 && std::isfinite(settings.stall_tolerance)))
        throw std::domain_error("fit_blurred: stall window " + std::to_string(settings.stall_window) + " / tolerance " +
                                std::to_string(settings.stall_tolerance) + " invalid; expected >= 0 / finite >= 0");
    for (double b : settings.blur_widths)
        if (!(b > 0.0) || !std::isfinite(b))
            throw std::domain_error("fit_blurred: blur width " + std::to_string(b) + " is invalid; expected > 0");
}

// This rank's observations (its share under MPI: every sum below is allreduced): the
// single-wavelength ones, or, when no rank has any, the RGB ones (white light: each channel
// blurred alike in ω).
std::vector<const Observation*> blurred_fit_observations(const std::vector<const Observation*>& observations,
                                                         const Communicator& comm) {
    std::vector<const Observation*> used, rgb;
    run_agreed(comm, [&] {
        for (std::size_t i = 0; i < observations.size(); ++i) {
            if (!observations[i])
                throw std::invalid_argument("fit_blurred: observation " + std::to_string(i) + " is null");
            validate(*observations[i], i);
            (observations[i]->lambdas_um.size() == 1 ? used : rgb).push_back(observations[i]);
        }
    });
    std::vector<double> used_count{double(used.size()), double(rgb.size())};
    comm.allreduce_sum(used_count);
    if (used_count[0] == 0.0) {
        if (used_count[1] == 0.0) throw std::invalid_argument("fit_blurred: no observation given");
        used = std::move(rgb);
    }
    return used;
}

// One blur width's data. Per observation: its blur matrix (shared by every observation of the
// same resolution, wavelength and blur width) and the square root of its blurred reference.
struct BlurMatrix {
    int n;
    double lambda_um, beta;
    Eigen::MatrixXd blur;        // n × n
    Eigen::MatrixXf blur_float;  // the same in single precision (the products are half an evaluation)
};
struct Blurred {
    std::size_t matrix;                           // into `matrices`
    std::vector<Eigen::MatrixXd> sqrt_reference;  // per channel, n × n: √(B R Bᵀ)
};
struct BlurredWidth {
    std::vector<BlurMatrix> matrices;
    std::vector<Blurred> data;
    std::vector<double> totals;         // per observation: Σ B R Bᵀ
    double inv_total = 0.0;             // 1 / every rank's Σ of the totals
    std::vector<double> root_exposures; // per observation: √e, fixed for the width
};

// The fit over every blur width: one slice plan per observation for all widths and iterations
// (single precision: these stages only need the shape, and are the costliest); only the heights
// change.
class BlurredFit {
public:
    BlurredFit(std::vector<const Observation*> used, const Heightfield& initial, const BlurredFitSettings& settings,
               const Communicator& comm)
        : m_used(std::move(used)),
          m_settings(settings),
          m_comm(comm),
          m_cols(std::size_t(initial.cols())),
          m_box_rows(m_used.size()),
          m_box_cols(m_used.size()),
          m_exact_sum(initial.values().size()) {
        m_plans.reserve(m_used.size());
        for (const Observation* o : m_used)
            m_plans.emplace_back(initial, o->query, o->lambdas_um, o->resolution, o->channels());
        // The texels each plan's adjoint writes (its box for the exact sums).
        for (std::size_t i = 0; i < m_used.size(); ++i) m_plans[i].gradient_box(m_box_rows[i], m_box_cols[i]);
    }

    // The blurred references at width `width` and, with calibrate_exposure, the exposures at
    // heights h.
    BlurredWidth prepare(double width, const std::vector<double>& h);
    // L = Σ_obs Σ (√M_b − √R_b)² / Σ R_b, M_b = B M Bᵀ of the coarse model slice M, at heights x.
    double loss(const BlurredWidth& w, const std::vector<double>& x, std::vector<double>& grad);
    // L-BFGS on one width from h (updated); false when the caller asked to stop.
    bool fit(int stage, int iterations, const BlurredWidth& w, std::vector<double>& h,
             const std::function<bool(int, int, double)>& on_iteration);

private:
    std::vector<const Observation*> m_used;
    const BlurredFitSettings& m_settings;
    const Communicator& m_comm;
    std::size_t m_cols;
    std::vector<SlicePlan<float>> m_plans;
    std::vector<std::vector<int>> m_box_rows, m_box_cols;
    detail::ExactParallelSum m_exact_sum;
};

BlurredWidth BlurredFit::prepare(double width, const std::vector<double>& h) {
    BlurredWidth w;
    w.data.resize(m_used.size());
    w.totals.resize(m_used.size());
    for (std::size_t i = 0; i < m_used.size(); ++i) {
        const Observation& o = *m_used[i];
        // The blur is a width in ω (the slope distribution is the same at every wavelength):
        // an RGB slice is blurred as one at the mean of its wavelengths.
        const double lambda = white_light_lambda_um(o.lambdas_um);
        // The footprint's lobe: |c|² has std σ_p/√2, so its far field intensity has
        // std 1/(2√2 π σ_p) in u.
        const double beta = width / (2.0 * std::sqrt(2.0) * k_pi * o.query.sigma_p_um);
        const int n = o.resolution;
        std::size_t m = 0;
        while (m < w.matrices.size() &&
               !(w.matrices[m].n == n && w.matrices[m].lambda_um == lambda && w.matrices[m].beta == beta))
            ++m;
        if (m == w.matrices.size()) {
            Eigen::MatrixXd b = blur_matrix(n, n, lambda, beta);
            Eigen::MatrixXf bf = b.cast<float>();
            w.matrices.push_back(BlurMatrix{n, lambda, beta, std::move(b), std::move(bf)});
        }
        const Eigen::MatrixXd& to_coarse = w.matrices[m].blur;
        Blurred& d = w.data[i];
        d.matrix = m;
        const int channels = o.channels();
        w.totals[i] = 0.0;
        for (int c = 0; c < channels; ++c) {
            Eigen::MatrixXd r =
                to_coarse * as_matrix(o.reference, n, channels, c).cwiseMax(0.0) * to_coarse.transpose();
            w.totals[i] += r.sum();
            d.sqrt_reference.push_back(r.cwiseSqrt());
        }
    }
    const double total = detail::exact_total(w.totals, m_comm);  // every rank's, in any order
    if (!(total > 0.0)) throw std::invalid_argument("fit_blurred: every reference slice is zero");
    w.inv_total = 1.0 / total;

    // Self-calibrated exposures e = Σ R_b / Σ M_b (the ratio of the energies,
    // calibration_detail.h) at the stage's starting heights, fixed during the stage:
    // re-estimated at every evaluation they let the blurred fit drift (measured: 5.3 %
    // instead of 2.2 % on exact data), fixed they cost nothing where the energy does not
    // depend on the heights.
    w.root_exposures.assign(m_used.size(), 1.0);
    if (m_settings.calibrate_exposure)
        for (std::size_t i = 0; i < m_used.size(); ++i) {
            const detail::FlushDenormals flush;  // the blur's float tails (core/denormals.h)
            const Eigen::MatrixXf& blur = w.matrices[w.data[i].matrix].blur_float;
            const int n = int(blur.rows());
            m_plans[i].set_heights(h);
            const std::vector<float>& f = m_plans[i].forward();
            const int channels = m_plans[i].channels();
            double model_total = 0.0;
            for (int c = 0; c < channels; ++c) {
                const Eigen::MatrixXf m = blur * channel_of(f, n, channels, c) * blur.transpose();
                for (int p = 0; p < n; ++p)
                    for (int q = 0; q < n; ++q) model_total += std::max(double(m(p, q)), 0.0);
            }
            m_plans[i].release();
            if (model_total > 0.0) w.root_exposures[i] = std::sqrt(w.totals[i] / model_total);
        }
    return w;
}

double BlurredFit::loss(const BlurredWidth& w, const std::vector<double>& x, std::vector<double>& grad) {
    // Every rank's observations, exactly: the same for any thread count and split over
    // ranks (core/exact_sum.h).
    return m_exact_sum.run(m_used.size(), m_comm, grad, [&](std::size_t i, detail::ExactScratch& scratch) {
        // The narrow blurs' Gaussian tails and the model's far pixels are denormal in
        // float: ~30× slower products without this (core/denormals.h).
        const detail::FlushDenormals flush;
        const Blurred& d = w.data[i];
        const Eigen::MatrixXf& blur = w.matrices[d.matrix].blur_float;
        const int n = int(blur.rows());
        SlicePlan<float>& plan = m_plans[i];
        plan.set_heights(x);
        const std::vector<float>& f = plan.forward();
        const int channels = plan.channels();
        // Self-calibrated exposure: the model scaled by √e, e fixed for the stage.
        const double root_exposure = m_settings.calibrate_exposure ? w.root_exposures[i] : 1.0;
        double v = 0.0;
        std::vector<float> weights(std::size_t(n) * n);
        std::vector<double> rgb_weights(channels == 1 ? 0 : std::size_t(n) * n * channels);
        for (int c = 0; c < channels; ++c) {
            const Eigen::MatrixXf m = blur * channel_of(f, n, channels, c) * blur.transpose();
            Eigen::MatrixXf dm(n, n);
            // Per pixel in storage order (columns: the square roots and divisions
            // vectorise), the differences kept; then their squares summed in the
            // original row order, so the loss is the same bits as one fused loop.
            thread_local Eigen::MatrixXd diffs;
            diffs.resize(n, n);
            const Eigen::MatrixXd& sqrt_reference = d.sqrt_reference[std::size_t(c)];
            for (int q = 0; q < n; ++q)
                for (int p = 0; p < n; ++p) {
                    const double mpq = double(m(p, q));
                    const double a = std::sqrt(std::max(mpq, 0.0) + 1e-300);
                    const double diff = root_exposure * a - sqrt_reference(p, q);
                    diffs(p, q) = diff;
                    dm(p, q) = mpq > 0.0 ? float(w.inv_total * diff * root_exposure / a) : 0.0f;
                }
            for (int p = 0; p < n; ++p)
                for (int q = 0; q < n; ++q) v += diffs(p, q) * diffs(p, q);
            const Eigen::MatrixXf wb = blur.transpose() * dm * blur;
            for (int p = 0; p < n; ++p)
                for (int q = 0; q < n; ++q) {
                    if (channels == 1)
                        weights[std::size_t(p) * n + q] = wb(p, q);
                    else
                        rgb_weights[(std::size_t(p) * n + q) * channels + c] = double(wb(p, q));
                }
        }
        const double term = v * w.inv_total;
        if (channels == 1)
            plan.adjoint_wavelength(0, weights, scratch.vector());
        else
            plan.adjoint(rgb_weights, scratch.vector());
        scratch.take_box(m_box_rows[i], m_box_cols[i], m_cols);
        // Only the height-independent tables stay between iterations.
        plan.release();
        return term;
    });
}

bool BlurredFit::fit(int stage, int iterations, const BlurredWidth& w, std::vector<double>& h,
                     const std::function<bool(int, int, double)>& on_iteration) {
    LbfgsOptions lo;
    lo.history = m_settings.history;
    lo.max_iterations = iterations;
    lo.gradient_tolerance = 0.0;
    bool go_on = true;
    detail::StallRule stall(m_settings.stall_window, m_settings.stall_tolerance);
    // L-BFGS takes its steps without curvature pairs as min(1, 1/‖g‖)·(−g): at most 1 in norm.
    // From flat heights the blurred loss is not convex (the pairs are skipped), and on a
    // 64² tile that is 1/64 texel rms per iteration: ~30 of stage 0's 40 iterations crawled
    // (experiments/2026-11-23-recovery-speed.md). Fitted in h / scale, those steps move the
    // heights by at most `scale` (1/8 texel rms); with pairs L-BFGS does not see the scale.
    // Only from 64² texels on (where it was measured): smaller tiles fit as before, bit for bit.
    const double scale = h.size() >= 4096 ? std::sqrt(double(h.size())) / 8.0 : 1.0;
    std::vector<double> x(h.size()), at(h.size());
    for (std::size_t k = 0; k < h.size(); ++k) x[k] = h[k] / scale;
    const auto scaled = [&](const std::vector<double>& y, std::vector<double>& grad) {
        for (std::size_t k = 0; k < y.size(); ++k) at[k] = y[k] * scale;
        const double v = loss(w, at, grad);
        for (double& gk : grad) gk *= scale;
        return v;
    };
    lbfgs_minimize(scaled, x, lo, [&](int it, double value) {
        if (on_iteration && !on_iteration(stage, it, value)) go_on = false;
        go_on = !m_comm.any(!go_on);  // every rank stops at the same iteration
        if (stall.stalled_at(value)) return false;  // stalled: the next width
        return go_on;
    });
    for (std::size_t k = 0; k < h.size(); ++k) h[k] = x[k] * scale;
    return go_on;
}

}  // namespace

Heightfield fit_blurred(const std::vector<const Observation*>& observations, const Heightfield& initial,
                        const BlurredFitSettings& settings, const std::function<bool(int, int, double)>& on_iteration,
                        const Communicator& comm) {
    check_blurred_settings(settings);
    BlurredFit fit(blurred_fit_observations(observations, comm), initial, settings, comm);
    std::vector<double> h = initial.values();
    for (std::size_t stage = 0; stage < settings.blur_widths.size(); ++stage) {
        const int stage_iterations = settings.width_iterations.empty() ? settings.iterations
                                                                       : settings.width_iterations[stage];
        if (stage_iterations == 0) continue;
        const BlurredWidth w = fit.prepare(settings.blur_widths[stage], h);
        if (!fit.fit(int(stage), stage_iterations, w, h, on_iteration)) break;
    }
    return initial.with_values(h);
}

}  // namespace wavebrdf
