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
#include <cstdint>
#include <string>

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
    double single_rms_um = 0.0;     // predicted rms height error with one exposure per slice
    double rms_um = 0.0;            // ... with `exposures`
    int exposures = 1;              // exposures per slice, summed
    bool capped = false;            // the target needs more than settings.max_exposures
    int proxy_rows = 0, proxy_cols = 0;
    std::size_t proxy_observations = 0;
    double density_ratio = 1.0;     // the proxy's positions per area over the full plan's
    std::int64_t forwards = 0;      // forward passes the prediction took
    double seconds = 0.0;           // wall time of the prediction
    std::string note;               // one line: what the planner did and why (no times: the same every run)
};

// Exposures meeting the target: the smallest k with single_rms_um / √k ≤ target_um, at most
// max_exposures (capped set when that is not enough); 1 when single_rms_um already meets it.
// Throws std::domain_error naming the value for a negative or non-finite rms, a target ≤ 0 or
// max_exposures < 1.
int exposures_for_target(double single_rms_um, double target_um, int max_exposures, bool* capped = nullptr);

// The photon-limited rms height error (µm, mean removed) of observing `surface` by `plan`
// with `photons` per slice, predicted on the proxy tile (the header's comment); the details
// (proxy size, observations, density ratio, forwards, seconds) in `details` when given.
// Throws std::domain_error for photons ≤ 0 or not finite, settings out of range, and as
// height_uncertainty does.
double predict_photon_limited_rms_um(const Heightfield& surface, const AcquisitionPlan& plan, double photons,
                                     const PhotonPlanSettings& settings = {}, PhotonPlan* details = nullptr);

// The photon-aware plan: the prediction with one exposure, then exposures_for_target against
// settings.target × range_um, with the note. Throws as the two above.
PhotonPlan plan_exposures(const Heightfield& surface, const AcquisitionPlan& plan, double photons, double range_um,
                          const PhotonPlanSettings& settings = {});

}  // namespace wavebrdf
