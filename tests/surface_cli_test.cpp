// The commands around measured surfaces: the unit check every command prints (docs/model.md,
// "Where the model holds"), `wavebrdf stats` against closed forms and the values
// SurfaceTopography publishes for the shared scans, `wavebrdf convert` and `recover --truth`
// with conditioning.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/surface_file.h"

namespace fs = std::filesystem;
using namespace wavebrdf::test;

namespace {

// A 32 × 32 Gaussian-noise heightfield of rms `rms` in the file's values, texel 1 µm, vscale 1.
void write_noise(const fs::path& path, double rms) {
    std::mt19937 rng(2);
    std::normal_distribution<double> normal(0.0, rms);
    std::vector<double> v(32 * 32);
    for (double& x : v) x = normal(rng);
    wavebrdf::write_heightfield_exr(path.string(), wavebrdf::Heightfield(32, 32, v, 1.0, 1.0), "test");
}

bool contains_text(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

bool starts_with_line(const std::string& text, const std::string& line) { return text.rfind(line + "\n", 0) == 0; }

}  // namespace

TEST(SurfaceCli, RenderWarnsOnHeightsInNanometres) {
    const fs::path dir = fresh_dir("surface_cli");
    write_noise(dir / "nm.exr", 50.0);  // 50 nm rms written as if µm
    const CliResult r = run_cli(dir, "render --heightfield nm.exr --resolution 8 --sigma-p-um 4 --x-um 16 "
                                     "--y-um 16 --out o.exr --quiet");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(contains_text(r.err, "wavebrdf: warning: nm.exr: rms slope")) << r.err;
    EXPECT_TRUE(contains_text(r.err, "heights are in nm")) << r.err;
    // The same surface in µm: the summary line, no warning.
    write_noise(dir / "um.exr", 0.05);
    const CliResult ok = run_cli(dir, "render --heightfield um.exr --resolution 8 --sigma-p-um 4 --x-um 16 "
                                      "--y-um 16 --out o2.exr");
    EXPECT_EQ(ok.exit_code, 0) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "um.exr: rms height")) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "phase rms")) << ok.err;
    EXPECT_FALSE(contains_text(ok.err, "warning")) << ok.err;
}

TEST(SurfaceCli, GenbrdfTableAndHeightfieldPrintTheUnitCheck) {
    const fs::path dir = fresh_dir("surface_cli");
    write_noise(dir / "nm.exr", 50.0);
    const CliResult g = run_cli(dir, "genbrdf -i nm.exr -o g.exr -r 8 -l 0.5 -x 16 -y 16 -p 4 --quiet");
    EXPECT_EQ(g.exit_code, 0) << g.err;
    EXPECT_TRUE(contains_text(g.err, "warning: nm.exr: rms slope")) << g.err;
    const CliResult t = run_cli(dir, "table --heightfield nm.exr --lights 2x2 --resolution 8 --sigma-p-um 4 --x-um 16 "
                                     "--y-um 16 --out t.exr --quiet");
    EXPECT_TRUE(contains_text(t.err, "warning: nm.exr: rms slope")) << t.err;
    const CliResult h = run_cli(dir, "heightfield --size 32 --out h.exr --no-png --texel-um 0.5");
    EXPECT_EQ(h.exit_code, 0) << h.err;
    EXPECT_TRUE(contains_text(h.err, "h.exr: rms height")) << h.err;
}

namespace {

// ../shared/real-surfaces/ beside the repository (or beside the worktree's parent), else "".
fs::path shared_surfaces_dir() {
    for (const fs::path& p : {fs::path(WAVEBRDF_SOURCE_DIR) / ".." / "shared" / "real-surfaces",
                              fs::path(WAVEBRDF_SOURCE_DIR) / ".." / ".." / "shared" / "real-surfaces"})
        if (fs::is_directory(p)) return fs::canonical(p);
    return {};
}

// `wavebrdf stats FILE ARGS --json` on a shared scan, parsed; skips the test when the scans are
// absent or this build does not read the format yet.
nlohmann::json shared_stats(const std::string& file, const std::string& args) {
    const fs::path dir = shared_surfaces_dir();
    if (dir.empty()) throw std::runtime_error("skip: ../shared/real-surfaces is absent");
    try {
        (void)wavebrdf::read_surface((dir / file).string());
    } catch (const std::exception& e) {
        throw std::runtime_error(std::string("skip: ") + e.what());
    }
    const fs::path work = fresh_dir("surface_cli");
    const CliResult r = run_cli(work, "stats " + quote((dir / file).string()) + " " + args + " --json --quiet");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(r.out);
}

void write_text_file(const fs::path& path, const std::string& text) {
    std::ofstream out(path);
    out << text;
}

}  // namespace

// A cosine written as a text matrix (rows along y): stats gives its closed-form parameters as
// JSON, with every ISO key; --psd and --acf write CSV.
TEST(SurfaceCli, StatsJsonOfACosine) {
    const fs::path dir = fresh_dir("surface_cli");
    std::string text;
    for (int r = 0; r < 20; ++r) {
        for (int c = 0; c < 64; ++c) text += std::to_string(0.3 * std::cos(2 * 3.141592653589793 * c / 16.0)) + " ";
        text += "\n";
    }
    write_text_file(dir / "cos.txt", text);
    const CliResult r = run_cli(dir, "stats cos.txt --spacing-um 0.5 --json --psd psd.csv --acf acf.csv");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    for (const char* key : {"Sa", "Sq", "Sp", "Sv", "Sz", "Ssk", "Sku", "Sdq", "Sdr", "Sal", "Str", "Std"})
        EXPECT_TRUE(j.contains(key)) << key;
    EXPECT_NEAR(j.at("Sq").get<double>(), 0.3 / std::sqrt(2.0), 1e-5);  // the text's 6 digits
    EXPECT_NEAR(j.at("Sku").get<double>(), 1.5, 1e-4);
    EXPECT_NEAR(j.at("Std").get<double>(), 90.0, 0.5);  // varies along x: lay along y
    EXPECT_EQ(j.at("dx_um").get<double>(), 0.5);
    EXPECT_TRUE(starts_with_line(read_text(dir / "psd.csv"), "q_per_um,psd_um4,count"));
    EXPECT_TRUE(starts_with_line(read_text(dir / "acf.csv"), "lag_um,acf,count"));
    EXPECT_TRUE(contains_text(r.err, "cos.txt: rms height")) << r.err;
}

TEST(SurfaceCli, StatsAndConvertRefuseUnmeasuredPointsUnlessFilled) {
    const fs::path dir = fresh_dir("surface_cli");
    std::string text;
    for (int r = 0; r < 12; ++r) {
        for (int c = 0; c < 12; ++c)
            text += (r == 3 && (c == 4 || c == 5)) || (r == 8 && c == 1) ? "nan " : std::to_string(0.01 * r + 0.02 * c) + " ";
        text += "\n";
    }
    write_text_file(dir / "holes.txt", text);
    expect_one_line_naming(run_cli(dir, "stats holes.txt --spacing-um 1 --quiet"), {"3 points", "--fill"});
    expect_one_line_naming(run_cli(dir, "convert holes.txt h.exr --spacing-um 1 --quiet"), {"3", "--fill"});
    EXPECT_FALSE(fs::exists(dir / "h.exr"));
    expect_one_line_naming(run_cli(dir, "convert holes.txt h.npy --spacing-um 1 --fill zero"), {"--fill 'zero'"});
    EXPECT_FALSE(fs::exists(dir / "h.npy"));
    // Filled, detrended and made periodic: every step printed and kept in the output.
    const CliResult ok = run_cli(dir, "convert holes.txt h.exr --spacing-um 1 --detrend plane --fill harmonic "
                                      "--periodic smooth");
    ASSERT_EQ(ok.exit_code, 0) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "conditioning: detrend: a plane removed")) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "conditioning: fill: 3 unmeasured points")) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "seam slope ratio")) << ok.err;
    EXPECT_TRUE(contains_text(ok.err, "h.exr: rms height")) << ok.err;
    const wavebrdf::MeasuredSurface back = wavebrdf::read_surface((dir / "h.exr").string());
    EXPECT_EQ(back.invalid_count(), 0u);
    // A plane with its plane removed: only the filled points' rounding is left.
    const CliResult stats = run_cli(dir, "stats h.exr --json --quiet");
    ASSERT_EQ(stats.exit_code, 0) << stats.err;
    EXPECT_LT(nlohmann::json::parse(stats.out).at("Sq").get<double>(), 1e-5);
}

// A measured truth, conditioned on the way in; the steps are in run.json.
TEST(SurfaceCli, RecoverConditionsAMeasuredTruth) {
    const fs::path dir = fresh_dir("surface_cli");
    std::string text;
    for (int r = 0; r < 8; ++r) {
        for (int c = 0; c < 8; ++c)
            text += r == 2 && c == 5 ? "nan " : std::to_string(0.05 * std::sin(r + 2.0 * c) + 0.01 * c) + " ";
        text += "\n";
    }
    write_text_file(dir / "t.txt", text);
    const CliResult r = run_cli(dir, "recover --truth t.txt --texel-um 2 --fill nearest --detrend plane "
                                     "--periodic smooth --sigma-p-um 3 --field-iterations 3 --refine-iterations 2 "
                                     "--no-plots --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(contains_text(r.err, "conditioning: fill: 1 unmeasured points")) << r.err;
    EXPECT_TRUE(contains_text(r.err, "t.txt: rms height")) << r.err;
    const std::string run = read_text(dir / "run" / "run.json");
    EXPECT_TRUE(contains_text(run, "truth conditioning: periodic")) << run;
    expect_one_line_naming(run_cli(dir, "recover --fill nearest --out other --quiet"), {"--truth"});
}

// SurfaceTopography's tests (test/IO/test_x3p.py, test_plu.py) publish these for the files
// copied to ../shared/real-surfaces (SOURCES.md).
TEST(SurfaceCli, StatsMatchSurfaceTopographysPublishedValues) {
    try {
        const nlohmann::json x3p = shared_stats("SurfaceTopography__x3p-2.x3p", "");
        EXPECT_NEAR(x3p.at("Sq").get<double>(), 7.728033e-2, 1e-8);  // 7.728033e-8 m
        EXPECT_NEAR(x3p.at("dx_um").get<double>() / x3p.at("dy_um").get<double>(), 0.12766 / 0.31458, 1e-4);
        // rms gradient 0.0620701: forward differences over the points that have both.
        EXPECT_NEAR(x3p.at("Sdq").get<double>(), 0.0620701, 1e-7);
    } catch (const std::runtime_error& e) {
        GTEST_SKIP() << e.what();
    }
}

TEST(SurfaceCli, StatsOfPlu1MatchPublishedRmsBeforeAndAfterCurvature) {
    try {
        EXPECT_NEAR(shared_stats("SurfaceTopography__plu-1.plu", "").at("Sq").get<double>(), 2.834391, 1e-6);
        EXPECT_NEAR(shared_stats("SurfaceTopography__plu-1.plu", "--detrend poly:2").at("Sq").get<double>(), 0.01818,
                    5e-6);
    } catch (const std::runtime_error& e) {
        GTEST_SKIP() << e.what();
    }
}
