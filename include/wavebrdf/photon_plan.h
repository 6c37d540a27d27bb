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

// The pilot (recovery_run.h's prepare_recovery runs it): the first-order prediction above sees the
// estimate's variance and its second-order bias but not where the recovery's own path ends: its
// estimate is one of many likelihood minima that differ above ~0.4 cycles per texel, 5–16 % above
// the prediction in rms on plu-1 (experiments/2026-11-30-final-refinement-stall.md). So where the
// first-order plan's prediction lies within k_photon_pilot_band of the target, the recovery itself
// (the same acquisition plan, schedule and cold start as the full run) runs on square tiles cut
// from the planner's surface (draw d on the cell (Halton₂(d), Halton₃(d)) of its grid of such
// cells), on draws of simulated Poisson slices at the first-order plan's exposures; the rms of its
// errors over the first-order prediction for the same tiles is the measured ratio ρ. Each tile's
// prediction is the full tile's model (its variance spectrum, from the full tile's proxy) applied to
// the tile's own heights (photon_plan_rms_um), so that ρ scales the very prediction the plan
// multiplies; a tile's own proxy read its first order 1–2 % off the full tile's on plu-1
// (experiments/2026-12-01-pilot-embedding.md). The tiles are as large as the draws' budget allows:
// a draw costs ~its texels and its ratio scatters ~1/side, so the budget
// (k_photon_pilot_budget_texels) buys the same precision on any tile side, while a larger tile
// holds more of the full tile's error: on plu-1's 128² tile 32² tiles read the ratio 3 % under
// 64² ones (the error at wavelengths beyond 32 texels, and the recovery's own excess on a small
// tile). But the tiles must be places of the surface, not the surface itself: draws on the full
// tile differ only in their noise (on plu-1 64² a ratio spread of 0.004) and miss the spread
// between acquisitions (0.86–1.02 % over seeds with the same exposures). So the side is half the
// surface's, within k_photon_pilot_min_texels … k_photon_pilot_texels and at most the surface's
// (photon_pilot_tile_texels), with at least k_photon_pilot_min_draws draws (photon_pilot_max_draws).
// The target bounds ONE run's error, not the mean over noise draws, so the exposures for the full
// tile are the fewest whose prediction times the upper ratio U = max(1, ρ + z √(se² + s_N²)) meets
// the target (z = k_photon_pilot_z; the first order is a lower bound): se is ρ's standard error
// over the draws and s_N the spread of one run's ratio on the full tile, taken as a draw's ratio's
// spread s_draw on a pilot tile scaled by the pilot tiles the full tile holds,
// s_N = s_draw √(n² / (rows cols)) (the full tile's rms error averages that many independent pilot
// tiles' squared errors; s_N = s_draw on a tile no larger than a pilot's). The draws go on (at
// least k_photon_pilot_min_draws, at most photon_pilot_max_draws) until ρ + z s_N ± 2 se (which
// holds U) asks for the same exposures; a draw's ratio scatters by 0.06–0.1 on plu-1's 32² tiles,
// 0.03–0.06 on its 64² ones.
constexpr int k_photon_pilot_texels = 64;      // the largest pilot tile's side
constexpr int k_photon_pilot_min_texels = 32;  // the smallest (where the surface is larger)
constexpr int k_photon_pilot_min_draws = 4;
constexpr int k_photon_pilot_max_draws = 16;
// The texels the draws recover at most (16 draws of 32², 4 of 64²).
constexpr long long k_photon_pilot_budget_texels = 16LL * 32 * 32;
// The pilot runs where the first-order prediction of the plan is at least target / band.
constexpr double k_photon_pilot_band = 1.5;
// The one-sided quantile of one run's error ratio the exposures are planned for (2: ~97.5 %).
constexpr double k_photon_pilot_z = 2.0;

// What the pilot measured (PhotonPlan::pilot).
struct PhotonPilot {
    bool ran = false;
    int rows = 0, cols = 0;            // the pilot's proxy tile
    int exposures = 0;                 // the exposures it was run at (the first-order plan's)
    int first_order_exposures = 0;     // the first-order plan's exposures (before the pilot)
    int tiles = 0;                     // distinct tiles the draws ran on
    std::vector<double> errors_um;     // each draw's rms height error (mean removed)
    std::vector<double> predicted_um;  // ... and the first-order prediction for its tile
    double measured_rms_um = 0.0;      // the errors' rms
    double predicted_rms_um = 0.0;     // the predictions' rms
    double ratio = 1.0;                // measured_rms_um / predicted_rms_um
    double ratio_sd = 0.0;             // the ratio's standard error over the draws
    double draw_sd = 0.0;              // the spread (sd) of one draw's ratio, errors_um / predicted_um
    double run_sd = 0.0;               // ... scaled to one run on the full tile (s_N above)
    double upper_ratio = 1.0;          // U above: the ratio the exposures are planned with
    double cpu_seconds = 0.0;          // the pilot's process CPU time
    std::string why_not;               // when it did not run: why
};

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
    PhotonPilot pilot;              // the pilot of the pipeline (set by prepare_recovery)
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

// The first-order prediction of `p` (made by plan_exposures for `surface`) with `exposures`:
// √(variance/k + bias(k)²) (µm). Throws as photon_limited_bias_um.
double photon_plan_rms_um(const Heightfield& surface, const PhotonPlan& p, int exposures);

// The middle rows × cols of `surface` made periodic (periodic-plus-smooth decomposition), or the
// surface itself where it is no larger: the proxy tiles' cut.
Heightfield photon_proxy_tile(const Heightfield& surface, int rows, int cols);
// The same cut at rows row0 … and columns col0 … (clamped into the surface).
Heightfield photon_proxy_tile_at(const Heightfield& surface, int row0, int col0, int rows, int cols);

// The side of the pilot's square tiles on a surface of rows × cols: half its smaller side, within
// k_photon_pilot_min_texels … k_photon_pilot_texels, at most that side (the whole surface below
// 2 × k_photon_pilot_min_texels). Throws std::invalid_argument for a side < 1.
int photon_pilot_tile_texels(int rows, int cols);

// The most draws the pilot takes on tiles of rows × cols texels: k_photon_pilot_budget_texels
// of them, at least k_photon_pilot_min_draws and at most k_photon_pilot_max_draws.
// Throws std::invalid_argument for a tile side < 1.
int photon_pilot_max_draws(int rows, int cols);

// The pilot's draw_sd, run_sd and upper_ratio (above) from its draws (errors_um, predicted_um),
// ratio and ratio_sd, for a full tile of rows × cols (the pilot's tiles pilot.rows × pilot.cols,
// k_photon_pilot_texels² where unset).
void set_photon_pilot_spread(PhotonPilot& pilot, int rows, int cols);

// The plan `p` (plan_exposures' for `surface`) with the pilot's measurement: `pilot` stored (its
// spread set for `surface`), the exposures the fewest (≤ settings.max_exposures) whose first-order
// prediction times pilot.upper_ratio meets the target, rms_um and bias_um that prediction, and the note saying
// what the pilot measured (or why it did not run).
void apply_photon_pilot(PhotonPlan& p, const Heightfield& surface, const PhotonPlanSettings& settings,
                        PhotonPilot pilot);

}  // namespace wavebrdf
