// Tests of the forward renderer: fast path against the direct sum, the direct sum against an
// independent transcription of docs/model.md §3-5, invariances, physics, and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <array>
#include <complex>

#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/generate.h"

using namespace wavebrdf;
using wavebrdf::test::make_query;
using wavebrdf::test::max_abs;
using wavebrdf::test::max_abs_diff;
using wavebrdf::test::random_heightfield;

namespace {

using wavebrdf::k_pi;
const Model kBrdfModels[] = {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff};

// docs/model.md §3-5 written out literally: absolute kernel positions μ_k, C_k and a_k as stated,
// ĝ_k(u) = C_k exp(−2π²σ²|u + a_k|²) e^{−i2π(u + a_k)·μ_k}, no algebraic shortcut. Only valid
// when the footprint does not wrap around the tile (then the periodic image is the texel).
std::vector<double> literal_model(const Heightfield& hf, const Query& q, double lambda, int n) {
    std::vector<double> out(static_cast<std::size_t>(n) * n, 0.0);
    const double w = hf.texel_um(), sigma = w / 2;
    for (int p = 0; p < n; ++p)
        for (int r = 0; r < n; ++r) {
            const double ox = slice_omega(p, n), oy = slice_omega(r, n);
            if (ox * ox + oy * oy > 1.0) continue;
            const double ci = std::sqrt(1 - q.omega_i[0] * q.omega_i[0] - q.omega_i[1] * q.omega_i[1]);
            const double co = std::sqrt(std::abs(1 - ox * ox - oy * oy));
            const bool ghs_type = !is_separable(q.model);
            const double scale = ghs_type ? (ci + co) / 2 : 1.0;
            const double ux = (q.omega_i[0] + ox) / lambda, uy = (q.omega_i[1] + oy) / lambda;
            std::complex<double> field = 0.0;
            for (int i = 0; i < hf.rows(); ++i)
                for (int j = 0; j < hf.cols(); ++j) {
                    const double mx = (i + 0.5) * w, my = (j + 0.5) * w;
                    const double d2 = (mx - q.x_um) * (mx - q.x_um) + (my - q.y_um) * (my - q.y_um);
                    if (d2 > 9 * q.sigma_p_um * q.sigma_p_um) continue;
                    const double c = std::exp(-d2 / (2 * q.sigma_p_um * q.sigma_p_um)) /
                                     (std::sqrt(k_pi) * q.sigma_p_um);
                    const double H = hf.vscale() * w * hf.value(i, j);
                    const double sx = hf.vscale() * (hf.value(i + 1, j) - hf.value(i - 1, j)) / 2;
                    const double sy = hf.vscale() * (hf.value(i, j + 1) - hf.value(i, j - 1)) / 2;
                    const double cinfo = scale * (H - sx * mx - sy * my);
                    const double ax = scale * 2 * sx / lambda, ay = scale * 2 * sy / lambda;
                    const std::complex<double> C = w * w * std::polar(1.0, -4 * k_pi / lambda * cinfo);
                    double c2 = 1.0;
                    if (q.model == Model::Kirchhoff)
                        c2 = (ci + co) - (ox + q.omega_i[0]) * sx - (oy + q.omega_i[1]) * sy;
                    const double gx = ux + ax, gy = uy + ay;
                    field += c * c2 * C * std::exp(-2 * k_pi * k_pi * sigma * sigma * (gx * gx + gy * gy)) *
                             std::polar(1.0, -2 * k_pi * (gx * mx + gy * my));
                }
            double c1 = 0;
            switch (q.model) {
                case Model::OHS:
                case Model::GHS: c1 = co / (lambda * lambda * ci); break;
                case Model::ROHS:
                case Model::RGHS: c1 = (ci + co) * (ci + co) / (4 * lambda * lambda * ci * co); break;
                case Model::Kirchhoff: c1 = 1 / (4 * lambda * lambda * ci * co); break;
            }
            out[static_cast<std::size_t>(p) * n + r] = c1 * std::norm(field);
        }
    return out;
}

std::vector<double> direct_slice(const Heightfield& hf, const Query& q, double lambda, int n, double tol = 0) {
    RenderOptions o;
    o.path = RenderPath::Direct;
    o.prune_tolerance = tol;
    return render_slice<double>(hf, q, lambda, n, o);
}

std::vector<double> separable(const Heightfield& hf, const Query& q, double lambda, int n) {
    RenderOptions o;
    o.path = RenderPath::Separable;
    return render_slice<double>(hf, q, lambda, n, o);
}

}  // namespace

TEST(BrdfTest, DirectSumMatchesLiteralModelForEveryModel) {
    const Heightfield hf = random_heightfield(24, 20, 0.3, 7, 0.8, 1.3);
    for (Model m : kBrdfModels) {
        const Query q = make_query(m, 9.7, 8.1, 2.0, 0.21, -0.13);
        const auto ref = literal_model(hf, q, 0.55, 24);
        const auto got = direct_slice(hf, q, 0.55, 24);
        EXPECT_LT(max_abs_diff(ref, got), 1e-10 * max_abs(ref)) << to_string(m);
        EXPECT_GT(max_abs(ref), 0.0);
    }
}

TEST(BrdfTest, SeparableMatchesDirectSum) {
    const Heightfield hf = random_heightfield(48, 40, 0.4, 11, 1.0, 1.0);
    for (Model m : {Model::OHS, Model::ROHS}) {
        for (double lambda : {0.4, 0.7}) {
            const Query q = make_query(m, 3.0, 37.5, 4.0, -0.3, 0.25);  // footprint wraps the tile
            const auto d = direct_slice(hf, q, lambda, 40);
            const auto s = separable(hf, q, lambda, 40);
            EXPECT_LT(max_abs_diff(d, s), 1e-11 * max_abs(d)) << to_string(m) << " " << lambda;
        }
    }
}

// The separable factors carry their Gaussians by recurrence from the peak: check a fine grid
// (many steps) with slopes steep enough to put some peaks off the slice.
TEST(BrdfTest, SeparableMatchesDirectSumOnFineGridsWithSteepSlopes) {
    const Heightfield hf = random_heightfield(16, 16, 0.5, 5, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 5.0, 9.0, 2.0, 0.2, -0.1);
    const auto d = direct_slice(hf, q, 0.5, 320);
    const auto s = separable(hf, q, 0.5, 320);
    EXPECT_LT(max_abs_diff(d, s), 1e-11 * max_abs(d));
    EXPECT_GT(max_abs(d), 0.0);
}

TEST(BrdfTest, FloatAgreesWithDouble) {
    const Heightfield hf = random_heightfield(64, 64, 0.4, 3, 1.0, 1.0);
    const Query q = make_query(Model::OHS, 30.0, 20.0, 6.0, 0.1, 0.0);
    const auto d = render_slice<double>(hf, q, 0.5, 48);
    const auto f = render_slice<float>(hf, q, 0.5, 48);
    const std::vector<double> fd(f.begin(), f.end());
    EXPECT_LT(max_abs_diff(d, fd), 1e-4 * max_abs(d));
}

TEST(BrdfTest, PruningErrorIsBelowToleranceForEveryModel) {
    const Heightfield hf = random_heightfield(48, 48, 0.5, 5, 1.0, 1.0);
    for (Model m : kBrdfModels) {
        const Query q = make_query(m, 20.0, 25.0, 5.0, 0.2, 0.1);
        const auto exact = direct_slice(hf, q, 0.5, 32, 0.0);
        const auto pruned = direct_slice(hf, q, 0.5, 32, 1e-6);
        EXPECT_LE(max_abs_diff(exact, pruned), 1e-6 * max_abs(exact)) << to_string(m);
    }
}

TEST(BrdfTest, ConstantHeightOffsetChangesNothing) {
    const Heightfield hf = random_heightfield(40, 40, 0.4, 9, 1.0, 1.0);
    std::vector<double> shifted = hf.values();
    for (double& v : shifted) v += 0.37;
    const Heightfield hf2 = hf.with_values(shifted);
    for (Model m : kBrdfModels) {
        const Query q = make_query(m, 12.0, 15.0, 4.0, 0.1, 0.2);
        const auto a = render_slice<double>(hf, q, 0.5, 32);
        const auto b = render_slice<double>(hf2, q, 0.5, 32);
        EXPECT_LT(max_abs_diff(a, b), 1e-10 * max_abs(a)) << to_string(m);
    }
}

TEST(BrdfTest, TranslatingHeightfieldAndQueryTogetherChangesNothing) {
    const int rows = 40, cols = 36;
    const Heightfield hf = random_heightfield(rows, cols, 0.4, 13, 0.9, 1.0);
    const int di = 7, dj = -11;
    std::vector<double> rolled(hf.values().size());
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            rolled[hf.index(((i + di) % rows + rows) % rows, ((j + dj) % cols + cols) % cols)] = hf.value(i, j);
    const Heightfield moved = hf.with_values(rolled);
    for (Model m : kBrdfModels) {
        const Query q = make_query(m, 5.0, 30.0, 3.5, -0.2, 0.3);
        Query q2 = q;
        q2.x_um += di * hf.texel_um();
        q2.y_um += dj * hf.texel_um();
        const auto a = render_slice<double>(hf, q, 0.6, 32);
        const auto b = render_slice<double>(moved, q2, 0.6, 32);
        EXPECT_LT(max_abs_diff(a, b), 1e-9 * max_abs(a)) << to_string(m);
    }
}

// Σ f · (2/n)² over the disk is ∫ f_r cos θ_o dω_o, ≈ 1 for a mirror (docs/model.md §13). The Gabor
// kernels blur the window by σ = w/2 in each axis, so the exact value is σ_p² / (σ_p² + σ²)
// (Parseval on the blurred Gaussian window), 0.9975 here; both are checked.
TEST(BrdfTest, FlatMirrorAlbedoIsOne) {
    const Heightfield flat(96, 96, std::vector<double>(96 * 96, 0.0), 1.0, 1.0);
    const double sigma_p = 10.0, sigma = 0.5;
    for (auto wi : {std::array<double, 2>{0.0, 0.0}, std::array<double, 2>{0.3, -0.2}}) {
        for (Model m : kBrdfModels) {
            const Query q = make_query(m, 48.0, 48.0, sigma_p, wi[0], wi[1]);
            const int n = 128;  // pixel spacing in u = 2/(nλ): 1.4 lobe standard deviations
            const auto f = render_slice<double>(flat, q, 1.0, n);
            double albedo = 0.0;
            for (double v : f) albedo += v * (2.0 / n) * (2.0 / n);
            EXPECT_NEAR(albedo, 1.0, 0.01) << to_string(m) << " wi=" << wi[0];
            EXPECT_NEAR(albedo, sigma_p * sigma_p / (sigma_p * sigma_p + sigma * sigma), 1e-3)
                << to_string(m) << " wi=" << wi[0];
        }
    }
}

TEST(BrdfTest, MirrorLobeIsAtTheMirrorDirection) {
    const Heightfield flat(64, 64, std::vector<double>(64 * 64, 0.0), 1.0, 1.0);
    const int n = 200;
    for (Model m : kBrdfModels) {
        const Query q = make_query(m, 10.0, 50.0, 6.0, 0.35, -0.5);
        const auto f = render_slice<double>(flat, q, 0.5, n);
        std::size_t best = 0;
        for (std::size_t i = 0; i < f.size(); ++i)
            if (f[i] > f[best]) best = i;
        const double ox = slice_omega(static_cast<int>(best / n), n);
        const double oy = slice_omega(static_cast<int>(best % n), n);
        // The mirror direction lies between two pixel centres here: within half a pixel.
        EXPECT_NEAR(ox, -0.35, 1.0 / n + 1e-12) << to_string(m);
        EXPECT_NEAR(oy, 0.5, 1.0 / n + 1e-12) << to_string(m);
    }
}

// H(x) = A sin(2π x/Λ): orders at ω_o,x = mλ/Λ with power J_m(4πA/λ)² (docs/model.md §13). The
// window is only a few periods wide, so neighbouring orders overlap and interfere with a phase
// that depends on the window's position against the grating; averaging the slice over eight
// positions one eighth of a period apart cancels those cross terms exactly.
TEST(BrdfTest, SinusoidalGratingOrdersFollowBessel) {
    const int rows = 256, cols = 96;
    const double w = 1.0, period = 32.0, lambda = 2.0;
    for (double beta : {1.0, 2.4}) {  // 4πA/λ
        const double amplitude = beta * lambda / (4 * k_pi);
        std::vector<double> v(static_cast<std::size_t>(rows) * cols);
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j)
                v[static_cast<std::size_t>(i) * cols + j] = amplitude * std::sin(2 * k_pi * (i + 0.5) * w / period) / w;
        const Heightfield hf(rows, cols, v, w, 1.0);
        const int n = 192;
        std::vector<double> f(static_cast<std::size_t>(n) * n, 0.0);
        for (int shift = 0; shift < 8; ++shift) {
            const Query q = make_query(Model::OHS, 128.0 + shift * period / 8, 48.0, 16.0);
            const auto s = render_slice<double>(hf, q, lambda, n);
            for (std::size_t i = 0; i < f.size(); ++i) f[i] += s[i];
        }
        // Power in a band of width λ/Λ around each order, summed over ω_y.
        double total = 0.0;
        std::vector<double> power(9, 0.0);
        for (int p = 0; p < n; ++p) {
            const int order = static_cast<int>(std::lround(slice_omega(p, n) * period / lambda));
            double row = 0.0;
            for (int r = 0; r < n; ++r) row += f[static_cast<std::size_t>(p) * n + r];
            total += row;
            if (std::abs(order) <= 4) power[static_cast<std::size_t>(order + 4)] += row;
        }
        for (int m = -3; m <= 3; ++m) {
            const double expected = std::pow(std::cyl_bessel_j(std::abs(m), beta), 2);
            EXPECT_NEAR(power[static_cast<std::size_t>(m + 4)] / total, expected, 0.015)
                << "beta " << beta << " order " << m;
        }
    }
}

TEST(BrdfTest, BadInputThrowsNamingTheValue) {
    const Heightfield hf = random_heightfield(16, 16, 0.2, 1);
    const Query good = make_query(Model::OHS, 0, 0, 3.0);
    EXPECT_THROW(render_slice<double>(hf, good, 0.0, 16), std::domain_error);
    EXPECT_THROW(render_slice<double>(hf, good, -0.5, 16), std::domain_error);
    EXPECT_THROW(render_slice<double>(hf, good, std::nan(""), 16), std::domain_error);
    EXPECT_THROW(render_slice<double>(hf, good, 0.5, 0), std::domain_error);
    EXPECT_THROW(render_slice<double>(hf, good, 0.5, 8193), std::domain_error);
    Query q = good;
    q.sigma_p_um = 0.0;
    EXPECT_THROW(render_slice<double>(hf, q, 0.5, 16), std::domain_error);
    q = good;
    q.omega_i = {0.8, 0.6};
    EXPECT_THROW(render_slice<double>(hf, q, 0.5, 16), std::domain_error);
    q.omega_i = {1.2, 0.0};
    try {
        render_slice<double>(hf, q, 0.5, 16);
        FAIL() << "expected a throw";
    } catch (const std::domain_error& e) {
        EXPECT_NE(std::string(e.what()).find("1.2"), std::string::npos) << e.what();
    }
    EXPECT_THROW(parse_model("Wave"), std::invalid_argument);
    RenderOptions o;
    o.prune_tolerance = 1e-3;
    EXPECT_THROW(render_slice<double>(hf, good, 0.5, 16, o), std::domain_error);
    o = RenderOptions{};
    o.tolerance = 0.5;
    EXPECT_THROW(render_slice<double>(hf, good, 0.5, 16, o), std::domain_error);
    // Every model has the separable and the fft paths (c3_nodes_test).
    o = RenderOptions{};
    o.path = RenderPath::Fft;
    q = good;
    q.model = Model::GHS;
    EXPECT_NO_THROW(render_slice<double>(hf, q, 0.5, 16, o));
}

// Issue 9: --x-um 3000000032 (and Python x_um = 32 + 64e8) gave an all-zero slice: the centre
// went through an int (overflow) before it was reduced to the tile. The docs promise any finite
// value, periodic: a shift by any whole number of periods gives the very same slice.
TEST(BrdfTest, ShiftByAHugeMultipleOfThePeriodGivesTheSameSlice) {
    const Heightfield hf = random_heightfield(64, 48, 0.4, 5, 1.0, 1.0);  // periods 64 x 48 um
    // Exact doubles: 32 + 64 k and 20 + 48 m for large k, m (all below 2^53).
    const std::array<std::array<double, 2>, 4> shifted{{{32.0 + 64e8, 20.0},
                                                        {3000000032.0, 20.0 - 48e8},
                                                        {32.0 - 64e13, 20.0 + 48e13},
                                                        {32.0 + 64.0 * 3e13, 20.0 - 48.0 * 1e14}}};
    for (Model m : {Model::OHS, Model::GHS}) {
        const Query q = make_query(m, 32.0, 20.0, 4.0, 0.1, -0.2);
        const auto expected = render_slice<double>(hf, q, 0.5, 24);
        ASSERT_GT(max_abs(expected), 0.0);
        for (const auto& [x, y] : shifted) {
            Query far = q;
            far.x_um = x;
            far.y_um = y;
            EXPECT_EQ(render_slice<double>(hf, far, 0.5, 24), expected) << to_string(m) << " at " << x << ", " << y;
        }
    }
    const FootprintKernels k = footprint_kernels(hf, 32.0, 20.0, 4.0);
    const FootprintKernels k_far = footprint_kernels(hf, 3000000032.0, 20.0 - 48e8, 4.0);
    EXPECT_EQ(k_far.row, k.row);
    EXPECT_EQ(k_far.col, k.col);
    EXPECT_EQ(k_far.dx_um, k.dx_um);
    EXPECT_EQ(k_far.weight, k.weight);
}

// Issue 9: --sigma-p-um 1e9 gave zeros and 7e8 tried to list 4e9 indices. The window is cut to
// one periodic tile, so footprints far larger than the tile are refused with the allowed range
// (σ_p ≤ 10 × the longer period); the limit itself still renders.
TEST(BrdfTest, FootprintFarLargerThanTheTileIsRefusedWithTheRange) {
    const Heightfield hf = random_heightfield(16, 8, 0.2, 1);  // 16 x 8 um: sigma_p <= 160 um
    using wavebrdf::test::expect_throw_naming;
    expect_throw_naming<std::domain_error>(
        [&] { render_slice<double>(hf, make_query(Model::OHS, 0, 0, 161.0), 0.5, 8); },
        "sigma_p <= 10 x the longer tile period = 160 um");
    expect_throw_naming<std::domain_error>([&] { render_slice<double>(hf, make_query(Model::GHS, 0, 0, 1e5), 0.5, 8); },
                                           "160 um");
    expect_throw_naming<std::domain_error>([&] { footprint_kernels(hf, 0, 0, 1e3); }, "160 um");
    expect_throw_naming<std::domain_error>([&] { render_slice<double>(hf, make_query(Model::OHS, 0, 0, 7e8), 0.5, 8); },
                                           "1e-06 to 1000000 um");
    expect_throw_naming<std::domain_error>([&] { render_slice<double>(hf, make_query(Model::OHS, 0, 0, 1e9), 0.5, 8); },
                                           "1e-06 to 1000000 um");
    const auto at_limit = render_slice<double>(hf, make_query(Model::OHS, 0, 0, 160.0), 0.5, 8);
    EXPECT_GT(max_abs(at_limit), 0.0);
}

// Issue 9: λ, texel and vscale of 1e-300 or 1e300 gave all-zero slices. Values outside a
// physically meaningful range are refused with the range in the message; the ends render.
TEST(BrdfTest, MeaninglessScalesAreRefusedWithTheRange) {
    using wavebrdf::test::expect_throw_naming;
    const Heightfield hf = random_heightfield(16, 16, 0.2, 1);
    const Query q = make_query(Model::OHS, 8, 8, 3.0);
    for (double lambda : {1e-300, 1e-3, 2e3, 1e300})
        expect_throw_naming<std::domain_error>([&] { render_slice<double>(hf, q, lambda, 8); },
                                               "expected 0.01 to 1000 um");
    EXPECT_GT(max_abs(render_slice<double>(hf, q, 0.01, 8)), 0.0);
    EXPECT_GT(max_abs(render_slice<double>(hf, q, 1000.0, 8)), 0.0);
    for (double texel : {1e-300, 1e-5, 2e4, 1e300})
        expect_throw_naming<std::domain_error>([&] { hf.with_scale(texel, 1.0); }, "expected 0.0001 to 10000 um");
    for (double vscale : {1e-300, -1e-300, 1e-7, 2e4, -1e300})
        expect_throw_naming<std::domain_error>([&] { hf.with_scale(1.0, vscale); },
                                               "expected 0 or 1e-06 <= |vscale| <= 10000");
    for (double vscale : {0.0, -0.5, 1e-6, 1e4}) EXPECT_NO_THROW(hf.with_scale(1.0, vscale));
    Query tiny = q;
    tiny.sigma_p_um = 1e-300;
    expect_throw_naming<std::domain_error>([&] { render_slice<double>(hf, tiny, 0.5, 8); },
                                           "expected 1e-06 to 1000000 um");
}

// Gaussian random surface, rms height σ_h: averaged over positions, the specular peak drops by
// exp(−(4π σ_h cos θ_i / λ)²) relative to a mirror (docs/model.md §13). The cos θ_i comes from the
// GHS-type models' phase scale (cos θ_i + cos θ_o)/2 = cos θ_i at the mirror direction; OHS and
// ROHS keep the full phase 4πH/λ, so their attenuation has no cos θ_i at oblique light.
TEST(BrdfTest, RoughSurfaceSpecularPeakFollowsBeckmannKirchhoff) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = p.cols = 256;
    p.correlation_um = 4.0;
    p.seed = 21;
    const double lambda = 0.5, g_target = 0.5;  // g = (4πσ_h/λ)²
    p.rms_height_um = std::sqrt(g_target) * lambda / (4 * k_pi);
    const Heightfield rough = generate_heightfield(p);
    const Heightfield flat(256, 256, std::vector<double>(256 * 256, 0.0), 1.0, 1.0);
    const int n = 11;  // odd: the slice has a pixel exactly at ω_o = −ω_i when ω_i = 0
    for (double tilt : {0.0, 0.5}) {
        for (Model m : kBrdfModels) {
            // A tilted light moves the mirror direction; pick ω_i on the pixel grid so that
            // −ω_i is a pixel centre: ω_o = slice_omega(3, 11) = −0.3636…
            const double wx = tilt == 0.0 ? 0.0 : -slice_omega(3, n);
            const std::size_t peak = tilt == 0.0 ? static_cast<std::size_t>(5 * n + 5)
                                                 : static_cast<std::size_t>(3 * n + 5);
            const double mirror = render_slice<double>(flat, make_query(m, 32, 32, 14.0, wx, 0.0), lambda, n)[peak];
            double mean = 0.0;
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    mean += render_slice<double>(rough, make_query(m, 32 + 64 * a, 32 + 64 * b, 14.0, wx, 0.0), lambda,
                                                 n)[peak] /
                            16.0;
            const double cos_i = std::sqrt(1 - wx * wx);
            const double phase_cos = is_separable(m) ? 1.0 : cos_i;
            const double expected = std::exp(-g_target * phase_cos * phase_cos);
            EXPECT_NEAR(mean / mirror, expected, 0.05 * expected) << to_string(m) << " tilt " << tilt;
            RecordProperty(std::string(to_string(m)) + "_tilt" + std::to_string(tilt),
                           std::to_string(mean / mirror / expected));
            // And the attenuation is real: far below the mirror's peak.
            EXPECT_LT(mean / mirror, 0.85) << to_string(m);
        }
    }
}
