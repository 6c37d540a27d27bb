#pragma once
// Photon-aware acquisition planning (docs/surfaces.md, "Photon-limited surfaces"): with
// Poisson noise the rms height error a plan leaves is set by the photons its slices hold, and
// with a fixed count per exposure it falls as 1/√(exposures). So before the slices are taken
// the planner predicts the photon-limited rms height error of the planned acquisition from
// the error-bar machinery (uncertainty.h: Fisher information of the Poisson counts, Cov(h) ≈
// G⁺) and, where it exceeds the target (a fraction of the peak to valley), takes k repeated
// exposures of every slice, summed (Poisson counts add: the sum of k exposures of N photons is
// one slice of k·N), with k the smallest that meets the target, at most `max_exposures`.
//
// The prediction is cheap: G⁺ on a proxy tile of at most proxy_texels² texels cut from the
// middle of the surface (made periodic by the periodic-plus-smooth decomposition), observed by
// the same plan (σ_p, slice size, wavelengths, lights, overlap and jitter) at the full tile's
// raster density: the variance is scaled by the ratio of the proxy's positions per area to the
// full tile's. Why a small tile stands for the whole: for heights of a small phase (nm at
// visible wavelengths) a slice's off-specular counts carry a Fisher information about each
// height that does not depend on the heights themselves, and a texel's variance is set by the
// footprints around it, not by the tile's extent (the check's bars on the full tiles: plu-1
// 1.25 nm rms at 64² and 1.26 nm at 256²).
//
// The bars are the estimate's variance; the maximum-likelihood estimate of heights seen through
// intensities is also biased where the photons barely resolve a spatial frequency: a Fourier mode
// of the heights whose error is mostly in its phase comes back shrunk on average by
// E[cos δφ] ≈ 1 − E[δφ²]/2 = 1 − V/(2T) (T its power in the truth, V its error variance: the
// second-order bias of a phase-uncertain mode; at most the whole mode). So the prediction adds,
// mode by mode over the whole tile's spectrum, the bias power T·min(1, V/(2T))², with V the
// variance of that mode by the proxy's G⁺ (f_qᴴ G⁺ f_q at the nearest of the proxy's frequencies;
// their mean is the bars' variance). On plu-1 32² (24 noise draws, one exposure) the draws' own variance matched
// the bars (2.92 % against 2.89 %) and the bias came to 1.22 % rms, predicted by this rule at
// 1.19 % (experiments/2026-11-30-photon-plan-bias.md). The bias falls faster than the variance
// with more photons (V/(2T) ∝ 1/k), so the exposures are searched with both.
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

struct PhotonPlanSettings {
    double target = k_default_target_error;  // rms height error / peak to valley; 0: no planning (0 … 1)
    int max_exposures = k_default_max_exposures;  // 1 … 10^4
    int proxy_texels = k_photon_proxy_texels;     // 4 … 64
};

struct PhotonPlan {
    double photons = 0.0;           // per exposure (the noise's N)
    double range_um = 0.0;          // the peak to valley the target is relative to
    double target = 0.0;            // settings.target
    double single_rms_um = 0.0;     // predicted rms height error with one exposure per slice (bars and bias)
    double rms_um = 0.0;            // ... with `exposures`
    double single_bias_um = 0.0;    // the photon-limited bias's share of single_rms_um (rms, µm)
    double bias_um = 0.0;           // ... of rms_um
    int exposures = 1;              // exposures per slice, summed
    bool capped = false;            // the target needs more than settings.max_exposures
    int proxy_rows = 0, proxy_cols = 0;
    std::size_t proxy_observations = 0;
    double density_ratio = 1.0;     // the proxy's positions per area over the full plan's
    std::int64_t forwards = 0;      // forward passes the prediction took
    double seconds = 0.0;           // wall time of the prediction
    // The variance of each Fourier mode of the heights on the proxy's rows × cols frequencies
    // (row-major, µm²: f_qᴴ G⁺ f_q / n with the density ratio, one exposure; 0 at q = 0; their
    // mean is the bars' variance): predict_photon_limited_rms_um fills it.
    std::vector<double> variance_spectrum;
    std::string note;               // one line: what the planner did and why (no times: the same every run)
};

// Exposures meeting the target: the smallest k (1 … max_exposures) with rms_um(k) ≤ target_um,
// rms_um(k) the predicted rms height error with k exposures, non-increasing in k (found by
// bisection); max_exposures with capped set when even that misses; 1 when rms_um(1) meets it.
// Throws std::domain_error naming the value for a negative or non-finite rms_um(1), a target ≤ 0
// or max_exposures < 1.
int exposures_for_target(const std::function<double(int)>& rms_um, double target_um, int max_exposures,
                         bool* capped = nullptr);

// The photon-limited rms height error (µm, mean removed) of observing `surface` by `plan`
// with `photons` per slice as the error bars predict it (the variance alone), on the proxy tile
// (the header's comment); the details (proxy size, observations, density ratio, forwards,
// seconds, the variance's spectrum) in `details` when given.
// Throws std::domain_error for photons ≤ 0 or not finite, settings out of range, and as
// height_uncertainty does.
double predict_photon_limited_rms_um(const Heightfield& surface, const AcquisitionPlan& plan, double photons,
                                     const PhotonPlanSettings& settings = {}, PhotonPlan* details = nullptr);

// The rms bias (µm) of the estimate of `surface` (mean removed) with `exposures` exposures, the
// header's rule: each Fourier mode q of the whole tile (power T) shrunk by min(1, V/(2T)), V the
// error variance of the mode, n·variance_spectrum[the proxy frequency nearest q] / exposures
// (n: the tile's texels). Throws std::invalid_argument for a spectrum that is not proxy_rows ×
// proxy_cols values, std::domain_error for exposures < 1.
double photon_limited_bias_um(const Heightfield& surface, const PhotonPlan& details, int exposures);

// The photon-aware plan: the prediction with one exposure (the bars' variance and the bias),
// then the fewest exposures k ≤ settings.max_exposures whose √(variance/k + bias(k)²) meets
// settings.target × range_um, with the note. Throws as the two above.
PhotonPlan plan_exposures(const Heightfield& surface, const AcquisitionPlan& plan, double photons, double range_um,
                          const PhotonPlanSettings& settings = {});

}  // namespace wavebrdf
