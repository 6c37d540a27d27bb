// The stall rule (src/core/stall_rule.h) against its definition evaluated directly, and against
// the two rules it replaces: a window difference on the newest values (what every L-BFGS stage
// stopped on) and a count of evaluations in a row that each lowered the lowest value by less than
// the tolerance (what the position loop stopped on). Sequences where those two disagree show
// which decision the one rule takes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <random>
#include <vector>

#include "core/stall_rule.h"

using wavebrdf::detail::StallRule;

namespace {

// The definition: the lowest of v[0..n] against the lowest of v[0..n − w], by direct minima.
bool stalled_by_definition(const std::vector<double>& v, std::size_t n, int window, double tolerance) {
    if (window <= 0 || n < std::size_t(window)) return false;
    const double now = *std::min_element(v.begin(), v.begin() + std::ptrdiff_t(n) + 1);
    const double then = *std::min_element(v.begin(), v.begin() + std::ptrdiff_t(n - std::size_t(window)) + 1);
    return then - now < tolerance * now;
}

// The window difference on the newest values.
bool stalled_by_window_difference(const std::vector<double>& v, std::size_t n, int window, double tolerance) {
    return window > 0 && n >= std::size_t(window) && v[n - std::size_t(window)] - v[n] < tolerance * v[n];
}

// The count in a row: the first index where `patience` values in a row each exceeded
// (1 − tolerance) × the lowest before it; v.size() when none.
std::size_t stop_by_count_in_a_row(const std::vector<double>& v, int patience, double tolerance) {
    double lowest = v[0];
    int count = 0;
    for (std::size_t n = 1; n < v.size(); ++n) {
        count = v[n] > (1.0 - tolerance) * lowest ? count + 1 : 0;
        lowest = std::min(lowest, v[n]);
        if (count >= patience) return n;
    }
    return v.size();
}

// The first index where the rule stalls; v.size() when it never does.
std::size_t stop_by_rule(const std::vector<double>& v, int window, double tolerance) {
    StallRule rule(window, tolerance);
    for (std::size_t n = 0; n < v.size(); ++n)
        if (rule.stalled_at(v[n])) return n;
    return v.size();
}

std::vector<double> random_losses(std::mt19937& rng, std::size_t size, bool never_rising) {
    std::uniform_real_distribution<double> step(never_rising ? 0.9 : 0.8, never_rising ? 1.0 : 1.15);
    std::vector<double> v{1.0};
    while (v.size() < size) v.push_back(v.back() * step(rng));
    return v;
}

}  // namespace

// Every evaluation of many random sequences, rising and falling, windows 1 to 5: stalled_at and
// quiet() as the definition says.
TEST(StallRule, DecidesAsItsDefinitionOnRandomSequences) {
    std::mt19937 rng(4711);
    int stalls = 0, goes_on = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const std::vector<double> v = random_losses(rng, 30, trial % 2 == 0);
        const double tolerance = std::vector<double>{0.0, 0.01, 0.05, 0.2}[std::size_t(trial) % 4];
        for (int window = 1; window <= 5; ++window) {
            StallRule rule(window, tolerance);
            for (std::size_t n = 0; n < v.size(); ++n) {
                const bool stalled = rule.stalled_at(v[n]);
                ASSERT_EQ(stalled, stalled_by_definition(v, n, window, tolerance))
                    << "trial " << trial << " window " << window << " n " << n;
                // quiet(): the largest k stalled_by_definition holds for.
                int quiet = 0;
                while (quiet < int(n) && stalled_by_definition(v, n, quiet + 1, tolerance)) ++quiet;
                ASSERT_EQ(rule.quiet(), quiet) << "trial " << trial << " n " << n;
                ASSERT_EQ(stalled, rule.quiet() >= window);
                (stalled ? stalls : goes_on) += 1;
            }
        }
    }
    EXPECT_GT(stalls, 1000);  // both decisions occur
    EXPECT_GT(goes_on, 1000);
}

// A loss that never rises (L-BFGS's): the rule is the window difference on the newest values at
// every evaluation, so every L-BFGS stage stops where it stopped before.
TEST(StallRule, NeverRisingLossStopsAsTheWindowDifference) {
    std::mt19937 rng(815);
    for (int trial = 0; trial < 200; ++trial) {
        std::vector<double> v = random_losses(rng, 40, true);
        v[20] = v[19];  // a step that did not lower it
        const double tolerance = std::vector<double>{0.0, 0.01, 0.05, 0.2}[std::size_t(trial) % 4];
        for (int window = 1; window <= 5; ++window) {
            StallRule rule(window, tolerance);
            for (std::size_t n = 0; n < v.size(); ++n)
                ASSERT_EQ(rule.stalled_at(v[n]), stalled_by_window_difference(v, n, window, tolerance))
                    << "trial " << trial << " window " << window << " n " << n;
        }
    }
}

// A loss falling 1 % of the start per evaluation, tolerance 2 %, window 2: each step lowers it by
// less than 2 %, so the count in a row stops at the second; two steps together lower it by more
// than 2 %, so the rule (and the window difference) never stops.
TEST(StallRule, SlowSteadyFallIsNotAStall) {
    const std::vector<double> v{1.00, 0.99, 0.98, 0.97, 0.96, 0.95};
    EXPECT_EQ(stop_by_count_in_a_row(v, 2, 0.02), 2u);
    EXPECT_EQ(stop_by_rule(v, 2, 0.02), v.size());
    for (std::size_t n = 0; n < v.size(); ++n) EXPECT_FALSE(stalled_by_window_difference(v, n, 2, 0.02));
}

// One value that rose after good progress: the window difference stops on it (its value is no
// lower than the one two back); the rule judges the lowest value, which halved over the window,
// and stops one evaluation later when the lowest has not moved for two.
TEST(StallRule, OneRiseIsNotAStall) {
    const std::vector<double> v{1.0, 0.5, 1.0, 0.9};
    EXPECT_TRUE(stalled_by_window_difference(v, 2, 2, 0.1));
    EXPECT_EQ(stop_by_rule(v, 2, 0.1), 3u);
    EXPECT_EQ(stop_by_count_in_a_row(v, 2, 0.1), 3u);
}

// On any sequence the rule stops no earlier than either rule it replaces (with window =
// patience and the same tolerance): it needs the lowest value to have fallen by less than the
// tolerance over the whole window, not over one step, and judges no single rise.
TEST(StallRule, StopsNoEarlierThanEitherFormerRule) {
    std::mt19937 rng(2718);
    int later_than_count = 0, later_than_window = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const std::vector<double> v = random_losses(rng, 30, trial % 2 == 0);
        const double tolerance = std::vector<double>{0.01, 0.05, 0.2}[std::size_t(trial) % 3];
        for (int window = 1; window <= 4; ++window) {
            const std::size_t rule = stop_by_rule(v, window, tolerance);
            std::size_t window_rule = v.size();
            for (std::size_t n = 0; n < v.size() && window_rule == v.size(); ++n)
                if (stalled_by_window_difference(v, n, window, tolerance)) window_rule = n;
            const std::size_t count_rule = stop_by_count_in_a_row(v, window, tolerance);
            ASSERT_GE(rule, window_rule) << "trial " << trial << " window " << window;
            ASSERT_GE(rule, count_rule) << "trial " << trial << " window " << window;
            later_than_count += rule > count_rule;
            later_than_window += rule > window_rule;
        }
    }
    EXPECT_GT(later_than_count, 0);  // the sequences tell the rules apart
    EXPECT_GT(later_than_window, 0);
}

// restart() forgets the values: the next `window` evaluations cannot stall, whatever came before.
TEST(StallRule, RestartIsANewStart) {
    StallRule rule(2, 0.1);
    EXPECT_FALSE(rule.stalled_at(1.0));
    EXPECT_FALSE(rule.stalled_at(1.0));
    EXPECT_TRUE(rule.stalled_at(1.0));
    EXPECT_EQ(rule.quiet(), 2);
    rule.restart();
    EXPECT_EQ(rule.quiet(), 0);
    EXPECT_FALSE(rule.stalled_at(1.0));
    EXPECT_FALSE(rule.stalled_at(1.0));
    EXPECT_TRUE(rule.stalled_at(1.0));
}

// Window 0 never stalls, and neither does tolerance 0 (the lowest value would have to fall by
// less than nothing), even on a loss that only rises.
TEST(StallRule, DegenerateSettings) {
    StallRule off(0, 1.0);
    for (int n = 0; n < 10; ++n) EXPECT_FALSE(off.stalled_at(1.0));
    StallRule exact(1, 0.0);
    for (double v : {1.0, 1.0, 2.0, 3.0, 0.5, 0.5}) EXPECT_FALSE(exact.stalled_at(v));
}
