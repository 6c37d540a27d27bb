// Analytic lobes (lobe.h): the distributions are normalised and consistent with their Smith Λ
// (by quadrature over the hemisphere), the BRDF is reciprocal and conserves energy where it
// must, the table file is one the table reader accepts, and anisotropy stretches the lobe along
// the axis it names.
#include "wavebrdf/lobe.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/constants.h"  // k_pi
#include "wavebrdf/io.h"
#include "wavebrdf/table.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

// ∫ g(θ, φ) dω over the upper hemisphere by the midpoint rule in (u = cos θ, φ); the
// substitution keeps the sample density fine near the pole where narrow lobes peak.
template <typename G>
double hemisphere_integral(G g, int n_theta = 1500, int n_phi = 128) {
    // θ on a grid dense near 0: u = 1 − t², t ∈ (0, 1], du = 2t dt.
    double sum = 0.0;
    for (int a = 0; a < n_theta; ++a) {
        const double t = (a + 0.5) / n_theta;
        const double cos_theta = 1.0 - t * t, sin_theta = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
        const double weight = 2.0 * t / n_theta * (2.0 * k_pi / n_phi);
        for (int b = 0; b < n_phi; ++b) {
            const double phi = (b + 0.5) / n_phi * 2.0 * k_pi;
            sum += weight * g(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
        }
    }
    return sum;
}

std::vector<Lobe> lobes() {
    std::vector<Lobe> out;
    for (LobeDistribution d : {LobeDistribution::ggx, LobeDistribution::beckmann})
        for (auto [ax, ay] : {std::pair{0.1, 0.1}, std::pair{0.3, 0.3}, std::pair{0.7, 0.7}, std::pair{0.15, 0.45}}) {
            Lobe lobe;
            lobe.distribution = d;
            lobe.alpha_x = ax;
            lobe.alpha_y = ay;
            out.push_back(lobe);
        }
    return out;
}

std::string name(const Lobe& lobe) { return lobe_description(lobe); }

TEST(Lobe, DistributionIsNormalised) {
    for (const Lobe& lobe : lobes()) {
        SCOPED_TRACE(name(lobe));
        const double integral =
            hemisphere_integral([&](double x, double y, double z) { return lobe_distribution(lobe, x, y, z) * z; });
        // GGX's tail beyond the quadrature's resolution is small for these α.
        EXPECT_NEAR(integral, 1.0, 2e-3);
    }
}

// The Smith Λ is consistent with D: the projected area of the visible microfacets equals the
// macrosurface's, ∫ G1(ω, h) max(0, ω·h) D(h) dω_h = cos θ with G1 = 1 / (1 + Λ(ω)) (Heitz 2014,
// eq. 2). A wrong Λ (or a D stretched along the wrong axis) fails it at grazing directions.
TEST(Lobe, SmithLambdaMatchesTheDistribution) {
    for (const Lobe& lobe : lobes()) {
        SCOPED_TRACE(name(lobe));
        for (double theta : {0.0, 0.6, 1.1, 1.4})
            for (double phi : {0.0, 0.7, 1.5707963267948966}) {
                const double wx = std::sin(theta) * std::cos(phi), wy = std::sin(theta) * std::sin(phi),
                             wz = std::cos(theta);
                const double g1 = 1.0 / (1.0 + lobe_lambda(lobe, wx, wy, wz));
                const double projected = hemisphere_integral([&](double x, double y, double z) {
                    return std::max(0.0, wx * x + wy * y + wz * z) * lobe_distribution(lobe, x, y, z);
                });
                EXPECT_NEAR(g1 * projected, wz, 3e-3) << "theta " << theta << " phi " << phi;
            }
    }
}

TEST(Lobe, BrdfIsReciprocal) {
    const std::vector<double> w = test::uniform_vector(400, -0.68, 0.68, 3);
    for (Lobe lobe : lobes()) {
        lobe.fresnel_f0 = 0.04;  // Schlick depends on ω_i·h = ω_o·h: still reciprocal
        for (std::size_t k = 0; k + 3 < w.size(); k += 4) {
            const double forward = lobe_brdf(lobe, w[k], w[k + 1], w[k + 2], w[k + 3]);
            const double backward = lobe_brdf(lobe, w[k + 2], w[k + 3], w[k], w[k + 1]);
            ASSERT_GT(forward, 0.0);
            ASSERT_NEAR(forward, backward, 1e-12 * forward) << name(lobe);
        }
    }
}

// Energy: the directional albedo ∫ f_r cos θ_o dω_o is at most 1 and close to 1 for a smooth
// lobe at normal light (single scattering loses little there); F0 scales it near the pole.
TEST(Lobe, AlbedoIsAtMostOneAndNearOneForSmoothLobes) {
    for (const Lobe& lobe : lobes()) {
        SCOPED_TRACE(name(lobe));
        for (double sin_i : {0.0, 0.5, 0.8}) {
            const double albedo = hemisphere_integral(
                [&](double x, double y, double z) { return lobe_brdf(lobe, sin_i, 0.0, x, y) * z; });
            EXPECT_LE(albedo, 1.0 + 2e-3);
            if (lobe.alpha_x <= 0.15 && lobe.alpha_y <= 0.15) {
                EXPECT_GT(albedo, 0.97) << "sin_i " << sin_i;
            }
        }
    }
}

// A narrow lobe at normal light samples D: f_r(0, ω_o) peaks at the mirror direction −ω_i and
// equals D(h) G2 / (4 cos θ_i cos θ_o) there (G2 ≈ 1 at the pole): 1 / (4 π α_x α_y).
TEST(Lobe, PeakAtTheMirrorDirection) {
    Lobe lobe;
    lobe.alpha_x = 0.05;
    lobe.alpha_y = 0.08;
    for (LobeDistribution d : {LobeDistribution::ggx, LobeDistribution::beckmann}) {
        lobe.distribution = d;
        EXPECT_NEAR(lobe_brdf(lobe, 0.0, 0.0, 0.0, 0.0), 1.0 / (4.0 * k_pi * 0.05 * 0.08), 1e-9);
        // An oblique light's peak is at −ω_i.
        const double at = lobe_brdf(lobe, 0.3, -0.2, -0.3, 0.2);
        EXPECT_GT(at, lobe_brdf(lobe, 0.3, -0.2, -0.28, 0.2));
        EXPECT_GT(at, lobe_brdf(lobe, 0.3, -0.2, -0.3, 0.22));
    }
}

TEST(Lobe, TableIsReadByTheTableReaderAndReciprocal) {
    LobeTableSpec spec;
    spec.lobe.distribution = LobeDistribution::beckmann;
    spec.lobe.alpha_x = 0.3;
    spec.lobe.alpha_y = 0.2;
    // 4 lights per axis at max_sin 0.5 and n = 8: light a sits on slice pixel a + 2, so the
    // table holds both (ω_i, ω_o) and (ω_o, ω_i) (as tests/table_test.cpp's ROHS check).
    spec.lights = {4, 4, 0.5};
    spec.resolution = 8;
    const BrdfTable t = lobe_table(spec);
    const fs::path path = fs::temp_directory_path() / ("wavebrdf_lobe_" + std::to_string(::getpid()) + ".exr");
    write_brdf_table(path.string(), t);
    const BrdfTable back = read_brdf_table(path.string());
    fs::remove(path);
    EXPECT_EQ(back.values, t.values);
    EXPECT_EQ(back.source, lobe_description(spec.lobe));
    EXPECT_EQ(back.spec.lights.rows, 4);
    EXPECT_EQ(back.spec.resolution, 8);
    auto value = [&](int a, int b, int p, int q) {
        return double(back.values[((((std::size_t(a) * 4 + std::size_t(b)) * 8 + std::size_t(p)) * 8) + std::size_t(q)) * 3]);
    };
    int pairs = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
            for (int a2 = 0; a2 < 4; ++a2)
                for (int b2 = 0; b2 < 4; ++b2) {
                    if (!back.rendered[std::size_t(a) * 4 + std::size_t(b)] ||
                        !back.rendered[std::size_t(a2) * 4 + std::size_t(b2)])
                        continue;
                    ASSERT_EQ(slice_omega(a2 + 2, 8), back.light_x[std::size_t(a2)]);
                    const double forward = value(a, b, a2 + 2, b2 + 2), backward = value(a2, b2, a + 2, b + 2);
                    EXPECT_NEAR(forward, backward, 1e-6 * std::abs(forward));
                    // Each entry is lobe_brdf at the pixel centre, in float.
                    EXPECT_NEAR(forward, lobe_brdf(spec.lobe, back.light_x[a], back.light_y[b], slice_omega(a2 + 2, 8),
                                                   slice_omega(b2 + 2, 8)),
                                1e-6 * std::abs(forward));
                    ++pairs;
                }
    EXPECT_EQ(pairs, 144);
}

// α_x > α_y: the lobe's second moment about the mirror direction is larger along x (slice rows)
// than along y, in the ratio of the α² (for a narrow lobe at normal light, ω_o ≈ 2 h).
TEST(Lobe, AnisotropyStretchesAlongItsAxis) {
    for (LobeDistribution d : {LobeDistribution::beckmann, LobeDistribution::ggx}) {
        LobeTableSpec spec;
        spec.lobe.distribution = d;
        spec.lobe.alpha_x = 0.12;
        spec.lobe.alpha_y = 0.04;
        spec.lights = {1, 1, 0.5};  // one light, at normal incidence
        spec.resolution = 256;
        const BrdfTable t = lobe_table(spec);
        double sum = 0, xx = 0, yy = 0;
        for (int p = 0; p < 256; ++p)
            for (int q = 0; q < 256; ++q) {
                const double v = static_cast<double>(t.values[(std::size_t(p) * 256 + std::size_t(q)) * 3]);
                const double ox = slice_omega(p, 256), oy = slice_omega(q, 256);
                if (ox * ox + oy * oy > 0.25) continue;  // the lobe's core, away from GGX's tail
                sum += v;
                xx += v * ox * ox;
                yy += v * oy * oy;
            }
        const double ratio = xx / yy;
        if (d == LobeDistribution::beckmann) {
            EXPECT_NEAR(ratio, 9.0, 1.0);
        } else {
            EXPECT_GT(ratio, 2.5);  // GGX's heavy tail is cut by the window; still clearly along x
        }
        std::printf("%s: second moments x/y %.3f\n", to_string(d), ratio);
        EXPECT_GT(sum, 0.0);
    }
}

TEST(Lobe, BadInputIsRefused) {
    Lobe lobe;
    lobe.alpha_x = 0.0;
    test::expect_throw_naming<std::invalid_argument>([&] { validate(lobe); }, "alpha_x 0");
    lobe.alpha_x = 0.2;
    lobe.fresnel_f0 = 1.5;
    test::expect_throw_naming<std::invalid_argument>([&] { validate(lobe); }, "fresnel_f0 1.5");
    test::expect_throw_naming<std::invalid_argument>([&] { parse_lobe_distribution("phong"); }, "'phong'");
    LobeTableSpec spec;
    spec.resolution = 0;
    test::expect_throw_naming<std::domain_error>([&] { lobe_table(spec); }, "resolution 0");
    spec.resolution = 512;
    spec.lights = {33, 32, 0.9};  // 33 · 512 > 16384 per side
    EXPECT_ANY_THROW(lobe_table(spec));
}

// The command writes the table lobe_table makes (read back by the table reader), and bad options
// fail with one line naming the value and leave no file.
TEST(Lobe, CommandWritesTheTableAndRefusesBadOptions) {
    const fs::path dir = test::fresh_dir("lobe");
    const test::CliResult r = test::run_cli(dir,
                                            "lobe --distribution beckmann --alpha-x 0.3 --alpha-y 0.1 --lights 3x5 "
                                            "--max-light-sin 0.7 --resolution 12 --out l.exr --png l.png --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "");
    const BrdfTable t = read_brdf_table((dir / "l.exr").string());
    LobeTableSpec spec;
    spec.lobe.distribution = LobeDistribution::beckmann;
    spec.lobe.alpha_x = 0.3;
    spec.lobe.alpha_y = 0.1;
    spec.lights = {3, 5, 0.7};
    spec.resolution = 12;
    EXPECT_EQ(t.values, lobe_table(spec).values);
    EXPECT_TRUE(fs::exists(dir / "l.png"));
    for (const auto& [args, needle] : std::vector<std::pair<std::string, std::string>>{
             {"lobe --alpha 5 --out bad.exr", "alpha_x 5"},
             {"lobe --alpha-y 0 --out bad.exr", "alpha_y 0"},
             {"lobe --distribution phong --out bad.exr", "'phong'"},
             {"lobe --fresnel-f0 -0.5 --out bad.exr", "fresnel_f0 -0.5"},
             {"lobe --lights 0x4 --out bad.exr", "--lights"},
             {"lobe --max-light-sin 1 --out bad.exr", "max sin"},
             {"lobe --resolution 9000 --out bad.exr", "resolution 9000"}}) {
        SCOPED_TRACE(args);
        test::expect_one_line_naming(test::run_cli(dir, args), {needle});
        EXPECT_FALSE(fs::exists(dir / "bad.exr"));
    }
}

}  // namespace
}  // namespace wavebrdf
