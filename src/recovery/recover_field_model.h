#pragma once
// Internal: the recovery's model check (experiments/2026-11-23-scalar-diffraction-model-check.md). The refinement
// (stage 3) fits the Gabor model, whose tangent-plane kernels are a first-order approximation
// of the surface: on slices that do not follow it (a real surface, the scalar-diffraction
// simulator) its best fit can lie further from the truth than the unwrapped heights. Here the
// heights are refined as well in the field model (the zero-slope Gabor field on the grid
// `refine` times finer than the texels: FieldOperator, a scalar-diffraction model of the
// object e^{−i(4π/λ)H}) and the pipeline keeps the heights whose own model explains the
// single-wavelength slices better (model selection on the relative amplitude loss).
#include <array>
#include <cstddef>
#include <string>
#include <functional>
#include <memory>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "recovery/stage_report.h"

namespace wavebrdf::detail {

// How the field model's surface runs between the texel centres.
enum class Interpolant {
    Blend,  // refined_heights' blend of the Gabor kernels' tangent planes (recover.h)
    Cubic,  // the periodic cubic-convolution interpolant (Keys, a = −½): through every texel
            // centre, C¹, exact for polynomials of degree ≤ 2 (scalar_diffraction.h's)
};

// Texel heights → heights on the grid `refine` times finer (odd refine) as a linear map: each
// fine sample is a fixed stencil (at most 9 × 9 texels: the blend's 7 × 7 kernels and its
// central-difference slopes; the cubic's 4 × 4) of the texel heights about its texel, the
// same for every texel of the periodic tile.
class HeightInterpolant {
public:
    // rows, cols ≥ 1; texel_um > 0; refine odd, 1 … 63. Throws std::invalid_argument.
    HeightInterpolant(int rows, int cols, double texel_um, int refine, Interpolant kind = Interpolant::Cubic);
    // heights_um: rows·cols texel heights → (rows·refine)·(cols·refine) fine heights (µm).
    void apply(const std::vector<double>& heights_um, std::vector<double>& fine_um) const;
    // The transpose: a gradient on the fine samples → on the texels.
    void transpose(const std::vector<double>& fine, std::vector<double>& texels) const;

private:
    int m_rows, m_cols, m_refine;
    static constexpr int k_reach = 4;  // stencil: texels −4 … 4 about the sample's texel
    std::vector<double> m_weights;     // [sa][sb][di][dj]
};

// The field model's relative amplitude loss over single-wavelength OHS / ROHS observations,
//   L(H) = Σ_slices [Σ_box (√(e) √c1 |F_o e^{−i(4π/λ_o) H̃}| − √R)² + Σ_outside R] / Σ R,
// H̃ = HeightInterpolant(H), F_o the observation's FieldOperator (its query as given in
// `queries`, e.g. with calibrated positions and σ_p), e its exposure (the energy ratio Σ R /
// Σ c1|F O|², with its gradient) when calibrate_exposure, else 1. With gabor_window the
// footprint window is the Gabor model's (render_slice's): its kernels, spaced w and each
// spread by G(·, w/2), make a Gaussian of σ² = σ_p² + w²/4 (up to ripples below 1 %), where
// FieldOperator's, spaced d = w/refine, make one of σ_p² + d²/4; so F_o is built with
// σ'² = σ_p² + (w² − d²)/4 and its field scaled by σ_p/σ' (the same integral). Collective: every sum over
// the observations is exact (core/exact_sum.h), so the value and gradient are the same bits
// for any thread count and split over ranks. With Observation::weights every sum (the box's,
// outside it, Σ R, the exposure's) weighs each pixel; a pixel of weight 0 is not read
// (amplitude_loss.h).
class FieldModelLoss {
public:
    // observations (this rank's; none null, each single-wavelength OHS / ROHS) and queries
    // (one per observation). The observations are read where they are at every evaluation (no
    // copy of their references): they must outlive the loss. An evaluation holds one
    // wavelength's object on the fine grid at a time. Throws std::invalid_argument on a
    // mismatch or when every rank's references are all zero.
    FieldModelLoss(const std::vector<const Observation*>& observations, const std::vector<Query>& queries, int rows,
                   int cols, double texel_um, int refine, bool calibrate_exposure, const Communicator& comm,
                   Interpolant interpolant = Interpolant::Cubic, bool gabor_window = true);
    ~FieldModelLoss();
    // L at texel heights_um (rows·cols, µm); gradient (when given) ∂L/∂H (1/µm).
    double operator()(const std::vector<double>& heights_um, std::vector<double>* gradient) const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// The Gabor model's relative amplitude loss on the same observations, Σ(√(e f) − √R)² / Σ R
// with f the full model's slice (render_slice's, slopes included) of `heightfield` at each
// query, e as above; weighted as FieldModelLoss (e over the pixels of weight > 0,
// observation_exposure). Collective and exact as FieldModelLoss.
double gabor_amplitude_loss(const std::vector<const Observation*>& observations, const std::vector<Query>& queries,
                            const Heightfield& heightfield, bool calibrate_exposure, const Communicator& comm);

// The Gabor model's Poisson deviance on the same observations at `photons` > 0 per slice, with
// its expectation and variance were the slices Poisson counts of that model
// (slice_photon_deviance, convergence.h, per observation; exposures as above). Collective;
// each of the three sums exact (the same bits for any thread count and split over ranks).
SliceDeviance gabor_photon_deviance(const std::vector<const Observation*>& observations,
                                    const std::vector<Query>& queries, const Heightfield& heightfield,
                                    bool calibrate_exposure, double photons, const Communicator& comm);

// One evaluation of FieldModelLoss: its value and gradient (1/µm) at some heights.
struct FieldModelEvaluation {
    double loss = 0.0;
    std::vector<double> gradient;
};

// A heightfield's heights in µm (row-major, rows·cols): FieldModelLoss's argument.
std::vector<double> heights_um_of(const Heightfield& heights);

// L-BFGS on FieldModelLoss from `start` (its heights), at most `iterations` steps, stopping when
// the loss fell by less than stall_tolerance of its value over stall_window steps.
// on_iteration(iteration, loss, heights) returning false stops (agreed over the ranks by the
// caller). Returns the heights (values in start's texel units); *loss receives the final loss.
// at_start (optional): the model already evaluated at heights_um_of(start), used instead of
// L-BFGS's first evaluation (the same bits: the result does not change). Throws
// std::invalid_argument when its gradient's size is not start's.
Heightfield refine_in_field_model(const FieldModelLoss& model, const Heightfield& start, int iterations, int history,
                                  int stall_window, double stall_tolerance,
                                  const std::function<bool(int, double, const Heightfield&)>& on_iteration,
                                  double* loss, const FieldModelEvaluation* at_start = nullptr);

// The model check's shortcut: true when the Gabor model's loss at its refined heights is below
// skip_ratio times the field model's loss at its start (the unwrapped heights), so the field
// refinement is not run and the Gabor heights are kept. skip_ratio in [0, 1]; 0: never skip.
// Throws std::invalid_argument outside that range.
bool skip_field_refinement(double gabor_loss, double field_start_loss, double skip_ratio);

// The model check's settings (RecoverSettings' model_check_*, the field stage's L-BFGS history
// and stall rule, the exposure calibration).
struct ModelCheckSettings {
    int iterations = 40;      // the field model's refinement (RecoverSettings::model_check_iterations)
    double skip_ratio = 0.1;  // skip_field_refinement's (model_check_skip_ratio)
    int history = 20;         // FieldRetrievalSettings' history, stall_window, stall_tolerance
    int stall_window = 5;
    double stall_tolerance = 5e-3;
    bool calibrate_exposure = false;
    Loss loss{LossKind::Amplitude, 1.0};  // the refinement's (refine_loss): Poisson asks the photon floor
};

// The model check after stage 3 (RecoverSettings::model_check_iterations): `unwrapped` (stage
// 2's heights) refined in the field model at refine × the texels on the single-wavelength
// OHS / ROHS observations `separable` (this rank's; index[i]: its index in the run's
// observations, for offsets_um, one per observation, empty: none) with every σ_p × sigma_scale,
// compared with `refined` (stage 3's) in the Gabor model on the same slices; returns the
// heights of the model with the lower relative amplitude loss. report(stage, iteration, loss,
// heights) as recover_stages' ("misfit:gabor", "misfit:field-start", "refine:field",
// "misfit:field", "select:gabor" / "select:field"; with skip_field_refinement true the field
// refinement and "refine:field" / "misfit:field" are left out); a false stops and returns
// `refined`. Collective. field_floor_loss (> 0; 0: none): the smallest final relative loss of
// the field stage's retrievals, which minimised the same loss over free objects, a superset of
// the field model's pure-phase ones: when skip_field_refinement(misfit:gabor, field_floor_loss)
// holds already, the field model is not even built ("misfit:field-floor" reported instead of
// "misfit:field-start"; experiments/2026-11-23-recovery-speed.md). With settings.loss
// Poisson, next: "misfit:gabor-noise" (gabor_photon_deviance's D / E[D] at `refined`), and
// when misfit_on_photon_floor holds, "select:gabor" and `refined` without the field model.
Heightfield check_model(const std::vector<const Observation*>& separable, const std::vector<std::size_t>& index,
                        const std::vector<std::array<double, 2>>& offsets_um, double sigma_scale,
                        const Heightfield& unwrapped, const Heightfield& refined, int refine,
                        const ModelCheckSettings& settings, const StageReport& report, const Communicator& comm,
                        double field_floor_loss = 0.0);

}  // namespace wavebrdf::detail
