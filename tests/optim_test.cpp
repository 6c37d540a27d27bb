// Tests of the optimisers: Adam's known first step, a hand-computed trajectory, convergence,
// checkpoint round trips and validation; L-BFGS on Rosenbrock and an ill-conditioned quadratic,
// its callback, evaluation count and failure modes.
#include <gtest/gtest.h>

#include "test_util.h"

#include <Eigen/Dense>
#include <omp.h>

#include <cmath>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/optim.h"

using namespace wavebrdf;
using wavebrdf::test::expect_throw_naming;
using wavebrdf::test::uniform_vector;

namespace {

// f(x) = Σ a_i (x_i − c_i)², a separable quadratic with curvatures a_i.
struct Quadratic {
    std::vector<double> a, c;
    double operator()(const std::vector<double>& x, std::vector<double>& g) const {
        double f = 0.0;
        g.resize(x.size());
        for (std::size_t i = 0; i < x.size(); ++i) {
            const double d = x[i] - c[i];
            f += a[i] * d * d;
            g[i] = 2.0 * a[i] * d;
        }
        return f;
    }
};

double rosenbrock(const std::vector<double>& x, std::vector<double>& g) {
    const double a = 1.0 - x[0], b = x[1] - x[0] * x[0];
    g[0] = -2.0 * a - 400.0 * x[0] * b;
    g[1] = 200.0 * b;
    return a * a + 100.0 * b * b;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Adam

TEST(OptimTest, AdamFirstStepMovesEachCoordinateByLr) {
    // With m̂ = g and v̂ = g² after one step, the update is lr · g / (|g| + ε) ≈ lr · sign(g),
    // whatever the gradient's scale (Kingma and Ba 2015, section 2.1).
    const AdamOptions options{0.01, 0.9, 0.99, 1e-8, 0.005};
    const std::vector<double> gradient = {1e-3, -2.0, 5e2, -7e-2, 0.0, 3.0};
    for (int epoch : {0, 10}) {
        Adam adam(gradient.size(), options);
        const std::vector<double> x0 = uniform_vector(gradient.size(), -1.0, 1.0, 5);
        std::vector<double> x = x0;
        adam.step(x, gradient, epoch);
        const double lr = options.lr * std::exp(-options.decay * epoch);
        EXPECT_DOUBLE_EQ(adam.learning_rate(epoch), lr);
        for (std::size_t i = 0; i < x.size(); ++i) {
            const double sign = gradient[i] > 0 ? 1.0 : gradient[i] < 0 ? -1.0 : 0.0;
            EXPECT_NEAR(x0[i] - x[i], lr * sign, 1e-4 * lr) << "coordinate " << i << ", epoch " << epoch;
        }
        EXPECT_EQ(adam.state().steps, 1);
    }
}

TEST(OptimTest, AdamTwoStepsMatchHandComputation) {
    // β₁ = 1/2, β₂ = 3/4, lr = 0.1, decay = ln 2 (so epoch 1 has lr = 0.05), ε = 1e-8.
    const AdamOptions options{0.1, 0.5, 0.75, 1e-8, std::log(2.0)};
    const double eps = options.epsilon;
    Adam adam(2, options);
    std::vector<double> x = {1.0, -3.0};
    // Step 1, g = (2, −1): m = (1, −1/2), v = (1, 1/4); m̂ = m / (1/2) = (2, −1),
    // v̂ = v / (1/4) = (4, 1).
    adam.step(x, {2.0, -1.0}, 0);
    EXPECT_NEAR(x[0], 1.0 - 0.1 * 2.0 / (2.0 + eps), 1e-15);
    EXPECT_NEAR(x[1], -3.0 + 0.1 * 1.0 / (1.0 + eps), 1e-15);
    const double x1_0 = x[0], x1_1 = x[1];
    // Step 2, g = (4, 3): m = (1/2 + 2, −1/4 + 3/2) = (5/2, 5/4),
    // v = (3/4 + 4, 3/16 + 9/4) = (19/4, 39/16); 1 − β₁² = 3/4, 1 − β₂² = 7/16:
    // m̂ = (10/3, 5/3), v̂ = (76/7, 39/7).
    adam.step(x, {4.0, 3.0}, 1);
    EXPECT_NEAR(x[0], x1_0 - 0.05 * (10.0 / 3.0) / (std::sqrt(76.0 / 7.0) + eps), 1e-15);
    EXPECT_NEAR(x[1], x1_1 - 0.05 * (5.0 / 3.0) / (std::sqrt(39.0 / 7.0) + eps), 1e-15);
    EXPECT_EQ(adam.state().steps, 2);
    EXPECT_DOUBLE_EQ(adam.state().m[0], 2.5);
    EXPECT_DOUBLE_EQ(adam.state().m[1], 1.25);
    EXPECT_DOUBLE_EQ(adam.state().v[0], 19.0 / 4.0);
    EXPECT_DOUBLE_EQ(adam.state().v[1], 39.0 / 16.0);
}

TEST(OptimTest, AdamConvergesOnQuadratic) {
    const std::size_t n = 8;
    const Quadratic q{uniform_vector(n, 0.1, 100.0, 11), uniform_vector(n, -1.0, 1.0, 12)};
    // The decay takes the step size from 0.05 to 0.05·e⁻¹⁰ over the run; its sum (≈ 25) is
    // ample for the distance (≤ 1 per coordinate).
    Adam adam(n, AdamOptions{0.05, 0.9, 0.99, 1e-8, 0.002});
    std::vector<double> x(n, 0.0), g;
    const double f0 = q(x, g);
    for (int epoch = 0; epoch < 5000; ++epoch) {
        q(x, g);
        adam.step(x, g, epoch);
    }
    for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR(x[i], q.c[i], 1e-4) << "coordinate " << i;
    EXPECT_LT(q(x, g), 1e-8 * f0);
}

TEST(OptimTest, AdamStateRoundTripReproducesTrajectory) {
    const std::size_t n = 20;
    const Quadratic q{uniform_vector(n, 0.5, 5.0, 21), uniform_vector(n, -1.0, 1.0, 22)};
    const AdamOptions options;  // the thesis's defaults
    const int total = 30, split = 12;

    Adam straight(n, options);
    std::vector<double> x_straight = uniform_vector(n, -2.0, 2.0, 23), g;
    const std::vector<double> x_start = x_straight;
    for (int epoch = 0; epoch < total; ++epoch) {
        q(x_straight, g);
        straight.step(x_straight, g, epoch);
    }

    // Run to the split, "checkpoint" (copy the state and x), resume in a fresh optimiser.
    std::vector<double> x = x_start;
    Adam::State checkpoint;
    {
        Adam first(n, options);
        for (int epoch = 0; epoch < split; ++epoch) {
            q(x, g);
            first.step(x, g, epoch);
        }
        checkpoint = first.state();
    }
    Adam resumed(n, options);
    resumed.set_state(checkpoint);
    EXPECT_EQ(resumed.state().steps, split);
    for (int epoch = split; epoch < total; ++epoch) {
        q(x, g);
        resumed.step(x, g, epoch);
    }
    // Bit for bit: the same operations on the same numbers.
    EXPECT_EQ(x, x_straight);
    EXPECT_EQ(resumed.state().m, straight.state().m);
    EXPECT_EQ(resumed.state().v, straight.state().v);
    EXPECT_EQ(resumed.state().steps, straight.state().steps);

    // Without the state the trajectory differs (bias correction restarts): the test has teeth.
    Adam fresh(n, options);
    std::vector<double> x_fresh = x_start;
    for (int epoch = 0; epoch < split; ++epoch) {
        q(x_fresh, g);
        fresh.step(x_fresh, g, epoch);
    }
    Adam restarted(n, options);
    for (int epoch = split; epoch < total; ++epoch) {
        q(x_fresh, g);
        restarted.step(x_fresh, g, epoch);
    }
    EXPECT_NE(x_fresh, x_straight);
}

TEST(OptimTest, AdamValidatesOptionsAndSizes) {
    const auto make = [](AdamOptions o) { Adam(3, o); };
    const double nan = std::nan("");
    expect_throw_naming<std::domain_error>([&] { make({0.0, 0.9, 0.99, 1e-8, 0.0}); }, "lr");
    expect_throw_naming<std::domain_error>([&] { make({nan, 0.9, 0.99, 1e-8, 0.0}); }, "lr");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 1.0, 0.99, 1e-8, 0.0}); }, "beta1");
    expect_throw_naming<std::domain_error>([&] { make({0.01, -0.1, 0.99, 1e-8, 0.0}); }, "beta1");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 0.9, 1.0, 1e-8, 0.0}); }, "beta2");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 0.9, nan, 1e-8, 0.0}); }, "beta2");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 0.9, 0.99, 0.0, 0.0}); }, "epsilon");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 0.9, 0.99, 1e-8, -1.0}); }, "decay");
    expect_throw_naming<std::domain_error>([&] { make({0.01, 0.9, 0.99, 1e-8, HUGE_VAL}); }, "decay");
    EXPECT_NO_THROW(make({0.01, 0.0, 0.0, 1e-8, 0.0}));

    Adam adam(3);
    std::vector<double> x(3, 0.0);
    EXPECT_THROW(adam.step(x, {1.0, 2.0}, 0), std::invalid_argument);
    EXPECT_THROW(adam.step(x, {1.0, 2.0, 3.0}, -1), std::invalid_argument);
    EXPECT_THROW(adam.step(x, {1.0, nan, 3.0}, 0), std::domain_error);
    EXPECT_EQ(adam.state().steps, 0);  // a rejected step changes nothing
    EXPECT_EQ(x, std::vector<double>(3, 0.0));

    Adam::State wrong;
    wrong.m.assign(4, 0.0);
    wrong.v.assign(4, 0.0);
    EXPECT_THROW(adam.set_state(wrong), std::invalid_argument);
    wrong.m.assign(3, 0.0);
    wrong.v.assign(3, -1.0);
    EXPECT_THROW(adam.set_state(wrong), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// L-BFGS

TEST(OptimTest, LbfgsMinimisesRosenbrock) {
    std::vector<double> x = {-1.2, 1.0};
    const LbfgsResult r = lbfgs_minimize(rosenbrock, x);
    EXPECT_LE(r.iterations, 100);
    EXPECT_NEAR(x[0], 1.0, 1e-6);
    EXPECT_NEAR(x[1], 1.0, 1e-6);
    EXPECT_LT(r.value, 1e-12);
    EXPECT_TRUE(r.converged);
    std::cout << "[ info     ] Rosenbrock: " << r.iterations << " iterations, " << r.evaluations << " evaluations\n";
}

TEST(OptimTest, LbfgsMinimisesIllConditionedQuadratic) {
    // f(x) = ½ (x − c)ᵀ Qᵀ Λ Q (x − c), eigenvalues from 1 to 10⁴ (condition number 10⁴), in a
    // random orthonormal basis Q so that no coordinate is separable.
    const int n = 50;
    std::mt19937_64 rng(31);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd random(n, n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) random(i, j) = normal(rng);
    const Eigen::MatrixXd basis = Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ();
    Eigen::VectorXd lambda(n);
    for (int i = 0; i < n; ++i) lambda[i] = std::pow(10.0, 4.0 * i / (n - 1));
    const Eigen::MatrixXd a = basis.transpose() * lambda.asDiagonal() * basis;
    const std::vector<double> c_std = uniform_vector(n, -1.0, 1.0, 32);
    const Eigen::VectorXd c = Eigen::Map<const Eigen::VectorXd>(c_std.data(), n);
    const auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
        const Eigen::VectorXd d = Eigen::Map<const Eigen::VectorXd>(x.data(), n) - c;
        const Eigen::VectorXd ad = a * d;
        Eigen::Map<Eigen::VectorXd>(g.data(), n) = ad;
        return 0.5 * d.dot(ad);
    };
    std::vector<double> x(n, 0.0);
    LbfgsOptions options;
    // Armijo steps of length 1 do not give L-BFGS the finite termination of CG; with this
    // spread-out spectrum it takes ~1200 iterations (250 with exact line searches).
    options.max_iterations = 2000;
    const LbfgsResult r = lbfgs_minimize(objective, x, options);
    EXPECT_TRUE(r.converged);
    for (int i = 0; i < n; ++i) EXPECT_NEAR(x[i], c_std[i], 1e-8) << "coordinate " << i;
    std::cout << "[ info     ] 50-D quadratic: " << r.iterations << " iterations, " << r.evaluations
              << " evaluations\n";
}

// float_history (the field stage's setting): the pairs rounded to float still give a descent
// direction that converges on Rosenbrock and, on the ill-conditioned quadratic, to the same
// minimum within 1e-6 in no more than 1.5× the double history's iterations; the pairs it keeps are
// float values (a state written back holds doubles that are exactly floats), and a run stopped and
// continued from its state takes the uninterrupted run's steps bit for bit.
TEST(OptimTest, LbfgsFloatHistoryConvergesAndContinuesBitForBit) {
    LbfgsOptions in_float;
    in_float.float_history = true;
    std::vector<double> x = {-1.2, 1.0};
    const LbfgsResult r = lbfgs_minimize(rosenbrock, x, in_float);
    EXPECT_TRUE(r.converged);
    EXPECT_NEAR(x[0], 1.0, 1e-6);
    EXPECT_NEAR(x[1], 1.0, 1e-6);

    const int n = 40;
    std::vector<double> lambda(n), c = uniform_vector(n, -1.0, 1.0, 33);
    for (int i = 0; i < n; ++i) lambda[i] = std::pow(10.0, 3.0 * i / (n - 1));
    const auto quadratic = [&](const std::vector<double>& v, std::vector<double>& g) {
        double f = 0.0;
        for (int i = 0; i < n; ++i) {
            // A coupled quadratic: neighbours mixed so that no coordinate is separable.
            const double d = v[i] - c[i], e = v[(i + 1) % n] - c[(i + 1) % n];
            f += 0.5 * lambda[i] * d * d + 0.25 * d * e;
            g[i] += lambda[i] * d + 0.25 * e;
            g[(i + 1) % n] += 0.25 * d;
        }
        return f;
    };
    LbfgsOptions dbl;
    dbl.max_iterations = 3000;
    dbl.gradient_tolerance = 1e-9;
    LbfgsOptions flt = dbl;
    flt.float_history = true;
    std::vector<double> xd(n, 0.0), xf(n, 0.0);
    const LbfgsResult rd = lbfgs_minimize(quadratic, xd, dbl), rf = lbfgs_minimize(quadratic, xf, flt);
    ASSERT_TRUE(rd.converged);
    ASSERT_TRUE(rf.converged);
    for (int i = 0; i < n; ++i) EXPECT_NEAR(xf[i], xd[i], 1e-6) << "coordinate " << i;
    EXPECT_LE(rf.iterations, rd.iterations * 3 / 2 + 5);
    EXPECT_NE(xf, xd) << "float_history changed nothing: the pairs were not rounded";

    std::vector<double> whole(n, 0.0);
    LbfgsOptions capped = flt;
    capped.max_iterations = 30;
    capped.gradient_tolerance = 0.0;
    lbfgs_minimize(quadratic, whole, capped);
    std::vector<double> part(n, 0.0);
    LbfgsState state;
    LbfgsOptions first = capped;
    first.max_iterations = 12;
    lbfgs_minimize(quadratic, part, first, {}, &state);
    ASSERT_FALSE(state.s.empty());
    for (const std::vector<double>& s : state.s)
        for (double v : s) ASSERT_EQ(v, double(float(v))) << "a kept pair is not in float";
    LbfgsOptions rest = capped;
    rest.max_iterations = 18;
    lbfgs_minimize(quadratic, part, rest, {}, &state);
    EXPECT_EQ(part, whole) << "not bitwise identical to the uninterrupted run";
}

// Long vectors (≥ 2^17 values, the field stage's band spectrum) run the two-loop recursion on
// all threads with chunked sums: the iterates must be the same bits on 1 and 2 threads, in
// double and in float history, and the minimisation must still converge.
TEST(OptimTest, LbfgsLongVectorsGiveTheSameBitsOnAnyThreadCount) {
    const int n = (1 << 17) + 4099;  // not a whole number of chunks
    std::vector<double> lambda(n), c = uniform_vector(std::size_t(n), -1.0, 1.0, 34);
    for (int i = 0; i < n; ++i) lambda[std::size_t(i)] = std::pow(10.0, 2.0 * double(i % 97) / 96.0);
    const auto quadratic = [&](const std::vector<double>& v, std::vector<double>& g) {
        double f = 0.0;
        for (int i = 0; i < n; ++i) {
            const std::size_t k = std::size_t(i), next = std::size_t((i + 1) % n);
            const double d = v[k] - c[k], e = v[next] - c[next];
            f += 0.5 * lambda[k] * d * d + 0.25 * d * e;
            g[k] += lambda[k] * d + 0.25 * e;
            g[next] += 0.25 * d;
        }
        return f;
    };
    for (const bool in_float : {false, true}) {
        LbfgsOptions o;
        o.max_iterations = 40;
        o.gradient_tolerance = 0.0;
        o.float_history = in_float;
        std::vector<std::vector<double>> x;
        std::vector<double> value;
        for (const int threads : {1, 2}) {
            const int before = omp_get_max_threads();
            omp_set_num_threads(threads);
            x.emplace_back(std::size_t(n), 0.0);
            value.push_back(lbfgs_minimize(quadratic, x.back(), o).value);
            omp_set_num_threads(before);
        }
        EXPECT_EQ(x[0], x[1]) << "float history " << in_float;
        std::vector<double> g0(std::size_t(n), 0.0);
        const double start = quadratic(std::vector<double>(std::size_t(n), 0.0), g0);
        EXPECT_LT(value[0], 1e-3 * start) << "float history " << in_float;
    }
}

TEST(OptimTest, LbfgsCallbackCanStopAndCountsEvaluations) {
    int calls = 0, evaluations = 0;
    std::vector<double> seen;
    const auto counted = [&](const std::vector<double>& x, std::vector<double>& g) {
        ++evaluations;
        return rosenbrock(x, g);
    };
    std::vector<double> x = {-1.2, 1.0};
    const LbfgsResult r = lbfgs_minimize(counted, x, {}, [&](int iteration, double value) {
        ++calls;
        EXPECT_EQ(iteration, calls);
        seen.push_back(value);
        return iteration < 3;
    });
    EXPECT_EQ(calls, 3);
    EXPECT_EQ(r.iterations, 3);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.evaluations, evaluations);
    EXPECT_GE(r.evaluations, r.iterations + 1);
    EXPECT_EQ(r.value, seen.back());
    std::vector<double> g(2);
    EXPECT_EQ(rosenbrock(x, g), r.value);  // x is the point whose value was reported
    for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_LT(seen[i], seen[i - 1]);  // Armijo decrease

    // A full run counts every call too.
    evaluations = 0;
    x = {-1.2, 1.0};
    const LbfgsResult full = lbfgs_minimize(counted, x);
    EXPECT_EQ(full.evaluations, evaluations);
}

TEST(OptimTest, LbfgsStopsWhenLineSearchFails) {
    // The gradient's sign is wrong, so the "descent" direction climbs f and no step passes.
    const Quadratic q{{1.0, 2.0}, {0.0, 0.0}};
    const auto wrong = [&](const std::vector<double>& x, std::vector<double>& g) {
        const double f = q(x, g);
        for (double& gi : g) gi = -gi;
        return f;
    };
    std::vector<double> x = {1.0, 1.0};
    LbfgsOptions options;
    options.max_line_search = 7;
    const LbfgsResult r = lbfgs_minimize(wrong, x, options);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(r.evaluations, 1 + options.max_line_search);
    EXPECT_EQ(x, (std::vector<double>{1.0, 1.0}));  // the last accepted point
    EXPECT_EQ(r.value, 3.0);
}

TEST(OptimTest, LbfgsEdgeCasesAndValidation) {
    const Quadratic q{{1.0, 1.0}, {0.5, -0.5}};
    // Already at the minimum: one evaluation, no step.
    std::vector<double> x = {0.5, -0.5};
    LbfgsResult r = lbfgs_minimize(q, x);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(r.evaluations, 1);
    // max_iterations = 0 evaluates the start only.
    x = {0.0, 0.0};
    LbfgsOptions zero;
    zero.max_iterations = 0;
    r = lbfgs_minimize(q, x, zero);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.evaluations, 1);
    EXPECT_EQ(r.value, 0.5);

    const auto with = [&](auto set) {
        LbfgsOptions o;
        set(o);
        std::vector<double> y = {0.0, 0.0};
        lbfgs_minimize(q, y, o);
    };
    expect_throw_naming<std::domain_error>([&] { with([](LbfgsOptions& o) { o.history = 0; }); }, "history");
    expect_throw_naming<std::domain_error>([&] { with([](LbfgsOptions& o) { o.max_iterations = -1; }); },
                                           "max_iterations");
    expect_throw_naming<std::domain_error>([&] { with([](LbfgsOptions& o) { o.gradient_tolerance = -1; }); },
                                           "gradient_tolerance");
    expect_throw_naming<std::domain_error>([&] { with([](LbfgsOptions& o) { o.max_line_search = 0; }); },
                                           "max_line_search");
    std::vector<double> empty;
    EXPECT_THROW(lbfgs_minimize(q, empty), std::invalid_argument);
    std::vector<double> start = {0.0, 0.0};
    EXPECT_THROW(lbfgs_minimize([](const std::vector<double>&, std::vector<double>&) { return std::nan(""); }, start),
                 std::domain_error);
}

// A run stopped after some iterations and continued from its x and LbfgsState takes the same
// steps as the uninterrupted run, bit for bit (without the state, the restarted history took
// other steps); a state that cannot fit is refused before any evaluation.
TEST(OptimTest, LbfgsStateContinuesBitForBit) {
    std::vector<double> whole = {-1.2, 1.0, 0.5, -0.7};
    const auto rosenbrock4 = [](const std::vector<double>& x, std::vector<double>& g) {
        double f = 0.0;
        g.assign(x.size(), 0.0);
        for (std::size_t i = 0; i + 1 < x.size(); ++i) {
            const double a = 1.0 - x[i], b = x[i + 1] - x[i] * x[i];
            f += a * a + 100.0 * b * b;
            g[i] += -2.0 * a - 400.0 * x[i] * b;
            g[i + 1] += 200.0 * b;
        }
        return f;
    };
    LbfgsOptions options;
    options.history = 3;
    options.max_iterations = 25;
    options.gradient_tolerance = 0.0;
    lbfgs_minimize(rosenbrock4, whole, options);

    std::vector<double> x = {-1.2, 1.0, 0.5, -0.7};
    LbfgsState state;
    LbfgsOptions first = options;
    first.max_iterations = 9;
    lbfgs_minimize(rosenbrock4, x, first, {}, &state);
    EXPECT_EQ(state.s.size(), 3u) << "history full after 9 iterations";
    LbfgsOptions rest = options;
    rest.max_iterations = 16;
    const LbfgsResult r = lbfgs_minimize(rosenbrock4, x, rest, {}, &state);
    EXPECT_EQ(r.iterations, 16);
    EXPECT_EQ(x, whole) << "not bitwise identical to the uninterrupted run";

    LbfgsState bad = state;
    bad.rho[0] = -1.0;
    int calls = 0;
    const auto counted = [&](const std::vector<double>& v, std::vector<double>& g) {
        ++calls;
        return rosenbrock4(v, g);
    };
    expect_throw_naming<std::invalid_argument>([&] { lbfgs_minimize(counted, x, rest, {}, &bad); }, "rho");
    bad = state;
    bad.s[1].pop_back();
    expect_throw_naming<std::invalid_argument>([&] { lbfgs_minimize(counted, x, rest, {}, &bad); }, "pair 1");
    LbfgsOptions short_history = options;
    short_history.history = 2;
    expect_throw_naming<std::invalid_argument>([&] { lbfgs_minimize(counted, x, short_history, {}, &state); },
                                               "3 pairs; expected at most 2");
    EXPECT_EQ(calls, 0);
}
