// `wavebrdf design` end to end: the run directory, its relief read back and scored here by the
// exact evaluation, and one-line errors for bad input before any work.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_util.h"
#include "wavebrdf/design.h"
#include "wavebrdf/io.h"

namespace wavebrdf {
namespace {

using namespace wavebrdf::test;

// `design --out run ARGS` in DIR; its design.json when it succeeded (else null).
struct DesignCliRun {
    CliResult cli;
    nlohmann::json json;
};
DesignCliRun run_design(const fs::path& dir, const std::string& args) {
    DesignCliRun run{run_cli(dir, "design --out run " + args), nullptr};
    if (run.cli.exit_code == 0) run.json = nlohmann::json::parse(read_text(dir / "run" / "design.json"));
    return run;
}

// The CLI's stderr holds FORMAT with VALUE printed into it (the number design.json records).
void expect_says(const std::string& err, const char* format, double value) {
    char expected[128];
    std::snprintf(expected, sizeof expected, format, value);
    EXPECT_NE(err.find(expected), std::string::npos) << expected << " not in: " << err;
}

TEST(DesignCli, WritesARunDirectoryWhoseReliefScoresAsReported) {
    const fs::path dir = fresh_dir("design_cli");
    const auto [r, j] = run_design(
        dir,
        "--size 24 --spectral 3 --band-um 0.45,0.65 --levels 4 "
        "--height-range-um 1 --region annulus:0.15,0.6 --specular-cone 0.1 "
        "--iterations 10 --refine-passes 5 --fabrication-error scale:5%,blur:0.2um --quiet --no-plots");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const char* name : {"design.json", "heights.exr", "target.exr", "far_field.exr", "metrics.csv", "heights.png",
                             "heights.stl", "masks.json", "masks_01.png", "masks_02.png"})
        EXPECT_TRUE(fs::is_regular_file(dir / "run" / name)) << name;
    EXPECT_EQ(j["target"]["kind"], "anti-mirror");
    EXPECT_EQ(j["levels_um"].size(), 4u);
    EXPECT_EQ(j["fabrication_errors"].size(), 3u);          // scale − and +, blur
    EXPECT_EQ(j["fabrication_files"]["masks"].size(), 2u);  // 4 levels: log2 4 binary-weighted masks
    const Heightfield hf = read_heightfield_exr((dir / "run" / "heights.exr").string());
    EXPECT_DOUBLE_EQ(hf.texel_um(), 0.5);
    std::vector<double> heights = heights_um(hf);
    for (double h : heights) {
        EXPECT_GE(h, -1e-6);
        EXPECT_LE(h, 1.0 + 1e-6);
    }
    // Independent of the run: its exported heights, scored here.
    const std::vector<double> lambdas = j["light"]["lambdas_um"].get<std::vector<double>>();
    const auto orders = exact_orders(heights, 24, 0.5, {0.0, 0.0}, lambdas);
    const auto reported = j["metrics"]["exact"]["specular_fraction"].get<std::vector<double>>();
    ASSERT_EQ(reported.size(), orders.size());
    for (std::size_t w = 0; w < orders.size(); ++w) {
        double specular = 0.0;
        for (std::size_t o = 0; o < orders[w].m.size(); ++o)
            if (std::hypot(orders[w].omega_x[o], orders[w].omega_y[o]) <= 0.1) specular += orders[w].power[o];
        EXPECT_NEAR(specular, reported[w], 1e-6);
    }
    EXPECT_LT(j["metrics"]["exact_direct_sum_check"]["max_flux_difference_relative_to_peak"].get<double>(), 1e-9);
    // The directory is a design's: a second run refuses it without --force, takes it with.
    const CliResult again = run_cli(dir,
                                    "design --out run --size 8 --spectral 3 --iterations 1 --refine-passes 0 --quiet");
    expect_one_line_naming(again, {"run"});
    const CliResult forced = run_cli(dir,
                                     "design --out run --size 8 --spectral 3 --iterations 1 --refine-passes 0 "
                                     "--quiet --force");
    EXPECT_EQ(forced.exit_code, 0) << forced.err;
}

TEST(DesignCli, AMissedColourIsReportedWithTheOptimalColourLimit) {
    // Blue on a 4-level 8² tile with one iteration misses Y ≥ 5 %: the CLI says so with the bound
    // design.json holds, and --no-view-survey leaves the survey out.
    const fs::path dir = fresh_dir("design_cli_bound");
    const auto [r, j] = run_design(dir,
                                   "--target colour:#0000FF --size 8 --spectral 8 --levels 4 --iterations 1 "
                                   "--refine-passes 0 --no-view-survey --no-plots");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_FALSE(j.contains("view_survey"));
    ASSERT_TRUE(j.contains("optimal_colour_bound"));
    expect_says(r.err, "brighter than Y %.3g", j["optimal_colour_bound"]["y_at_target"].get<double>());
    // The mixture bound's line, with design.json's numbers: out of reach for mixtures or not, and
    // whether this relief exceeds the bound.
    ASSERT_TRUE(j.contains("mixture_bound"));
    const auto& m = j["mixture_bound"];
    if (!m["reachable_at_target"].get<bool>()) {
        EXPECT_NE(r.err.find("out of reach for this view as level mixtures"), std::string::npos) << r.err;
        if (!m["delta_uv_at_min_y"].is_null())
            expect_says(r.err, "delta u'v' >= %.3g", m["delta_uv_at_min_y"].get<double>());
    } else {
        EXPECT_NE(r.err.find("the levels do not rule it out"), std::string::npos) << r.err;
    }
    EXPECT_EQ(r.err.find("exceeds the mixture bound") != std::string::npos,
              !m["design_check"]["absolute"]["within"].get<bool>())
        << r.err;
}

TEST(DesignCli, AColourTheConeBoundRulesOutIsSaidSoAndSurveyed) {
    // Red on 16 levels within 2 µm in the mirror cone: the cone bound rules it out in incident
    // power; the CLI says so with design.json's numbers, and the view survey says which view reaches it.
    const fs::path dir = fresh_dir("design_cli_cone");
    const auto [r, j] = run_design(dir,
                                   "--target colour:#FF0000 --size 16 --spectral 16 --levels 16 "
                                   "--height-range-um 2 --iterations 2 --refine-passes 0 --no-plots");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    ASSERT_TRUE(j.contains("cone_bound"));
    const auto& c = j["cone_bound"];
    ASSERT_TRUE(c["out_of_reach_at_target"].get<bool>());
    expect_says(r.err, "more than Y %.3g of the incident light", c["y_at_target"].get<double>());
    expect_says(r.err, "within delta u'v' %.3g of it", c["delta_uv_ruled_out"].get<double>());
    EXPECT_EQ(r.err.find("lifted by the division") != std::string::npos,
              !c["design_check"]["normalised"]["within"].get<bool>())
        << r.err;
    EXPECT_TRUE(c["design_check"]["absolute"]["within"].get<bool>());
    // The metrics count incident power: the design's own Y is the check's absolute Y, which the
    // bound covers.
    const auto& e = j["metrics"]["exact"];
    EXPECT_NEAR(e["luminous_efficiency"].get<double>(), c["design_check"]["absolute"]["y"].get<double>(), 1e-12);
    EXPECT_NEAR(e["luminous_efficiency_share_of_reflected"].get<double>(), c["design_check"]["normalised"]["y"].get<double>(), 1e-12);
    EXPECT_LE(e["luminous_efficiency"].get<double>(), c["design_check"]["absolute"]["bound_y_at_its_chromaticity"].get<double>());
    ASSERT_TRUE(j.contains("view_survey"));
    EXPECT_NE(r.err.find("design: reachable: from view"), std::string::npos) << r.err;
}

TEST(DesignCli, BadInputGetsOneLineBeforeAnyWork) {
    const fs::path dir = fresh_dir("design_cli");
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --levels 8 --min-feature-um 1"),
                           {"--min-feature-um", "--levels"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --target colour:#12345"), {"#12345"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --target pattern:missing.png"), {"missing.png"});
    {
        std::ofstream bad(dir / "bad.png");
        bad << "not a png";
    }
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --target pattern:bad.png"), {"bad.png"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --target anti-mirror --light-x 0.7"), {"--region"});
    expect_one_line_naming(
        run_cli(dir, "design --size 16 --out a --target colour:#ff0000 --spectral 8 --view-x 0.95 --view-y 0.3"),
        {"view"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --fabrication-error scale:90%"), {"scale"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --region ring:1"), {"ring:1"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --max-memory-gb 0.000001"), {"max-memory-gb"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --anneal-sweeps -1"), {"--anneal-sweeps -1"});
    expect_one_line_naming(run_cli(dir, "design --size 16 --out a --spectral 4 --target colour:#00ff00 --anneal-sweeps 5"),
                           {"--anneal-sweeps 5", "colour:#00ff00"});
    expect_one_line_naming(run_cli(dir, "design --size 256 --out a --spectral 16 --band-um 0.4,0.7 --continuation off "
                                        "--anneal-sweeps 400"),
                           {"--anneal-sweeps 400", "256x256", "CPU-s"});
    EXPECT_FALSE(fs::exists(dir / "a"));
}

}  // namespace
}  // namespace wavebrdf
