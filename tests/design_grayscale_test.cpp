// Grayscale designs (--min-feature-um): the loop's gradient through the filtered
// parameterisation equals central finite differences, and a design's exported relief has no
// spatial frequency above 1/F beyond what rounding onto the evaluation's levels adds (a DFT
// here), stays within [0, H] and has no etch masks.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <nlohmann/json.hpp>
#include <random>

#include "cli_util.h"
#include "design/evaluator.h"
#include "design/grayscale.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

namespace wavebrdf {
namespace {

using namespace wavebrdf::test;

DesignOptions grey_options(int size, double feature) {
    DesignOptions o;
    o.target = parse_design_target("colour:#00FF00");
    o.size = size;
    o.texel_um = 0.5;
    o.spectral = 4;
    o.levels = 0;
    o.min_feature_um = feature;
    o.height_range_um = 2.0;
    return o;
}

TEST(DesignGrayscale, LoopGradientEqualsCentralFiniteDifferences) {
    const PreparedDesign p = prepare_design(grey_options(16, 1.5));
    ASSERT_EQ(p.options.levels, detail::k_grayscale_levels);
    detail::Evaluator evaluator(p, {1.0});
    const detail::FeatureFilter filter(16, 0.5, 1.5);
    std::mt19937 rng(5);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<double> z(256), grad;
    for (double& v : z) v = g(rng);
    (void)detail::grayscale_loss(filter, evaluator, 2.0, detail::k_grayscale_levels, z, &grad);
    for (std::size_t t : {std::size_t{3}, std::size_t{77}, std::size_t{200}}) {
        const double e = 1e-6, keep = z[t];
        z[t] = keep + e;
        const double up = detail::grayscale_loss(filter, evaluator, 2.0, detail::k_grayscale_levels, z, nullptr);
        z[t] = keep - e;
        const double down = detail::grayscale_loss(filter, evaluator, 2.0, detail::k_grayscale_levels, z, nullptr);
        z[t] = keep;
        EXPECT_NEAR(grad[t], (up - down) / (2.0 * e), 1e-4 * (std::abs(grad[t]) + 1e-3)) << t;
    }
}

TEST(DesignGrayscale, TheExportedReliefHasNoDetailFinerThanTheMinimumFeature) {
    const fs::path dir = fresh_dir("design_grayscale");
    const int N = 32;
    const double F = 2.0, H = 2.0;
    DesignOptions o = grey_options(N, F);
    o.iterations = 30;
    const DesignResult r = run_design(prepare_design(o));
    ASSERT_GE(r.curve.size(), 2u);
    EXPECT_LT(r.curve.back().loss, r.curve.front().loss);
    write_design_directory((dir / "run").string(), r, false);
    EXPECT_FALSE(fs::exists(dir / "run" / "masks.json"));
    EXPECT_TRUE(fs::exists(dir / "run" / "heights.png"));
    const nlohmann::json j = nlohmann::json::parse(read_text(dir / "run" / "design.json"));
    EXPECT_EQ(j["constraints"]["min_feature_um"], F);
    EXPECT_LT(j["metrics"]["exact_direct_sum_check"]["max_flux_difference_relative_to_peak"].get<double>(), 1e-9);
    const std::vector<double> h = heights_um(read_heightfield_exr((dir / "run" / "heights.exr").string()));
    ASSERT_EQ(h.size(), static_cast<std::size_t>(N * N));
    for (double v : h) {
        EXPECT_GE(v, -1e-6);
        EXPECT_LE(v, H + 1e-6);
    }
    // Σ over |ν| > 1/F of |DFT h|²: the filtered heights have none; rounding each height onto the
    // 256 levels (error ≤ Δ/2, plus float32 storage) adds at most N² Σ_t (Δ/2)² (Parseval).
    const double step = H / (detail::k_grayscale_levels - 1), L = N * 0.5;
    double above = 0.0, total = 0.0;
    for (int m = -N / 2; m < N / 2; ++m)
        for (int n = -N / 2; n < N / 2; ++n) {
            std::complex<double> s(0.0, 0.0);
            for (int i = 0; i < N; ++i)
                for (int k = 0; k < N; ++k)
                    s += h[static_cast<std::size_t>(i * N + k)] * std::polar(1.0, -2.0 * k_pi * (m * i + n * k) / N);
            if (m != 0 || n != 0) total += std::norm(s);
            if (std::hypot(m, n) / L > 1.0 / F + 1e-9) above += std::norm(s);
        }
    const double bound = static_cast<double>(N) * N * static_cast<double>(N) * N * (0.5 * step) * (0.5 * step) * 1.01;
    EXPECT_LT(above, bound);
    EXPECT_GT(total, 100.0 * bound);  // the relief itself is not flat
}

TEST(DesignGrayscale, BadCombinationsAreRefused) {
    DesignOptions o = grey_options(16, 0.6);  // below two texels
    EXPECT_THROW(prepare_design(o), std::domain_error);
    o = grey_options(16, 2.0);
    o.levels = 8;  // levels and a grayscale feature contradict
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    o = grey_options(16, 2.0);
    o.level_step_um = 0.1;
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    const fs::path dir = fresh_dir("design_grayscale");
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --spectral 4 --target colour:#00FF00 --min-feature-um 0.6"),
                           {"--min-feature-um", "0.6"});
    const CliResult ok = run_cli(dir, "design --size 16 --out b --spectral 4 --target colour:#00FF00 --min-feature-um 2 "
                                      "--iterations 3 --quiet --no-plots");
    EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

}  // namespace
}  // namespace wavebrdf
