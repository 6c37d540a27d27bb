#pragma once
// Photon-aware acquisition planning (docs/surfaces.md, "Photon-limited surfaces"): with
// Poisson noise the rms height error a plan leaves is set by the photons its slices hold, and
// with a fixed count per exposure it falls about as 1/√(exposures). So before the slices are
// taken the planner estimates the photon-limited rms height error of the planned acquisition
// (below) and, where it exceeds the target (a fraction of the peak to valley), takes k repeated
// exposures of every slice, summed (Poisson counts add: the sum of k exposures of N photons is
// one slice of k·N), with k the smallest that meets the target, at most `max_exposures`.
//
// The error is measured, not guessed, on a proxy tile of at most proxy_texels² texels cut from
// the middle of the surface (made periodic by the periodic-plus-smooth decomposition), observed
// by the same plan (σ_p, slice size, wavelengths, lights, overlap and jitter) at the full tile's
// raster density. Its Gauss-Newton matrix G at the truth (uncertainty.h; Cov(h) ≈ G⁺: the error
// bars) gives the first order, variance/k; but the maximum-likelihood heights seen through
// intensities are biased where the photons barely resolve a spatial frequency (a mode mostly
// uncertain in its phase comes back shrunk), their variance exceeds the bars there, and modes
// the photons do not resolve at all come back below the bars (shrunk to nothing): all
// second order in the noise (∝ 1/k²; experiments/2026-11-30-photon-plan-bias.md and
// -variance.md): on plu-1 64² with 5 exposures the draws' error was 1.043 % against the bars'
// 0.918 %. So for a candidate k the planner runs the estimator itself on the proxy, a Monte
// Carlo: k_photon_mc_draws Poisson draws of the proxy's slices with k·N photons each (k exposures
// summed; N scaled by the proxy's raster density over the full plan's), seeded from
// settings.seed (the run's seed: the same plan every run), each solved for the
// maximum-likelihood heights from the truth by quasi-Newton steps (L-BFGS whose first inverse
// Hessian is G⁻¹ at the truth, dense Cholesky; the gradient of the Poisson deviance by the
// adjoint, observation.h) until a step moves the heights by < 1 % of the bars' rms, at most
// k_photon_mc_steps steps (Newton steps with G held fixed crept: 8 of them left the error 4 %
// short on the test's 16² tile). The rms over the draws of each estimate's error against the
// proxy's truth holds the bias and the second-order variance together. The plan takes the
// fewest k whose one-sided 95 % upper bound on the mean square error (its mean over the 16 draws
// + t₀.₉₅,₁₅ = 1.753 standard errors, rooted) meets the target; the search starts at one exposure
// and guesses the next k from the error's 1/√k (typically 3 values of k, about 300 loss and
// gradient evaluations of the proxy's slices each: about 2 s for 49 slices of 32²). What the
// Monte Carlo cannot hold: content of the surface outside the proxy, and a recovery that ends in
// another maximum than the one by the truth (where the Monte Carlo starts): in the directions the
// photons barely constrain the likelihood is nearly flat and the estimate depends on where the
// optimiser comes from (plu-1 32², one exposure: the Monte Carlo on the whole patch 2.85 %, the
// recovery 3.14 % over 24 draws; on the 30 nm 16² test tile they agree, 1.285 % and 1.286 %).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// The default target: the recovery's accuracy target (convergence.h's k_predicted_error_limit).
constexpr double k_default_target_error = 0.01;
// The default cap on exposures per slice: the error at most 4 × lower than with one exposure.
constexpr int k_default_max_exposures = 16;
// The default proxy tile, texels per side (plan_exposures below).
constexpr int k_photon_proxy_texels = 16;
// The Monte Carlo's noise draws per candidate exposure count, and Newton steps per draw at most.
constexpr int k_photon_mc_draws = 16;
constexpr int k_photon_mc_steps = 20;

struct PhotonPlanSettings {
    double target = k_default_target_error;  // rms height error / peak to valley; 0: no planning (0 … 1)
    int max_exposures = k_default_max_exposures;  // 1 … 10^4
    int proxy_texels = k_photon_proxy_texels;     // 4 … 64
    std::uint64_t seed = 1;                       // the Monte Carlo's noise draws
};

struct PhotonPlan {
    // The Monte Carlo of the estimator at one exposure count.
    struct MonteCarlo {
        int exposures = 0;
        double rms_um = 0.0;    // rms height error over the draws (mean removed)
        double bound_um = 0.0;  // its one-sided 95 % upper bound (the mean square's, rooted)
        int gradients = 0;      // loss and gradient evaluations on the proxy's observations
        int most_steps = 0;     // the most Newton steps a draw took
    };
    double photons = 0.0;           // per exposure (the noise's N)
    double range_um = 0.0;          // the peak to valley the target is relative to
    double target = 0.0;            // settings.target
    double bars_rms_um = 0.0;       // the error bars' rms on the proxy, one exposure (first order)
    double rms_um = 0.0;            // the Monte Carlo's rms error with `exposures`
    double bound_um = 0.0;          // ... its 95 % upper bound (what met the target)
    int exposures = 1;              // exposures per slice, summed
    bool capped = false;            // the target needs more than settings.max_exposures
    int proxy_rows = 0, proxy_cols = 0;
    std::size_t proxy_observations = 0;
    double density_ratio = 1.0;     // the full plan's area per position over the proxy's
    std::int64_t forwards = 0;      // forward passes forming the proxy's G
    int gradients = 0;              // loss and gradient evaluations of the Monte Carlo, all k
    std::vector<MonteCarlo> tried;  // each exposure count the search ran, ascending
    double seconds = 0.0;           // wall time of the plan
    std::string note;               // one line: what the planner did and why (no times: the same every run)
};

// Exposures meeting the target: the smallest k (1 … max_exposures) with rms_um(k) ≤ target_um,
// rms_um(k) non-increasing in k; max_exposures with capped set when even that misses. The search
// starts at 1 and guesses the next k where rms_um(k)·√(k/k') meets the target, bisecting after
// three guesses (rms_um is costly: a Monte Carlo). Throws std::domain_error naming the value for
// an rms_um that is negative or not finite, a target ≤ 0 or max_exposures < 1.
int exposures_for_target(const std::function<double(int)>& rms_um, double target_um, int max_exposures,
                         bool* capped = nullptr);

// The photon-limited rms height error (µm, mean removed) of observing `surface` by `plan` with
// `photons` per slice as the error bars predict it (first order: the variance alone), on the
// proxy tile (the header's comment); the details (proxy size, observations, density ratio,
// forwards, seconds, bars_rms_um) in `details` when given.
// Throws std::domain_error for photons ≤ 0 or not finite, settings out of range, and as
// height_uncertainty does.
double predict_photon_limited_rms_um(const Heightfield& surface, const AcquisitionPlan& plan, double photons,
                                     const PhotonPlanSettings& settings = {}, PhotonPlan* details = nullptr);

// The photon-aware plan (the header's comment): the bars, then the fewest exposures
// k ≤ settings.max_exposures whose Monte Carlo error bound meets settings.target × range_um
// (with no target: one exposure, its Monte Carlo), with the note. Throws as above and
// std::domain_error for range_um ≤ 0 or not finite.
PhotonPlan plan_exposures(const Heightfield& surface, const AcquisitionPlan& plan, double photons, double range_um,
                          const PhotonPlanSettings& settings = {});

}  // namespace wavebrdf
