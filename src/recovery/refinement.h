#pragma once
// Internal: the refinement's pieces (recover.h, stage 3), for both its forms: on the heights
// alone and with the footprint positions as variables as well (recover_positions.h,
// refine_heights_and_positions). The observation objective is the full slice model
// (slice_plan.h) against every rank's observations, summed exactly; the rounds are L-BFGS with
// one report stream and the refinement's stopping rules.
#include <array>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/exact_sum.h"
#include "recovery/coarse_correction.h"
#include "recovery/observation_loss.h"
#include "recovery/stage_report.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::detail {

// Stage 3 stops once its loss / loss(flat heights) is below this: the heights are then exact
// to the precision of the single-precision slices.
inline constexpr double k_refine_relative_tolerance = 1e-14;

// The refinement's data term: the mean of `loss` over every rank's observations of the full
// slice model at heights x (texel units, rows · cols of `flat`), with its gradient. Each slice's
// plan is built on the first evaluation (on the thread that owns the observation) and keeps
// only its height-independent tables between evaluations: only the heights change. Each plan's
// gradient goes into the exact sum over its box (the texels its adjoint writes), so the sums
// are the same for any thread count and split over ranks.
// With positions (position_index non-null: observation i's gathered position, `positions` of
// them), x holds after the heights 2 offsets per position in texels; the offsets used are
// t − mean(t) per coordinate (a common shift is the surface's, which the slices cannot see) and
// a plan is rebuilt when its position's offset changed.
// Each slice's misfit is observation_loss.h's slice_misfit (weights, exposure and gradient);
// with calibrate_exposure its exposure is the energy ratio at every evaluation, its gradient
// included. Every σ_p is used × sigma_scale.
class ObservationObjective {
public:
    ObservationObjective(const std::vector<Observation>& observations, double observations_total,
                         const Heightfield& flat, const Loss& loss, bool calibrate_exposure, double sigma_scale,
                         const Communicator& comm, const std::vector<std::size_t>* position_index = nullptr,
                         std::size_t positions = 0);

    // The value (collective); g receives the gradient (x's size).
    double operator()(const std::vector<double>& x, std::vector<double>& g);

    double sigma_scale() const { return m_sigma_scale; }
    void set_sigma_scale(double s);  // every plan rebuilt at the next evaluation

    // The observations in the sum (one flag each; empty: all). A rung of the wavelength ladder
    // and the outlier repair's local losses sum over a part.
    const std::vector<char>& active() const { return m_active; }
    void set_active(std::vector<char> active) { m_active = std::move(active); }

    // Whether observation i's slice can see texel (row, col): its plan's gradient box holds it,
    // or it has no plan yet (nothing known: it may).
    bool sees(std::size_t i, int row, int col) const;

    // Each observation's exposure at the last evaluation that summed it (1 without calibration).
    const std::vector<double>& exposures() const { return m_exposures; }

    // The offsets in µm (2 per position, mean removed per coordinate) of the texel offsets that
    // follow the heights in x.
    std::vector<double> offsets_um(const std::vector<double>& x) const;

private:
    const std::vector<Observation>& m_observations;
    double m_total;
    const Heightfield& m_flat;
    Loss m_loss;
    bool m_calibrate_exposure;
    double m_sigma_scale;
    const Communicator& m_comm;
    const std::vector<std::size_t>* m_index;
    std::size_t m_positions, m_cells;
    std::vector<std::unique_ptr<SlicePlan<float>>> m_plans;
    std::vector<std::array<double, 2>> m_plan_offset;
    std::vector<std::vector<int>> m_box_rows, m_box_cols;
    ExactParallelSum m_exact_sum;
    std::vector<std::vector<double>> m_height_scratch;  // per thread, with positions
    std::vector<double> m_exposures;
    std::vector<char> m_active;
};

// Rounds of L-BFGS on x (the heights first, rows · cols of `flat`, then any further variables),
// each reporting every iteration with the heights it reached and counting iterations across
// rounds (done()). A round stops at its iteration count, where loss / reference_loss falls below
// max(k_refine_relative_tolerance, relative_tolerance), where the stall rule holds
// (core/stall_rule.h; window 0: never), or where a report returns false (then every later round
// returns at once). With a coarse basis (coarse_correction.h; x the heights alone), L-BFGS runs
// on the heights and the coarse coefficients together (coarse_joint), then, with
// coarse_iterations > 0, on the coefficients alone ("refine:coarse").
class RefinementRounds {
public:
    using Objective = std::function<double(const std::vector<double>&, std::vector<double>&)>;
    RefinementRounds(Objective objective, const Heightfield& flat, int history, double reference_loss,
                     StageReport report, const CoarseBasis* coarse = nullptr, bool coarse_joint = false,
                     int coarse_iterations = 0);

    // One round of at most `iterations` from x (updated); true when the stall rule stopped it.
    bool run(std::vector<double>& x, int iterations, const StageId& stage = StageKind::Refine,
             double relative_tolerance = 0.0, int stall_window = 0, double stall_tolerance = 0.0);

    bool go_on() const { return m_go_on; }  // false once a report asked to stop
    void stop() { m_go_on = false; }
    int done() const { return m_done; }  // iterations so far (the metrics' count)
    // Whether any iteration was reported, and the loss of the last one.
    bool reported() const { return m_reported; }
    double last_loss() const { return m_last_loss; }
    double reference_loss() const { return m_reference_loss; }
    void set_done(int done) { m_done = done; }
    const Objective& objective() const { return m_objective; }
    // The heights of x (its first rows · cols values).
    Heightfield heights_of(const std::vector<double>& x) const;

private:
    Objective m_objective;
    const Heightfield& m_flat;
    LbfgsOptions m_options;
    double m_reference_loss;
    StageReport m_report;
    const CoarseBasis* m_coarse;
    bool m_coarse_joint;
    int m_coarse_iterations;
    bool m_go_on = true;
    int m_done = 0;
    bool m_reported = false;
    double m_last_loss = 0.0;
};

// σ_p's self-calibration around the refinement (calibration_detail.h refine_sigma_scale): a
// golden-section search on log s at fixed x, reported as "calibrate:sigma", alternated with
// rounds of L-BFGS on x (refine_iterations / 6, the last one the rest). The objective's scale
// is left at the returned one.
double calibrate_sigma_rounds(ObservationObjective& objective, RefinementRounds& rounds, std::vector<double>& x,
                              int refine_iterations, const StageReport& report);

}  // namespace wavebrdf::detail
