// Single-texel outliers after the refinement (src/recovery/outlier_repair.h; docs/recovery.md,
// Speed, eighth pass): a texel a wrap (λ/2) from the surface is put back where the loss of the
// slices that see it agrees, and left where it does not.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "recovery/outlier_repair.h"
#include "test_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf {
namespace {

std::vector<double> smooth_surface(int rows, int cols) {
    std::vector<double> t(std::size_t(rows * cols));
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            t[std::size_t(i * cols + j)] = 0.03 * std::sin(2.0 * k_pi * i / rows) * std::cos(2.0 * k_pi * j / cols);
    return t;
}

// A loss with a local minimum at every whole wrap W of each texel (as one wavelength's phase) and
// a weak pull to the truth, summed over the 3 × 3 texels around `texel` (its "slices").
double wrapped_local_loss(const std::vector<double>& h, const std::vector<double>& truth, int rows, int cols,
                          double wrap, std::size_t texel) {
    const int ti = int(texel) / cols, tj = int(texel) % cols;
    double s = 0.0;
    for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
            const std::size_t p = std::size_t(((ti + di + rows) % rows) * cols + (tj + dj + cols) % cols);
            const double d = h[p] - truth[p];
            s += 1.0 - std::cos(2.0 * k_pi * d / wrap) + 1e-3 * d * d;
        }
    return s;
}

TEST(OutlierRepair, ATexelAWrapOffReturnsAndTheRestIsUntouched) {
    const int rows = 12, cols = 10;
    const double wrap = 0.25;
    const std::vector<double> truth = smooth_surface(rows, cols);
    std::vector<double> h = truth;
    h[37] += wrap;
    // A local minimum in that texel alone: a small step either way raises the loss.
    const auto loss = [&](const std::vector<double>& x, std::size_t t) {
        return wrapped_local_loss(x, truth, rows, cols, wrap, t);
    };
    std::vector<double> step = h;
    step[37] += 0.01;
    EXPECT_GT(loss(step, 37), loss(h, 37));
    step[37] -= 0.02;
    EXPECT_GT(loss(step, 37), loss(h, 37));
    const detail::OutlierRepairCounts counts = detail::repair_outlier_texels(h, rows, cols, 6.0, 0.25 * wrap, 16,
                                                                             {wrap}, loss);
    EXPECT_EQ(counts.flagged, 1);
    EXPECT_EQ(counts.kept, 1);
    EXPECT_EQ(counts.evaluations, 1 + 2 + 2);       // the start, quadratic, median, ± the wrap
    EXPECT_LT(std::abs(h[37] - truth[37]), 1e-12);  // h − wrap is the truth exactly
    for (std::size_t p = 0; p < h.size(); ++p)
        if (p != 37) {
            EXPECT_EQ(h[p], truth[p]) << p;
        }
}

TEST(OutlierRepair, NothingChangesWhereTheLossDoesNotFallOrNothingStandsOut) {
    const int rows = 12, cols = 10;
    const std::vector<double> truth = smooth_surface(rows, cols);
    std::vector<double> h = truth;
    h[37] += 0.25;
    const std::vector<double> before = h;
    // A loss that prefers the texel where it is.
    const auto prefers = [&](const std::vector<double>& x, std::size_t) { return std::abs(x[37] - before[37]); };
    detail::OutlierRepairCounts counts = detail::repair_outlier_texels(h, rows, cols, 6.0, 0.05, 16, {0.25}, prefers);
    EXPECT_EQ(counts.flagged, 9);  // the texel, then its 8 neighbours, which stand out through it while it stays
    EXPECT_EQ(counts.kept, 0);
    EXPECT_EQ(h, before);
    // A smooth surface: nothing flagged, nothing evaluated (the absolute floor keeps the robust
    // test's noise out).
    std::vector<double> g = truth;
    int calls = 0;
    counts = detail::repair_outlier_texels(g, rows, cols, 6.0, 0.05, 16, {0.25},
                                           [&](const std::vector<double>&, std::size_t) {
                                               ++calls;
                                               return 0.0;
                                           });
    EXPECT_EQ(counts.flagged, 0);
    EXPECT_EQ(calls, 0);
    EXPECT_EQ(g, truth);
    // Off: threshold 0, or a grid too small.
    counts = detail::repair_outlier_texels(h, rows, cols, 0.0, 0.05, 16, {0.25}, prefers);
    EXPECT_EQ(counts.evaluations, 0);
}

// The real loss (Gabor OHS slices at one wavelength, amplitude loss): for a texel of a 16² surface
// moved by λ/2, the loss of the slices that see it (their gradient boxes hold it: not all of them
// here) changes exactly as the loss of every slice does, and the repair, judged on those slices
// alone, puts it back near the truth.
TEST(OutlierRepair, OnGaborSlicesATexelHalfAWavelengthOffReturnsToTheTruth) {
    const int n = 16;
    const double texel_um = 2.0, lambda = 0.5;
    const Heightfield truth = test::random_heightfield(n, n, 0.1, 43, texel_um);
    std::vector<Observation> observations;
    for (int a = 0; a < 6; ++a)
        for (int b = 0; b < 6; ++b) {
            Observation o;
            o.query = test::make_query(Model::OHS, (a + 0.3) * 32.0 / 6, (b + 0.6) * 32.0 / 6, 3.0);
            o.lambdas_um = {lambda};
            o.resolution = 32;
            o.reference = to_reference(render_observation(truth, o));
            observations.push_back(std::move(o));
        }
    const std::size_t texel = 7 * n + 9;
    const int tr = int(texel) / n, tc = int(texel) % n;
    std::vector<Observation> seeing;  // the slices whose gradient box holds the texel
    for (const Observation& o : observations) {
        const SlicePlan<double> plan(truth, o.query, o.lambdas_um, o.resolution, o.channels());
        std::vector<int> rows, cols;
        plan.gradient_box(rows, cols);
        if (std::binary_search(rows.begin(), rows.end(), tr) && std::binary_search(cols.begin(), cols.end(), tc))
            seeing.push_back(o);
    }
    ASSERT_FALSE(seeing.empty());
    ASSERT_LT(seeing.size(), observations.size());  // a local evaluation
    Loss loss;
    loss.kind = LossKind::Amplitude;
    const auto local_loss = [&](const std::vector<double>& x, std::size_t) {
        return observation_loss(truth.with_values(x), seeing, loss, nullptr);
    };
    const double wrap = 0.5 * lambda / texel_um;  // value units (vscale 1)
    std::vector<double> h = truth.values();
    h[texel] += wrap;
    // The local evaluation is exact: the slices that do not see the texel do not change, so the
    // loss over every slice changes by the same sum (observation_loss is a mean: counts apply).
    const auto full_loss = [&](const std::vector<double>& x) {
        return observation_loss(truth.with_values(x), observations, loss, nullptr);
    };
    const double full_change = (full_loss(h) - full_loss(truth.values())) * double(observations.size());
    const double local_change = (local_loss(h, texel) - local_loss(truth.values(), texel)) * double(seeing.size());
    EXPECT_GT(local_change, 0.0);
    EXPECT_NEAR(full_change, local_change, 1e-9 * std::abs(full_change));
    const detail::OutlierRepairCounts counts = detail::repair_outlier_texels(h, n, n, 6.0, 0.25 * wrap, 16, {wrap},
                                                                             local_loss);
    EXPECT_EQ(counts.kept, 1);
    EXPECT_LT(std::abs(h[texel] - truth.values()[texel]) * texel_um, 0.03);  // µm; was 0.25
}

}  // namespace
}  // namespace wavebrdf

namespace wavebrdf {
namespace {

TEST(OutlierRepair, RecoverHeightsRefusesBadSettingsWithOneLine) {
    const auto message = [](const RecoverSettings& s) {
        try {
            recover_heights({}, 4, 4, 2.0, 1.0, s);
        } catch (const std::exception& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    RecoverSettings rounds;
    rounds.outlier_repair_rounds = -2;  // −1 is unset: the schedule's
    EXPECT_NE(message(rounds).find("outlier repair rounds -2"), std::string::npos) << message(rounds);
}

}  // namespace
}  // namespace wavebrdf
