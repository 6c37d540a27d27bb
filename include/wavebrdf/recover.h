#pragma once
// Recovering the true heightfield from BRDF slices at several overlapping footprint positions
// and several wavelengths (docs/model.md §14): the fields first, the heights from them.
//
//  0. Blurred fit (fit_blurred). From a flat start the phase retrieval has no useful gradient
//     (the flat object's field is a specular lobe; the data lie elsewhere). Slices blurred in u
//     show the distribution of slopes, smooth in the heights: L-BFGS on them, wide blur to
//     narrow, in the full model, finds the shape to ~2 % of the height range.
//  1. Field retrieval per wavelength (retrieve_field). The model's field is a ptychographic
//     far field: with an object O on a grid `refine` times finer than the texels,
//       I(u) = env(u) · Σ_a P_a O_a e^{−i2π u·δ_a},
//     P the footprint window (known), δ_a = x_a − μ_p (FieldOperator). The object must be
//     finer than the texels: ±1 µm heights change by ≈ 3 rad per texel at λ = 0.5 µm (aliased
//     on the texel grid, where the Gabor kernels' tilts carry it); on a grid of spacing
//     < λ/2 it is sampled, and the model leaves ~0.1 % of the slices' amplitude unexplained.
//     L-BFGS on the amplitude loss Σ(√c1 |I| − √R)² over the object's spectrum inside the
//     band the slices see, started from the current heights, longest wavelength first.
//  2. Unwrapping (unwrap_heights): the refined grid samples the phase finely enough to unwrap
//     it spatially (least squares over neighbours), averaged over the wavelengths; per sample
//     by synthetic wavelengths λ1λ2/|λ1 − λ2| where no grid is given.
//  3. Refinement of the heights in the full Gabor model (slopes included) with L-BFGS on the
//     observations' amplitude loss and the model's analytic gradient.
//
// Under MPI (communicator.h, docs/scale.md) every function below that takes a Communicator is
// collective: each rank passes its share of the observations (any split; observation_share
// keeps each region's footprints on one rank) and the same settings and starting point; every
// sum over the observations (losses, gradients, normalisations, the band and the coverage) is
// allreduced in rank order, so every rank returns the same result, the same bits for a given
// number of ranks, and it equals the one-process result up to the order of those sums.
//
// Conventions: objects and fields are complex, row-major (object: (rows·refine) ×
// (cols·refine) samples, sample a at x = (a + ½) w/refine; field: resolution² slice pixels);
// e^{−ix} phase convention of docs/model.md §8. Heights in µm unless named otherwise.
#include <complex>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf {

// ---- 0. Blurred slices: the shape of the surface from a flat start -------------------------

struct BlurredFitSettings {
    // Blur widths, widest first, in units of the footprint's own far-field lobe (intensity std
    // 1/(2√2 π σ_p) in u): each stage fits slices blurred by a Gaussian this many lobes wide.
    std::vector<double> blur_widths{16.0, 8.0, 4.0, 2.0};
    int iterations = 40;  // L-BFGS iterations per stage
    int history = 20;
    // Self-calibration of the exposure: each slice's blurred model is scaled by its exposure
    // e = Σ R_b / Σ M_b (the ratio of the energies), taken at each blur stage's starting
    // heights and held for the stage.
    bool calibrate_exposure = false;
    // Per stage (empty, the default: `iterations` for every width; else one count ≥ 0 per blur
    // width, 0 skipping that width).
    std::vector<int> width_iterations;
    // A stage also stops once its loss fell by less than stall_tolerance (a fraction of its value)
    // over the last stall_window iterations (0, the default: off). The narrow widths' losses
    // level off (≈ 1 % per 5 iterations near 40) while the wide ones still fall by ≈ 15 %
    // (experiments/2026-11-23-recovery-speed.md).
    int stall_window = 0;
    double stall_tolerance = 0.0;
};

// Heights that match the single-wavelength observations blurred in u (the distribution of
// reflected directions, smooth in the heights), from `initial` (e.g. flat), wide blur first:
// L-BFGS on Σ(√(B f Bᵀ) − √(B R Bᵀ))² / Σ B R Bᵀ in the full model (slices in single
// precision), B the Gaussian blur over the slice pixels. When no rank has a single-wavelength
// observation, the RGB ones are fitted instead (white light): each channel blurred alike, in ω
// as at white_light_lambda_um of its wavelengths (the slope distribution is the same at every
// wavelength). on_iteration(stage, iteration, loss)
// returning false stops. Throws std::invalid_argument when no observation
// is given (on any rank), std::domain_error for a blur width ≤ 0 or iterations < 0. `comm`:
// the ranks the observations are split over (collective; on_iteration's stop is agreed).
Heightfield fit_blurred(const std::vector<Observation>& observations, const Heightfield& initial,
                        const BlurredFitSettings& settings = {},
                        const std::function<bool(int, int, double)>& on_iteration = {},
                        const Communicator& comm = serial_communicator());
// The same over observations held elsewhere (none null; recover_heights passes a subset
// without copying its slices).
Heightfield fit_blurred(const std::vector<const Observation*>& observations, const Heightfield& initial,
                        const BlurredFitSettings& settings = {},
                        const std::function<bool(int, int, double)>& on_iteration = {},
                        const Communicator& comm = serial_communicator());

// The wavelength (µm) an RGB slice of these wavelengths is blurred at in fit_blurred: their
// mean. Throws std::invalid_argument on an empty list.
double white_light_lambda_um(const std::vector<double>& lambdas_um);

// ---- 1. The ptychographic field model ------------------------------------------------------

// The linear map from a complex object on a grid `refine` times finer than the texels to the
// far field of one footprint at one wavelength (the formula above), on the slice grid of one
// observation. It is the separable Gabor field of render_slice, for the heightfield of texel
// w/refine, with every slope set to zero (same kernels, weights, 3σ_p cut, envelope
// exp(−2π²(w/2refine)²|u|²) and pixel grid), so for OHS / ROHS
//   slice = amplitude_factor² · |forward(e^{−i(4π/λ)H})|²  wherever all slopes vanish.
// Pixels where the envelope is below 1e-16 of its peak are left 0 by forward and ignored by
// adjoint.
class FieldOperator {
public:
    // rows, cols ≥ 1 texels of width texel_um (> 0, µm); query and λ as for render_slice
    // (OHS or ROHS: the other models are not separable); resolution 1…8192; refine 1…64.
    // Throws std::invalid_argument / std::domain_error naming the bad value.
    FieldOperator(int rows, int cols, double texel_um, const Query& query, double lambda_um, int resolution,
                  int refine = 1);
    ~FieldOperator();
    FieldOperator(FieldOperator&&) noexcept;
    FieldOperator& operator=(FieldOperator&&) noexcept;

    // object: (rows·refine)·(cols·refine) values → field: resolution² values.
    std::vector<std::complex<double>> forward(const std::vector<std::complex<double>>& object) const;
    // The adjoint (conjugate transpose) of forward: resolution² values → object values.
    std::vector<std::complex<double>> adjoint(const std::vector<std::complex<double>>& field) const;
    // √c1 per slice pixel (0 outside the disk and where c1 is not finite): f = this² · |I|².
    const std::vector<double>& amplitude_factor() const;
    int resolution() const;

private:
    struct Impl;
    friend struct FieldAccess;  // the retrieval loop works on the factor matrices directly
    std::unique_ptr<Impl> m_impl;
};

struct FieldRetrievalSettings {
    // The object grid is this many times finer than the texels (odd, so that every texel
    // centre is an object sample: texel (i, j) is sample (i·refine + refine/2, …)).
    int refine = 1;
    int iterations = 50;  // L-BFGS iterations (accepted steps)
    // Keep only the object's spectrum inside the band the slices see: the union of their disks
    // |u − ω_i/λ| ≤ 1/λ widened by the window's spectral reach 3/(2πσ_p). What lies outside
    // reaches no pixel; left free it drifts and corrupts the phases.
    bool band_limit = true;
    int history = 20;                   // L-BFGS pairs
    double relative_tolerance = 1e-12;  // stop when the relative loss drops below this
    // Stopping rule: stop when the relative loss fell by less than stall_tolerance (a fraction
    // of its value) over the last stall_window iterations (0: run all `iterations`). The loss
    // has a floor (the zero-slope model's error, ~1e-3 of the slices' amplitude); once near it
    // further iterations move the heights by far less than the refinement corrects (measured:
    // experiments/2026-11-23-recovery-speed.md).
    int stall_window = 5;
    double stall_tolerance = 0.005;
    // Self-calibration of the exposure: each slice's model amplitude is scaled by √e, e =
    // Σ R / Σ c1|I|² over the disk's pixels (the ratio of the energies, per evaluation, its
    // gradient included).
    bool calibrate_exposure = false;
};

struct FieldRetrievalResult {
    std::vector<std::complex<double>> object;  // (rows·refine)·(cols·refine), up to a global phase
    double relative_loss = 0.0;                // Σ(√c1|I| − √R)² / Σ R over the observations
    int iterations = 0;
};

// Phase retrieval of the object at one wavelength from single-wavelength observations (all
// with lambdas_um == {lambda_um}, OHS or ROHS) of a rows × cols tile with texels of texel_um:
// L-BFGS on L(O) = Σ_slices Σ_pixels (√c1|I| − √R)² / Σ R (the products in single precision).
// Samples no footprint reaches are 0. `initial` (the object's size; empty: all ones, a flat
// surface, which only converges with dense positions) is the starting object, e.g.
// object_from_heights. on_iteration(iteration, relative_loss), when given, is called after
// each step; returning false stops. Throws std::invalid_argument naming the observation that
// does not fit or a size mismatch, std::domain_error for iterations < 0 or history < 1.
// `comm`: the ranks the observations are split over (collective; a rank's share may be
// empty, not all of them; on_iteration's stop is agreed).
FieldRetrievalResult retrieve_field(const std::vector<Observation>& observations, double lambda_um, int rows, int cols,
                                    double texel_um, const std::vector<std::complex<double>>& initial = {},
                                    const FieldRetrievalSettings& settings = {},
                                    const std::function<bool(int, double)>& on_iteration = {},
                                    const Communicator& comm = serial_communicator());
// The same for observations held elsewhere (no copy of their references; the vector overload
// forwards here). Throws std::invalid_argument for a null pointer.
FieldRetrievalResult retrieve_field(const std::vector<const Observation*>& observations, double lambda_um, int rows,
                                    int cols, double texel_um, const std::vector<std::complex<double>>& initial = {},
                                    const FieldRetrievalSettings& settings = {},
                                    const std::function<bool(int, double)>& on_iteration = {},
                                    const Communicator& comm = serial_communicator());

// Heights (µm) of `heightfield` on the grid `refine` times finer than its texels (odd refine;
// (rows·refine) × (cols·refine), row-major): the blend of the Gabor kernels' tangent planes
// Σ_k G(x − μ_k) (H_k + s_k·(x − μ_k)) / Σ_k G(x − μ_k), the height whose e^{−i(4π/λ)H} the
// model's kernels approximate. At texel centres it is close to H_k.
std::vector<double> refined_heights(const Heightfield& heightfield, int refine);

// The object e^{−i(4π/λ)H} of refined_heights, the field stage's starting point.
std::vector<std::complex<double>> object_from_heights(const Heightfield& heightfield, double lambda_um, int refine);

// ---- 2. Multi-wavelength unwrapping --------------------------------------------------------

// Heights H_k (µm, mean 0) such that fields[l][k] ∝ e^{−i(4π/λ_l)H_k} up to one unknown global
// phase per wavelength, from fields at one or more distinct wavelengths; |fields[l][k]| weighs
// sample k at wavelength l (0: no information). Two starts:
//  - rows, cols > 0: the fields are samples on a periodic rows × cols grid, fine enough that
//    neighbours differ by less than π in phase: the wrapped differences, averaged over the
//    wavelengths, are integrated by least squares (spatial unwrapping);
//  - rows = cols = 0: each sample on its own, by synthetic wavelengths λ1λ2/|λ1 − λ2|, coarse
//    to fine, from the first whose half covers height_range_um (a bound on max H − min H).
// Then, with two or more wavelengths and no spatial start, each sample takes the branch of the
// shortest wavelength that fits all wavelengths best (this needs phase errors well below the
// 2π(λ_b/λ_a − 1)/2 that separates branches; the spatial start is far more robust), and a joint
// least-squares fit of heights and global phases ends it. Throws std::invalid_argument on size
// mismatches, no field, equal wavelengths or a grid that does not hold the fields;
// std::domain_error for a non-positive λ or range.
// With `reference` (heights in µm, one per sample) the start is the reference itself: each
// sample then takes the branch nearest it. The reference must be well within λ/4 of the truth
// at the shortest wavelength (the global phases are aligned to it), or, with two or more
// wavelengths, within a quarter of the shortest synthetic wavelength and close on average.
std::vector<double> unwrap_heights(const std::vector<double>& lambdas_um,
                                   const std::vector<std::vector<std::complex<double>>>& fields, double height_range_um,
                                   int rows = 0, int cols = 0, const std::vector<double>* reference = nullptr);

// ---- 3. The pipeline -----------------------------------------------------------------------

// The smallest odd object-grid refinement whose sampling holds a slice's band and the field's
// (d = w/q < λ / (2 (1 + |ω_i|))).
int auto_refine(double texel_um, double lambda_min_um, double max_omega_i = 0.0);

// What the caller states about the surface (roughness_plan.h). The schedule (scheduled_settings)
// takes the rough-surface plan or the smooth schedule from it; unstated, the surface counts as
// smooth (the common case, and `wavebrdf recover`'s default of ±1 µm at correlation 4 texels).
struct SurfaceClass {
    std::optional<double> height_range_um;  // stated peak to valley (µm, ≥ 0)
    std::optional<double> correlation_um;   // stated correlation length (µm, > 0)
    // A known surface's measured roughness (measure_roughness), planned for instead of the
    // stated range and correlation (still both needed: the plan applies only where both are > 0).
    std::optional<MeasuredRoughness> measured;
};

// With error bars (RecoverSettings::error_bars), at least this many refinement iterations on
// every slice where refine_iterations is unset: the bars are the loss's curvature at its
// minimum, and the smooth schedule's 8 stop short of it by more than the noise moves the
// estimate (experiments/2026-11-23-error-bars.md).
constexpr int k_uncertainty_refine_iterations = 40;

// FieldRetrievalSettings with iterations unset (−1), RecoverSettings::field's default.
inline FieldRetrievalSettings unset_field_iterations() {
    FieldRetrievalSettings f;
    f.iterations = -1;
    return f;
}

// Settings of −1 (−1.0) are unset: scheduled_settings resolves them, from the surface class,
// the calibration asked for and error bars (the one place the run's defaults live). A value
// the caller sets is kept as given.
struct RecoverSettings {
    BlurredFitSettings blurred;  // stage 0 (empty blur_widths: start the field stage from flat)
    // White light (no single-wavelength OHS / ROHS observation): stage 0 on the RGB slices with
    // these settings, then stage 3 (docs/recovery.md, White light).
    BlurredFitSettings white_blurred{{16.0, 8.0, 4.0, 2.0, 1.0, 0.5}, 40, 20, false, {}, 0, 0.0};
    // (After stage 3 up to two rounds of white light's defect repair follow: connected regions
    // of texels farther than 3 robust deviations from their neighbours' median, grown by one, up
    // to 64 texels, each shifted by whole wraps (λ̄/2) or set to the fill around it where that
    // lowers the loss (detail::repair_defect_regions), then stage 3 again.)
    // … and before stage 3, a smoothness continuation: stage 3's loss plus weight · mean (Δh)²
    // (h in texel units, Δ the 5-point Laplacian) for white_smoothness_iterations L-BFGS
    // iterations at each of these weights in turn (largest first; empty: none), which keeps the
    // refinement out of the wrap defects and checkerboards the spectral loss has as local minima.
    std::vector<double> white_smoothness{10.0, 1.0, 0.1, 0.01};
    int white_smoothness_iterations = 20;
    int blur_wavelengths = 1;  // stage 0 uses the slices of this many longest wavelengths (0: all)
    // Stage 1, per wavelength (its refine is replaced by `refine`). field.iterations −1: the
    // schedule's (50; smooth surfaces 25; rough ones up to the plan's 200).
    FieldRetrievalSettings field = unset_field_iterations();
    int refine = 0;  // object grid refinement; 0: auto_refine
    // Bound on the height range for unwrapping (stage 2); −1: the stated surface range (at least
    // 1e-3 µm), else 4 µm. The spatial unwrapping (the default) does not read it.
    double height_range_um = -1.0;
    // Stage 1 only at wavelengths ≥ this (µm; 0: all): a rough surface's plan (roughness_plan.h)
    // measures a long wavelength whose field starts stage 3, the shorter ones' fields (started
    // in wrong basins, measured to raise the error) are left out and their slices enter stage 3
    // only. When no wavelength reaches it, every wavelength runs the field stage.
    // −1: the rough plan's shortest long wavelength, else 0.
    double field_lambda_min_um = -1.0;
    // Stage 1 only at this many longest single-wavelength wavelengths (0: all; with
    // field_lambda_min_um > 0 that applies instead). Smooth surfaces: 1, the refinement then
    // reaches the same heights from the longest field alone.
    // −1: 1 on smooth surfaces without calibration, else 0.
    int field_wavelengths = -1;
    // Stage 3: L-BFGS on the heights in the full model, on the observations' amplitude loss.
    // −1: 8 on smooth surfaces without calibration (after the ladder), else 40; 40 with error_bars.
    int refine_iterations = -1;
    // Stage 3 as a continuation over the wavelengths (rough surfaces: roughness_plan.h;
    // docs/recovery.md, "Rough surfaces"): when > 0, before the refinement on every
    // observation, one round of refine_ladder_iterations L-BFGS iterations on the observations
    // at wavelengths ≥ each single-wavelength OHS / ROHS slice's wavelength that is ≥ this (µm),
    // longest first, each round started from the last (a rung adds one wavelength). 0 (the
    // default): the refinement on every observation at once. Not with calibrate.sigma or
    // calibrate.positions (their refinements run as before), nor for white light.
    // −1: the rough plan's (its shortest long wavelength), else 0.
    double refine_ladder_min_um = -1.0;
    int refine_ladder_iterations = 40;
    // The same ladder over this many longest single-wavelength wavelengths (0: none; with
    // refine_ladder_min_um > 0 that applies instead): with 1, refine_ladder_iterations on the
    // longest wavelength's slices alone (a fraction of the cost per iteration), then
    // refine_iterations on every slice (docs/recovery.md, "Settings by stage").
    // −1: 1 on smooth surfaces without calibration where refine_iterations is unset (a stated
    // count is the whole refinement), else 0.
    int refine_ladder_wavelengths = -1;
    // A ladder rung stops early once its loss / loss(flat) drops below this (0: every rung
    // runs refine_ladder_iterations; stage 3's own 1e-14 still applies). The rung's loss is
    // its slices' part of the mean over every observation. On exact data the loss tracks the
    // squared height error, and the refinement on every slice continues from where the rung
    // stopped; with noise the loss floor lies far above any useful value here, so the rung runs
    // to its cap as before.
    // −1: 1e-8 on smooth surfaces without calibration, else 0.
    double refine_ladder_relative_tolerance = -1.0;
    // A ladder rung also stops once its loss fell by less than refine_ladder_stall_tolerance (a
    // fraction of its value) over the last refine_ladder_stall_window iterations (0: off). A
    // rung trapped by a single-texel outlier stalls at a loss ≈ 1e-5 from its ~17th iteration on while an untrapped one falls by 25–50 % every 5: the repair after the rung
    // then comes without the idle iterations.
    // A rung with this rule (window and tolerance > 0) that reaches its cap without stalling,
    // above its relative tolerance, runs on under the rule, up to 4 × its cap in all: where the
    // truth holds a texel-scale texture the loss still falls 2–3 % an iteration at 40
    // (experiments/2026-11-30-refinement-budget.md).
    // −1: 5 on smooth surfaces without calibration, else 0.
    int refine_ladder_stall_window = -1;
    double refine_ladder_stall_tolerance = 0.01;
    // Single-texel outliers: after stage 3 with
    // single-wavelength slices (not white light, not with position calibration), up to this many
    // rounds of: texels farther than 6 robust deviations (and a quarter of the shortest
    // wavelength's λ/2) from the quadratic through their 8 neighbours, each tried at that
    // quadratic, the neighbours' median and ± λ/2 of every wavelength, judged by the loss of the
    // slices that see it and kept where that loss falls; where any was kept, 30 iterations of
    // the refinement on every slice (stopped early where loss / loss(flat) falls below
    // refine_ladder_relative_tolerance) (0: off). A texel the refinement left ≈ 0.22 µm off while every other
    // converged is a local minimum it does not leave (seeds 4 and 10632 at 32², 10423 at 64²).
    // −1: 3 on smooth surfaces without calibration (a second trapped texel may stand out only
    // once the first is repaired), else 1.
    int outlier_repair_rounds = -1;
    int refine_history = 20;
    // Stage 3's coarse space (docs/scale.md, "One machine: large surfaces"): levels of periodic
    // cubic B-splines of node spacing refine_coarse_spacing texels, doubled while an axis keeps
    // ≥ 4 nodes (0: off). With refine_coarse_weight > 0 L-BFGS runs on (x, c), h = x + weight·B c
    // (mean-free; gradient Bᵀ∇h, no new adjoint): the smooth directions get steps of their own
    // size. With refine_coarse_iterations > 0, after each round of stage 3 L-BFGS on c alone
    // (h fixed) for that many iterations. Default 16: on at 64² and above (one level of 4² nodes
    // at 64², none below: a surface of 32² runs as without it); at 128² it took seed 6501 from
    // 0.047 % to 0.0003 % (the whole-surface undulation gone).
    double refine_coarse_spacing = 16.0;
    double refine_coarse_weight = 1.0;
    int refine_coarse_iterations = 0;
    Loss refine_loss{LossKind::Amplitude, 1.0};
    // Self-calibration (calibration.h): parts of the acquisition refined with the heights.
    CalibrationSettings calibrate;
    // Model check (docs/recovery.md, "How it works"): after stage 3 the unwrapped heights
    // are refined as well in the field model (the zero-slope field on the fine grid of stage 1:
    // a scalar-diffraction model, not the Gabor expansion) for up to this many L-BFGS
    // iterations (stopping as the field stage does: field.stall_window, stall_tolerance), and
    // the heights whose own model explains the single-wavelength OHS / ROHS slices better
    // (relative amplitude loss, "misfit:gabor" / "misfit:field" in the metrics) are returned.
    // With refine_loss Poisson the Gabor heights are kept at once when their deviance is on the
    // photon-noise floor (misfit_on_photon_floor, convergence.h; "misfit:gabor-noise": D / E[D]).
    // 0: off (stage 3's heights).
    int model_check_iterations = 40;
    // The model check skips the field refinement and keeps stage 3's heights when misfit:gabor
    // is below this fraction of the field model's loss at the unwrapped heights (its start,
    // "misfit:field-start"; one evaluation): the refinement lowers that loss by ~25 % on Gabor
    // data and ~5 × on scalar-diffraction data, so it cannot win then. 0 to 1; 0: never skip.
    double model_check_skip_ratio = 0.1;
    // Stage 1 on overlapping tiles (docs/scale.md, "One machine: large surfaces"): along an
    // axis of more than field_tile_threshold texels (0: never) the field is retrieved on tiles
    // of about field_tile_core texels (8 … 4096) plus a margin of the footprint's reach and a
    // 4-texel feathering ramp, blended into one field. Not with calibrate.positions (its field
    // stage stays whole). Smaller surfaces: the whole surface.
    int field_tile_threshold = 64;
    int field_tile_core = 48;
    // With calibrate.positions, the outer loop (docs/recovery.md, "Self-calibration"; the
    // position loop's stage, stage_positions.cpp, with its own settings, schedule.cpp): after
    // stage 3, every position is registered on its own at the final heights (a grid search of
    // its full-model loss over ± 2 texels in half-texel steps about its offset, a parabola, one
    // Newton step), the affine part of the registration's update removed, positions far worse
    // than the median searched wide (over ± position_rescue_radius_texels), and the field stage
    // (while the registration still moves the offsets) and stage 3 run again from the registered
    // positions; at most this many times, stopping when the offsets stop moving or the loss
    // stalls (the recovery's one stall rule, src/core/stall_rule.h). 0: off (one recovery); −1:
    // the library's default (schedule.cpp, k_position_outer_passes: 40). At most 100.
    int position_outer_passes = -1;
    // How far the position loop searches a lost position (± texels, > 0 … 16) about its offset,
    // on a grid of the same number of points at any radius. The CLI and Python recover() raise
    // it to 4 × the stated position uncertainty (recovery_run.h).
    double position_rescue_radius_texels = 4.0;
    // The surface as stated (the schedule's choice between the smooth and the rough plan).
    SurfaceClass surface;
    // Error bars follow (uncertainty.h): an unset refine_iterations becomes at least
    // k_uncertainty_refine_iterations.
    bool error_bars = false;
};

// `settings` with every unset value (−1) resolved as recover_heights runs them (the schedule's
// defaults): smooth surfaces (settings.surface unstated, or stated and not rough by
// plan_for_roughness / plan_for_measured_roughness) without self-calibration get the smooth
// schedule (the field stage at the longest wavelength only, 25 iterations; the refinement on
// that wavelength's slices, then 8 iterations on every slice; 3 rounds of the outlier repair:
// the same heights as the longer schedule at about half the CPU time,
// experiments/2026-11-23-recovery-speed.md); rough ones the plan's field iterations, long
// wavelengths and refinement ladder; calibrated runs the library's longer schedule. Values set
// (not −1) are kept. Throws std::domain_error for texel_um ≤ 0 where a stated surface needs it.
RecoverSettings scheduled_settings(const RecoverSettings& settings, double texel_um);

// What recover_heights reports after every iteration of every stage: "blur:S" (blur stage S,
// iterations), "blur" (its result), "field:λ" (iterations, then with cascading its result
// after unwrapping), "unwrap", "refine", "repair:outliers" (only where a texel was flagged:
// iteration = texels changed, loss = texels evaluated; outlier_repair_rounds) and "refine" again
// where one changed, then with the model check (model_check_iterations)
// "misfit:gabor", with the Poisson loss "misfit:gabor-noise" (the Gabor deviance over its
// expectation; on the floor the Gabor heights are selected at once), "misfit:field-start" (the
// field model's loss at the unwrapped heights),
// "refine:field" (iterations), "misfit:field" (loss: each model's relative amplitude loss on
// the single-wavelength slices at its heights; the last two left out when
// model_check_skip_ratio skips the field refinement) and "select:gabor" or "select:field" (the
// heights returned).
//
// Every step carries its stage's kind and planned iteration total (what a progress bar needs),
// so that no front end reads the names.
enum class StageKind {
    BlurredFit,      // "blur:S": blur width S's iterations
    BlurredResult,   // "blur": the blurred fit's heights
    ExposuresHeld,   // "exposures:held"
    Field,           // "field:λ": the field retrieval at λ (µm)
    Unwrap,          // "unwrap"
    SigmaSearch,     // "sigma:…" (σ_p research at the unwrapped heights)
    Refine,          // "refine": the refinement on every slice
    RefineRung,      // "refine:λ": the wavelength ladder's rung at λ
    RefineCoarse,    // "refine:coarse": the coarse space's iterations
    CalibrateSigma,  // "calibrate:sigma": σ_p rounds
    RepairOutliers,  // "repair:outliers"
    RepairWhite,     // "repair": white light's defect repair
    Positions,       // "positions:register", "positions:newton", "positions:rescue", "positions:stall"
    ModelMisfit,     // "misfit:gabor", "misfit:gabor-noise", "misfit:field-start", "misfit:field-floor", "misfit:field"
    ModelRefine,     // "refine:field": the refinement in the field model
    ModelSelect,     // "select:gabor", "select:field"
    Thesis,          // "thesis": the thesis's Adam epochs (recover_heights_thesis)
    Other,           // none of the above (a stage the list does not know: a bug)
};
constexpr int k_stage_kinds = int(StageKind::Other) + 1;

// The kind's name: the metrics text of its steps (metrics.csv, run.json), whole ("blur",
// "unwrap"), or, ending in ':', the prefix of the steps named per width, wavelength or model
// ("field:" for "field:0.7"); "other" for Other.
const char* stage_kind_name(StageKind kind);

// The kind of a step named `stage` (exact names before prefixes: "refine:coarse" is
// RefineCoarse, "refine:0.7" RefineRung); Other for a name of no kind.
StageKind stage_kind(const std::string& stage);

// The most iterations a step of `kind` reports in one stage with `settings` as resolved by
// scheduled_settings (a progress bar's length, ≥ 1), or 0 for a kind reported once per result
// (blur, unwrap, repairs, positions, misfits, selections). Thesis: 0 here (its epochs are
// BaselineSettings').
int planned_iterations(const RecoverSettings& settings, StageKind kind);

struct StageMetrics {
    std::string stage;
    StageKind kind = StageKind::Other;
    int total = 0;  // planned_iterations for this stage (0: a result, reported once)
    int iteration = 0;
    double loss = 0.0;              // the stage's own loss (relative for the blur and field stages; 0 for results)
    double seconds = 0.0;           // since recover_heights started
    double height_rel_rmse = -1.0;  // when a truth is given and heights exist (else −1)
    double height_rel_rmse_plane_removed = -1.0;  // the same with the best-fit plane removed (else −1)
};

// The heightfield (rows × cols, values in texel units with the given texel_um and vscale)
// whose slices best match `observations`, from a flat start: the blurred fit and the fields on
// the single-wavelength OHS / ROHS observations, unwrapping, refinement on all observations
// (spectral ones included). Observations are used as given (measured, noisy or rendered).
// Per-pixel weights (observation.h) are honoured: the stages that fit the full slice model
// (refinement, positions, σ_p searches, exposures) count only the pixels of weight > 0, each
// with its weight, and the blurred fit, field stage and model check, whose models read whole
// slices, see the pixels of weight 0 filled from their weighted neighbours (a start only).
// on_step returning false stops the recovery and returns the estimate so far (flat, the
// blurred fit, the last unwrapped heights or the refinement's last step). `truth`, when given,
// only feeds height_rel_rmse in the metrics. Without any single-wavelength OHS / ROHS slice
// (white light: RGB slices only) the blurred fit runs on the RGB slices (white_blurred), then
// the refinement and the defect repair (docs/recovery.md, White light);
// no field stage. Throws std::invalid_argument when the observations
// are empty, or the truth's size differs;
// std::domain_error for vscale 0.
// `comm`: the ranks the observations are split over (collective; a rank's share may be
// empty). on_step is called on every rank and its stop is agreed (any rank's false stops all
// at the same step); the heights are the same bits on every rank. Equal to the one-process run
// (up to the order of the sums) when each wavelength's observations are in the order of their
// positions' first appearance (planned acquisitions are), as observation_share splits them.
// After the first collective step, an exception on one rank of several ends every rank
// (run_or_abort), since the others would wait for it.
// `calibration`, when given, receives the acquisition as refined with settings.calibrate
// (calibration.h; its per-observation entries follow `observations`).
Heightfield recover_heights(const std::vector<Observation>& observations, int rows, int cols, double texel_um,
                            double vscale, const RecoverSettings& settings = {},
                            const std::function<bool(const StageMetrics&)>& on_step = {},
                            const Heightfield* truth = nullptr, const Communicator& comm = serial_communicator(),
                            Calibration* calibration = nullptr);

// RMS of (estimate − truth) in µm after removing each one's mean, divided by the truth's
// height range max − min (µm). Throws std::invalid_argument on a size mismatch and
// std::domain_error when the truth is flat.
double height_rel_rmse(const Heightfield& estimate, const Heightfield& truth);

// The same with the best-fit plane a + b·x + c·y (least squares over the texel centres) removed
// from estimate − truth: the error that is not a tilt. A tilt of the light, or of the sample,
// moves every slice as a plane in the heights does, so a plane is not observable from the
// slices. Throws as height_rel_rmse does.
double height_rel_rmse_plane_removed(const Heightfield& estimate, const Heightfield& truth);

}  // namespace wavebrdf
