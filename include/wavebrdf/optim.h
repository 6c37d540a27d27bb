#pragma once
// Optimisers for the heights: Adam (the thesis's) and L-BFGS.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace wavebrdf {

// The most epochs or iterations any run accepts (inversion, recovery stages, the thesis's
// baseline): ten million, beyond a week at the fastest epoch (~50 ms), and far inside int
// arithmetic (2147483647 epochs overflowed the progress total).
constexpr int k_max_iterations = 10'000'000;

// Throws std::invalid_argument "<name> <count> is out of range; expected 0 to 10000000"
// unless 0 ≤ count ≤ k_max_iterations.
void validate_iterations(long long count, const std::string& name);

// Adam (Kingma and Ba 2015, Algorithm 1) with an exponential learning-rate decay per epoch:
// lr_epoch = lr · exp(−decay · epoch). Defaults are the thesis's: 0.01, 0.9, 0.99, 0.005.
// Each step t = 1, 2, ...: m ← β₁m + (1 − β₁)g, v ← β₂v + (1 − β₂)g², m̂ = m/(1 − β₁ᵗ),
// v̂ = v/(1 − β₂ᵗ), x ← x − lr_epoch · m̂/(√v̂ + ε). The step count t (bias correction) and the
// epoch (learning rate) are independent, so several steps may share one epoch.
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
    // lr · exp(−decay · epoch) with the given epoch (0-based). Throws std::invalid_argument on
    // a size mismatch or epoch < 0, std::domain_error on a non-finite gradient entry; in
    // both cases before changing x or the state.
    void step(std::vector<double>& x, const std::vector<double>& gradient, int epoch);
    // lr · exp(−decay · epoch); throws std::invalid_argument for epoch < 0.
    double learning_rate(int epoch) const;

    // Full state, for checkpoints: moments and step count.
    struct State {
        std::vector<double> m, v;
        long long steps = 0;
    };
    const State& state() const { return m_state; }
    // Throws std::invalid_argument on a size mismatch, steps < 0, or a non-finite moment or
    // v < 0 (a corrupt checkpoint), leaving the state unchanged.
    void set_state(const State& state);

private:
    AdamOptions m_options;
    State m_state;
};

// Limited-memory BFGS with a backtracking (Armijo) line search, minimising f(x)
// (Nocedal and Wright 2006, Algorithms 7.4, 7.5 and 3.1). Direction by the two-loop recursion
// with H₀ = (sᵀy / yᵀy) I from the newest pair; pairs with sᵀy ≤ 1e-12 |s||y| are skipped.
// Line search: c₁ = 1e-4, halving, starting at step 1, or at min(1, 1/‖g‖₂) while no pair is
// kept (the first iteration, and after a reset); a non-finite trial value or gradient counts
// as a failed trial. Options are validated with std::domain_error naming the option
// (history ≥ 1, max_iterations ≥ 0, gradient_tolerance finite and ≥ 0, max_line_search ≥ 1).
struct LbfgsOptions {
    int history = 10;  // pairs kept (m)
    int max_iterations = 100;
    double gradient_tolerance = 1e-10;  // stop when ‖g‖∞ ≤ this
    int max_line_search = 20;
    // Keep the pairs s, y in float (half the history's memory: 8·history·size bytes instead of
    // 16·history·size); ρ, the direction and every dot product stay in double. The recursion then
    // uses the rounded pairs (relative 6e-8), a slightly different H; off: double, as before.
    bool float_history = false;
};

struct LbfgsResult {
    int iterations = 0;      // accepted steps
    int evaluations = 0;     // calls of the objective, the one at the start included
    double value = 0.0;      // f at the returned x
    bool converged = false;  // ‖g‖∞ ≤ gradient_tolerance at the returned x
};

// The curvature history of lbfgs_minimize, for checkpoints: the kept pairs, oldest first,
// s_k = x_{k+1} − x_k and y_k = ∇f(x_{k+1}) − ∇f(x_k), and ρ_k = 1 / s_kᵀy_k (> 0). Empty: no
// curvature known yet (the start). With x this is everything the next iteration depends on:
// f and ∇f at x are evaluated again, which gives the same values for a deterministic objective.
struct LbfgsState {
    std::vector<std::vector<double>> s, y;
    std::vector<double> rho;
};

// Throws std::invalid_argument naming what is wrong when `state` cannot continue a run on
// `size` parameters with `history` pairs kept: unequal pair counts, more pairs than
// `history`, a vector not of `size`, a non-finite entry, or ρ not finite and > 0.
void validate_lbfgs_state(const LbfgsState& state, std::size_t size, int history);

// `objective(x, gradient)` returns f(x) and writes ∇f(x) into gradient (resized to x.size()).
// `on_iteration(iteration, value)`, when given, is called after each accepted step; returning
// false stops the run. Trial points are evaluated in a separate vector, so `x` only ever holds
// accepted points, and during on_iteration it already holds the newest one. Stops also at the
// gradient tolerance, after max_iterations, or when a line search finds no acceptable step in
// max_line_search trials; x is then the last accepted point and `value` its f. Throws
// std::invalid_argument for an empty x or objective or an objective that resizes the
// gradient, std::domain_error when f or ∇f at the starting x is not finite.
// `state`, when given, is the curvature history to start from (validate_lbfgs_state; empty
// for a fresh start) and is updated after every accepted step, before on_iteration: a run
// stopped there and started again from the same x and *state takes exactly the steps the
// uninterrupted run takes (bit for bit, for a deterministic objective). iteration counts
// this call's steps only.
LbfgsResult lbfgs_minimize(const std::function<double(const std::vector<double>&, std::vector<double>&)>& objective,
                           std::vector<double>& x, const LbfgsOptions& options = {},
                           const std::function<bool(int, double)>& on_iteration = {}, LbfgsState* state = nullptr);

}  // namespace wavebrdf
