#include "wavebrdf/generate.h"
#include "wavebrdf/constants.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

namespace wavebrdf {
namespace {

using wavebrdf::k_pi;

// Independent re-implementations of the statistics the generators promise, in µm.
double rms_height_um(const Heightfield& hf) {
    double sum = 0.0;
    double sum_sq = 0.0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) {
            sum += hf.height_um(i, j);
            sum_sq += hf.height_um(i, j) * hf.height_um(i, j);
        }
    const double n = static_cast<double>(hf.rows()) * hf.cols();
    const double mean = sum / n;
    return std::sqrt(sum_sq / n - mean * mean);
}

double mean_height_um(const Heightfield& hf) {
    double sum = 0.0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) sum += hf.height_um(i, j);
    return sum / (static_cast<double>(hf.rows()) * hf.cols());
}

double rms_slope(const Heightfield& hf) {
    double sum = 0.0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) {
            const double sx = 0.5 * (hf.value(i + 1, j) - hf.value(i - 1, j));
            const double sy = 0.5 * (hf.value(i, j + 1) - hf.value(i, j - 1));
            sum += sx * sx + sy * sy;
        }
    return std::sqrt(sum / (2.0 * hf.rows() * hf.cols()));
}

// Normalised periodic autocorrelation at lag (di, dj) texels (the fields have zero mean).
double autocorrelation(const Heightfield& hf, int di, int dj) {
    double num = 0.0;
    double den = 0.0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) {
            num += hf.value(i, j) * hf.value(i + di, j + dj);
            den += hf.value(i, j) * hf.value(i, j);
        }
    return num / den;
}

SurfaceParams isotropic(int rows, int cols, std::uint64_t seed = 7) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = rows;
    p.cols = cols;
    p.seed = seed;
    return p;
}

TEST(GenerateTest, ParsesAndNamesEveryType) {
    for (const SurfaceType t : {SurfaceType::Flat, SurfaceType::Isotropic, SurfaceType::Brushed, SurfaceType::Scratched,
                                SurfaceType::Grating})
        EXPECT_EQ(parse_surface_type(to_string(t)), t);
    EXPECT_THROW(parse_surface_type("wavy"), std::invalid_argument);
    EXPECT_THROW(parse_surface_type(""), std::invalid_argument);
    EXPECT_THROW(parse_surface_type("Isotropic"), std::invalid_argument);
}

TEST(GenerateTest, FlatIsZero) {
    SurfaceParams p;
    p.type = SurfaceType::Flat;
    p.rows = 5;
    p.cols = 9;
    p.texel_um = 0.5;
    const Heightfield hf = generate_heightfield(p);
    EXPECT_EQ(hf.rows(), 5);
    EXPECT_EQ(hf.cols(), 9);
    EXPECT_DOUBLE_EQ(hf.texel_um(), 0.5);
    EXPECT_DOUBLE_EQ(hf.vscale(), 1.0);
    for (const double v : hf.values()) EXPECT_EQ(v, 0.0);
}

TEST(GenerateTest, IsotropicRealisesRequestedRmsHeight) {
    for (const double texel_um : {1.0, 0.25}) {
        SurfaceParams p = isotropic(128, 96);
        p.texel_um = texel_um;
        p.rms_height_um = 0.37;
        const Heightfield hf = generate_heightfield(p);
        EXPECT_DOUBLE_EQ(hf.texel_um(), texel_um);
        EXPECT_DOUBLE_EQ(hf.vscale(), 1.0);
        EXPECT_NEAR(rms_height_um(hf), 0.37, 1e-9 * 0.37);
        EXPECT_NEAR(mean_height_um(hf), 0.0, 1e-12);
        // Values are in units of texel width.
        EXPECT_NEAR(hf.value(3, 4) * texel_um, hf.height_um(3, 4), 1e-15);
    }
}

TEST(GenerateTest, IsotropicRealisesRequestedRmsSlope) {
    SurfaceParams p = isotropic(128, 160);
    p.rms_slope = 0.2;
    p.rms_height_um = 5.0;  // ignored when rms_slope > 0
    const Heightfield hf = generate_heightfield(p);
    EXPECT_NEAR(rms_slope(hf), 0.2, 1e-9 * 0.2);
    // The slope is dimensionless: the same request at another texel width gives the same
    // values in texel units (heights scale with the texel).
    p.texel_um = 3.0;
    const Heightfield scaled = generate_heightfield(p);
    EXPECT_NEAR(rms_slope(scaled), 0.2, 1e-9 * 0.2);
}

TEST(GenerateTest, IsotropicAutocorrelationIsGaussian) {
    SurfaceParams p = isotropic(512, 512, 3);
    p.texel_um = 0.5;
    p.correlation_um = 4.0;  // ℓ = 8 texels
    const Heightfield hf = generate_heightfield(p);
    const double expected = std::exp(-1.0);
    EXPECT_NEAR(autocorrelation(hf, 8, 0), expected, 0.15 * expected);
    EXPECT_NEAR(autocorrelation(hf, 0, 8), expected, 0.15 * expected);
    // exp(−(r/ℓ)²): at r = ℓ/2 the correlation is e^{−1/4}, at 2ℓ e^{−4}.
    EXPECT_NEAR(autocorrelation(hf, 4, 0), std::exp(-0.25), 0.1 * std::exp(-0.25));
    EXPECT_LT(std::abs(autocorrelation(hf, 16, 0)), 0.08);
}

TEST(GenerateTest, BrushedIsLongerAlongColumns) {
    SurfaceParams p = isotropic(256, 256, 11);
    p.type = SurfaceType::Brushed;
    p.correlation_um = 4.0;
    p.anisotropy = 8.0;
    const Heightfield hf = generate_heightfield(p);
    EXPECT_NEAR(rms_height_um(hf), p.rms_height_um, 1e-9 * p.rms_height_um);
    const double along_x = autocorrelation(hf, 4, 0);
    const double along_y = autocorrelation(hf, 0, 4);
    EXPECT_NEAR(along_x, std::exp(-1.0), 0.15 * std::exp(-1.0));
    EXPECT_GT(along_y, 0.95);  // e^{−1/64} in expectation
    EXPECT_GT(autocorrelation(hf, 0, 32), 0.2);
}

TEST(GenerateTest, SameSeedSameFieldOtherSeedOtherField) {
    for (const SurfaceType t : {SurfaceType::Isotropic, SurfaceType::Brushed, SurfaceType::Scratched}) {
        SurfaceParams p = isotropic(64, 80, 42);
        p.type = t;
        const Heightfield a = generate_heightfield(p);
        const Heightfield b = generate_heightfield(p);
        EXPECT_EQ(a.values(), b.values()) << to_string(t);
        p.seed = 43;
        const Heightfield c = generate_heightfield(p);
        double diff = 0.0;
        for (std::size_t k = 0; k < a.values().size(); ++k)
            diff = std::max(diff, std::abs(a.values()[k] - c.values()[k]));
        EXPECT_GT(diff, 1e-3 * (p.rms_height_um / p.texel_um)) << to_string(t);
    }
}

// The wrap-around neighbour difference has the statistics of the interior ones: no seam.
void expect_seamless(const Heightfield& hf, double tolerance) {
    double interior_x = 0.0;
    double interior_y = 0.0;
    double wrap_x = 0.0;
    double wrap_y = 0.0;
    for (int i = 1; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) {
            const double d = hf.value(i, j) - hf.value(i - 1, j);
            interior_x += d * d;
        }
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 1; j < hf.cols(); ++j) {
            const double d = hf.value(i, j) - hf.value(i, j - 1);
            interior_y += d * d;
        }
    for (int j = 0; j < hf.cols(); ++j) {
        const double d = hf.value(0, j) - hf.value(hf.rows() - 1, j);
        wrap_x += d * d;
    }
    for (int i = 0; i < hf.rows(); ++i) {
        const double d = hf.value(i, 0) - hf.value(i, hf.cols() - 1);
        wrap_y += d * d;
    }
    interior_x = std::sqrt(interior_x / ((hf.rows() - 1.0) * hf.cols()));
    interior_y = std::sqrt(interior_y / (hf.rows() * (hf.cols() - 1.0)));
    wrap_x = std::sqrt(wrap_x / hf.cols());
    wrap_y = std::sqrt(wrap_y / hf.rows());
    EXPECT_NEAR(wrap_x / interior_x, 1.0, tolerance);
    EXPECT_NEAR(wrap_y / interior_y, 1.0, tolerance);
}

TEST(GenerateTest, IsotropicAndBrushedTileSeamlessly) {
    SurfaceParams p = isotropic(512, 512, 5);
    p.correlation_um = 3.0;
    expect_seamless(generate_heightfield(p), 0.2);
    p.type = SurfaceType::Brushed;
    p.anisotropy = 4.0;
    p.correlation_um = 2.0;
    expect_seamless(generate_heightfield(p), 0.2);
}

TEST(GenerateTest, GratingMatchesFormula) {
    SurfaceParams p;
    p.type = SurfaceType::Grating;
    p.rows = 64;
    p.cols = 7;
    p.texel_um = 0.5;
    p.amplitude_um = 0.08;
    p.period_um = 8.0;  // 16 texels: divides the 64-texel tile
    const Heightfield hf = generate_heightfield(p);
    for (int i = 0; i < p.rows; ++i)
        for (int j = 0; j < p.cols; ++j) {
            const double x_um = (i + 0.5) * p.texel_um;
            EXPECT_NEAR(hf.height_um(i, j), 0.08 * std::sin(2.0 * k_pi * x_um / 8.0), 1e-15);
        }
    const HeightStats s = height_stats(hf);
    EXPECT_NEAR(s.rms_height_um, 0.08 / std::sqrt(2.0), 1e-12);
    EXPECT_NEAR(s.mean_um, 0.0, 1e-15);
    // Periodic: the wrap-around difference equals the interior one of the same phase.
    EXPECT_NEAR(hf.value(0, 0) - hf.value(-1, 0), hf.value(16, 0) - hf.value(15, 0), 1e-14);
}

TEST(GenerateTest, ScratchedHasGroovesOnASmoothBase) {
    SurfaceParams p = isotropic(256, 256, 9);
    p.type = SurfaceType::Scratched;
    p.scratch_count = 20;
    p.scratch_depth_um = 0.05;
    p.scratch_width_um = 1.5;
    const Heightfield hf = generate_heightfield(p);
    const HeightStats s = height_stats(hf);
    // Grooves reach ≈ −depth (plus the base, rms 0.1·depth); the deeper groove wins at crossings.
    EXPECT_GT(s.min_um, -1.5 * p.scratch_depth_um);
    EXPECT_LT(s.min_um, -0.8 * p.scratch_depth_um);
    // Most texels lie on the base, far from every groove.
    int near_base = 0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j)
            if (std::abs(hf.height_um(i, j)) < 0.35 * p.scratch_depth_um) ++near_base;
    EXPECT_GT(near_base, 0.75 * hf.rows() * hf.cols());
    EXPECT_LT(s.max_um, 0.5 * p.scratch_depth_um);
}

TEST(GenerateTest, ScratchesAreContinuousAcrossTheTileBorder) {
    // Only scratches, no base: every groove must continue across the border, so the wrap
    // difference is no larger than the largest interior difference.
    SurfaceParams p = isotropic(96, 64, 4);
    p.type = SurfaceType::Scratched;
    p.scratch_count = 30;
    p.scratch_depth_um = 1.0;
    p.scratch_width_um = 4.0;
    p.correlation_um = 1e6;  // a base far smoother than the tile: a single low mode
    const Heightfield hf = generate_heightfield(p);
    double interior = 0.0;
    for (int i = 1; i < hf.rows(); ++i)
        for (int j = 1; j < hf.cols(); ++j)
            interior = std::max({interior, std::abs(hf.value(i, j) - hf.value(i - 1, j)),
                                 std::abs(hf.value(i, j) - hf.value(i, j - 1))});
    double wrap = 0.0;
    for (int j = 0; j < hf.cols(); ++j) wrap = std::max(wrap, std::abs(hf.value(0, j) - hf.value(-1, j)));
    for (int i = 0; i < hf.rows(); ++i) wrap = std::max(wrap, std::abs(hf.value(i, 0) - hf.value(i, -1)));
    EXPECT_LE(wrap, interior * 1.05);
}

TEST(GenerateTest, ScratchSpansOnePeriodAlongItsDominantAxis) {
    // A single scratch is one period long along its dominant axis (so an axis-aligned one is a
    // closed periodic line): every row, or every column, of texels crosses its groove.
    SurfaceParams p = isotropic(64, 64, 1);
    p.type = SurfaceType::Scratched;
    p.scratch_count = 1;
    p.scratch_depth_um = 1.0;
    p.scratch_width_um = 2.0;
    const Heightfield hf = generate_heightfield(p);
    int rows_crossed = 0;
    int cols_crossed = 0;
    for (int i = 0; i < hf.rows(); ++i) {
        double lo = 0.0;
        for (int j = 0; j < hf.cols(); ++j) lo = std::min(lo, hf.height_um(i, j));
        if (lo < -0.5) ++rows_crossed;
    }
    for (int j = 0; j < hf.cols(); ++j) {
        double lo = 0.0;
        for (int i = 0; i < hf.rows(); ++i) lo = std::min(lo, hf.height_um(i, j));
        if (lo < -0.5) ++cols_crossed;
    }
    EXPECT_TRUE(rows_crossed == hf.rows() || cols_crossed == hf.cols())
        << rows_crossed << " rows, " << cols_crossed << " columns";
}

TEST(GenerateTest, NonSquareWorksForEveryType) {
    for (const SurfaceType t : {SurfaceType::Flat, SurfaceType::Isotropic, SurfaceType::Brushed, SurfaceType::Scratched,
                                SurfaceType::Grating}) {
        SurfaceParams p = isotropic(48, 80, 2);
        p.type = t;
        p.period_um = 16.0;
        const Heightfield hf = generate_heightfield(p);
        EXPECT_EQ(hf.rows(), 48) << to_string(t);
        EXPECT_EQ(hf.cols(), 80) << to_string(t);
        for (const double v : hf.values()) ASSERT_TRUE(std::isfinite(v)) << to_string(t);
        if (t == SurfaceType::Isotropic || t == SurfaceType::Brushed) {
            EXPECT_NEAR(rms_height_um(hf), p.rms_height_um, 1e-9 * p.rms_height_um);
        }
        // Odd sizes and a single row or column as well.
        for (const auto& size : {std::pair<int, int>{1, 37}, {37, 1}, {3, 5}, {17, 2}}) {
            p.rows = size.first;
            p.cols = size.second;
            const Heightfield small = generate_heightfield(p);
            EXPECT_EQ(small.rows(), size.first);
            EXPECT_EQ(small.cols(), size.second);
            if (t == SurfaceType::Isotropic) {
                EXPECT_NEAR(rms_height_um(small), p.rms_height_um, 1e-9 * p.rms_height_um);
            }
        }
    }
}

TEST(GenerateTest, LongCorrelationStillReachesTheRequest) {
    // ℓ far beyond the tile: the power spectrum underflows away from DC unless handled in logs.
    SurfaceParams p = isotropic(32, 40);
    p.correlation_um = 1e5;
    Heightfield hf = generate_heightfield(p);
    EXPECT_NEAR(rms_height_um(hf), p.rms_height_um, 1e-9 * p.rms_height_um);
    p.type = SurfaceType::Brushed;
    p.rows = 512;  // the field is constant along y: only the rows are independent samples
    p.cols = 8;
    p.correlation_um = 0.01;  // shorter than a texel: white along x
    p.anisotropy = 1e6;
    hf = generate_heightfield(p);
    EXPECT_NEAR(rms_height_um(hf), p.rms_height_um, 1e-9 * p.rms_height_um);
    EXPECT_LT(std::abs(autocorrelation(hf, 1, 0)), 0.2);
    EXPECT_GT(autocorrelation(hf, 0, 1), 0.99);
}

TEST(GenerateTest, ZeroRmsGivesFlatAndDegenerateGridsThrow) {
    SurfaceParams p = isotropic(16, 16);
    p.rms_height_um = 0.0;
    const Heightfield zero = generate_heightfield(p);
    for (const double v : zero.values()) EXPECT_EQ(v, 0.0);
    // 1×1 has no zero-mean variation; 2×2 has no central-difference slope.
    p = isotropic(1, 1);
    EXPECT_THROW(generate_heightfield(p), std::invalid_argument);
    p.rms_height_um = 0.0;
    EXPECT_NO_THROW(generate_heightfield(p));
    p = isotropic(2, 2);
    EXPECT_NO_THROW(generate_heightfield(p));
    p.rms_slope = 0.1;
    EXPECT_THROW(generate_heightfield(p), std::invalid_argument);
    // Scratched and the others are defined on a single texel.
    for (const SurfaceType t : {SurfaceType::Flat, SurfaceType::Scratched, SurfaceType::Grating}) {
        p = isotropic(1, 1);
        p.type = t;
        EXPECT_NO_THROW(generate_heightfield(p)) << to_string(t);
    }
}

TEST(GenerateTest, HeightStatsMatchesHandComputedValues) {
    // h (texel units) = [[0, 1], [2, −3]] at w = 2, v = 0.5 → H = v·w·h = h µm.
    const Heightfield hf(2, 2, {0.0, 1.0, 2.0, -3.0}, 2.0, 0.5);
    const HeightStats s = height_stats(hf);
    EXPECT_DOUBLE_EQ(s.mean_um, 0.0);
    EXPECT_DOUBLE_EQ(s.rms_height_um, std::sqrt((0.0 + 1.0 + 4.0 + 9.0) / 4.0));
    EXPECT_DOUBLE_EQ(s.min_um, -3.0);
    EXPECT_DOUBLE_EQ(s.max_um, 2.0);
    EXPECT_DOUBLE_EQ(s.rms_slope, 0.0);  // on a 2×2 grid the central differences vanish

    // 3×1 ramp-like field: s_x = v·(h[i+1] − h[i−1]) / 2 with wrap.
    const Heightfield line(3, 1, {0.0, 1.0, 5.0}, 1.0, 2.0);
    const HeightStats t = height_stats(line);
    // s_x = (1−5, 5−0, 0−1)·2/2 = (−4, 5, −1); s_y = 0.
    EXPECT_NEAR(t.rms_slope, std::sqrt((16.0 + 25.0 + 1.0) / 6.0), 1e-14);
    EXPECT_NEAR(t.mean_um, 4.0, 1e-14);
    EXPECT_NEAR(t.min_um, 0.0, 1e-14);
    EXPECT_NEAR(t.max_um, 10.0, 1e-14);

    // A generated field: height_stats agrees with the independent helpers.
    SurfaceParams p = isotropic(64, 48);
    p.rms_slope = 0.3;
    const Heightfield g = generate_heightfield(p);
    EXPECT_NEAR(height_stats(g).rms_slope, 0.3, 1e-9);
    EXPECT_NEAR(height_stats(g).rms_height_um, rms_height_um(g), 1e-12);
}

TEST(GenerateTest, BadParametersThrowTheRightException) {
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    constexpr double inf = std::numeric_limits<double>::infinity();
    const auto expect_throws = [](const std::function<void(SurfaceParams&)>& edit, bool domain, const char* what) {
        for (const SurfaceType t : {SurfaceType::Flat, SurfaceType::Isotropic, SurfaceType::Brushed,
                                    SurfaceType::Scratched, SurfaceType::Grating}) {
            SurfaceParams p = isotropic(8, 8);
            p.type = t;
            edit(p);
            if (domain) {
                EXPECT_THROW(generate_heightfield(p), std::domain_error) << what << " " << to_string(t);
            } else {
                EXPECT_THROW(generate_heightfield(p), std::invalid_argument) << what << " " << to_string(t);
            }
        }
    };
    expect_throws([](SurfaceParams& p) { p.rows = 0; }, false, "rows 0");
    expect_throws([](SurfaceParams& p) { p.cols = -3; }, false, "cols -3");
    expect_throws([](SurfaceParams& p) { p.rows = 16385; }, false, "rows 16385");
    expect_throws([](SurfaceParams& p) { p.type = static_cast<SurfaceType>(99); }, false, "unknown type");
    expect_throws([](SurfaceParams& p) { p.texel_um = 0.0; }, true, "texel 0");
    expect_throws([](SurfaceParams& p) { p.texel_um = -1.0; }, true, "texel -1");
    expect_throws([](SurfaceParams& p) { p.texel_um = nan; }, true, "texel nan");
    expect_throws([](SurfaceParams& p) { p.correlation_um = 0.0; }, true, "correlation 0");
    expect_throws([](SurfaceParams& p) { p.correlation_um = inf; }, true, "correlation inf");
    expect_throws([](SurfaceParams& p) { p.anisotropy = 0.0; }, true, "anisotropy 0");
    expect_throws([](SurfaceParams& p) { p.rms_height_um = -0.1; }, true, "rms height < 0");
    expect_throws([](SurfaceParams& p) { p.rms_height_um = nan; }, true, "rms height nan");
    expect_throws([](SurfaceParams& p) { p.rms_slope = -0.1; }, true, "rms slope < 0");
    expect_throws([](SurfaceParams& p) { p.rms_slope = inf; }, true, "rms slope inf");
    expect_throws([](SurfaceParams& p) { p.scratch_count = -1; }, true, "count < 0");
    expect_throws([](SurfaceParams& p) { p.scratch_depth_um = -0.1; }, true, "depth < 0");
    expect_throws([](SurfaceParams& p) { p.scratch_depth_um = nan; }, true, "depth nan");
    expect_throws([](SurfaceParams& p) { p.scratch_width_um = 0.0; }, true, "width 0");
    expect_throws([](SurfaceParams& p) { p.amplitude_um = inf; }, true, "amplitude inf");
    expect_throws([](SurfaceParams& p) { p.period_um = 0.0; }, true, "period 0");
    expect_throws([](SurfaceParams& p) { p.period_um = -4.0; }, true, "period < 0");

    // Messages name the parameter and the bad value.
    SurfaceParams p = isotropic(8, 8);
    p.correlation_um = -2.5;
    try {
        generate_heightfield(p);
        ADD_FAILURE() << "no exception";
    } catch (const std::domain_error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("correlation_um"), std::string::npos) << what;
        EXPECT_NE(what.find("-2.5"), std::string::npos) << what;
        EXPECT_NE(what.find("> 0"), std::string::npos) << what;
    }
    p = isotropic(0, 8);
    try {
        generate_heightfield(p);
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("rows = 0"), std::string::npos) << what;
    }
}

TEST(GenerateTest, WithHeightRangeScalesPeakToValleyAboutTheMean) {
    SurfaceParams p;
    p.rows = 24;
    p.cols = 20;
    p.texel_um = 2.0;
    p.seed = 4;
    const Heightfield hf = generate_heightfield(p).with_scale(2.0, 0.5);
    const Heightfield scaled = with_height_range(hf, 1.7);
    const HeightStats before = height_stats(hf), after = height_stats(scaled);
    EXPECT_NEAR(after.max_um - after.min_um, 1.7, 1e-12);
    EXPECT_NEAR(after.mean_um, before.mean_um, 1e-12);
    EXPECT_NEAR(after.rms_height_um / before.rms_height_um, 1.7 / (before.max_um - before.min_um), 1e-12);
    EXPECT_EQ(scaled.texel_um(), 2.0);
    EXPECT_EQ(scaled.vscale(), 0.5);
    EXPECT_THROW(with_height_range(hf, 0.0), std::domain_error);
    EXPECT_THROW(with_height_range(hf, std::numeric_limits<double>::quiet_NaN()), std::domain_error);
    EXPECT_THROW(with_height_range(Heightfield(4, 4, std::vector<double>(16, 1.0)), 1.0), std::domain_error);
}

}  // namespace
}  // namespace wavebrdf
