// Stitching footprint patches into positions (src/recovery/stitch_positions.h): at the true
// heights, patches cut from a known surface at known offsets (some of them the twin) give the
// offsets back and the twins found.
#include "recovery/stitch_positions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace wavebrdf::detail;

namespace {

// A smooth surface (µm) of correlation ~4 texels: a fixed sum of cosines.
double surface(double u, double v) {
    static const struct {
        double ku, kv, phase, amp;
    } waves[] = {{0.31, 0.12, 0.3, 0.5},   {-0.18, 0.27, 1.1, 0.4}, {0.07, -0.35, 2.0, 0.35}, {0.42, 0.25, 0.7, 0.2},
                 {-0.29, -0.21, 2.9, 0.3}, {0.21, 0.44, 4.1, 0.15}, {0.11, 0.05, 5.0, 0.3}};
    double h = 0.0;
    for (const auto& w : waves) h += w.amp * std::cos(w.ku * u + w.kv * v + w.phase);
    return h;
}

// The patch of a footprint stated at `centre` whose window truly sits at centre + d: it reads
// h(x + d), or as the twin −h(2c + d − x).
StitchPatch cut_patch(std::array<double, 2> centre, std::array<double, 2> d, bool twin, int tile = 14) {
    StitchPatch p;
    p.rows = p.cols = tile;
    p.origin_row = int(std::lround(centre[0] - tile / 2.0));
    p.origin_col = int(std::lround(centre[1] - tile / 2.0));
    p.centre = centre;
    p.heights_um.resize(std::size_t(tile) * tile);
    for (int a = 0; a < tile; ++a)
        for (int b = 0; b < tile; ++b) {
            const double u = p.origin_row + a + 0.5, v = p.origin_col + b + 0.5;
            p.heights_um[std::size_t(a) * tile + b] = twin
                                                          ? -surface(2 * centre[0] + d[0] - u, 2 * centre[1] + d[1] - v)
                                                          : surface(u + d[0], v + d[1]);
        }
    return p;
}

}  // namespace

TEST(StitchPositions, SolveRecoversExactDifferences) {
    // Offsets known, every pair's shift exact: the least squares gives them back (mean 0).
    const std::vector<std::array<double, 2>> d{{0.5, -1.0}, {-2.0, 0.25}, {1.0, 1.5}, {0.5, -0.75}};
    std::vector<StitchPair> pairs;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) pairs.push_back({a, b, {d[a][0] - d[b][0], d[a][1] - d[b][1]}, 1.0 + a});
    const auto found = solve_stitch_offsets(4, pairs);
    for (int i = 0; i < 4; ++i)
        for (int c = 0; c < 2; ++c) EXPECT_NEAR(found[i][c], d[i][c], 1e-6);
}

TEST(StitchPositions, PairRegistrationFindsTheRelativeShift) {
    const StitchPatch a = cut_patch({20.2, 19.7}, {1.3, -0.4}, false);
    const StitchPatch b = cut_patch({21.6, 20.1}, {-0.9, 1.1}, false);
    const PairRegistration r = register_patch_pair(a, b, 1.5, 0.25);
    EXPECT_NEAR(r.shift[0], 1.3 - (-0.9), 0.05);
    EXPECT_NEAR(r.shift[1], -0.4 - 1.1, 0.05);
    EXPECT_LT(r.misfit, 1e-3);
    // The twin of b does not register as b does.
    const PairRegistration t = register_patch_pair(a, cut_patch({21.6, 20.1}, {-0.9, 1.1}, true), 1.5, 0.25);
    EXPECT_GT(t.misfit, 10 * r.misfit);
}

TEST(StitchPositions, FlipTwiceIsTheIdentityInside) {
    const StitchPatch p = cut_patch({20.3, 19.6}, {0.4, -0.2}, true);
    const StitchPatch back = flip_patch(flip_patch(p));
    // Within 2σ of the centre the double resampling stays close.
    for (int a = 0; a < p.rows; ++a)
        for (int b = 0; b < p.cols; ++b) {
            const double u = p.origin_row + a + 0.5 - p.centre[0], v = p.origin_col + b + 0.5 - p.centre[1];
            if (std::hypot(u, v) > 3.0) continue;
            EXPECT_NEAR(back.heights_um[std::size_t(a) * p.cols + b], p.heights_um[std::size_t(a) * p.cols + b], 0.02);
        }
}

TEST(StitchPositions, KnownShiftsAndTwinsAreRecovered) {
    // 7 × 7 stated centres 1.5 texels apart, offsets up to ±2.5 texels (mean removed), every
    // third patch the twin.
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uni(-2.5, 2.5);
    std::vector<std::array<double, 2>> centres, d;
    for (int i = 0; i < 7; ++i)
        for (int j = 0; j < 7; ++j) {
            centres.push_back({14.0 + 1.5 * i + 0.1 * j, 14.0 + 1.5 * j});
            d.push_back({uni(rng), uni(rng)});
        }
    std::array<double, 2> mean{0, 0};
    const double count = double(d.size());
    for (const auto& x : d) mean = {mean[0] + x[0] / count, mean[1] + x[1] / count};
    for (auto& x : d) x = {x[0] - mean[0], x[1] - mean[1]};
    std::vector<StitchPatch> patches;
    std::vector<int> twin;
    for (std::size_t k = 0; k < centres.size(); ++k) {
        twin.push_back(k % 3 == 1);
        patches.push_back(cut_patch(centres[k], d[k], twin.back()));
    }
    StitchSettings settings;
    settings.max_distance_texels = 9.0;  // every pair that can overlap here (|d| ≤ 2.5 texels), fewer to register
    const StitchResult r = stitch_positions(patches, settings);
    ASSERT_EQ(r.offsets_texels.size(), patches.size());
    // The resolved patches' offsets (mean 0 over them, as the truth's mean over them), to < 0.05 texel.
    std::array<double, 2> resolved_mean{0, 0};
    int resolved = 0;
    for (std::size_t k = 0; k < patches.size(); ++k)
        if (r.resolved[k]) {
            ++resolved;
            resolved_mean = {resolved_mean[0] + d[k][0], resolved_mean[1] + d[k][1]};
        }
    ASSERT_GT(resolved, 0);
    double worst = 0.0;
    for (std::size_t k = 0; k < patches.size(); ++k) {
        EXPECT_EQ(r.twin[k], twin[k]) << "patch " << k;
        if (!r.resolved[k]) continue;
        for (int c = 0; c < 2; ++c)
            worst = std::max(worst, std::abs(r.offsets_texels[k][c] - (d[k][c] - resolved_mean[c] / resolved)));
    }
    EXPECT_LT(worst, 0.05);
    EXPECT_GE(resolved, int(patches.size()) - 3) << "unresolved: " << r.unresolved;
    EXPECT_GT(r.pairs_used, int(patches.size()));
}
