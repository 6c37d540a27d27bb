#pragma once
// The stall rule every iterative part of the recovery stops on (L-BFGS in each stage, the
// position loop's passes): a loss has stalled when its lowest value so far fell by less than
// `tolerance` × that lowest value over the last `window` evaluations. These losses have a floor
// (the model's own error, or the noise), and near it further iterations move the heights by far
// less than the next stage corrects.
//
// Judged on the lowest value, not the newest, so a loss that rises (the position loop's can) does
// not stall on one value that rose; and on the fall over the whole window, so a slow steady fall
// is not a stall. On a loss that never rises (every L-BFGS run: each accepted step lowers or keeps
// it) the lowest value is the newest, and the rule is the window difference
// loss[n − window] − loss[n] < tolerance · loss[n]. Tolerance 0 never stalls.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace wavebrdf::detail {

class StallRule {
public:
    // window ≤ 0: never stalls. tolerance: finite, ≥ 0 (the caller validates). Values: finite.
    StallRule(int window, double tolerance) : m_window(std::size_t(std::max(0, window))), m_tolerance(tolerance) {}

    // Records the loss after one more evaluation; true when the loss has stalled (quiet() ≥ window).
    bool stalled_at(double value) {
        m_lowest.push_back(m_lowest.empty() ? value : std::min(m_lowest.back(), value));
        return m_window > 0 && m_lowest.size() > m_window && fell_little(m_window);
    }

    // How many evaluations back the lowest value was still within the tolerance of today's: the
    // largest k with lowest[n − k] − lowest[n] < tolerance · lowest[n] (0: the newest value lowered
    // it by more, or nothing to compare). The loss has stalled once this reaches the window.
    int quiet() const {
        std::size_t k = 0;
        while (k + 1 < m_lowest.size() && fell_little(k + 1)) ++k;
        return int(k);
    }

    // Forgets every value (the next evaluations are a new start, e.g. heights from another stage).
    void restart() { m_lowest.clear(); }

private:
    // The lowest value fell by less than the tolerance over the last k evaluations (k < size).
    bool fell_little(std::size_t k) const {
        const double now = m_lowest.back();
        return m_lowest[m_lowest.size() - 1 - k] - now < m_tolerance * now;
    }

    std::size_t m_window;
    double m_tolerance;
    std::vector<double> m_lowest;  // the lowest value after each evaluation
};

}  // namespace wavebrdf::detail
