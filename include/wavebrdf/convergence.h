#pragma once
// Whether a recovery converged, judged without the truth (docs/recovery.md, "Did it
// converge?"): a user with measured slices has no truth to compare with, only the slices, the
// noise they were measured with, the error bars and the model check. recover writes the result
// into run.json ("convergence") and prints its one-line warning.
//
// The misfit against the noise floor: with the Poisson loss (photon counts, loss.h) the slices'
// deviance at the estimate, D = Σ_p 2 [k log(k/μ) − (k − μ)] over every pixel of every slice
// (k the measured counts, μ the estimate's: its slice times the count scale N / Σ R), is what
// the noise alone leaves when the estimate is the truth: E[D] = Σ_p e(μ_p) with
// e(μ) = E[2 (K log(K/μ) − (K − μ))], K ~ Poisson(μ), summed exactly over K (about 1 for many
// photons per pixel, much less for few: most of a slice's pixels are dark). A converged
// estimate leaves D ≈ E[D] (a little below: it fits part of the noise); a recovery stuck in a
// wrong basin leaves the slices' speckle unexplained and D several times E[D].
// Without noise (a study's simulated slices, stored as float) the floor is the slices' rounding:
// the relative amplitude misfit Σ(√I − √R)² / Σ R of a converged estimate is ~10⁻⁸ or less.
// Other losses (amplitude on measured slices, mse) state no noise level: the misfit is reported
// but not judged; the error bars (below), whose noise variance is estimated from the residuals
// at the estimate (uncertainty.h), warn where even they exceed the target, but cannot pass it.
// Observations with per-pixel weights: only the values of weight > 0 count, each term of D,
// E[D], Σ(√I − √R)² and Σ R times its weight (Var[D]'s times its square), and N counts the
// photons of those pixels (N / Σ R over them, as the weighted Poisson loss's scale).
#include <string>
#include <vector>

#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"

namespace wavebrdf {

// Not converged when the deviance exceeds its noise floor by this factor and by more than
// k_misfit_sd_limit of its standard deviations (a converged estimate leaves 0.99, a little
// below 1 as it fits part of the noise; a 32² recovery stopped at 0.35 % of the range 1.17;
// docs/recovery.md, "Did it converge?").
constexpr double k_misfit_ratio_limit = 1.05;
constexpr double k_misfit_sd_limit = 5.0;
// The rule above: true when a deviance D (expected E[D] ± sd under photon noise) is on the
// noise floor, i.e. not above it by both the ratio and the standard deviations. Also the model
// check's (recover.h, model_check_iterations): a Gabor fit on the floor is kept.
bool misfit_on_photon_floor(double deviance, double expected, double sd);
// Slices off their own floor. A misfit summed over every slice cannot see a few slices left
// unexplained (a pit of a few texels in a wrong local basin: on a 256² scan 24 of 21 632 slices,
// the worst 37 × its limit below, while the whole sat at 0.97×, the fitted noise of the others
// outweighing them). So each slice is judged too, on its pixels of at least
// k_slice_bright_photons expected photons, where a pixel's deviance is close to a χ²₁ term and
// the sum close to a Gamma distribution of the sum's mean and variance (the dim pixels are left
// out: there one stray photon adds 2 log(1/μ), a tail no moment-matched law holds). A slice is
// off its floor above that Gamma's quantile at 1 − k_slice_false_alarm / M (M the run's slices;
// Wilson–Hilferty's cube-root normal approximation). The slices' tails are heavier than the
// Gamma's: at the truth, simulated slices of two real 64² patches (four noise draws each) reached
// 0.93–0.96 × the limit at 10⁻², 0.85–0.91 × at 10⁻⁴; hence 10⁻⁴, and a run fails only where at
// least k_slices_off_floor_min slices are off: a local error is seen by every footprint that
// holds it (the planner overlaps neighbours by ≥ 60 %), a noise excursion by one slice alone.
constexpr double k_slice_bright_photons = 1.0;
constexpr double k_slice_false_alarm = 1e-4;
constexpr int k_slices_off_floor_min = 2;
// That limit for a slice whose bright-pixel deviance has mean `expected` and variance
// `variance` (both > 0; else HUGE_VAL) among `slices` ≥ 1 slices.
double slice_deviance_limit(double expected, double variance, double slices);
// Without noise: not converged above this relative amplitude misfit.
constexpr double k_noiseless_misfit_limit = 1e-5;
// Error bars: a warning when twice the median σ exceeds this fraction of the height range (the
// recovery's target, docs/surfaces.md).
constexpr double k_error_bar_limit = 0.01;
// The noise limit: the rms height error the error bars predict, √(mean σ²) over the texels (the
// Laplace approximation's expected rms error of the mean-free heights), against the recovery's
// target, this fraction of the height range. A misfit on the photon-noise floor says the slices
// are explained as well as their noise allows, not that the noise leaves the heights within the
// target: where 10⁴ photons per slice carry too little information on nm heights, or the slices
// resolve too little of the surface's spectrum, the estimate fits the noise instead (measured on
// real scans, docs/surfaces.md). So a recovery whose misfit passes is also judged by its bars.
constexpr double k_predicted_error_limit = 0.01;

// The check's own error bars cost a forward pass per texel of every observation's footprint box
// and a solve on the texels (exact up to 64²: O(texels³)); beside a short run at 64² that was
// measured at 1.2–2.6× the recovery's own CPU time. So by default (CheckErrorBars::Auto) the
// check computes them only where their predicted CPU time (predicted_uncertainty_seconds,
// uncertainty.h) is at most this fraction of the recovery's; elsewhere the noise limit is not
// judged and the check says so (error_bars "skipped", with both times). CPU time, not wall
// time: the rule decides the same on a loaded machine. Always: computed whatever they cost;
// Off: never (error_bars "off"). Error bars the run computes anyway (--uncertainty) always judge.
// Memory as the recovery's own rule (memory.h, require_memory against --max-memory-gb, else the
// physical memory): bars whose predicted peak (predicted_uncertainty_cost's bytes and what the
// run holds) exceeds the limit are not computed, Always included: a finished recovery is not
// lost to the check's allocation (error_bars "skipped" under Auto, "unavailable" under Always,
// the note the refusal's message).
constexpr double k_check_error_bars_budget = 1.0;
enum class CheckErrorBars { Auto, Always, Off };
std::string to_string(CheckErrorBars mode);
// "auto", "always" or "off"; std::invalid_argument naming the value otherwise.
CheckErrorBars parse_check_error_bars(const std::string& text);
// The rule above: whether bars predicted to take `predicted_seconds` of CPU are computed beside
// a recovery that took `run_seconds` of CPU (Always: yes; Off: no; Auto: predicted ≤ budget ×
// run, both finite and ≥ 0; a prediction that is not finite is not affordable).
bool check_error_bars_affordable(CheckErrorBars mode, double predicted_seconds, double run_seconds);
// The memory half of the rule: whether bars whose run would peak at `needed_bytes` (what the
// run holds and the bars' own) fit `limit_bytes` (Off: never asked; a need that is not finite
// never fits; an infinite limit, an unknown physical memory, takes any finite need).
bool check_error_bars_fit(double needed_bytes, double limit_bytes);
// The CPU seconds this process has used (all threads; CLOCK_PROCESS_CPUTIME_ID).
double process_cpu_seconds();

struct ConvergenceCheck {
    // "poisson" (judged against the photon-noise floor), "noiseless" (judged against the float
    // slices' rounding) or "none" (no noise level known: not judged).
    std::string floor = "none";
    double deviance = -1.0;           // Poisson: D (all slices, all ranks); else −1
    double expected_deviance = -1.0;  // Poisson: E[D] at the estimate's μ; else −1
    double deviance_sd = -1.0;        // Poisson: √Var[D]; else −1
    double misfit_ratio = -1.0;       // Poisson: D / E[D]; else −1
    double relative_misfit = 0.0;     // Σ(√I − √R)² / Σ R over every slice (every loss)
    // The model check (recover.h, model_check_iterations), from the run's metrics: each model's
    // relative amplitude misfit on the single-wavelength slices and which heights were kept
    // (−1 / "" when it did not run).
    double model_misfit_gabor = -1.0, model_misfit_field = -1.0;
    std::string model_selected;
    // Error bars (uncertainty.h), when computed: their median σ over the height range (else −1).
    double median_sigma_relative = -1.0;
    // Error bars, when computed (asked for, or by the check itself: needs_error_bars): √(mean σ²)
    // over the height range, the rms error they predict (else −1).
    double predicted_error_relative = -1.0;
    // Where the check needed error bars (needs_error_bars), what became of them: "given" (the
    // run's own, --uncertainty), "computed" (for the check, by the cost rule or Always),
    // "skipped" (Auto: predicted beyond k_check_error_bars_budget of the run), "off"
    // (CheckErrorBars::Off) or "unavailable" (the problem has none: error_bars_note says why);
    // "" where none were needed (the misfit already failed, or noiseless slices).
    std::string error_bars;
    std::string error_bars_note;
    // The CPU seconds the bars were predicted to take and the recovery took (the cost rule's
    // operands; −1 when the rule was not applied), and what the check's own bars took
    // ("computed"; else −1). Rank 0's, the same on every rank.
    double error_bars_predicted_seconds = -1.0, run_seconds = -1.0;
    // The peak bytes the bars were predicted to need with what the run holds, and the limit
    // they were held to (memory_limit; −1 when the rule was not applied).
    double error_bars_predicted_bytes = -1.0, memory_limit_bytes = -1.0;
    double error_bars_seconds = -1.0;
    // Where the bars were not computed for their cost or memory: the lower bound of the rms
    // error they would predict (add_error_lower_bound), over the height range, and the CPU
    // seconds G's diagonal took (else −1 both).
    double error_lower_bound_relative = -1.0, error_lower_bound_seconds = -1.0;
    // The CPU seconds check_convergence's forwards took (each observation's slice rendered by its
    // built plan, summed over this rank's observations; rank 0's, the same on every rank): the
    // cost rule's measure of a forward.
    double pass_seconds = -1.0;
    bool converged = true;             // no reason below
    std::vector<std::string> reasons;  // why it did not converge (or may miss the target), one clause each
    // "" when converged; else "the recovery did not converge: REASON; …" where the misfit is a
    // reason, "the recovery is likely inaccurate: REASON; …" where only the error bars are.
    bool misfit_failed = false;
    // Poisson: the slices off their own floor (k_slice_false_alarm above), and the worst one's
    // bright-pixel deviance over its limit and its footprint centre (−1 / 0 when none).
    int slices_off_floor = 0;
    double worst_slice_excess = -1.0, worst_slice_x_um = 0.0, worst_slice_y_um = 0.0;
    // The texture check (texel_texture.h), where the run has a predicted per-texel error: that σ
    // over the height range and where it came from ("error bars", "photon plan", "error lower
    // bound"; "" and −1: not judged), the texels more than k_texture_sigmas σ off their 3 × 3
    // median, their fraction, their share of the texel-scale power, and whether it warned.
    double texture_sigma_relative = -1.0;
    std::string texture_sigma_source;
    int texture_texels = 0;
    double texture_fraction = 0.0, texture_power_share = 0.0;
    bool texture_warned = false;
    std::string warning() const;
    // Whether the run was judged: by a noise floor ("poisson", "noiseless"), or, with floor
    // "none", by error bars that found it wide (a reason). Bars within the target do not pass a
    // run of floor "none": their noise is the residuals', and at a wrong basin's minimum they
    // are as narrow as at the truth's (16², gaussian noise, amplitude loss: 0.13 % predicted,
    // 3.8 % true; 0.35 % predicted, 27 % true), so only the misfit against a known noise level
    // can show a wrong basin. Such a run is reported, not judged: `converged` only means no
    // reason was found.
    bool judged() const { return floor != "none" || !converged; }
};

// The misfit part of the check: the estimate's slices for `observations` (this rank's share
// under MPI; collective: the sums are over every rank) against their references. `photons`:
// the photons per slice N when the slices are photon counts (a study's poisson:N noise, or a
// Poisson loss's N; 0: unknown); else `noiseless` true: a study's exact slices; else not judged. `calibration`, when not null and refined (positions, exposures, σ_p scale, its
// per-observation entries for `observations`), is applied to the estimate's slices as the
// recovery fitted them. Throws std::invalid_argument when observations are empty or a
// reference's size is not its slice's.
ConvergenceCheck check_convergence(const std::vector<Observation>& observations, const Heightfield& estimate,
                                   double photons, bool noiseless, const Calibration* calibration = nullptr,
                                   const Communicator& comm = serial_communicator());

// Adds the model check (misfit:gabor, misfit:field, select:* from the run's metrics; ignored
// when absent) and the error bars (median σ in µm over the height range; < 0: none) to `check`,
// with their reasons.
void add_model_check(ConvergenceCheck& check, double misfit_gabor, double misfit_field, const std::string& selected);
void add_error_bars(ConvergenceCheck& check, double median_sigma_um, double height_range_um);

// Whether the check is left to the error bars: a misfit that passed on photon counts (floor
// "poisson": it cannot tell an accurate estimate from one that fits the noise), or a loss that
// states no noise level (floor "none": the misfit is not judged at all; the bars, their noise
// estimated from the residuals, can only fail such a run: ConvergenceCheck::judged).
bool needs_error_bars(const ConvergenceCheck& check);
// The noise limit (k_predicted_error_limit above): the error bars' σ (µm, one per texel, ≥ 0)
// over the height range (µm, > 0; else nothing is added). A reason when √(mean σ²) exceeds the
// limit, unless the wide-bars reason (add_error_bars) is there already.
void add_predicted_error(ConvergenceCheck& check, const std::vector<double>& sigma_um, double height_range_um);

// The noise limit where the bars are not computed (their cost or memory) on photon counts
// (floor "poisson"): the lower bound of
// the rms error they would predict, from G's diagonal alone (fisher_rms_error_lower_bound_um,
// uncertainty.h; µm, HUGE_VAL: a texel no slice sees), over the height range (µm, > 0; else
// nothing is added). A reason when it exceeds k_predicted_error_limit: the bars would then
// predict at least as much. Within the limit it passes nothing (the bars may still exceed it).
void add_error_lower_bound(ConvergenceCheck& check, double bound_um, double height_range_um);

// One slice's Poisson deviance D of its reference against `model` (the model's slice, o's size,
// exposure applied) at `photons` > 0 per slice, and D's expectation and variance were the
// reference Poisson counts of that model: the check's per-observation terms (above: weights,
// the photons of the counted values). All 0 when the slice holds no light.
struct SliceDeviance {
    double deviance = 0.0;
    double expected = 0.0;
    double variance = 0.0;
    // The same over the pixels of at least k_slice_bright_photons expected photons.
    double bright_deviance = 0.0, bright_expected = 0.0, bright_variance = 0.0;
};
SliceDeviance slice_photon_deviance(const Observation& o, const std::vector<double>& model, double photons);

// e(μ) and Var of the Poisson deviance of one pixel of mean μ ≥ 0 (see above), by exact sums
// over the counts (to 12 standard deviations past μ). For tests and the check above.
void poisson_deviance_moments(double mu, double& mean, double& variance);

}  // namespace wavebrdf
