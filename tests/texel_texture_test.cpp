// texel_texture.h: the texture check on synthetic surfaces. A binary texel texture like sur-2's
// scan artefact (texels flipping between two levels over 40 % of the tile) is flagged and warned
// at the noise level where it hurt (2 σ beyond the target); a smooth Gaussian surface of the same
// rms height, and an estimate's own noise, are not.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/texel_texture.h"

namespace wavebrdf {
namespace {

constexpr int k_n = 128;

double rms_of(const Heightfield& h) {
    double mean = 0.0, square = 0.0;
    for (const double v : h.values()) mean += v;
    mean /= double(h.values().size());
    for (const double v : h.values()) square += (v - mean) * (v - mean);
    return std::sqrt(square / double(h.values().size()));
}

double range_of(const Heightfield& h) {
    const auto [lo, hi] = std::minmax_element(h.values().begin(), h.values().end());
    return *hi - *lo;
}

// Gaussian-correlated, correlation 4 texels of 1 µm (SurfaceParams' defaults).
Heightfield smooth_surface(double rms_um, std::uint64_t seed) {
    SurfaceParams p;
    p.rows = p.cols = k_n;
    p.rms_height_um = rms_um;
    p.seed = seed;
    return generate_heightfield(p);
}

// A smooth surface plus, on rows 40–90 (40 % of the tile), texels raised by `step_um` at random
// (probability 1/2 each): sur-2's texture (two levels 7.5 nm apart on a 3.4 nm rms surface).
Heightfield textured_surface() {
    const Heightfield base = smooth_surface(0.0034, 7);
    std::vector<double> v = base.values();
    std::mt19937_64 rng(20261130);
    std::bernoulli_distribution flip(0.5);
    for (int i = 40; i < 91; ++i)
        for (int j = 0; j < k_n; ++j)
            if (flip(rng)) v[std::size_t(i) * k_n + j] += 0.0075;
    return base.with_values(v);
}

TEST(TexelTexture, BinaryTextureIsFlaggedAndWarned) {
    const Heightfield textured = textured_surface();
    const double range = range_of(textured), sigma = 0.009 * range;  // sur-2 128²'s bars: 0.965 %
    const TexelTexture t = texel_texture(textured, sigma);
    std::printf("binary texture: %d texels (%.4f), %.3f of the texel-scale power, threshold %.3g um\n", t.texels,
                t.fraction, t.power_share, t.threshold_um);
    // Of the 6 528 textured texels, those raised among lowered neighbours (or lowered among
    // raised ones) stand a step off the median: far more than 5 % of the tile.
    EXPECT_GT(t.fraction, 2.0 * k_texture_fraction) << t.texels;
    EXPECT_GT(t.power_share, 0.5);
    EXPECT_NEAR(t.rms_height_um, rms_of(textured), 1e-12);
    ConvergenceCheck check;
    check.floor = "poisson";
    add_texel_texture(check, textured, 0.009, range, "error bars");
    EXPECT_TRUE(check.texture_warned);
    EXPECT_FALSE(check.converged);
    ASSERT_EQ(check.reasons.size(), 1u);
    EXPECT_NE(check.warning().find("Spikes"), std::string::npos) << check.warning();
    EXPECT_EQ(check.warning().rfind("the recovery is likely inaccurate", 0), 0u) << check.warning();
    // Counted, not warned, where twice σ is inside the target (sur-2 128² with 8 exposures:
    // 0.48 %, met at 0.84–0.90 %).
    ConvergenceCheck narrow;
    narrow.floor = "poisson";
    add_texel_texture(narrow, textured, 0.004, range, "photon plan");
    EXPECT_GT(narrow.texture_fraction, k_texture_fraction);
    EXPECT_FALSE(narrow.texture_warned);
    EXPECT_TRUE(narrow.converged);
}

TEST(TexelTexture, SmoothSurfaceOfTheSameRmsIsNot) {
    const Heightfield textured = textured_surface();
    const Heightfield smooth = smooth_surface(rms_of(textured), 7);
    EXPECT_NEAR(rms_of(smooth), rms_of(textured), 1e-9);
    const double range = range_of(smooth);
    const TexelTexture t = texel_texture(smooth, 0.009 * range);
    std::printf("smooth: %d texels (%.4f)\n", t.texels, t.fraction);
    EXPECT_LT(t.fraction, 0.002) << t.texels;
    ConvergenceCheck check;
    add_texel_texture(check, smooth, 0.009, range, "error bars");
    EXPECT_FALSE(check.texture_warned);
    EXPECT_TRUE(check.converged);
    EXPECT_EQ(check.texture_sigma_source, "error bars");
}

// An estimate's noise of σ per texel on a flat tile stands off the 3 × 3 median by 0.97 σ rms:
// 4 σ leaves it below 10⁻³ of the texels.
TEST(TexelTexture, AnEstimatesOwnNoiseIsNot) {
    std::mt19937_64 rng(5);
    std::normal_distribution<double> noise(0.0, 0.001);
    std::vector<double> v(std::size_t(k_n) * k_n);
    for (double& x : v) x = noise(rng);
    const Heightfield h(k_n, k_n, v, 1.0, 1.0);
    const TexelTexture t = texel_texture(h, 0.001);
    std::printf("noise: %d texels (%.5f)\n", t.texels, t.fraction);
    EXPECT_LT(t.fraction, 1e-3) << t.texels;
    // Yet the same noise at a tenth of that σ is texture (the rule is in units of σ).
    EXPECT_GT(texel_texture(h, 0.0001).fraction, 0.1);
}

TEST(TexelTexture, RefusesABadSigma) {
    const Heightfield h = smooth_surface(0.01, 1);
    EXPECT_THROW(texel_texture(h, 0.0), std::invalid_argument);
    EXPECT_THROW(texel_texture(h, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
    ConvergenceCheck check;
    add_texel_texture(check, h, -1.0, 1.0, "error bars");  // not judged
    EXPECT_TRUE(check.texture_sigma_source.empty());
    EXPECT_TRUE(check.converged);
}

}  // namespace
}  // namespace wavebrdf
