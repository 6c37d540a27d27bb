#pragma once
// Optimisers for the heights: Adam (the thesis's) and L-BFGS.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace wavebrdf {

// Adam (Kingma and Ba 2015) with an exponential learning-rate decay per epoch:
// lr_epoch = lr · exp(−decay · epoch). Defaults are the thesis's: 0.01, 0.9, 0.99, 0.005.
struct AdamOptions {
    double lr = 0.01;
    double beta1 = 0.9;
    double beta2 = 0.99;
    double epsilon = 1e-8;
    double decay = 0.005;
};

class Adam {
public:
    // Throws std::domain_error naming the option for lr ≤ 0, β outside [0, 1), ε ≤ 0,
    // decay < 0, or a non-finite value.
    Adam(std::size_t size, const AdamOptions& options = {});
    // One update of `x` (size as constructed) against `gradient`, at learning rate
    // lr · exp(−decay · epoch) with the given epoch (0-based).
    void step(std::vector<double>& x, const std::vector<double>& gradient, int epoch);
    double learning_rate(int epoch) const;

    // Full state, for checkpoints: moments and step count.
    struct State {
        std::vector<double> m, v;
        long long steps = 0;
    };
    const State& state() const { return m_state; }
    void set_state(const State& state);  // throws std::invalid_argument on a size mismatch

private:
    AdamOptions m_options;
    State m_state;
};

// Limited-memory BFGS with a backtracking (Armijo) line search, minimising f(x).
struct LbfgsOptions {
    int history = 10;            // pairs kept (m)
    int max_iterations = 100;
    double gradient_tolerance = 1e-10;  // stop when ‖g‖∞ ≤ this
    int max_line_search = 20;
};

struct LbfgsResult {
    int iterations = 0;
    int evaluations = 0;
    double value = 0.0;
    bool converged = false;
};

// `objective(x, gradient)` returns f(x) and writes ∇f(x) into gradient (resized to x.size()).
// `on_iteration(iteration, value)`, when given, is called after each accepted step; returning
// false stops the run.
LbfgsResult lbfgs_minimize(
    const std::function<double(const std::vector<double>&, std::vector<double>&)>& objective,
    std::vector<double>& x, const LbfgsOptions& options = {},
    const std::function<bool(int, double)>& on_iteration = {});

}  // namespace wavebrdf
