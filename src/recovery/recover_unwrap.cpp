// Stage 2 of the recovery: heights from the phases of fields at several wavelengths.
//
// The field at λ has the phase θ_k = −(4π/λ)H_k + φ_λ (mod 2π), φ_λ unknown. For two
// wavelengths λa < λb the product z_a conj(z_b) has the phase −(4π/Λ)H_k + const with the
// synthetic wavelength Λ = λa λb / (λb − λa) (classical two-wavelength interferometry, e.g.
// Wyant, Appl. Opt. 10, 2113 (1971); hierarchical: Cheng and Wyant, Appl. Opt. 24, 3049
// (1985)). So the "channels" are the single wavelengths and all pairs; each determines H
// modulo Λ/2. Coarse to fine: the coarsest channel whose Λ/2 covers the height range gives H
// up to a constant (cut where the phases leave their largest gap); every finer channel then
// picks, per texel, the branch nearest the current estimate. A joint Gauss–Newton fit of H and
// the global phases over the single wavelengths ends it.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <fftw3.h>

#include "core/fftw_planner.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/recover.h"

namespace wavebrdf {

namespace {

double wrap_phase(double a) { return a - 2.0 * k_pi * std::floor(a / (2.0 * k_pi) + 0.5); }

struct Channel {
    double lambda_um;                     // (synthetic) wavelength Λ
    std::vector<std::complex<double>> z;  // phase −(4π/Λ)H + const
};

// Phase offset ψ that best aligns channel z with heights H: arg Σ_k z_k e^{+i(4π/Λ)H_k}.
double align(const Channel& c, const std::vector<double>& heights) {
    std::complex<double> sum = 0.0;
    for (std::size_t k = 0; k < heights.size(); ++k)
        sum += c.z[k] * std::polar(1.0, 4.0 * k_pi / c.lambda_um * heights[k]);
    return std::arg(sum);
}

// Heights from one channel alone, cut where its phases have their widest empty arc, so that a
// range below Λ/2 unwraps without a jump. Texels of weight 0 stay at 0.
std::vector<double> coarse_heights(const Channel& c) {
    std::vector<double> phases;
    for (const auto& v : c.z)
        if (std::abs(v) > 0.0) phases.push_back(std::arg(v));
    std::vector<double> heights(c.z.size(), 0.0);
    if (phases.empty()) return heights;
    std::sort(phases.begin(), phases.end());
    double gap = phases.front() + 2.0 * k_pi - phases.back(), cut = phases.back() + 0.5 * gap;
    for (std::size_t i = 1; i < phases.size(); ++i)
        if (phases[i] - phases[i - 1] > gap) {
            gap = phases[i] - phases[i - 1];
            cut = phases[i - 1] + 0.5 * gap;
        }
    // Phases measured from the cut lie in (0, 2π); H = −(Λ/4π)·phase.
    for (std::size_t k = 0; k < c.z.size(); ++k) {
        if (!(std::abs(c.z[k]) > 0.0)) continue;
        double a = std::arg(c.z[k]) - cut;
        a -= 2.0 * k_pi * std::floor(a / (2.0 * k_pi));
        heights[k] = -c.lambda_um / (4.0 * k_pi) * a;
    }
    return heights;
}

void remove_mean(std::vector<double>& h) {
    double mean = 0.0;
    for (double v : h) mean += v;
    mean /= double(h.size());
    for (double& v : h) v -= mean;
}

// Least-squares integration of height differences on a periodic rows × cols grid: the H with
// Σ (H[i+1,j] − H[i,j] − gx[i,j])² + (H[i,j+1] − H[i,j] − gy[i,j])² minimal, i.e. the periodic
// Poisson equation ΔH = div g, solved with the DFT (Ghiglia and Romero, JOSA A 11, 107 (1994),
// for the periodic case). Mean 0.
std::vector<double> integrate_differences(int rows, int cols, const std::vector<double>& gx,
                                          const std::vector<double>& gy) {
    const std::size_t total = std::size_t(rows) * cols;
    std::vector<std::complex<double>> div(total);
    const auto at = [cols](int i, int j) { return std::size_t(i) * cols + j; };
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const int im = (i + rows - 1) % rows, jm = (j + cols - 1) % cols;
            div[at(i, j)] = gx[at(i, j)] - gx[at(im, j)] + gy[at(i, j)] - gy[at(i, jm)];
        }
    fftw_plan forward = nullptr, backward = nullptr;
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        {
            auto* data = reinterpret_cast<fftw_complex*>(div.data());
            forward = fftw_plan_dft_2d(rows, cols, data, data, FFTW_FORWARD, FFTW_ESTIMATE);
            backward = fftw_plan_dft_2d(rows, cols, data, data, FFTW_BACKWARD, FFTW_ESTIMATE);
        }
    }
    fftw_execute(forward);
    for (int a = 0; a < rows; ++a)
        for (int b = 0; b < cols; ++b) {
            // Eigenvalue of the periodic 5-point Laplacian for the mode (a, b).
            const double lap = 2.0 * std::cos(2.0 * k_pi * a / rows) - 2.0 + 2.0 * std::cos(2.0 * k_pi * b / cols) -
                               2.0;
            div[at(a, b)] = (a == 0 && b == 0) || lap == 0.0 ? 0.0 : div[at(a, b)] / lap;
        }
    fftw_execute(backward);
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        fftw_destroy_plan(forward);
        fftw_destroy_plan(backward);
    }
    std::vector<double> h(total);
    for (std::size_t k = 0; k < total; ++k) h[k] = div[k].real() / double(total);
    return h;
}

// Heights from the wrapped phase differences between neighbouring samples, averaged over the
// wavelengths (weighted by the product of the neighbours' amplitudes and by (4π/λ)², i.e. by
// each wavelength's height resolution) and integrated in the least-squares sense. Valid where
// neighbouring samples differ by less than π in phase at every wavelength.
std::vector<double> spatial_heights(const std::vector<double>& lambdas_um,
                                    const std::vector<std::vector<std::complex<double>>>& fields, int rows, int cols) {
    const std::size_t total = std::size_t(rows) * cols;
    std::vector<double> gx(total, 0.0), gy(total, 0.0);
    const auto at = [cols](int i, int j) { return std::size_t(i) * cols + j; };
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const std::size_t k = at(i, j), kx = at((i + 1) % rows, j), ky = at(i, (j + 1) % cols);
            double sx = 0.0, wx = 0.0, sy = 0.0, wy = 0.0;
            for (std::size_t l = 0; l < fields.size(); ++l) {
                const double kappa = 4.0 * k_pi / lambdas_um[l];
                const auto& f = fields[l];
                // H difference = −Δθ / κ; weight κ² |z||z'| (inverse variance of the estimate).
                const double ax = std::abs(f[k]) * std::abs(f[kx]), ay = std::abs(f[k]) * std::abs(f[ky]);
                sx += ax * kappa * kappa * (-std::arg(f[kx] * std::conj(f[k])) / kappa);
                wx += ax * kappa * kappa;
                sy += ay * kappa * kappa * (-std::arg(f[ky] * std::conj(f[k])) / kappa);
                wy += ay * kappa * kappa;
            }
            gx[k] = wx > 0.0 ? sx / wx : 0.0;
            gy[k] = wy > 0.0 ? sy / wy : 0.0;
        }
    return integrate_differences(rows, cols, gx, gy);
}

}  // namespace

std::vector<double> unwrap_heights(const std::vector<double>& lambdas_um,
                                   const std::vector<std::vector<std::complex<double>>>& fields, double height_range_um,
                                   int rows, int cols, const std::vector<double>* reference) {
    if (fields.empty() || fields.size() != lambdas_um.size())
        throw std::invalid_argument("unwrap_heights: " + std::to_string(fields.size()) + " fields for " +
                                    std::to_string(lambdas_um.size()) +
                                    " wavelengths; expected one field per wavelength, at least one");
    if (!std::isfinite(height_range_um) || height_range_um <= 0.0)
        throw std::domain_error("unwrap_heights: height_range_um " + std::to_string(height_range_um) +
                                " is invalid; expected a finite value > 0");
    const std::size_t texels = fields[0].size();
    if (rows != 0 && (rows < 1 || cols < 1 || std::size_t(rows) * std::size_t(cols) != texels))
        throw std::invalid_argument("unwrap_heights: grid " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    " does not hold the fields' " + std::to_string(texels) + " values");
    for (std::size_t l = 0; l < fields.size(); ++l) {
        validate_lambda(lambdas_um[l]);
        if (fields[l].size() != texels || texels == 0)
            throw std::invalid_argument("unwrap_heights: field " + std::to_string(l) + " has " +
                                        std::to_string(fields[l].size()) + " values; expected " +
                                        std::to_string(texels) + " (the same for all, > 0)");
        for (std::size_t m = 0; m < l; ++m)
            if (lambdas_um[m] == lambdas_um[l])
                throw std::invalid_argument("unwrap_heights: wavelength " + std::to_string(lambdas_um[l]) +
                                            " um is given twice; expected distinct wavelengths");
    }

    if (reference && reference->size() != texels)
        throw std::invalid_argument("unwrap_heights: reference has " + std::to_string(reference->size()) +
                                    " heights; expected " + std::to_string(texels));
    std::vector<double> h;
    if (reference) {
        h = *reference;
    } else if (rows > 0) {
        h = spatial_heights(lambdas_um, fields, rows, cols);
    } else {
        // Channels: single wavelengths and synthetic pairs, coarse (long Λ) first.
        std::vector<Channel> channels;
        for (std::size_t l = 0; l < fields.size(); ++l) channels.push_back({lambdas_um[l], fields[l]});
        for (std::size_t a = 0; a < fields.size(); ++a)
            for (std::size_t b = 0; b < fields.size(); ++b) {
                if (!(lambdas_um[a] < lambdas_um[b])) continue;
                Channel c{lambdas_um[a] * lambdas_um[b] / (lambdas_um[b] - lambdas_um[a]), {}};
                c.z.resize(texels);
                for (std::size_t k = 0; k < texels; ++k) c.z[k] = fields[a][k] * std::conj(fields[b][k]);
                channels.push_back(std::move(c));
            }
        std::sort(channels.begin(), channels.end(),
                  [](const Channel& p, const Channel& q) { return p.lambda_um > q.lambda_um; });
        // The finest channel that still covers the range (Λ/2 > range) starts; coarser ones only
        // add noise (their phase errors are scaled up by Λ/λ).
        std::size_t start = 0;
        for (std::size_t c = 0; c < channels.size(); ++c)
            if (channels[c].lambda_um >= 2.0 * height_range_um) start = c;
        h = coarse_heights(channels[start]);
        for (std::size_t c = start + 1; c < channels.size(); ++c) {
            const Channel& ch = channels[c];
            const double psi = align(ch, h);
            for (std::size_t k = 0; k < texels; ++k) {
                if (!(std::abs(ch.z[k]) > 0.0)) continue;
                // Residual phase of this channel at the current estimate, in (−π, π]: the
                // branch nearest the estimate.
                const double r = wrap_phase(std::arg(ch.z[k]) - psi + 4.0 * k_pi / ch.lambda_um * h[k]);
                h[k] -= ch.lambda_um / (4.0 * k_pi) * r;
            }
        }
    }

    // Branch choice per sample against all wavelengths at once: among the heights that fit the
    // shortest wavelength exactly, within a quarter of the shortest synthetic wavelength of the
    // estimate (where the joint fit has one maximum), the one with the best joint fit
    // J(H) = Σ_l |z_l| cos(arg z_l − φ_l + (4π/λ_l) H). Corrects what one noisy channel
    // got wrong. (Not after spatial unwrapping: its least-squares average over neighbours is
    // already on the right branch, and a per-sample choice would only let outliers jump.)
    const bool spatial = !reference && rows > 0;
    if (fields.size() > 1 && !spatial) {
        std::size_t shortest = 0;
        double min_synthetic = std::numeric_limits<double>::infinity();
        for (std::size_t a = 0; a < fields.size(); ++a) {
            if (lambdas_um[a] < lambdas_um[shortest]) shortest = a;
            for (std::size_t b = 0; b < fields.size(); ++b)
                if (lambdas_um[a] < lambdas_um[b])
                    min_synthetic = std::min(min_synthetic,
                                             lambdas_um[a] * lambdas_um[b] / (lambdas_um[b] - lambdas_um[a]));
        }
        std::vector<double> phi(fields.size());
        for (std::size_t l = 0; l < fields.size(); ++l) phi[l] = align({lambdas_um[l], fields[l]}, h);
        const double half_step = 0.5 * lambdas_um[shortest];  // the shortest λ's branches: H + m λ/2
        const int branches = std::max(0, int(std::floor(0.25 * min_synthetic / half_step)));
        const double kappa0 = 4.0 * k_pi / lambdas_um[shortest];
        for (std::size_t k = 0; k < texels; ++k) {
            if (!(std::abs(fields[shortest][k]) > 0.0)) continue;
            const double base = h[k] -
                                wrap_phase(std::arg(fields[shortest][k]) - phi[shortest] + kappa0 * h[k]) / kappa0;
            double best = -std::numeric_limits<double>::infinity(), best_h = h[k];
            for (int m = -branches; m <= branches; ++m) {
                const double cand = base + m * half_step;
                double j_value = 0.0;
                for (std::size_t l = 0; l < fields.size(); ++l)
                    j_value += std::abs(fields[l][k]) *
                               std::cos(std::arg(fields[l][k]) - phi[l] + 4.0 * k_pi / lambdas_um[l] * cand);
                if (j_value > best) {
                    best = j_value;
                    best_h = cand;
                }
            }
            h[k] = best_h;
        }
    }

    // Joint fit over the single wavelengths: minimise Σ_l |z_lk| (1 − cos ρ_lk),
    // ρ_lk = arg z_lk − φ_l + (4π/λ_l) H_k, alternating φ_l and a Gauss–Newton step in H_k.
    for (int pass = 0; pass < 3; ++pass) {
        std::vector<double> phi(fields.size());
        for (std::size_t l = 0; l < fields.size(); ++l) phi[l] = align({lambdas_um[l], fields[l]}, h);
        for (std::size_t k = 0; k < texels; ++k) {
            double num = 0.0, den = 0.0;
            for (std::size_t l = 0; l < fields.size(); ++l) {
                const double w = std::abs(fields[l][k]);
                if (!(w > 0.0)) continue;
                const double kappa = 4.0 * k_pi / lambdas_um[l];
                const double r = wrap_phase(std::arg(fields[l][k]) - phi[l] + kappa * h[k]);
                num += w * kappa * r;
                den += w * kappa * kappa;
            }
            if (den > 0.0) h[k] -= num / den;
        }
    }
    remove_mean(h);
    return h;
}

}  // namespace wavebrdf
