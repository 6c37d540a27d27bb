#pragma once
// Internal: the design loop's evaluation (design_run.cpp), here so that the tests can check its
// gradient against finite differences.
#include <vector>

#include "design/engine.h"
#include "design/target.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf::detail {

// The loop's evaluation: level weights → loss (mean over the fabrication scale samples) and
// its gradient with respect to the weights and, when asked, the level step (the levels are
// 0, Δ, …, (K − 1)Δ: Δ starts at the prepared design's step and is the loop's to move,
// set_step_um).
class Evaluator {
public:
    Evaluator(const PreparedDesign& p, std::vector<double> scales)
        : m_p(p), m_sets(*p.order_sets), m_spectra(p.options.size, p.options.levels), m_scales(std::move(scales)) {
        m_heights.base_um = 0.0;
        m_heights.step_um = p.levels_um[1] - p.levels_um[0];
    }

    double step_um() const { return m_heights.step_um; }
    void set_step_um(double step_um) { m_heights.step_um = step_um; }

    // step_gradient (with gradient): ∂loss/∂Δ.
    double evaluate(const std::vector<double>& weights, std::vector<double>* gradient, Fractions* nominal = nullptr,
                    double* step_gradient = nullptr) {
        m_spectra.forward(weights);
        const int K = m_p.options.levels, N = m_p.options.size;
        if (gradient) m_buffers.reset(K, N);
        double loss = 0.0;
        if (step_gradient) *step_gradient = 0.0;
        const double inv = 1.0 / static_cast<double>(m_scales.size());
        for (double scale : m_scales) {
            const LevelHeights h{m_heights.base_um * scale, m_heights.step_um * scale};
            m_flux.resize(m_sets.size());
            m_amplitude.resize(m_sets.size());
            for (std::size_t w = 0; w < m_sets.size(); ++w)
                order_flux(m_sets[w], m_spectra, h, m_amplitude[w], m_flux[w]);
            const Fractions f = group_fractions(*m_p.target, m_flux);
            if (nominal && scale == 1.0) *nominal = f;
            Fractions df;
            loss += inv * m_p.target->loss(f, gradient ? &df : nullptr);
            if (!gradient) continue;
            for (auto& d : df)
                for (double& x : d) x *= inv;
            flux_gradient(*m_p.target, m_flux, f, df, m_grad);
            for (std::size_t w = 0; w < m_sets.size(); ++w) {
                order_flux_adjoint(m_sets[w], h, m_amplitude[w], m_grad[w], K, m_buffers);
                // The heights' step is scale · Δ.
                if (step_gradient)
                    *step_gradient += scale * order_flux_step_gradient(m_sets[w], m_spectra, h, m_amplitude[w], m_grad[w]);
            }
        }
        if (gradient) m_spectra.adjoint(m_buffers.sum(), *gradient);
        return loss;
    }

private:
    const PreparedDesign& m_p;
    const std::vector<OrderSet>& m_sets;
    LevelSpectra m_spectra;
    std::vector<double> m_scales;
    LevelHeights m_heights;
    GradientBuffers m_buffers;
    std::vector<std::vector<Complex>> m_amplitude;
    std::vector<std::vector<double>> m_flux, m_grad;
};


}  // namespace wavebrdf::detail
