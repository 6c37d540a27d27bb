// The refinement's observation objective and its L-BFGS rounds (refinement.h).
#include "recovery/refinement.h"

#include <algorithm>
#include <cstdio>
#include <omp.h>
#include <utility>

#include "core/stall_rule.h"
#include "recovery/calibration_detail.h"
#include "recovery/observation_loss.h"

namespace wavebrdf::detail {

ObservationObjective::ObservationObjective(const std::vector<Observation>& observations, double observations_total,
                                           const Heightfield& flat, const Loss& loss, bool calibrate_exposure,
                                           double sigma_scale, const Communicator& comm,
                                           const std::vector<std::size_t>* position_index, std::size_t positions)
    : m_observations(observations),
      m_total(observations_total),
      m_flat(flat),
      m_loss(loss),
      m_calibrate_exposure(calibrate_exposure),
      m_sigma_scale(sigma_scale),
      m_comm(comm),
      m_index(position_index),
      m_positions(position_index ? positions : 0),
      m_cells(flat.values().size()),
      m_plans(observations.size()),
      m_plan_offset(observations.size()),
      m_box_rows(observations.size()),
      m_box_cols(observations.size()),
      m_exact_sum(m_cells + 2 * m_positions),
      m_height_scratch(m_index ? std::size_t(std::max(1, omp_get_max_threads())) : 0),
      m_exposures(observations.size(), 1.0) {}

void ObservationObjective::set_sigma_scale(double s) {
    m_sigma_scale = s;
    for (auto& p : m_plans) p.reset();
}

bool ObservationObjective::sees(std::size_t i, int row, int col) const {
    return !m_plans[i] || (std::binary_search(m_box_rows[i].begin(), m_box_rows[i].end(), row) &&
                           std::binary_search(m_box_cols[i].begin(), m_box_cols[i].end(), col));
}

std::vector<double> ObservationObjective::offsets_um(const std::vector<double>& x) const {
    const double texel_um = m_flat.texel_um();
    std::vector<double> off(2 * m_positions);
    for (int c = 0; c < 2; ++c) {
        double mean = 0.0;
        for (std::size_t p = 0; p < m_positions; ++p) mean += x[m_cells + 2 * p + std::size_t(c)];
        mean /= double(m_positions);
        for (std::size_t p = 0; p < m_positions; ++p)
            off[2 * p + std::size_t(c)] = texel_um * (x[m_cells + 2 * p + std::size_t(c)] - mean);
    }
    return off;
}

double ObservationObjective::operator()(const std::vector<double>& x, std::vector<double>& g) {
    const double scale = 1.0 / m_total;  // all ranks' observations
    const std::size_t cols = std::size_t(m_flat.cols());
    const bool with_positions = m_index != nullptr;
    const std::vector<double> off = with_positions ? offsets_um(x) : std::vector<double>{};
    const std::vector<double> heights =
        with_positions ? std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(m_cells)) : std::vector<double>{};
    const std::vector<int> row0{0};
    const double value = m_exact_sum.run(m_observations.size(), m_comm, g, [&](std::size_t i, ExactScratch& scratch) {
        if (!m_active.empty() && !m_active[i]) return 0.0;
        const Observation& o = m_observations[i];
        const std::size_t p = with_positions ? (*m_index)[i] : 0;
        const std::array<double, 2> d = with_positions ? std::array<double, 2>{off[2 * p], off[2 * p + 1]}
                                                       : std::array<double, 2>{0.0, 0.0};
        // Built on the flat surface's geometry (no copy of the heights per observation), then
        // given the heights like every later call; with positions rebuilt where the offset moved
        // (the kernels, their window weights and the engines' tables all follow the centre).
        if (!m_plans[i] || (with_positions && m_plan_offset[i] != d)) {
            m_plans[i] = std::make_unique<SlicePlan<float>>(
                m_flat, calibrated_query(o, m_sigma_scale, with_positions ? &d : nullptr), o.lambdas_um,
                o.resolution, o.channels());
            m_plans[i]->gradient_box(m_box_rows[i], m_box_cols[i]);
            m_plan_offset[i] = d;
        }
        SlicePlan<float>& plan = *m_plans[i];
        plan.set_heights(with_positions ? heights : x);
        std::vector<double> d_estimate;
        const double v = slice_misfit(m_loss, plan.forward(), o, m_calibrate_exposure, &d_estimate, &m_exposures[i]);
        if (!with_positions) {
            plan.adjoint(d_estimate, scratch.vector(), scale);
            scratch.take_box(m_box_rows[i], m_box_cols[i], cols);
        } else {
            std::vector<double>& s = scratch.vector();
            // The adjoint writes rows·cols values: into this thread's zeroed height scratch, of
            // which the box is moved into the exact sum's scratch (the cost of the footprint).
            std::vector<double>& grad = m_height_scratch[std::size_t(omp_get_thread_num())];
            if (grad.size() != m_cells) grad.assign(m_cells, 0.0);
            const std::array<double, 2> gp = plan.adjoint_with_position(d_estimate, grad, scale);
            for (int r : m_box_rows[i])
                for (int c : m_box_cols[i]) {
                    const std::size_t at = std::size_t(r) * cols + std::size_t(c);
                    s[at] = grad[at];
                    grad[at] = 0.0;
                }
            scratch.take_box(m_box_rows[i], m_box_cols[i], cols);
            s[m_cells + 2 * p] += gp[0];
            s[m_cells + 2 * p + 1] += gp[1];
            scratch.take_box(row0, {int(m_cells + 2 * p), int(m_cells + 2 * p + 1)}, 1);
        }
        plan.release();
        return scale * v;
    });
    if (with_positions) {
        // Chain rule through the gauge (t − mean t) and the unit (µm per texel): the same on
        // every rank (the sums are exact and allreduced).
        const double texel_um = m_flat.texel_um();
        for (int c = 0; c < 2; ++c) {
            double mean = 0.0;
            for (std::size_t p = 0; p < m_positions; ++p) mean += g[m_cells + 2 * p + std::size_t(c)];
            mean /= double(m_positions);
            for (std::size_t p = 0; p < m_positions; ++p) {
                double& gp = g[m_cells + 2 * p + std::size_t(c)];
                gp = texel_um * (gp - mean);
            }
        }
    }
    return value;
}

std::string stage_part(double value) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", value);
    return text;
}

RefinementRounds::RefinementRounds(Objective objective, const Heightfield& flat, int history, double reference_loss,
                                   StageReport report, const CoarseBasis* coarse, bool coarse_joint,
                                   int coarse_iterations)
    : m_objective(std::move(objective)),
      m_flat(flat),
      m_reference_loss(reference_loss),
      m_report(std::move(report)),
      m_coarse(coarse),
      m_coarse_joint(coarse_joint),
      m_coarse_iterations(coarse_iterations) {
    m_options.history = history;
    m_options.gradient_tolerance = 0.0;
}

Heightfield RefinementRounds::heights_of(const std::vector<double>& x) const {
    const std::size_t cells = m_flat.values().size();
    if (x.size() == cells) return m_flat.with_values(x);
    return m_flat.with_values(std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(cells)));
}

bool RefinementRounds::run(std::vector<double>& x, int iterations, const StageId& stage, double relative_tolerance,
                           int stall_window, double stall_tolerance) {
    if (iterations <= 0 || !m_go_on) return false;
    const double stop_below = std::max(k_refine_relative_tolerance, relative_tolerance) * m_reference_loss;
    LbfgsOptions round = m_options;
    round.max_iterations = iterations;
    const int before = m_done;
    // The stall rule (the values are every rank's: all agree).
    StallRule stall(stall_window, stall_tolerance);
    bool stalled = false;
    const auto go_on_at = [&](double value) {
        if (stall.stalled_at(value) && value > stop_below) stalled = true;
        return !stalled && value > stop_below;
    };
    if (m_coarse && m_coarse_joint) {
        // L-BFGS on z = (x, c), h = x + B c.
        std::vector<double> z(x.size() + m_coarse->size(), 0.0);
        std::copy(x.begin(), x.end(), z.begin());
        lbfgs_minimize(coarse_objective(m_objective, *m_coarse), z, round, [&](int it, double value) {
            m_done = before + it;
            x = coarse_heights(z, *m_coarse);
            const Heightfield current = m_flat.with_values(x);
            m_reported = true;
            m_last_loss = value;
            if (!m_report(stage, m_done, value, &current)) return m_go_on = false;
            return go_on_at(value);
        });
        x = coarse_heights(z, *m_coarse);
    } else {
        lbfgs_minimize(m_objective, x, round, [&](int it, double value) {
            m_done = before + it;
            const Heightfield current = heights_of(x);
            m_reported = true;
            m_last_loss = value;
            if (!m_report(stage, m_done, value, &current)) return m_go_on = false;
            return go_on_at(value);
        });
    }
    if (m_coarse && m_coarse_iterations > 0 && m_go_on) {
        // L-BFGS on c alone, h fixed: the smooth directions by themselves.
        const std::vector<double> h0 = x;
        std::vector<double> c(m_coarse->size(), 0.0);
        LbfgsOptions co = m_options;
        co.max_iterations = m_coarse_iterations;
        lbfgs_minimize(coarse_only_objective(m_objective, *m_coarse, h0), c, co, [&](int it, double value) {
            x = h0;
            m_coarse->apply(c.data(), x);
            const Heightfield current = m_flat.with_values(x);
            return m_go_on = m_report(StageKind::RefineCoarse, it, value, &current);
        });
        x = h0;
        m_coarse->apply(c.data(), x);
    }
    return stalled;
}

double calibrate_sigma_rounds(ObservationObjective& objective, RefinementRounds& rounds, std::vector<double>& x,
                              int refine_iterations, const StageReport& report) {
    std::vector<double> no_g;
    const double s = refine_sigma_scale(
        [&](double scale) {
            objective.set_sigma_scale(scale);
            return objective(x, no_g);
        },
        [&](int round, double scale, double value) {
            objective.set_sigma_scale(scale);
            const Heightfield current = rounds.heights_of(x);
            if (!report(StageKind::CalibrateSigma, round, value, &current)) {
                rounds.stop();
                return false;
            }
            rounds.run(x, round + 1 < k_sigma_rounds ? std::max(1, refine_iterations / (2 * k_sigma_rounds))
                                                     : std::max(1, refine_iterations - rounds.done()));
            return rounds.go_on();
        },
        objective.sigma_scale());
    objective.set_sigma_scale(s);
    return s;
}

}  // namespace wavebrdf::detail
