// The one golden-section search (core/golden_section.h) that the colour bound's dual and the σ_p
// self-calibration use: its minimiser against the known minimum of functions whose minimum is
// known in closed form, its number of evaluations, and the bracket it keeps.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/golden_section.h"

namespace wavebrdf {
namespace {

TEST(GoldenSection, FindsAParabolasMinimumInExactlyTheEvaluationsAsked) {
    int calls = 0;
    double value = 0.0;
    const double x = detail::golden_section_minimum(
        [&](double t) {
            ++calls;
            return (t - 0.123) * (t - 0.123) + 2.0;
        },
        -1.0, 1.0, 30, &value);
    EXPECT_EQ(calls, 30);
    EXPECT_NEAR(x, 0.123, 1e-5);
    EXPECT_NEAR(value, 2.0, 1e-9);
}

TEST(GoldenSection, BracketShrinksByTheGoldenRatioPerEvaluation) {
    // |x − x*| is at most the final bracket, 2 · 0.618^(evaluations − 2), for a convex f with its
    // minimum anywhere inside, at an edge, or in a flat bottom.
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    for (const int evaluations : {3, 8, 20, 60}) {
        const double width = 2.0 * std::pow(g, evaluations - 2);
        for (const double centre : {-0.77, 0.0, 0.4, 1.0, -1.0}) {
            const double x = detail::golden_section_minimum([&](double t) { return std::abs(t - centre); }, -1.0, 1.0,
                                                            evaluations);
            EXPECT_LE(std::abs(x - centre), width + 1e-15) << evaluations << " " << centre;
        }
        // A plateau [0.2, 0.5]: the minimiser found is on it, or within the final bracket of it.
        double value = -1.0;
        const double x = detail::golden_section_minimum(
            [](double t) { return t < 0.2   ? 0.2 - t
                                  : t > 0.5 ? t - 0.5
                                            : 0.0; }, -1.0, 1.0, evaluations, &value);
        EXPECT_GE(x, 0.2 - width);
        EXPECT_LE(x, 0.5 + width);
        EXPECT_EQ(value, x < 0.2 ? 0.2 - x : x > 0.5 ? x - 0.5 : 0.0) << "value is f at the minimiser";
    }
}

TEST(GoldenSection, FewerThanThreeEvaluationsStillEvaluatesThree) {
    int calls = 0;
    detail::golden_section_minimum(
        [&](double t) {
            ++calls;
            return t * t;
        },
        -1.0, 1.0, 0);
    EXPECT_EQ(calls, 2 + 1);
}

}  // namespace
}  // namespace wavebrdf
