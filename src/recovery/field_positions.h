#pragma once
// Internal: position correction inside the field stage (self-calibration of positions,
// docs/recovery.md, "Self-calibration"), as ptychography's gradient-based position
// correction: the object's L-BFGS runs in chunks of a few iterations, and between chunks every
// footprint position's offset takes a few gradient steps at the fixed object.
//
// The gradient with respect to a footprint centre μ (FieldOperator's terms): the model is
// Ψ = A(P ⊙ O) with the window P_a ∝ e^{−|x_a − μ|²/(2σ_p²)} (the phases e^{−i2πu·δ_a},
// δ_a = x_a − μ, move by a common phase e^{i2πu·μ} that |Ψ| does not see), so
//   ∂L/∂μ = Σ_a Re(conj(G_a) O_a) · δ_a / σ_p²,   G = Aᴴ g  (the object's gradient, P inside),
// one adjoint per observation. The 3σ_p cut is held fixed (a sample entering or leaving it is
// a jump the derivative does not see).
#include <array>
#include <complex>
#include <functional>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// The amplitude loss Σ_k w_k (√c1_k |Ψ_k| − √R_k)² of observation `o` (single wavelength
// lambda_um, OHS or ROHS; w_k its pixel weights, 1 without; a pixel of weight 0 is not read)
// over its disk's pixels under FieldOperator(rows, cols, texel_um, query
// with the centre moved by offset_um, lambda_um, resolution, refine) applied to `object`
// ((rows·refine)·(cols·refine) samples). With `gradient_um` given it receives ∂loss/∂offset
// (per µm, x then y). Thread-safe; throws as FieldOperator for invalid arguments.
double field_position_loss(const Observation& o, const std::array<double, 2>& offset_um,
                           const std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                           double texel_um, int refine, std::array<double, 2>* gradient_um);

// The object shifted by (shift_x_um, shift_y_um) on its periodic grid (rows·refine ×
// cols·refine samples of spacing texel_um/refine): out(x) = object(x − shift), by a phase ramp
// on its discrete Fourier transform (exact for a band-limited object). Used for the gauge:
// moving every position by −m and the object by −m leaves every slice as it was.
std::vector<std::complex<double>> shift_object(const std::vector<std::complex<double>>& object, int rows, int cols,
                                               double texel_um, int refine, double shift_x_um, double shift_y_um);

// At the fixed object: `steps` gradient steps (per position, Barzilai–Borwein lengths capped
// at one texel, halved until the position's loss decreases) on every position's offset, all
// positions in lockstep; then the offsets' mean is removed and the object shifted with it (the
// gauge, shift_object). group: this rank's observations at lambda_um; position[g] its
// position's index into offsets_um (2 per position, every rank's, µm). Collective: each
// position's loss and gradient is summed exactly over its observations on every rank
// (core/exact_sum.h), so every rank takes the same steps and 1, 2, 3 ranks give the same bits.
// Returns the rms (over positions and coordinates, texels) of the offsets' change.
double correct_positions(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                         std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                         double texel_um, int refine, int steps, std::vector<double>& offsets_um,
                         const Communicator& comm);

// retrieve_field (recover.h) with position correction: L-BFGS on the object in chunks of
// chunk_iterations (restarted from the object so far, the observations at their stated
// centres + offsets_um), each followed by correct_positions(steps); settings.iterations in all.
// Stops early when a chunk ends on the stall rule and the offsets moved by less than 0.01 texel
// rms. Collective as retrieve_field; offsets_um is updated on every rank.
FieldRetrievalResult retrieve_field_with_positions(
    const std::vector<const Observation*>& group, const std::vector<std::size_t>& position, double lambda_um, int rows,
    int cols, double texel_um, const std::vector<std::complex<double>>& initial, const FieldRetrievalSettings& settings,
    const std::function<bool(int, double)>& on_iteration, std::vector<double>& offsets_um, const Communicator& comm,
    int chunk_iterations = 10, int steps = 3);

}  // namespace wavebrdf::detail
