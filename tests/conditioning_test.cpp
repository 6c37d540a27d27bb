// Conditioning a measured surface: each step against what it must do by construction (a
// removed form is gone, a filled hole is harmonic, a resampled plane stays that plane, the
// periodic component's smooth part solves Moisan's Poisson equation) and its record.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "wavebrdf/conditioning.h"

using namespace wavebrdf;

namespace {

constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();

template <typename F>
MeasuredSurface sample(int rows, int cols, double dx, double dy, F f) {
    MeasuredSurface s;
    s.rows = rows;
    s.cols = cols;
    s.dx_um = dx;
    s.dy_um = dy;
    s.format = "npy";
    s.heights_um.resize(static_cast<std::size_t>(rows) * cols);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) s.heights_um[static_cast<std::size_t>(r) * cols + c] = f(c * dx, r * dy, r, c);
    return s;
}

double& h(MeasuredSurface& s, int r, int c) { return s.heights_um[static_cast<std::size_t>(r) * s.cols + c]; }

}  // namespace

TEST(Conditioning, DetrendRemovesPlaneAndQuadricOverMeasuredPointsOnly) {
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 1e-3);
    // A plane plus a quadric plus small noise, with holes holding wild values marked NaN.
    MeasuredSurface s = sample(40, 50, 0.5, 0.7, [&](double x, double y, int, int) {
        return 3.0 + 0.2 * x - 0.1 * y + 0.01 * x * y - 0.004 * x * x + noise(rng);
    });
    for (int r = 10; r < 15; ++r)
        for (int c = 20; c < 30; ++c) h(s, r, c) = nan_value;
    ConditioningOptions o;
    o.detrend_order = 2;
    ConditioningReport report;
    const MeasuredSurface d = condition(s, o, &report);
    double sq = 0.0;
    int n = 0;
    for (const double z : d.heights_um)
        if (std::isfinite(z)) {
            sq += z * z;
            ++n;
        }
    EXPECT_LT(std::sqrt(sq / n), 1.2e-3);  // the noise is left, nothing of the form
    EXPECT_TRUE(std::isnan(d.heights_um[10 * 50 + 20]));
    ASSERT_EQ(report.steps.size(), 1u);
    EXPECT_NE(report.steps[0].find("order 2"), std::string::npos);
    ASSERT_FALSE(d.metadata.empty());
    EXPECT_EQ(d.metadata.back().first, "conditioning");
    // A plane alone leaves the quadric.
    o.detrend_order = 1;
    const MeasuredSurface p = condition(s, o);
    sq = 0.0;
    n = 0;
    for (const double z : p.heights_um)
        if (std::isfinite(z)) {
            sq += z * z;
            ++n;
        }
    EXPECT_GT(std::sqrt(sq / n), 0.01);
}

TEST(Conditioning, HarmonicFillSolvesLaplaceAndKeepsMeasuredPoints) {
    MeasuredSurface s = sample(30, 40, 1.0, 2.0, [](double x, double y, int, int) { return std::sin(0.2 * x) + 0.05 * y; });
    for (int r = 8; r < 16; ++r)
        for (int c = 10; c < 22; ++c) h(s, r, c) = nan_value;
    ConditioningOptions o;
    o.fill = FillMethod::Harmonic;
    ConditioningReport report;
    MeasuredSurface f = condition(s, o, &report);
    for (std::size_t k = 0; k < s.heights_um.size(); ++k)
        if (std::isfinite(s.heights_um[k])) {
            EXPECT_EQ(f.heights_um[k], s.heights_um[k]);
        }
    // The discrete Laplacian with weights 1/dx², 1/dy² vanishes on every filled point.
    for (int r = 8; r < 16; ++r)
        for (int c = 10; c < 22; ++c) {
            const double lap = (h(f, r, c - 1) + h(f, r, c + 1) - 2 * h(f, r, c)) / 1.0 +
                               (h(f, r - 1, c) + h(f, r + 1, c) - 2 * h(f, r, c)) / 4.0;
            EXPECT_NEAR(lap, 0.0, 1e-8);
        }
    EXPECT_NE(report.steps[0].find("96 unmeasured points"), std::string::npos) << report.steps[0];
    EXPECT_NE(report.steps[0].find("harmonic"), std::string::npos);
    // A linear surface is harmonic: the fill restores it exactly.
    MeasuredSurface plane = sample(20, 20, 1.0, 1.0, [](double x, double y, int, int) { return 0.3 * x - 0.2 * y; });
    const MeasuredSurface full = plane;
    for (int r = 5; r < 12; ++r)
        for (int c = 6; c < 9; ++c) h(plane, r, c) = nan_value;
    const MeasuredSurface back = condition(plane, o);
    for (std::size_t k = 0; k < full.heights_um.size(); ++k) EXPECT_NEAR(back.heights_um[k], full.heights_um[k], 1e-8);
}

TEST(Conditioning, NearestAndMeanFill) {
    MeasuredSurface s = sample(5, 6, 1.0, 1.0, [](double, double, int r, int c) { return 10.0 * r + c; });
    h(s, 2, 2) = nan_value;  // nearest: four at distance 1; tie broken by the front
    h(s, 0, 0) = nan_value;  // nearest of (0,0): (0,1)=1 or (1,0)=10 (tie), not (1,1)
    h(s, 4, 5) = nan_value;
    h(s, 4, 4) = nan_value;  // (4,4): nearest (4,3)=43 or (3,4)=34; (4,5): (3,5)=35
    ConditioningOptions o;
    o.fill = FillMethod::Nearest;
    MeasuredSurface f = condition(s, o);
    EXPECT_EQ(h(f, 4, 5), 35.0);
    EXPECT_TRUE(h(f, 0, 0) == 1.0 || h(f, 0, 0) == 10.0);
    EXPECT_TRUE(h(f, 4, 4) == 43.0 || h(f, 4, 4) == 34.0);
    o.fill = FillMethod::Mean;
    f = condition(s, o);
    double sum = 0.0;
    int n = 0;
    for (const double z : s.heights_um)
        if (std::isfinite(z)) {
            sum += z;
            ++n;
        }
    EXPECT_DOUBLE_EQ(h(f, 2, 2), sum / n);
}

TEST(Conditioning, UnfilledPointsAreRefusedWithTheirCount) {
    MeasuredSurface s = sample(8, 8, 1.0, 2.0, [](double x, double, int, int) { return x; });
    h(s, 1, 1) = nan_value;
    h(s, 3, 1) = nan_value;
    h(s, 5, 6) = nan_value;
    ConditioningOptions o;
    o.resample_um = 1.0;
    try {
        condition(s, o);
        FAIL() << "unmeasured points were resampled";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("3 of 64 points"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("--fill"), std::string::npos) << e.what();
    }
}

TEST(Conditioning, ResampleToSquareTexelsKeepsAPlaneAndTheExtent) {
    const MeasuredSurface s =
        sample(33, 21, 0.5, 0.25, [](double x, double y, int, int) { return 1.0 + 0.3 * x - 0.7 * y; });
    ConditioningOptions o;
    o.resample_um = 0.4;
    ConditioningReport report;
    const MeasuredSurface r = condition(s, o, &report);
    EXPECT_EQ(r.cols, 26);  // (21 − 1) · 0.5 / 0.4 + 1
    EXPECT_EQ(r.rows, 21);  // (33 − 1) · 0.25 / 0.4 + 1
    EXPECT_EQ(r.dx_um, 0.4);
    EXPECT_EQ(r.dy_um, 0.4);
    for (int y = 0; y < r.rows; ++y)
        for (int x = 0; x < r.cols; ++x)
            EXPECT_NEAR(r.heights_um[static_cast<std::size_t>(y) * r.cols + x], 1.0 + 0.3 * 0.4 * x - 0.7 * 0.4 * y, 1e-12);
    EXPECT_NE(report.steps[0].find("bilinear"), std::string::npos);
    o.resample_um = 1e-6;
    EXPECT_THROW(condition(s, o), std::invalid_argument);
}

TEST(Conditioning, CropKeepsTheNamedWindow) {
    const MeasuredSurface s = sample(10, 12, 1.0, 1.0, [](double, double, int r, int c) { return 100.0 * r + c; });
    ConditioningOptions o;
    o.crop = std::array<int, 4>{2, 3, 4, 5};
    const MeasuredSurface c = condition(s, o);
    EXPECT_EQ(c.rows, 4);
    EXPECT_EQ(c.cols, 5);
    EXPECT_EQ(c.heights_um[0], 203.0);
    EXPECT_EQ(c.heights_um.back(), 507.0);
    o.crop = std::array<int, 4>{8, 0, 4, 5};
    EXPECT_THROW(condition(s, o), std::invalid_argument);
}

TEST(Conditioning, PeriodicPlusSmoothRemovesTheSeam) {
    std::mt19937 rng(9);
    std::normal_distribution<double> noise(0.0, 0.01);
    const MeasuredSurface s =
        sample(48, 64, 1.0, 1.0, [&](double x, double y, int, int) { return 0.02 * x + 0.01 * y + noise(rng); });
    ConditioningOptions o;
    o.periodic = PeriodicMethod::Smooth;
    ConditioningReport report;
    const MeasuredSurface p = condition(s, o, &report);
    EXPECT_GT(report.seam_ratio_before, 10.0);
    EXPECT_LT(report.seam_ratio_after, 1.5);
    EXPECT_NEAR(report.seam_ratio_after, seam_slope_ratio(p), 1e-12);
    // The smooth component u − p solves the periodic Poisson equation Δ s = v (Moisan eq. 7):
    // v is the seam's jumps on the edges and 0 inside.
    const int rows = 48, cols = 64;
    auto u = [&](int r, int c) { return s.heights_um[static_cast<std::size_t>(r) * cols + c]; };
    auto sm = [&](int r, int c) {
        r = (r + rows) % rows;
        c = (c + cols) % cols;
        return u(r, c) - p.heights_um[static_cast<std::size_t>(r) * cols + c];
    };
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            double v = 0.0;
            if (r == 0) v += u(rows - 1, c) - u(0, c);
            if (r == rows - 1) v += u(0, c) - u(rows - 1, c);
            if (c == 0) v += u(r, cols - 1) - u(r, 0);
            if (c == cols - 1) v += u(r, 0) - u(r, cols - 1);
            const double lap = sm(r + 1, c) + sm(r - 1, c) + sm(r, c + 1) + sm(r, c - 1) - 4 * sm(r, c);
            EXPECT_NEAR(lap, v, 1e-10) << r << "," << c;
        }
    // Mean kept.
    double a = 0.0, b = 0.0;
    for (std::size_t k = 0; k < s.heights_um.size(); ++k) {
        a += s.heights_um[k];
        b += p.heights_um[k];
    }
    EXPECT_NEAR(a, b, 1e-9);
}

TEST(Conditioning, MirrorTilingIsContinuousAcrossTheSeam) {
    const MeasuredSurface s = sample(6, 7, 1.0, 1.0, [](double x, double y, int, int) { return 0.5 * x + y; });
    ConditioningOptions o;
    o.periodic = PeriodicMethod::Mirror;
    ConditioningReport report;
    const MeasuredSurface m = condition(s, o, &report);
    EXPECT_EQ(m.rows, 12);
    EXPECT_EQ(m.cols, 14);
    EXPECT_EQ(report.seam_ratio_after, 0.0);  // the edge row meets its own reflection
    EXPECT_GT(report.seam_ratio_before, 1.0);
    EXPECT_EQ(m.heights_um[static_cast<std::size_t>(11) * 14 + 13], s.heights_um[0]);
}

TEST(Conditioning, ParsersNameTheOptionAndTheChoices) {
    EXPECT_EQ(parse_detrend("poly:3", "--detrend"), 3);
    EXPECT_EQ(parse_detrend("plane", "--detrend"), 1);
    EXPECT_EQ(parse_fill_method("harmonic", "--fill"), FillMethod::Harmonic);
    EXPECT_EQ(parse_periodic_method("mirror", "--periodic"), PeriodicMethod::Mirror);
    EXPECT_EQ(parse_crop("1,2,30,40", "--crop"), (std::array<int, 4>{1, 2, 30, 40}));
    for (const char* bad : {"poly:11", "poly:", "poly:x", "cubic"})
        EXPECT_THROW(parse_detrend(bad, "--detrend"), std::invalid_argument) << bad;
    EXPECT_THROW(parse_crop("1,2,3", "--crop"), std::invalid_argument);
    EXPECT_THROW(parse_crop("1,2,3,-4", "--crop"), std::invalid_argument);
    try {
        parse_fill_method("zero", "--fill");
        FAIL();
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("--fill 'zero'"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("harmonic"), std::string::npos);
    }
}
