#pragma once
// Internal: position correction inside the field stage (self-calibration of positions,
// docs/recovery.md, "Self-calibration: positions"), as ptychography's gradient-based position
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

// The amplitude loss Σ_k (√c1_k |Ψ_k| − √R_k)² of observation `o` (single wavelength
// lambda_um, OHS or ROHS) over its disk's pixels under FieldOperator(rows, cols, texel_um, query
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

// The cross-validation fold (0 … folds − 1) of observation o's stated position: cells of σ_p
// (o.query.sigma_p_um) coloured as a checkerboard for 2 folds, (cell x + cell y) mod 3 for 3,
// 2×2 colours for 4, so that a position's nearest neighbours (one step ≈ σ_p away) lie in other
// folds. Depends only on the stated query (every rank and every observation at one position
// agree). folds must be 2 … 4.
int position_fold(const Observation& o, int folds);

// Round 6 (docs/recovery.md, "Self-calibration: positions"): ptychography's annealing
// position correction (Maiden et al. 2012). At the fixed object every position's offset is
// moved to the best point of a grid of trial shifts of its own loss (the sum over its
// observations of field_position_loss): offset + (a, b)·radius/n, |a|, |b| ≤ n, n =
// max(2, ⌈radius⌉) (so the grid's step is at most one texel), kept only where it lowers that
// position's loss (ties: the offset so far); then the gauge (the offsets' mean removed, the
// object shifted with it). Collective: each position's trial losses are summed exactly over
// its observations on every rank (core/exact_sum.h), so every rank and any split give the same
// bits. Returns the rms (over positions and coordinates, texels) of the offsets' change.
// Throws std::invalid_argument for radius ≤ 0 or > 16 texels.
double search_positions(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                        std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                        double texel_um, int refine, double radius_texels, std::vector<double>& offsets_um,
                        const Communicator& comm);

// The annealing schedule of the field stage's position search (retrieve_field_with_positions):
// radius_texels > 0 turns it on. After every chunk of chunk_iterations L-BFGS iterations (the
// L-BFGS restarted after each move: its history is stale), search_positions with the radius
// radius_texels · 2^−round, but not below min_radius_texels, instead of the gradient steps.
struct PositionSearch {
    double radius_texels = 0.0;  // 0: off (the gradient steps of correct_positions)
    double min_radius_texels = 0.25;
    int chunk_iterations = 5;
    // Before each correction (the search or, with radius_texels 0, the gradient steps) the
    // object is projected onto pure-phase objects (every sample's amplitude set to the mean
    // amplitude, its phase kept; a reflecting surface's object is e^{−i(4π/λ)H}), and the
    // retrieval continues from the projection: a free amplitude can absorb the positions'
    // errors where overlapping footprints disagree. Measured not to help (round 6).
    bool project_phase = false;
};

// A study hook (experiments/recover_study.cpp): when set, called after every position
// correction round of retrieve_field_with_positions with the offsets (2 per position, µm).
// Not thread-safe to set while a recovery runs; empty by default.
void set_position_probe(std::function<void(const std::vector<double>&)> probe);
// Calls the probe (when set) with offsets (2 per position, µm); the outer loop calls it with
// stage 3's offsets before each registration.
void call_position_probe(const std::vector<double>& offsets_um);

// retrieve_field (recover.h) with position correction: L-BFGS on the object in chunks of
// chunk_iterations (restarted from the object so far, the observations at their stated
// centres + offsets_um), each followed by correct_positions(steps); settings.iterations in all.
// Stops early when a chunk ends on the stall rule and the offsets moved by less than 0.01 texel
// rms. With folds ≥ 2 (cross-validation, "leave the position out"): after each chunk, for
// each fold f (position_fold) the object is refitted (chunk_iterations from the object of all)
// to the observations outside f only, and f's positions are corrected against that refit,
// which has not seen their data for a chunk; the gauge then shifts the object of all.
// Measured not to help (docs/recovery.md, "round 4"): kept for the study, off by default.
// folds = 0: every position against the object of all (the default path, unchanged).
// search.radius_texels > 0: the annealing grid search (PositionSearch, search_positions) after
// each chunk of search.chunk_iterations instead of the gradient steps (folds must be 0).
// Collective as retrieve_field; offsets_um is updated on every rank.
FieldRetrievalResult retrieve_field_with_positions(
    const std::vector<const Observation*>& group, const std::vector<std::size_t>& position, double lambda_um, int rows,
    int cols, double texel_um, const std::vector<std::complex<double>>& initial, const FieldRetrievalSettings& settings,
    const std::function<bool(int, double)>& on_iteration, std::vector<double>& offsets_um, const Communicator& comm,
    int chunk_iterations = 10, int steps = 3, int folds = 0, const PositionSearch& search = {});

}  // namespace wavebrdf::detail
