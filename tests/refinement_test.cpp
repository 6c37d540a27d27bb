// The refinement's pieces (src/recovery/refinement.h): the observation objective of both its
// forms (the heights alone; the positions as variables as well) and the L-BFGS rounds.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "position_cases.h"
#include "recovery/recover_positions.h"
#include "recovery/refinement.h"
#include "wavebrdf/recover.h"

using namespace wavebrdf;

namespace {

test::OffCase small_refine_case() { return test::off_case(5111, 0.5, 24, 3); }

}  // namespace

// With every offset 0 the positions' form is the heights' form: the same value and the same
// height gradient (one algorithm, two sets of variables).
TEST(Refinement, PositionsAtZeroOffsetsAreTheHeightsAlone) {
    const test::OffCase c = small_refine_case();
    const Heightfield flat = c.truth.with_values(std::vector<double>(c.truth.values().size(), 0.0));
    const Heightfield start = c.truth.with_values([&] {
        std::vector<double> h = c.truth.values();
        for (std::size_t k = 0; k < h.size(); ++k) h[k] *= 0.9 + 0.01 * double(k % 7);
        return h;
    }());
    const double total = double(c.observations.size());
    const Loss loss{LossKind::Amplitude, 1.0};
    std::vector<std::size_t> index;
    const auto positions = detail::gather_positions(c.observations, index, serial_communicator()).size();
    detail::ObservationObjective heights(c.observations, total, flat, loss, false, 1.0, serial_communicator());
    detail::ObservationObjective joint(c.observations, total, flat, loss, false, 1.0, serial_communicator(), &index,
                                       positions);
    std::vector<double> x = start.values(), g;
    const double value = heights(x, g);
    std::vector<double> z = x, gz;
    z.resize(x.size() + 2 * positions, 0.0);
    const double value_joint = joint(z, gz);
    EXPECT_NEAR(value_joint, value, 1e-12 * value);
    ASSERT_EQ(gz.size(), z.size());
    double scale = 0.0;
    for (double v : g) scale = std::max(scale, std::abs(v));
    ASSERT_GT(scale, 0.0);
    for (std::size_t k = 0; k < x.size(); ++k) EXPECT_NEAR(gz[k], g[k], 1e-9 * scale) << "texel " << k;
}

// The positions' gradient (the offsets' part, through the gauge t − mean t) agrees with central
// differences of the value.
TEST(Refinement, OffsetGradientMatchesFiniteDifferences) {
    const test::OffCase c = small_refine_case();
    const Heightfield flat = c.truth.with_values(std::vector<double>(c.truth.values().size(), 0.0));
    const double total = double(c.observations.size());
    std::vector<std::size_t> index;
    const auto positions = detail::gather_positions(c.observations, index, serial_communicator()).size();
    detail::ObservationObjective joint(c.observations, total, flat, Loss{LossKind::Amplitude, 1.0}, false, 1.0,
                                       serial_communicator(), &index, positions);
    std::vector<double> z = c.truth.values(), g, unused;
    const std::size_t cells = z.size();
    z.resize(cells + 2 * positions, 0.0);
    for (std::size_t p = 0; p < positions; ++p) z[cells + 2 * p] = 0.1 * double(p % 3) - 0.1;
    joint(z, g);
    const double step = 1e-3;  // texels
    for (std::size_t k : {cells, cells + 1, cells + 2 * positions - 1}) {
        std::vector<double> plus = z, minus = z;
        plus[k] += step;
        minus[k] -= step;
        const double fd = (joint(plus, unused) - joint(minus, unused)) / (2.0 * step);
        EXPECT_GT(std::abs(fd), 1e-6) << "variable " << k;  // the offsets move the slices
        EXPECT_NEAR(g[k], fd, 0.02 * std::abs(fd)) << "variable " << k;
    }
}

// The rounds: L-BFGS on a quadratic reaches its minimum, reports every iteration under the
// stage's name with the count across rounds, and a round stops below the relative tolerance.
TEST(Refinement, RoundsCountAcrossRoundsAndStopBelowTheTolerance) {
    const Heightfield flat(2, 2, std::vector<double>(4, 0.0), 1.0, 1.0);
    const std::vector<double> target{1.0, -2.0, 0.5, 3.0};
    const auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
        double f = 0.0;
        for (std::size_t k = 0; k < x.size(); ++k) {
            const double d = x[k] - target[k];
            f += d * d;
            g[k] = 2.0 * d;
        }
        return f;
    };
    std::vector<std::string> stages;
    std::vector<int> iterations;
    const detail::StageReport report = [&](const detail::StageId& stage, int iteration, double, const Heightfield* h) {
        EXPECT_NE(h, nullptr);
        EXPECT_EQ(stage.kind, StageKind::RefineRung);
        stages.push_back(stage.name);
        iterations.push_back(iteration);
        return true;
    };
    std::vector<double> x(4, 0.0);
    std::vector<double> g0(4);
    const double reference = objective(x, g0);
    detail::RefinementRounds rounds(objective, flat, 5, reference, report);
    rounds.run(x, 2, {StageKind::RefineRung, detail::stage_part(0.7)});
    ASSERT_EQ(iterations.size(), 2u);
    EXPECT_EQ(iterations.back(), 2);
    rounds.run(x, 50, {StageKind::RefineRung, detail::stage_part(0.55)}, 1e-6);
    EXPECT_EQ(stages.front(), "refine:0.7");
    EXPECT_EQ(stages.back(), "refine:0.55");
    EXPECT_GT(iterations.back(), 2);  // counted on from the first round
    EXPECT_EQ(iterations.back(), rounds.done());
    EXPECT_TRUE(rounds.reported());
    EXPECT_LT(rounds.last_loss(), 1e-6 * reference);
    EXPECT_LT(iterations.back(), 2 + 50);  // stopped by the tolerance, not the count
    for (std::size_t k = 0; k < x.size(); ++k) EXPECT_NEAR(x[k], target[k], 1e-3);
    // A report that asks to stop ends the round and every later one.
    detail::RefinementRounds stopping(objective, flat, 5, reference,
                                      [](const detail::StageId&, int, double, const Heightfield*) { return false; });
    std::vector<double> y(4, 0.0);
    stopping.run(y, 10);
    EXPECT_FALSE(stopping.go_on());
    EXPECT_EQ(stopping.done(), 1);
    stopping.run(y, 10);
    EXPECT_EQ(stopping.done(), 1);
}
