#include "wavebrdf/optim.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// L-BFGS's two-loop recursion on vectors this long (the field stage's band spectrum: ~5e5
// values, 20 pairs read twice per iteration) runs on all threads: on one it held the other core
// idle for ~10 % of the field stage. Its dot products are summed over fixed chunks of
// k_lbfgs_chunk values, the chunks' partial sums added in chunk order, so the result is the
// same for any thread count. Shorter vectors keep Eigen's own (serial) sums, bit for bit.
constexpr Eigen::Index k_lbfgs_parallel_length = Eigen::Index(1) << 17;
constexpr Eigen::Index k_lbfgs_chunk = Eigen::Index(1) << 13;

// aᵀb (each in float or double, summed in double) over fixed chunks, on all threads.
template <class A, class B>
double chunked_dot(const A& a, const B& b) {
    const Eigen::Index n = b.size(), chunks = (n + k_lbfgs_chunk - 1) / k_lbfgs_chunk;
    std::vector<double> part(static_cast<std::size_t>(chunks));
#pragma omp parallel for schedule(static) if (!detail::in_parallel_region())
    for (Eigen::Index c = 0; c < chunks; ++c) {
        const Eigen::Index first = c * k_lbfgs_chunk, len = std::min(k_lbfgs_chunk, n - first);
        part[static_cast<std::size_t>(c)] =
            a.segment(first, len).template cast<double>().dot(b.segment(first, len).template cast<double>());
    }
    double sum = 0.0;
    for (double p : part) sum += p;
    return sum;
}
// v += s·a (a in float or double), on all threads (elementwise: the same for any thread count).
template <class A>
void parallel_add(const A& a, double s, Eigen::VectorXd& v) {
    const Eigen::Index n = v.size(), chunks = (n + k_lbfgs_chunk - 1) / k_lbfgs_chunk;
#pragma omp parallel for schedule(static) if (!detail::in_parallel_region())
    for (Eigen::Index c = 0; c < chunks; ++c) {
        const Eigen::Index first = c * k_lbfgs_chunk, len = std::min(k_lbfgs_chunk, n - first);
        v.segment(first, len) += s * a.segment(first, len).template cast<double>();
    }
}

void require(bool ok, const char* option, double value, const char* expected) {
    if (!ok) throw std::domain_error(std::string(option) + " must be " + expected + ", got " + format_shortest(value));
}

}  // namespace

void validate_iterations(long long count, const std::string& name) {
    if (count < 0 || count > k_max_iterations)
        throw std::invalid_argument(name + " " + std::to_string(count) + " is out of range; expected 0 to " +
                                    std::to_string(k_max_iterations));
}

// ---------------------------------------------------------------------------------------------
// Adam

Adam::Adam(std::size_t size, const AdamOptions& options) : m_options(options) {
    const auto finite = [](double v) { return std::isfinite(v); };
    require(finite(options.lr) && options.lr > 0.0, "Adam lr", options.lr, "finite and > 0");
    require(finite(options.beta1) && options.beta1 >= 0.0 && options.beta1 < 1.0, "Adam beta1", options.beta1,
            "in [0, 1)");
    require(finite(options.beta2) && options.beta2 >= 0.0 && options.beta2 < 1.0, "Adam beta2", options.beta2,
            "in [0, 1)");
    require(finite(options.epsilon) && options.epsilon > 0.0, "Adam epsilon", options.epsilon, "finite and > 0");
    require(finite(options.decay) && options.decay >= 0.0, "Adam decay", options.decay, "finite and >= 0");
    m_state.m.assign(size, 0.0);
    m_state.v.assign(size, 0.0);
    m_state.steps = 0;
}

double Adam::learning_rate(int epoch) const {
    if (epoch < 0) throw std::invalid_argument("Adam: epoch must be >= 0, got " + std::to_string(epoch));
    return m_options.lr * std::exp(-m_options.decay * static_cast<double>(epoch));
}

void Adam::step(std::vector<double>& x, const std::vector<double>& gradient, int epoch) {
    const std::size_t n = m_state.m.size();
    if (x.size() != n || gradient.size() != n)
        throw std::invalid_argument("Adam::step: expected " + std::to_string(n) + " parameters and gradients, got " +
                                    std::to_string(x.size()) + " and " + std::to_string(gradient.size()));
    // Checked before any update, so that one NaN does not poison the moments for good and the
    // caller can still checkpoint the last good state.
    for (std::size_t i = 0; i < n; ++i)
        if (!std::isfinite(gradient[i]))
            throw std::domain_error("Adam::step: gradient[" + std::to_string(i) + "] is not finite (" +
                                    format_shortest(gradient[i]) + ")");
    const double lr = learning_rate(epoch);
    const long long t = m_state.steps + 1;
    const double b1 = m_options.beta1, b2 = m_options.beta2, eps = m_options.epsilon;
    // Bias corrections 1 − β^t of Kingma and Ba (2015), Algorithm 1.
    const double c1 = 1.0 - std::pow(b1, static_cast<double>(t));
    const double c2 = 1.0 - std::pow(b2, static_cast<double>(t));
    double* m = m_state.m.data();
    double* v = m_state.v.data();
    for (std::size_t i = 0; i < n; ++i) {
        const double g = gradient[i];
        m[i] = b1 * m[i] + (1.0 - b1) * g;
        v[i] = b2 * v[i] + (1.0 - b2) * g * g;
        const double m_hat = m[i] / c1, v_hat = v[i] / c2;
        x[i] -= lr * m_hat / (std::sqrt(v_hat) + eps);
    }
    m_state.steps = t;
}

void Adam::set_state(const State& state) {
    const std::size_t n = m_state.m.size();
    if (state.m.size() != n || state.v.size() != n)
        throw std::invalid_argument("Adam::set_state: expected moments of size " + std::to_string(n) + ", got " +
                                    std::to_string(state.m.size()) + " and " + std::to_string(state.v.size()));
    if (state.steps < 0)
        throw std::invalid_argument("Adam::set_state: steps must be >= 0, got " + std::to_string(state.steps));
    for (std::size_t i = 0; i < n; ++i)
        if (!std::isfinite(state.m[i]) || !std::isfinite(state.v[i]) || state.v[i] < 0.0)
            throw std::invalid_argument("Adam::set_state: moment " + std::to_string(i) +
                                        " is not finite or v < 0 (m = " + format_shortest(state.m[i]) +
                                        ", v = " + format_shortest(state.v[i]) + ")");
    m_state = state;
}

// ---------------------------------------------------------------------------------------------
// L-BFGS (Nocedal and Wright 2006, Algorithm 7.4 and 7.5; Armijo backtracking, Algorithm 3.1)

void validate_lbfgs_state(const LbfgsState& state, std::size_t size, int history) {
    const std::size_t pairs = state.s.size();
    if (state.y.size() != pairs || state.rho.size() != pairs)
        throw std::invalid_argument("L-BFGS state: " + std::to_string(state.s.size()) + " s, " +
                                    std::to_string(state.y.size()) + " y and " + std::to_string(state.rho.size()) +
                                    " rho; expected equal counts");
    if (pairs > static_cast<std::size_t>(std::max(history, 0)))
        throw std::invalid_argument("L-BFGS state: " + std::to_string(pairs) + " pairs; expected at most " +
                                    std::to_string(history) + " (the history kept)");
    for (std::size_t k = 0; k < pairs; ++k) {
        if (state.s[k].size() != size || state.y[k].size() != size)
            throw std::invalid_argument(
                "L-BFGS state: pair " + std::to_string(k) + " has " + std::to_string(state.s[k].size()) + " and " +
                std::to_string(state.y[k].size()) + " values; expected " + std::to_string(size));
        const auto finite = [](const std::vector<double>& v) {
            return std::all_of(v.begin(), v.end(), [](double a) { return std::isfinite(a); });
        };
        if (!finite(state.s[k]) || !finite(state.y[k]) || !std::isfinite(state.rho[k]) || !(state.rho[k] > 0.0))
            throw std::invalid_argument("L-BFGS state: pair " + std::to_string(k) +
                                        " is not finite or its rho is not > 0 (rho = " + format_shortest(state.rho[k]) +
                                        ")");
    }
}

LbfgsResult lbfgs_minimize(const std::function<double(const std::vector<double>&, std::vector<double>&)>& objective,
                           std::vector<double>& x, const LbfgsOptions& options,
                           const std::function<bool(int, double)>& on_iteration, LbfgsState* state) {
    require(options.history >= 1, "L-BFGS history", options.history, ">= 1");
    require(options.max_iterations >= 0, "L-BFGS max_iterations", options.max_iterations, ">= 0");
    require(std::isfinite(options.gradient_tolerance) && options.gradient_tolerance >= 0.0, "L-BFGS gradient_tolerance",
            options.gradient_tolerance, "finite and >= 0");
    require(options.max_line_search >= 1, "L-BFGS max_line_search", options.max_line_search, ">= 1");
    if (!objective) throw std::invalid_argument("lbfgs_minimize: the objective is empty");
    if (x.empty()) throw std::invalid_argument("lbfgs_minimize: x is empty");
    if (state) validate_lbfgs_state(*state, x.size(), options.history);

    using Vec = Eigen::VectorXd;
    const std::size_t n = x.size();
    const auto en = static_cast<Eigen::Index>(n);
    constexpr double c1 = 1e-4;               // Armijo's sufficient-decrease constant
    constexpr double curvature_skip = 1e-12;  // pairs with sᵀy ≤ this·|s||y| are not kept

    LbfgsResult result;
    std::vector<double> trial(n), trial_gradient(n), g_std(n);
    // One evaluation, counted, with its gradient checked for size.
    const auto evaluate = [&](const std::vector<double>& at, std::vector<double>& grad) {
        grad.assign(n, 0.0);
        const double f = objective(at, grad);
        ++result.evaluations;
        if (grad.size() != n)
            throw std::invalid_argument("lbfgs_minimize: the objective resized the gradient to " +
                                        std::to_string(grad.size()) + ", expected " + std::to_string(n));
        return f;
    };
    const auto all_finite = [](const std::vector<double>& v) {
        return std::all_of(v.begin(), v.end(), [](double a) { return std::isfinite(a); });
    };

    double f = evaluate(x, g_std);
    if (!std::isfinite(f) || !all_finite(g_std))
        throw std::domain_error("lbfgs_minimize: the objective or its gradient is not finite at the start (f = " +
                                format_shortest(f) + ")");
    Vec xv = Eigen::Map<const Vec>(x.data(), en);
    Vec g = Eigen::Map<const Vec>(g_std.data(), en);
    result.value = f;
    result.converged = g.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance;

    // A pair in double (s, y) or, with float_history, in float (sf, yf; s and y empty).
    using VecF = Eigen::VectorXf;
    struct Pair {
        Vec s, y;
        VecF sf, yf;
        double rho;  // 1 / sᵀy (of the pair before any rounding to float)
    };
    const bool in_float = options.float_history;
    const auto make_pair = [&](Vec s, Vec y, double rho) {
        Pair p;
        if (in_float) {
            p.sf = s.cast<float>();
            p.yf = y.cast<float>();
        } else {
            p.s = std::move(s);
            p.y = std::move(y);
        }
        p.rho = rho;
        return p;
    };
    // sᵀv, yᵀv and v += a·s, v += a·y of a pair, whichever its storage (long vectors: on all
    // threads, chunked_dot / parallel_add).
    const bool parallel = en >= k_lbfgs_parallel_length;
    const auto s_dot = [&](const Pair& p, const Vec& v) {
        if (parallel) return in_float ? chunked_dot(p.sf, v) : chunked_dot(p.s, v);
        return in_float ? p.sf.cast<double>().dot(v) : p.s.dot(v);
    };
    const auto y_dot = [&](const Pair& p, const Vec& v) {
        if (parallel) return in_float ? chunked_dot(p.yf, v) : chunked_dot(p.y, v);
        return in_float ? p.yf.cast<double>().dot(v) : p.y.dot(v);
    };
    const auto add_s = [&](const Pair& p, double a, Vec& v) {
        if (parallel && in_float)
            parallel_add(p.sf, a, v);
        else if (parallel)
            parallel_add(p.s, a, v);
        else if (in_float)
            v += a * p.sf.cast<double>();
        else
            v += a * p.s;
    };
    const auto add_y = [&](const Pair& p, double a, Vec& v) {
        if (parallel && in_float)
            parallel_add(p.yf, a, v);
        else if (parallel)
            parallel_add(p.y, a, v);
        else if (in_float)
            v += a * p.yf.cast<double>();
        else
            v += a * p.y;
    };
    const auto y_squared_norm = [&](const Pair& p) {
        if (parallel) return in_float ? chunked_dot(p.yf, p.yf) : chunked_dot(p.y, p.y);
        return in_float ? p.yf.cast<double>().squaredNorm() : p.y.squaredNorm();
    };
    std::deque<Pair> history;
    std::vector<double> alpha(static_cast<std::size_t>(options.history));
    if (state)
        for (std::size_t k = 0; k < state->s.size(); ++k)
            history.push_back(make_pair(Eigen::Map<const Vec>(state->s[k].data(), en),
                                        Eigen::Map<const Vec>(state->y[k].data(), en), state->rho[k]));
    // The history, back into *state (after every accepted step).
    const auto save_state = [&] {
        if (!state) return;
        state->s.resize(history.size());
        state->y.resize(history.size());
        state->rho.resize(history.size());
        for (std::size_t k = 0; k < history.size(); ++k) {
            if (in_float) {
                state->s[k].assign(history[k].sf.data(), history[k].sf.data() + en);
                state->y[k].assign(history[k].yf.data(), history[k].yf.data() + en);
            } else {
                state->s[k].assign(history[k].s.data(), history[k].s.data() + en);
                state->y[k].assign(history[k].y.data(), history[k].y.data() + en);
            }
            state->rho[k] = history[k].rho;
        }
    };

    while (!result.converged && result.iterations < options.max_iterations) {
        // Two-loop recursion: d = −H g, with H₀ = γ I, γ = sᵀy / yᵀy of the newest pair.
        Vec d = g;
        for (std::size_t k = history.size(); k-- > 0;) {
            alpha[k] = history[k].rho * s_dot(history[k], d);
            add_y(history[k], -alpha[k], d);
        }
        if (!history.empty()) {
            const Pair& last = history.back();
            d *= 1.0 / (last.rho * y_squared_norm(last));
        }
        for (std::size_t k = 0; k < history.size(); ++k) {
            const double beta = history[k].rho * y_dot(history[k], d);
            add_s(history[k], alpha[k] - beta, d);
        }
        d = -d;
        double slope = g.dot(d);
        // H is positive definite in exact arithmetic; should rounding make d uphill anyway,
        // forget the history and fall back to steepest descent.
        if (!(slope < 0.0) || !std::isfinite(slope)) {
            history.clear();
            d = -g;
            slope = g.dot(d);
        }
        // Without curvature information the step length of −g has no scale: start at
        // min(1, 1/‖g‖) so that the first trial moves x by at most 1.
        double step = history.empty() ? std::min(1.0, 1.0 / g.norm()) : 1.0;

        // Armijo backtracking: halve until f(x + αd) ≤ f(x) + c₁ α gᵀd. A non-finite value or
        // gradient at the trial point counts as a failed trial.
        bool accepted = false;
        double f_trial = f;
        for (int ls = 0; ls < options.max_line_search; ++ls, step *= 0.5) {
            Eigen::Map<Vec>(trial.data(), en) = xv + step * d;
            f_trial = evaluate(trial, trial_gradient);
            if (std::isfinite(f_trial) && f_trial <= f + c1 * step * slope && all_finite(trial_gradient)) {
                accepted = true;
                break;
            }
        }
        if (!accepted) break;  // x stays at the last accepted point; converged stays false

        const Vec x_new = Eigen::Map<const Vec>(trial.data(), en);
        const Vec g_new = Eigen::Map<const Vec>(trial_gradient.data(), en);
        Vec s = x_new - xv, y = g_new - g;
        const double sy = s.dot(y);
        // Keep the pair only with enough positive curvature, so that H stays positive definite.
        if (sy > curvature_skip * s.norm() * y.norm()) {
            if (static_cast<int>(history.size()) == options.history) history.pop_front();
            history.push_back(make_pair(std::move(s), std::move(y), 1.0 / sy));
        }
        xv = x_new;
        g = g_new;
        f = f_trial;
        x = trial;
        ++result.iterations;
        result.value = f;
        result.converged = g.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance;
        save_state();
        if (on_iteration && !on_iteration(result.iterations, f)) break;
    }
    return result;
}

}  // namespace wavebrdf
