#pragma once
// The stall rule every iterative stage of the recovery stops on: the loss fell by less than
// `tolerance` (a fraction of its current value) over the last `window` iterations. The loss
// of these stages has a floor (the model's own error, or the noise), and near it further
// iterations move the heights by far less than the next stage corrects.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace wavebrdf::detail {

class StallRule {
public:
    // window ≤ 0: never stalls. tolerance: finite, ≥ 0 (the caller validates).
    StallRule(int window, double tolerance) : m_window(std::size_t(std::max(0, window))), m_tolerance(tolerance) {}

    // Records the loss after one more iteration; true when the loss has stalled.
    bool stalled_at(double value) {
        m_values.push_back(value);
        return m_window > 0 && m_values.size() > m_window &&
               m_values[m_values.size() - 1 - m_window] - value < m_tolerance * value;
    }

private:
    std::size_t m_window;
    double m_tolerance;
    std::vector<double> m_values;
};

}  // namespace wavebrdf::detail
