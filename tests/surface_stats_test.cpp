// ISO 25178-2 parameters, PSD and ACF against surfaces whose values are known in closed form
// (sinusoids, Gaussian bumps), Parseval's identity, and the unit check's warnings.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "wavebrdf/surface_stats.h"

using namespace wavebrdf;

namespace {

constexpr double kPi = 3.14159265358979323846;

// z(x, y) sampled at x = c · dx, y = r · dy.
template <typename F>
HeightGrid sample_surface(int rows, int cols, double dx, double dy, F f) {
    HeightGrid g;
    g.rows = rows;
    g.cols = cols;
    g.dx_um = dx;
    g.dy_um = dy;
    g.heights_um.resize(static_cast<std::size_t>(rows) * cols);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) g.heights_um[static_cast<std::size_t>(r) * cols + c] = f(c * dx, r * dy);
    return g;
}

}  // namespace

// z = A cos(2π x / L) over whole periods, with a sample on each crest and trough.
TEST(SurfaceStats, SinusoidAlongXHasItsClosedFormParameters) {
    const double a = 0.3, period = 16.0, dx = 0.5, dy = 0.7;
    const HeightGrid g = sample_surface(96, 256, dx, dy, [&](double x, double) { return a * std::cos(2 * kPi * x / period); });
    const SurfaceParameters p = surface_parameters(g);
    EXPECT_NEAR(p.Sq, a / std::sqrt(2.0), 1e-12);
    // Sa: the mean of the sampled |cos| (32 points a period), and within 0.5 % of 2A/π.
    double sum_abs = 0.0;
    for (int c = 0; c < 256; ++c) sum_abs += std::abs(a * std::cos(2 * kPi * c * dx / period));
    EXPECT_NEAR(p.Sa, sum_abs / 256, 1e-12);
    EXPECT_NEAR(p.Sa, 2 * a / kPi, 5e-3 * a);
    EXPECT_NEAR(p.Sp, a, 1e-12);
    EXPECT_NEAR(p.Sv, a, 1e-12);
    EXPECT_NEAR(p.Sz, 2 * a, 1e-12);
    EXPECT_NEAR(p.Ssk, 0.0, 1e-10);
    EXPECT_NEAR(p.Sku, 1.5, 1e-10);
    // Forward differences of a cosine: rms 2A sin(k dx / 2) / (√2 dx) over whole periods (the
    // last column's pair is missing, 1/256 of them); the continuous value A k / √2 differs by
    // the factor sin(k dx/2) / (k dx/2) = 0.9984.
    const double k = 2 * kPi / period;
    const double discrete = 2 * a * std::sin(k * dx / 2) / (std::sqrt(2.0) * dx);
    EXPECT_NEAR(p.Sdq, discrete, 3e-3 * discrete);
    EXPECT_NEAR(p.Sdq, a * k / std::sqrt(2.0), 5e-3 * discrete);
    // Sdr: mean of sqrt(1 + s²) − 1 over a period, by a fine midpoint sum of the exact slope.
    double sum = 0.0;
    const int n = 100000;
    for (int m = 0; m < n; ++m) {
        const double s = a * k * std::sin(2 * kPi * (m + 0.5) / n);
        sum += std::sqrt(1 + s * s);
    }
    const double sdr = 100.0 * (sum / n - 1.0);
    EXPECT_NEAR(p.Sdr, sdr, 0.01 * sdr);
    // The ACF is cos(k τx): it reaches 0.2 first straight along x, at acos(0.2) / k, and never
    // along y (the grooves): Str is bounded by half the grid's extent.
    // The unbiased estimate over a finite grid is cos(k τx) plus an edge term of order
    // 1/(k · (M − b) · dx): its crossing, from the ACF along x by a direct sum and linear
    // interpolation between lags, and within 3 % of the infinite surface's acos(0.2) / k.
    double expected = -1.0, previous = 1.0;
    for (int b = 1; b < 128 && expected < 0.0; ++b) {
        double num = 0.0, den = 0.0;
        for (int c = 0; c + b < 256; ++c) num += std::cos(k * c * dx) * std::cos(k * (c + b) * dx);
        for (int c = 0; c < 256; ++c) den += std::cos(k * c * dx) * std::cos(k * c * dx);
        const double acf = (num / (256 - b)) / (den / 256);
        if (acf <= 0.2) expected = (b - 1 + (previous - 0.2) / (previous - acf)) * dx;
        previous = acf;
    }
    EXPECT_NEAR(p.Sal, expected, 1e-3 * expected);
    EXPECT_NEAR(p.Sal, std::acos(0.2) / k, 0.03 * std::acos(0.2) / k);
    EXPECT_TRUE(p.acf_decayed_somewhere);
    EXPECT_FALSE(p.acf_decayed_everywhere);
    EXPECT_LT(p.Str, 0.15);
    // Grooves run along y.
    EXPECT_NEAR(p.Std, 90.0, 0.5);
}

TEST(SurfaceStats, LayDirectionFollowsTheGrooves) {
    const HeightGrid along_x = sample_surface(128, 128, 1.0, 1.0, [](double, double y) { return std::cos(2 * kPi * y / 8); });
    EXPECT_NEAR(surface_parameters(along_x).Std, 0.0, 0.5);
    // Varying along (1, 1): the grooves run along (1, −1), i.e. at 135°.
    const HeightGrid diagonal =
        sample_surface(128, 128, 1.0, 1.0, [](double x, double y) { return std::cos(2 * kPi * (x + y) / 16); });
    EXPECT_NEAR(surface_parameters(diagonal).Std, 135.0, 0.5);
}

// z = h exp(−r² / (2 s²)), well inside the grid: ∫|∇z|² dA = π h², ∫z dA = 2π s² h,
// ∫z² dA = π s² h² (integrals over the plane; the tails beyond the grid are below 1e-20).
TEST(SurfaceStats, GaussianBumpOnNonSquareSpacing) {
    const double h = 0.2, s = 6.0, dx = 0.5, dy = 0.8;
    const int rows = 100, cols = 160;
    const double x0 = cols * dx / 2, y0 = rows * dy / 2;
    const HeightGrid g = sample_surface(rows, cols, dx, dy, [&](double x, double y) {
        const double r2 = (x - x0) * (x - x0) + (y - y0) * (y - y0);
        return h * std::exp(-r2 / (2 * s * s));
    });
    const SurfaceParameters p = surface_parameters(g);
    const double area = rows * dx * cols * dy;
    const double mean = 2 * kPi * s * s * h / area;
    EXPECT_NEAR(p.Sq, std::sqrt(kPi * s * s * h * h / area - mean * mean), 1e-6);
    EXPECT_NEAR(p.Sp, h - mean, 1e-3 * h);
    EXPECT_NEAR(p.Sv, mean, 1e-9);
    // Forward differences of a bump sampled at s/dx = 12 and s/dy = 7.5 points, averaged over
    // the (rows − 1)(cols − 1) points that have both: within 0.5 % of π h² over their area.
    const double cells = (rows - 1) * dx * (cols - 1) * dy;
    EXPECT_NEAR(p.Sdq, std::sqrt(kPi * h * h / cells), 5e-3 * std::sqrt(kPi * h * h / cells));
    // A round bump correlates alike in every direction whatever the spacing (a mix-up of dx
    // and dy would give Str ≈ dy/dx or dx/dy).
    EXPECT_GT(p.Str, 0.9);
}

TEST(SurfaceStats, PsdSumsToTheVarianceAndPeaksAtTheSinusoid) {
    std::mt19937 rng(7);
    std::normal_distribution<double> normal(0.0, 0.05);
    const HeightGrid noise = sample_surface(64, 80, 0.3, 0.45, [&](double, double) { return 1.0 + normal(rng); });
    const Spectrum2d c = power_spectrum_2d(noise);
    double sum = 0.0;
    for (const double v : c.values) sum += v;
    const double sq = surface_parameters(noise).Sq;
    EXPECT_NEAR(sum * c.step_x * c.step_y / (4 * kPi * kPi), sq * sq, 1e-12 * sq * sq);

    const double period = 8.0;
    const HeightGrid wave = sample_surface(64, 64, 0.5, 0.5, [&](double x, double) { return std::sin(2 * kPi * x / period); });
    const RadialProfile radial = radial_power_spectrum(wave);
    std::size_t best = 0;
    for (std::size_t k = 0; k < radial.value.size(); ++k)
        if (radial.value[k] > radial.value[best]) best = k;
    // The peak's ring holds 2π/L (bins one Δq wide, centred on multiples of Δq).
    EXPECT_NEAR(radial.r[best], 2 * kPi / period, 0.5 * 2 * kPi / (64 * 0.5));
    // Its 2-D PSD holds the power at (0, ±k) alone, centred at (rows/2, cols/2 ± 4).
    const Spectrum2d c2 = power_spectrum_2d(wave);
    const double peak = c2.values[32 * 64 + 36];
    EXPECT_GT(peak, 0.0);
    EXPECT_NEAR(c2.values[32 * 64 + 28], peak, 1e-9 * peak);
    EXPECT_NEAR(peak * 2 * c2.step_x * c2.step_y / (4 * kPi * kPi), 0.5, 1e-9);
}

TEST(SurfaceStats, AcfIsOneAtZeroLagAndMatchesADirectSum) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const HeightGrid g = sample_surface(9, 7, 1.0, 2.0, [&](double, double) { return u(rng); });
    const Spectrum2d acf = autocorrelation_2d(g);
    ASSERT_EQ(acf.rows, 17);
    ASSERT_EQ(acf.cols, 13);
    double mean = 0.0;
    for (const double z : g.heights_um) mean += z;
    mean /= 63.0;
    auto z = [&](int r, int c) { return g.heights_um[static_cast<std::size_t>(r) * 7 + c] - mean; };
    double zero = 0.0;
    for (int r = 0; r < 9; ++r)
        for (int c = 0; c < 7; ++c) zero += z(r, c) * z(r, c);
    zero /= 63.0;
    for (int a = -8; a <= 8; ++a)
        for (int b = -6; b <= 6; ++b) {
            double sum = 0.0;
            int n = 0;
            for (int r = 0; r < 9; ++r)
                for (int c = 0; c < 7; ++c)
                    if (r + a >= 0 && r + a < 9 && c + b >= 0 && c + b < 7) {
                        sum += z(r, c) * z(r + a, c + b);
                        ++n;
                    }
            EXPECT_NEAR(acf.values[static_cast<std::size_t>(a + 8) * 13 + (b + 6)], sum / n / zero, 1e-12)
                << a << "," << b;
        }
}

TEST(SurfaceStats, FlatAndBadInputs) {
    const HeightGrid flat = sample_surface(8, 8, 1.0, 1.0, [](double, double) { return 2.5; });
    const SurfaceParameters p = surface_parameters(flat);
    EXPECT_EQ(p.Sq, 0.0);
    EXPECT_EQ(p.Sdr, 0.0);
    EXPECT_EQ(p.Str, 1.0);

    HeightGrid holes = flat;
    holes.heights_um[3] = std::numeric_limits<double>::quiet_NaN();
    holes.heights_um[9] = std::numeric_limits<double>::quiet_NaN();
    try {
        surface_parameters(holes);
        FAIL() << "NaN heights were accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("2 points"), std::string::npos) << e.what();
    }
    HeightGrid thin = sample_surface(1, 8, 1.0, 1.0, [](double, double) { return 0.0; });
    EXPECT_THROW(surface_parameters(thin), std::invalid_argument);
    HeightGrid spacing = flat;
    spacing.dx_um = 0.0;
    EXPECT_THROW(surface_parameters(spacing), std::invalid_argument);
}

TEST(SurfaceStats, HeightfieldIsTransposedIntoTheImageFrame) {
    // Heightfield rows run along x: values varying with the row index vary along x, grooves
    // along y, Std 90°.
    std::vector<double> v(64 * 32);
    for (int i = 0; i < 64; ++i)
        for (int j = 0; j < 32; ++j) v[static_cast<std::size_t>(i) * 32 + j] = std::cos(2 * kPi * i / 8.0);
    const Heightfield hf(64, 32, v, 0.5, 0.1);
    const HeightGrid g = height_grid(hf);
    EXPECT_EQ(g.rows, 32);
    EXPECT_EQ(g.cols, 64);
    const SurfaceParameters p = surface_parameters(hf);
    EXPECT_NEAR(p.Std, 90.0, 0.5);
    EXPECT_NEAR(p.Sq, 0.1 * 0.5 / std::sqrt(2.0), 1e-12);
}

TEST(UnitCheck, NanometreHeightsWarn) {
    // 50 nm rms roughness written in nm but read as µm on 1 µm texels.
    std::mt19937 rng(11);
    std::normal_distribution<double> normal(0.0, 50.0);
    std::vector<double> v(32 * 32);
    for (double& x : v) x = normal(rng);
    const UnitCheck nm = check_units(Heightfield(32, 32, v, 1.0, 1.0), 0.5);
    ASSERT_FALSE(nm.warnings.empty());
    EXPECT_NE(nm.warnings[0].find("rms slope"), std::string::npos) << nm.warnings[0];
    EXPECT_NE(nm.warnings[0].find("nm"), std::string::npos) << nm.warnings[0];
    // The same in µm: no warning, and the phase is 4π Sq / λ.
    const UnitCheck um = check_units(Heightfield(32, 32, v, 1.0, 1e-3), 0.5);
    EXPECT_TRUE(um.warnings.empty());
    EXPECT_NEAR(um.phase_rms_rad, 4 * kPi * um.rms_height_um / 0.5, 1e-12);
    // In metres: a mirror.
    const UnitCheck m = check_units(Heightfield(32, 32, v, 1.0, 1e-6), 0.5);  // 5e-5 um rms
    ASSERT_EQ(m.warnings.size(), 1u);
    EXPECT_NE(m.warnings[0].find("in m read as um"), std::string::npos) << m.warnings[0];
    EXPECT_NE(describe(um).find("rms height"), std::string::npos);
}

// The footprint's check sees exactly the footprint's texels: on z = A cos(2π j / 8) (along the
// columns, 1 µm texels) its rms height is A/√2 and its rms slope A sin(2π/8) / 2 (the wrapping
// central difference of the cosine, averaged over both axes), whatever the rest of the tile
// holds — here 10⁶ µm everywhere more than 3 σ_p + 2 texels away (what a footprint read of a
// file leaves as 0, and what the whole-tile check sees).
TEST(UnitCheck, FootprintCheckSeesOnlyTheFootprintsTexels) {
    const int n = 256;
    const double A = 0.05, sigma_p = 5.0, cx = 128.0, cy = 100.0;
    std::vector<double> v(static_cast<std::size_t>(n) * n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const bool near = std::abs(i - cx) <= 3 * sigma_p + 2 && std::abs(j - cy) <= 3 * sigma_p + 2;
            v[static_cast<std::size_t>(i) * n + j] = near ? A * std::cos(2 * kPi * j / 8.0) : 1e6;
        }
    const Heightfield hf(n, n, v, 1.0, 1.0);
    const UnitCheck c = check_units_footprint(hf, cx, cy, sigma_p, 0.5);
    EXPECT_NEAR(c.rms_height_um, A / std::sqrt(2.0), 0.03 * A / std::sqrt(2.0));
    EXPECT_NEAR(c.rms_slope, A * std::sin(2 * kPi / 8.0) / 2.0, 0.03 * A * std::sin(2 * kPi / 8.0) / 2.0);
    EXPECT_TRUE(c.warnings.empty());
    // The whole tile is another surface altogether.
    EXPECT_GT(check_units(hf, 0.5).rms_height_um, 1e5);
}
