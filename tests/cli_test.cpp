// End-to-end tests of the `wavebrdf` executable: every bad input must give one clear line on
// stderr naming the problem, a non-zero exit and no (partial) output file; the happy paths
// must write their files, and genbrdf must agree with render for the same parameters.
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>

#include "cli_util.h"
#include "png_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"
#include "wavebrdf/text.h"

namespace fs = std::filesystem;
using namespace wavebrdf::test;

namespace {

// A fresh directory per test (named after it and the process, since ctest may run the tests
// in parallel), so that leftovers from one test cannot satisfy another's checks.
class CliTest : public ::testing::Test {
protected:
    void SetUp() override { m_dir = fresh_dir("cli"); }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(m_dir);
    }

    fs::path path(const std::string& name) const { return m_dir / name; }
    std::string qpath(const std::string& name) const { return quote(path(name).string()); }

    CliResult run(const std::string& args) const { return run_cli(m_dir, args); }

    // A small random heightfield written by the tool itself; returns its path.
    std::string make_heightfield(const std::string& name = "h.exr", const std::string& size = "64") {
        const CliResult r = run("heightfield --size " + size + " --seed 7 --out " + qpath(name) + " --no-png --quiet");
        EXPECT_EQ(r.exit_code, 0) << r.err;
        EXPECT_TRUE(fs::exists(path(name)));
        return path(name).string();
    }

    // The checks every bad input must pass: non-zero exit; exactly one line on stderr (a
    // trailing newline aside) that contains every one of `needles` (the offending value and/or
    // option); no file at any of `outputs` and no temporary `*.tmp-*` beside them.
    void expect_clean_failure(const CliResult& r, const std::vector<std::string>& needles,
                              const std::vector<fs::path>& outputs) const {
        if (!expect_one_line_naming(r, needles)) return;
        for (const fs::path& output : outputs) {
            EXPECT_FALSE(fs::exists(output)) << output << " was left behind";
            const fs::path dir = output.parent_path();
            std::error_code ec;
            if (!fs::is_directory(dir, ec)) continue;
            for (const auto& entry : fs::directory_iterator(dir))
                EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
                    << "temporary file left behind: " << entry.path();
        }
    }

    fs::path m_dir;
};

bool starts_with(const std::string& text, const std::string& prefix) {
    return text.compare(0, prefix.size(), prefix) == 0;
}

bool is_png(const fs::path& path) {
    const std::string head = read_text(path).substr(0, 8);
    return head == std::string("\x89PNG\r\n\x1a\n", 8);
}

// A single-channel (R) float EXR written with OpenEXR directly, so it may hold values that
// wavebrdf's own writer (which goes through a validated Heightfield) never would.
void write_raw_exr(const std::string& file, int rows, int cols, const std::vector<float>& values) {
    Imf::Header header(cols, rows);
    header.channels().insert("R", Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    frame.insert("R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(values.data())), sizeof(float),
                                 sizeof(float) * static_cast<std::size_t>(cols)));
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

// The A channel of an EXR (empty when there is none).
std::vector<float> read_alpha(const std::string& file) {
    Imf::InputFile in(file.c_str());
    if (in.header().channels().findChannel("A") == nullptr) return {};
    const Imath::Box2i dw = in.header().dataWindow();
    const int cols = dw.max.x - dw.min.x + 1, rows = dw.max.y - dw.min.y + 1;
    std::vector<float> alpha(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols));
    Imf::FrameBuffer frame;
    frame.insert("A", Imf::Slice::Make(Imf::FLOAT, alpha.data(), dw));
    in.setFrameBuffer(frame);
    in.readPixels(dw.min.y, dw.max.y);
    return alpha;
}

// Same size, and every value within `rel` of the larger image's peak.
void expect_same_image(const wavebrdf::RgbImage& a, const wavebrdf::RgbImage& b, double rel) {
    ASSERT_EQ(a.rows, b.rows);
    ASSERT_EQ(a.cols, b.cols);
    ASSERT_EQ(a.data.size(), b.data.size());
    double peak = 0.0;
    for (std::size_t k = 0; k < a.data.size(); ++k) {
        ASSERT_TRUE(std::isfinite(a.data[k]) && std::isfinite(b.data[k])) << "pixel value " << k;
        peak = std::max({peak, std::abs(double(a.data[k])), std::abs(double(b.data[k]))});
    }
    ASSERT_GT(peak, 0.0) << "an all-black slice would make the comparison vacuous";
    double worst = 0.0;
    for (std::size_t k = 0; k < a.data.size(); ++k)
        worst = std::max(worst, std::abs(double(a.data[k]) - double(b.data[k])));
    EXPECT_LE(worst, rel * peak) << "peak " << peak;
}

// ---------------------------------------------------------------------------------------------
// Happy paths

TEST_F(CliTest, VersionIsTheOneInTheFileVersion) {
    std::ifstream in(fs::path(WAVEBRDF_SOURCE_DIR) / "VERSION");
    std::string version;
    ASSERT_TRUE(std::getline(in, version));
    ASSERT_FALSE(version.empty());
    const CliResult r = run("--version");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out, "wavebrdf " + version + "\n");
}

TEST_F(CliTest, HeightfieldWritesExrAndPng) {
    const CliResult r = run("heightfield --size 32x48 --out h.exr --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "");
    EXPECT_EQ(r.out, "");  // --quiet: "print nothing"
    ASSERT_TRUE(fs::exists(path("h.exr")));
    ASSERT_TRUE(fs::exists(path("h.png")));  // the default preview name
    EXPECT_TRUE(is_png(path("h.png")));
    const wavebrdf::Heightfield hf = wavebrdf::read_heightfield_exr(path("h.exr").string());
    EXPECT_EQ(hf.rows(), 32);
    EXPECT_EQ(hf.cols(), 48);
}

TEST_F(CliTest, RenderWritesExrAndPngQuietly) {
    const std::string hf = make_heightfield();
    const CliResult r = run("render --heightfield " + quote(hf) +
                            " --lambda-um 0.5 --resolution 32 --out a.exr --png a.png --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "") << "--quiet with stderr not a terminal must print nothing";
    EXPECT_EQ(r.out, "");
    ASSERT_TRUE(fs::exists(path("a.exr")));
    ASSERT_TRUE(fs::exists(path("a.png")));
    EXPECT_TRUE(is_png(path("a.png")));
    const wavebrdf::RgbImage image = wavebrdf::read_rgb_exr(path("a.exr").string());
    EXPECT_EQ(image.rows, 32);
    EXPECT_EQ(image.cols, 32);
    EXPECT_TRUE(read_alpha(path("a.exr").string()).empty()) << "render writes RGB, not RGBA";
    for (const auto& entry : fs::directory_iterator(m_dir))
        EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos);
}

// Without --quiet, but with stderr a file: no progress bar (no '\r' redraws), just the
// one-line summary and the heightfield's unit check (docs/cli.md).
TEST_F(CliTest, RenderWithoutQuietPrintsOnlyASummaryWhenNotATerminal) {
    const std::string hf = make_heightfield();
    const CliResult r = run("render --heightfield " + quote(hf) + " --resolution 16 --out a.exr");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
    const std::vector<std::string> lines = lines_of(r.err);
    ASSERT_EQ(lines.size(), 2u) << r.err;
    EXPECT_TRUE(starts_with(lines[0], "rendered 16x16 slice")) << lines[0];
    EXPECT_TRUE(starts_with(lines[1], hf + ": rms height")) << lines[1];
}

// render and genbrdf read only the footprint's rows of a file; their unit check describes the
// footprint's own texels (not a tile of zeros around them): on z = A cos(2π j / 8) the rms
// height is A/√2, with the file 32 times taller than the footprint.
TEST_F(CliTest, UnitCheckOfAFootprintReadDescribesTheFootprint) {
    const int rows = 1024, cols = 64;
    const double A = 0.05;
    std::vector<double> v(static_cast<std::size_t>(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) v[static_cast<std::size_t>(i) * cols + j] = A * std::cos(2 * M_PI * j / 8.0);
    const std::string hf = path("tall.exr").string();
    wavebrdf::write_heightfield_exr(hf, wavebrdf::Heightfield(rows, cols, v, 1.0, 1.0));
    for (const std::string& cmd : {"render --heightfield " + quote(hf) + " --x-um 512 --y-um 32 --sigma-p-um 5 --resolution 16 --out a.exr",
                                  "genbrdf -i " + quote(hf) + " -o g.exr -x 512 -y 32 -p 5 -r 16 -l 0.5"}) {
        const CliResult r = run(cmd);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const std::string needle = hf + ": rms height ";
        const std::size_t at = r.err.find(needle);
        ASSERT_NE(at, std::string::npos) << r.err;
        const double rms = std::atof(r.err.c_str() + at + needle.size());
        EXPECT_NEAR(rms, A / std::sqrt(2.0), 0.03 * A / std::sqrt(2.0)) << cmd << "\n" << r.err;
    }
}

TEST_F(CliTest, GenbrdfMatchesRender) {
    const std::string hf = make_heightfield();
    const CliResult g = run("genbrdf -i " + quote(hf) + " -o g.exr -r 32 -l 0.5 --quiet");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    EXPECT_EQ(g.err, "");
    EXPECT_EQ(g.out, "");
    const CliResult r = run("render --heightfield " + quote(hf) +
                            " --lambda-um 0.5 --resolution 32 --out r.exr --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::vector<float> alpha = read_alpha(path("g.exr").string());
    ASSERT_EQ(alpha.size(), 32u * 32u) << "genbrdf writes RGBA";
    for (float a : alpha) ASSERT_EQ(a, 1.0f);
    expect_same_image(wavebrdf::read_rgb_exr(path("g.exr").string()), wavebrdf::read_rgb_exr(path("r.exr").string()),
                      1e-6);
}

// genBrdf's -s S -t T is the light (S, T, 1) normalised; its projection is render's --light-*.
TEST_F(CliTest, GenbrdfLightDirectionIsNormalised) {
    const std::string hf = make_heightfield();
    const CliResult g = run("genbrdf -i " + quote(hf) + " -o g.exr -r 32 -l 0.5 -s 0.3 -t 0 --quiet");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    const double light_x = 0.3 / std::sqrt(0.3 * 0.3 + 0.0 * 0.0 + 1.0);  // 0.3 / sqrt(1.09)
    const CliResult r = run("render --heightfield " + quote(hf) + " --lambda-um 0.5 --light-x " +
                            wavebrdf::format_shortest(light_x) + " --light-y 0 --resolution 32 --out r.exr --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_same_image(wavebrdf::read_rgb_exr(path("g.exr").string()), wavebrdf::read_rgb_exr(path("r.exr").string()),
                      1e-6);
    // And it is not the unnormalised direction (0.3, 0): the check above has teeth.
    const CliResult u = run("render --heightfield " + quote(hf) +
                            " --lambda-um 0.5 --light-x 0.3 --resolution 32 --out u.exr --quiet");
    ASSERT_EQ(u.exit_code, 0) << u.err;
    const auto gi = wavebrdf::read_rgb_exr(path("g.exr").string());
    const auto ui = wavebrdf::read_rgb_exr(path("u.exr").string());
    EXPECT_NE(gi.data, ui.data);
}

// genBrdf's -l 0 is its spectral mode (8 samples), i.e. render --spectral 8.
TEST_F(CliTest, GenbrdfLambdaZeroIsSpectral) {
    const std::string hf = make_heightfield();
    const CliResult g = run("genbrdf -i " + quote(hf) + " -o g.exr -r 16 -l 0 --quiet");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    EXPECT_EQ(g.err, "");
    const CliResult r = run("render --heightfield " + quote(hf) + " --spectral 8 --resolution 16 --out r.exr --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_same_image(wavebrdf::read_rgb_exr(path("g.exr").string()), wavebrdf::read_rgb_exr(path("r.exr").string()),
                      1e-6);
}

// Issue 11: `heightfield --texel-um 0.5` then `render` without --texel-um rendered with 1 um
// texels (a silent 2x error). The file now says 0.5 and every reader uses it: the slice is the
// one of --texel-um 0.5, bit for bit, and not the one of 1 um texels; a disagreeing option wins
// with one warning line naming both values. genbrdf (-w, -v) does the same.
TEST_F(CliTest, RenderAndGenbrdfUseTheHeightfieldFilesTexelSize) {
    const CliResult h = run(
        "heightfield --type grating --period-um 8 --amplitude-um 0.2 --size 64 --texel-um 0.5 --out g.exr --no-png");
    ASSERT_EQ(h.exit_code, 0) << h.err;
    const wavebrdf::HeightfieldAttributes attributes = wavebrdf::read_heightfield_attributes(path("g.exr").string());
    ASSERT_TRUE(attributes.texel_um.has_value());
    EXPECT_EQ(*attributes.texel_um, 0.5);
    EXPECT_NE(attributes.made_by.find("type=grating"), std::string::npos) << attributes.made_by;
    EXPECT_NE(attributes.made_by.find("seed=1"), std::string::npos) << attributes.made_by;
    EXPECT_NE(attributes.made_by.find("period_um=8"), std::string::npos) << attributes.made_by;

    const std::string render = "render --heightfield g.exr --sigma-p-um 6 --resolution 32 --quiet";
    const CliResult from_file = run(render + " --out file.exr");
    ASSERT_EQ(from_file.exit_code, 0) << from_file.err;
    EXPECT_EQ(from_file.err, "") << "no option given: nothing to disagree with";
    const CliResult explicit_half = run(render + " --texel-um 0.5 --out half.exr");
    ASSERT_EQ(explicit_half.exit_code, 0) << explicit_half.err;
    EXPECT_EQ(explicit_half.err, "") << "an option that agrees with the file is no warning";
    const CliResult one = run(render + " --texel-um 1 --out one.exr");
    ASSERT_EQ(one.exit_code, 0) << one.err;
    EXPECT_EQ(one.err, "wavebrdf: warning: --texel-um 1 disagrees with g.exr's texel_um 0.5; using 1\n");
    const auto file_image = wavebrdf::read_rgb_exr(path("file.exr").string());
    expect_same_image(file_image, wavebrdf::read_rgb_exr(path("half.exr").string()), 0.0);
    // The 8 um grating at 0.5 um texels is 16 texels; at 1 um, 16 um: other diffraction orders.
    EXPECT_NE(file_image.data, wavebrdf::read_rgb_exr(path("one.exr").string()).data);
    const wavebrdf::SliceFile slice = wavebrdf::read_slice_exr(path("file.exr").string());
    ASSERT_TRUE(slice.attributes.has_value());
    EXPECT_EQ(slice.attributes->texel_um, 0.5);
    EXPECT_EQ(slice.attributes->heightfield_file, "g.exr");
    EXPECT_EQ(slice.attributes->query.sigma_p_um, 6.0);
    EXPECT_EQ(slice.attributes->lambdas_um, std::vector<double>{0.5});
    EXPECT_EQ(wavebrdf::read_slice_exr(path("one.exr").string()).attributes->texel_um, 1.0);
    // --vscale too.
    const CliResult vscale = run(render + " --vscale 2 --out v.exr");
    ASSERT_EQ(vscale.exit_code, 0) << vscale.err;
    EXPECT_EQ(vscale.err, "wavebrdf: warning: --vscale 2 disagrees with g.exr's vscale 1; using 2\n");

    // genbrdf: the file's values where -w / -v are not given (genBrdf's own files carry none
    // and keep its defaults of 1).
    const CliResult g = run("genbrdf -i g.exr -o gen.exr -p 6 -r 32 -l 0.5 --quiet");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    EXPECT_EQ(g.err, "");
    expect_same_image(wavebrdf::read_rgb_exr(path("gen.exr").string()), file_image, 1e-6);
    const CliResult g1 = run("genbrdf -i g.exr -o gen1.exr -p 6 -r 32 -l 0.5 -w 1 --quiet");
    ASSERT_EQ(g1.exit_code, 0) << g1.err;
    EXPECT_EQ(g1.err, "wavebrdf: warning: -w 1 disagrees with g.exr's texel_um 0.5; using 1\n");
    expect_same_image(wavebrdf::read_rgb_exr(path("gen1.exr").string()),
                      wavebrdf::read_rgb_exr(path("one.exr").string()), 1e-6);
}

// A heightfield file without attributes (genBrdf's, wavebrdf 0.1's) renders with the defaults.
TEST_F(CliTest, RenderOfAFileWithoutAttributesUsesTheDefaults) {
    const std::string hf = make_heightfield("h.exr", "32");
    // The same values with no attributes: rewritten through the plain RGB writer's channel R.
    const wavebrdf::Heightfield field = wavebrdf::read_heightfield_exr(hf);
    {
        Imf::Header header(32, 32);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        std::vector<float> data(field.values().begin(), field.values().end());
        Imf::FrameBuffer frame;
        frame.insert("R",
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(data.data()), sizeof(float), 32 * sizeof(float)));
        Imf::OutputFile out(path("plain.exr").string().c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(32);
    }
    EXPECT_FALSE(wavebrdf::read_heightfield_attributes(path("plain.exr").string()).texel_um.has_value());
    const CliResult a = run("render --heightfield plain.exr --resolution 16 --out a.exr --quiet");
    ASSERT_EQ(a.exit_code, 0) << a.err;
    EXPECT_EQ(a.err, "");
    const CliResult b = run("render --heightfield " + quote(hf) + " --texel-um 1 --resolution 16 --out b.exr --quiet");
    ASSERT_EQ(b.exit_code, 0) << b.err;
    expect_same_image(wavebrdf::read_rgb_exr(path("a.exr").string()), wavebrdf::read_rgb_exr(path("b.exr").string()),
                      0.0);
    EXPECT_EQ(wavebrdf::read_slice_exr(path("a.exr").string()).attributes->texel_um, 1.0);
}

// Issue 9: --x-um 3000000032 gave an all-zero slice (the centre overflowed an int before it was
// reduced to the tile); any finite position is periodic, so a whole number of 64 um periods
// away gives the very same slice.
TEST_F(CliTest, RenderPositionAHugeMultipleOfThePeriodAway) {
    const std::string hf = quote(make_heightfield());  // 64 x 64 texels of 1 um
    const std::string base = "render --heightfield " + hf + " --sigma-p-um 4 --resolution 24 --quiet";
    ASSERT_EQ(run(base + " --x-um 32 --y-um 20 --out a.exr").exit_code, 0);
    ASSERT_EQ(run(base + " --x-um 3000000032 --y-um -6399999980 --out b.exr").exit_code, 0);
    const auto a = wavebrdf::read_rgb_exr(path("a.exr").string());
    expect_same_image(a, wavebrdf::read_rgb_exr(path("b.exr").string()), 0.0);
}

// Issue 9: meaningless values are refused with the allowed range, before any output.
TEST_F(CliTest, OutOfRangeValuesNameTheRange) {
    const std::string hf = quote(make_heightfield());
    const std::string base = "render --heightfield " + hf + " --resolution 8 --out a.exr";
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
        {" --x-um nan", {"query position (nan"}},
        {" --sigma-p-um 1e9", {"sigma_p 1000000000 um", "1e-06 to 1000000 um"}},
        {" --sigma-p-um 1000", {"sigma_p 1000 um", "64 x 64 um", "640 um"}},
        {" --lambda-um 1e-300", {"wavelength 1e-300 um", "0.01 to 1000 um"}},
        {" --lambda-um 1e300", {"wavelength 1e+300 um", "0.01 to 1000 um"}},
        {" --texel-um 1e-300", {"texel width 1e-300 um", "0.0001 to 10000 um"}},
        {" --vscale 1e-300", {"vertical scale 1e-300", "1e-06 <= |vscale| <= 10000"}},
    };
    for (const auto& [extra, needles] : cases) {
        SCOPED_TRACE(extra);
        expect_clean_failure(run(base + extra), needles, {path("a.exr")});
    }
    // genbrdf -s 1e200: s^2 + t^2 + 1 overflowed to inf and gave normal incidence.
    const std::string g = "genbrdf -i " + hf + " -o g.exr -r 8";
    expect_clean_failure(run(g + " -s 1e200"), {"-s 1e+200", "sqrt(s^2 + t^2) <= 1e6"}, {path("g.exr")});
    expect_clean_failure(run(g + " -t -1e7"), {"-t -10000000", "<= 1e6"}, {path("g.exr")});
    expect_clean_failure(run(g + " -s nan"), {"-s nan"}, {path("g.exr")});
    expect_clean_failure(run(g + " -x nan"), {"query position (nan"}, {path("g.exr")});
    // The steepest light accepted still renders.
    EXPECT_EQ(run(g + " -s 1e6 --quiet").exit_code, 0);
    // Counts: 2147483647 scratches would run for days.
    expect_clean_failure(run("heightfield --type scratched --scratches 2147483647 --size 16 --out h2.exr"),
                         {"scratch_count = 2147483647", "0 to 10000"}, {path("h2.exr"), path("h2.png")});
}

// ---------------------------------------------------------------------------------------------
// Bad heightfield inputs

TEST_F(CliTest, MissingHeightfield) {
    const CliResult r = run("render --heightfield missing.exr --resolution 16 --out a.exr --png a.png");
    expect_clean_failure(r, {"missing.exr", "does not exist"}, {path("a.exr"), path("a.png")});
    const CliResult g = run("genbrdf -i missing.exr -o g.exr -r 16");
    expect_clean_failure(g, {"missing.exr", "does not exist"}, {path("g.exr")});
}

TEST_F(CliTest, CorruptHeightfield) {
    std::ofstream(path("corrupt.exr")) << "this is not an OpenEXR file\nsecond line\n";
    const CliResult r = run("render --heightfield corrupt.exr --resolution 16 --out a.exr");
    expect_clean_failure(r, {"corrupt.exr", "not an OpenEXR file"}, {path("a.exr")});
    const CliResult g = run("genbrdf -i corrupt.exr -o g.exr -r 16");
    expect_clean_failure(g, {"corrupt.exr", "not an OpenEXR file"}, {path("g.exr")});
}

TEST_F(CliTest, TruncatedHeightfield) {
    const std::string hf = make_heightfield("cut.exr", "128");
    fs::resize_file(hf, fs::file_size(hf) / 2);
    const CliResult r = run("render --heightfield cut.exr --resolution 16 --out a.exr");
    expect_clean_failure(r, {"cut.exr"}, {path("a.exr")});
    const CliResult g = run("genbrdf -i cut.exr -o g.exr -r 16");
    expect_clean_failure(g, {"cut.exr"}, {path("g.exr")});
}

TEST_F(CliTest, NonFiniteHeights) {
    std::vector<float> values(8 * 8, 0.25f);
    values[3 * 8 + 5] = std::numeric_limits<float>::quiet_NaN();
    write_raw_exr(path("nan.exr").string(), 8, 8, values);
    const CliResult r = run("render --heightfield nan.exr --resolution 16 --out a.exr");
    expect_clean_failure(r, {"nan.exr", "row 3, column 5", "not finite"}, {path("a.exr")});
    const CliResult g = run("genbrdf -i nan.exr -o g.exr -r 16");
    expect_clean_failure(g, {"nan.exr", "not finite"}, {path("g.exr")});

    values[3 * 8 + 5] = std::numeric_limits<float>::infinity();
    write_raw_exr(path("inf.exr").string(), 8, 8, values);
    const CliResult i = run("render --heightfield inf.exr --resolution 16 --out a.exr");
    expect_clean_failure(i, {"inf.exr", "not finite"}, {path("a.exr")});
}

// ---------------------------------------------------------------------------------------------
// Bad parameters

TEST_F(CliTest, NonPositiveWavelength) {
    const std::string hf = quote(make_heightfield());
    const std::string base = "render --heightfield " + hf + " --resolution 16 --out a.exr";
    // --lambda-um 0 is an explicit bad value, not "use the default".
    expect_clean_failure(run(base + " --lambda-um 0"), {"wavelength 0 "}, {path("a.exr")});
    expect_clean_failure(run(base + " --lambda-um -1"), {"wavelength -1"}, {path("a.exr")});
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r 16 -l -0.5"), {"wavelength -0.5"}, {path("g.exr")});
}

TEST_F(CliTest, LightDirectionOutsideUnitDisk) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("render --heightfield " + hf + " --light-x 0.8 --light-y 0.7 --resolution 16 --out a.exr"),
                         {"light direction (0.8, 0.7)"}, {path("a.exr")});
    // Exactly on the unit circle is out too (cos θ_i = 0).
    expect_clean_failure(run("render --heightfield " + hf + " --light-x 1 --resolution 16 --out a.exr"),
                         {"light direction (1, 0)"}, {path("a.exr")});
}

TEST_F(CliTest, NonPositiveSigmaP) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("render --heightfield " + hf + " --sigma-p-um 0 --resolution 16 --out a.exr"),
                         {"sigma_p 0 "}, {path("a.exr")});
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r 16 -p -1"), {"sigma_p -1"}, {path("g.exr")});
}

TEST_F(CliTest, ResolutionOutOfRange) {
    const std::string hf = quote(make_heightfield());
    for (const char* n : {"0", "8193", "-4"}) {
        SCOPED_TRACE(n);
        expect_clean_failure(run("render --heightfield " + hf + " --resolution " + n + " --out a.exr --png a.png"),
                             {std::string("resolution ") + n + " "}, {path("a.exr"), path("a.png")});
        expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r " + n), {std::string("resolution ") + n + " "},
                             {path("g.exr")});
    }
}

TEST_F(CliTest, UnknownModel) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("render --heightfield " + hf + " --model Foo --resolution 16 --out a.exr"), {"'Foo'"},
                         {path("a.exr")});
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r 16 -d Foo"), {"'Foo'"}, {path("g.exr")});
}

TEST_F(CliTest, UnwritableOutput) {
    const std::string hf = quote(make_heightfield());
    // A missing directory.
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out /nonexistent_dir/x.exr"),
                         {"/nonexistent_dir/x.exr"}, {"/nonexistent_dir/x.exr"});
    expect_clean_failure(run("genbrdf -i " + hf + " -o /nonexistent_dir/g.exr -r 16"), {"/nonexistent_dir/g.exr"},
                         {"/nonexistent_dir/g.exr"});
    // A "directory" that is a regular file.
    std::ofstream(path("plain")) << "a regular file\n";
    const std::string under_file = (path("plain") / "x.exr").string();
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out " + quote(under_file)),
                         {under_file}, {under_file});
    // A good EXR but an unwritable PNG: neither is written.
    expect_clean_failure(
        run("render --heightfield " + hf + " --resolution 16 --out a.exr --png /nonexistent_dir/a.png"),
        {"/nonexistent_dir/a.png"}, {path("a.exr"), "/nonexistent_dir/a.png"});
    // The output is a directory.
    fs::create_directory(path("dir.exr"));
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out dir.exr"),
                         {"dir.exr", "is a directory"}, {});
    EXPECT_TRUE(fs::is_empty(path("dir.exr")));
}

// Outputs replace only regular files: a FIFO, a symbolic link or a device node given as an
// output is refused before any work and stays what it was (the temp-and-rename write used to
// replace it with a regular file: `--out /dev/null` as root replaced the machine's /dev/null,
// which is why this test makes its own device node instead).
TEST_F(CliTest, OutputsThatAreNotRegularFilesAreRefused) {
    const std::string hf = quote(make_heightfield());
    const auto type_of = [](const fs::path& p) { return fs::symlink_status(p).type(); };
    ASSERT_EQ(::mkfifo(path("fifo.exr").c_str(), 0644), 0);
    std::ofstream(path("target.png")) << "keep\n";
    fs::create_symlink(path("target.png"), path("link.png"));
    std::vector<std::string> names = {"fifo.exr", "link.png"};
    if (::mknod(path("null").c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) names.push_back("null");
    for (const std::string& name : names) {
        SCOPED_TRACE(name);
        const fs::file_type before = type_of(path(name));
        for (const std::string& args :
             {"render --heightfield " + hf + " --resolution 16 --out " + qpath(name),
              "render --heightfield " + hf + " --resolution 16 --out a.exr --png " + qpath(name),
              "genbrdf -i " + hf + " -r 16 -o " + qpath(name), "heightfield --size 16 --no-png --out " + qpath(name)}) {
            SCOPED_TRACE(args);
            expect_clean_failure(run(args), {path(name).string(), "not a regular file; refusing to replace it"},
                                 {path("a.exr")});
            EXPECT_EQ(type_of(path(name)), before) << "the output was replaced";
        }
    }
    EXPECT_EQ(read_text(path("target.png")), "keep\n") << "wrote through the link";
}

// Two outputs (or an output and the input) naming one file: the second used to replace the
// first silently (`--out o.exr --png o.exr` lost the EXR; `heightfield --out h.png` wrote its
// default preview h.png over the EXR).
TEST_F(CliTest, EqualPathsAreRefused) {
    const std::string hf_path = make_heightfield();
    const std::string hf = quote(hf_path);
    const std::string before = read_text(hf_path);
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out o.exr --png o.exr"),
                         {"--out o.exr", "--png o.exr", "same file"}, {path("o.exr")});
    fs::create_directory(path("sub"));
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out o.exr --png sub/../o.exr"),
                         {"--out o.exr", "--png sub/../o.exr", "same file"}, {path("o.exr")});
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out ./h.exr"),
                         {"--heightfield", "--out ./h.exr", "same file"}, {});
    expect_clean_failure(run("genbrdf -i " + hf + " -r 16 -o h.exr"), {"-i", "-o h.exr", "same file"}, {});
    EXPECT_EQ(read_text(hf_path), before) << "the input was replaced";
    expect_clean_failure(run("heightfield --size 16 --out x.png"), {"--out x.png", "default preview", "same file"},
                         {path("x.png")});
    expect_clean_failure(run("heightfield --size 16 --out x.exr --png ./x.exr"),
                         {"--out x.exr", "--png ./x.exr", "same file"}, {path("x.exr")});
    // Different names stay fine, and --no-png needs no preview name.
    EXPECT_EQ(run("heightfield --size 16 --out y.exr --no-png --quiet").exit_code, 0);
    EXPECT_EQ(run("render --heightfield " + hf + " --resolution 16 --out o.exr --png o.png --quiet").exit_code, 0);
}

// SIGTERM while an output is being written (its temporary exists): the process ends by the
// signal and removes the temporary (it used to stay behind as `o.exr.tmp-PID-N`).
TEST_F(CliTest, SigtermDuringAWriteLeavesNoTemporary) {
    const std::string hf = make_heightfield();
    bool caught = false;
    // A 2048^2 slice takes a fraction of a second to compress and write: watch for its
    // temporary and signal then. Try again with a larger slice when the write was missed.
    for (int resolution : {2048, 3072, 4096}) {
        fs::remove(path("o.exr"));
        fs::remove(path("o.png"));
        const pid_t pid = start_cli(m_dir, {"render", "--heightfield", hf, "--resolution", std::to_string(resolution),
                                            "--out", "o.exr", "--png", "o.png", "--quiet"});
        ASSERT_GT(pid, 0);
        int status = 0;
        for (;;) {
            if (!temporaries_under(m_dir).empty()) {
                ::kill(pid, SIGTERM);
                caught = true;
                break;
            }
            if (::waitpid(pid, &status, WNOHANG) == pid) break;
        }
        if (caught) {
            ASSERT_EQ(::waitpid(pid, &status, 0), pid);
            // Ended by the signal, unless the write finished in the instant before it.
            if (WIFSIGNALED(status)) {
                EXPECT_EQ(WTERMSIG(status), SIGTERM);
                EXPECT_FALSE(fs::exists(path("o.png")));
            }
            break;
        }
    }
    if (!caught) GTEST_SKIP() << "never saw a write in progress";
    EXPECT_EQ(temporaries_under(m_dir), std::vector<std::string>{});
}

TEST_F(CliTest, BadSpectralAndPrecision) {
    const std::string hf = quote(make_heightfield());
    const std::string base = "render --heightfield " + hf + " --resolution 16 --out a.exr";
    // --spectral 0 is an explicit bad value, not "no --spectral".
    expect_clean_failure(run(base + " --spectral 0"), {"--spectral 0"}, {path("a.exr")});
    expect_clean_failure(run(base + " --spectral 257"), {"--spectral 257"}, {path("a.exr")});
    expect_clean_failure(run(base + " --precision quad"), {"'quad'"}, {path("a.exr")});
    expect_clean_failure(run(base + " --path sideways"), {"'sideways'"}, {path("a.exr")});
}

// An exposure the PNG writer rejects must fail before the EXR is written, not after.
TEST_F(CliTest, BadExposureLeavesNoExr) {
    const std::string hf = quote(make_heightfield());
    for (const char* e : {"nan", "1e999"}) {
        SCOPED_TRACE(e);
        expect_clean_failure(
            run("render --heightfield " + hf + " --resolution 16 --out a.exr --png a.png --exposure " + e),
            {"--exposure"}, {path("a.exr"), path("a.png")});
    }
}

TEST_F(CliTest, NoOutputGiven) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16"), {"no output given"}, {});
}

TEST_F(CliTest, UnsupportedGenbrdfMethod) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r 16 -m Geometric"), {"'Geometric'"}, {path("g.exr")});
}

TEST_F(CliTest, BadHeightfieldArguments) {
    const std::vector<fs::path> outputs = {path("h.exr"), path("h.png")};
    expect_clean_failure(run("heightfield --type foo --size 16 --out h.exr"), {"'foo'"}, outputs);
    expect_clean_failure(run("heightfield --size 0 --out h.exr"), {"--size '0'", "1 to 16384"}, outputs);
    expect_clean_failure(run("heightfield --size 12xq --out h.exr"), {"'12xq'"}, outputs);
    expect_clean_failure(run("heightfield --size 16x --out h.exr"), {"'16x'"}, outputs);
    expect_clean_failure(run("heightfield --size 16 --out /nonexistent_dir/h.exr"), {"/nonexistent_dir/h.exr"},
                         {"/nonexistent_dir/h.exr"});
    // A writable EXR but an unwritable preview: neither is written.
    expect_clean_failure(run("heightfield --size 16 --out h.exr --png /nonexistent_dir/h.png"),
                         {"/nonexistent_dir/h.png"}, outputs);
}

// CLI11's own parse errors come out in the same one-line form as the commands' errors.
TEST_F(CliTest, ParseErrorsAreOneLine) {
    const std::string hf = quote(make_heightfield());
    expect_clean_failure(run("render --heightfield " + hf + " --resolution abc --out a.exr"), {"--resolution", "abc"},
                         {path("a.exr")});
    expect_clean_failure(run("render --heightfield " + hf + " --resolution 16 --out a.exr --bogus"), {"--bogus"},
                         {path("a.exr")});
    expect_clean_failure(run("render --resolution 16 --out a.exr"), {"--heightfield"}, {path("a.exr")});
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr -r 16 -l"), {"-l"}, {path("g.exr")});
    expect_clean_failure(
        run("render --heightfield " + hf + " --lambda-um 0.5 --spectral 8 --resolution 16 --out a.exr"),
        {"--lambda-um", "--spectral"}, {path("a.exr")});
    expect_clean_failure(run(""), {"subcommand"}, {});
    // CLI11 checks for a missing subcommand before unknown arguments, so an unknown subcommand
    // is reported as a missing one.
    expect_clean_failure(run("frobnicate"), {"subcommand"}, {});
    // --help is not an error: usage on stdout, exit 0.
    const CliResult help = run("render --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_NE(help.out.find("--lambda-um"), std::string::npos);
}

// Every command's --help names the model document, --threads and OMP_NUM_THREADS; those
// that read or write slices state their unit.
TEST_F(CliTest, HelpStatesUnitsModelAndThreads) {
    for (const std::string command : {"heightfield", "render", "genbrdf", "invert", "recover"}) {
        SCOPED_TRACE(command);
        const CliResult r = run(command + " --help");
        ASSERT_EQ(r.exit_code, 0) << r.err;
        for (const char* needle : {"docs/model.md", "--threads", "OMP_NUM_THREADS", "stderr"})
            EXPECT_NE(r.out.find(needle), std::string::npos) << needle << " missing from:\n" << r.out;
        if (command != "heightfield") {
            EXPECT_NE(r.out.find("f_r in 1/sr"), std::string::npos) << r.out;
        }
    }
    const CliResult top = run("--help");
    EXPECT_NE(top.out.find("docs/model.md"), std::string::npos) << top.out;
}

// The slice image decoded from the EXR a run wrote.
wavebrdf::RgbImage slice_of(const fs::path& exr) { return wavebrdf::read_rgb_exr(exr.string()); }

// The default preview is the log scale (5 decades) of the very slice written; the options
// reach the library (false colour, colour bar widen the picture); linear on --exposure.
TEST_F(CliTest, RenderPreviewOptions) {
    const std::string hf = quote(make_heightfield());
    const std::string base = "render --heightfield " + hf + " --resolution 32 --out a.exr --quiet --png ";
    ASSERT_EQ(run(base + "a.png --no-axes --no-colour-bar").exit_code, 0);
    wavebrdf::test::DecodedPng png = wavebrdf::test::read_png_rgb(path("a.png").string());
    ASSERT_EQ(png.rows, 32);
    ASSERT_EQ(png.cols, 32);
    wavebrdf::PreviewOptions log;
    log.log_decades = 5.0;
    EXPECT_EQ(png.rgb, wavebrdf::make_slice_preview(slice_of(path("a.exr")), log).rgb);

    ASSERT_EQ(run(base + "b.png --log-decades 2 --false-colour --colour-bar").exit_code, 0);
    png = wavebrdf::test::read_png_rgb(path("b.png").string());
    log.log_decades = 2.0;
    log.false_colour = log.colour_bar = true;
    log.axes = true;  // on by default
    log.unit = "1/sr";
    const wavebrdf::Preview8 expected = wavebrdf::make_slice_preview(slice_of(path("a.exr")), log);
    EXPECT_GT(png.cols, 32);
    EXPECT_EQ(png.rows, expected.rows);
    EXPECT_EQ(png.cols, expected.cols);
    EXPECT_EQ(png.rgb, expected.rgb);

    ASSERT_EQ(run(base + "c.png --exposure -2 --reinhard --no-axes --no-colour-bar").exit_code, 0);
    wavebrdf::write_rgb_png(path("c-ref.png").string(), slice_of(path("a.exr")), -2.0, true);
    EXPECT_EQ(wavebrdf::test::read_png_rgb(path("c.png").string()).rgb,
              wavebrdf::test::read_png_rgb(path("c-ref.png").string()).rgb);

    for (const char* bad : {"0", "-1", "31", "nan"})
        expect_clean_failure(run(base + "d.png --log-decades " + bad), {"--log-decades"}, {path("d.png")});
    expect_clean_failure(run(base + "d.png --log --exposure 1"), {"--log", "--exposure"}, {path("d.png")});
    expect_clean_failure(run(base + "d.png --log-decades 3 --reinhard"), {"--log-decades", "--reinhard"},
                         {path("d.png")});
}

TEST_F(CliTest, GenbrdfWritesAPreview) {
    const std::string hf = quote(make_heightfield());
    const CliResult r = run("genbrdf -i " + hf + " -o g.exr -r 24 --png g.png --colour-bar --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const wavebrdf::test::DecodedPng png = wavebrdf::test::read_png_rgb(path("g.png").string());
    EXPECT_GT(png.cols, 24);
    EXPECT_GE(png.rows, 24);
    expect_clean_failure(run("genbrdf -i " + hf + " -o g.exr --png g.exr"), {"-o", "--png"}, {});
}

TEST_F(CliTest, HeightfieldPreviewInFalseColourWithABar) {
    const CliResult r = run("heightfield --size 40x30 --out h.exr --false-colour --colour-bar --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const wavebrdf::test::DecodedPng png = wavebrdf::test::read_png_rgb(path("h.png").string());
    const wavebrdf::Preview8 expected = wavebrdf::make_heightfield_preview(
        wavebrdf::read_heightfield_exr(path("h.exr").string()), true, true);
    EXPECT_EQ(png.rows, expected.rows);
    EXPECT_EQ(png.cols, expected.cols);
    EXPECT_GT(png.cols, 30);
    EXPECT_EQ(png.rgb, expected.rgb);
}

// Raw float pixels of an RGB EXR, to compare two runs bit for bit.
std::vector<float> pixels_of(const fs::path& exr) { return wavebrdf::read_rgb_exr(exr.string()).data; }

// --threads N: the slice is the same bit for bit on 1 and 2 threads (each pixel and each
// column block of the products is computed by one thread in a fixed order), on both paths;
// bad counts are one line naming the value; every command takes the option.
TEST_F(CliTest, ThreadsOptionGivesTheSameSliceAndIsBounded) {
    const std::string hf = quote(make_heightfield("h.exr", "96"));
    for (const std::string path_name : {"separable", "direct"}) {
        SCOPED_TRACE(path_name);
        const std::string base = "render --heightfield " + hf + " --resolution 96 --quiet --path " + path_name;
        ASSERT_EQ(run(base + " --threads 1 --out t1.exr").exit_code, 0);
        ASSERT_EQ(run(base + " --threads 2 --out t2.exr").exit_code, 0);
        const std::vector<float> one = pixels_of(path("t1.exr")), two = pixels_of(path("t2.exr"));
        ASSERT_EQ(one.size(), two.size());
        EXPECT_TRUE(std::equal(one.begin(), one.end(), two.begin())) << "the slice depends on the thread count";
    }
    for (const char* bad : {"0", "abc", "1025", "-1", "2.5", ""}) {
        SCOPED_TRACE(bad);
        expect_clean_failure(
            run("render --heightfield " + hf + " --resolution 8 --out x.exr --threads '" + std::string(bad) + "'"),
            {"--threads"}, {path("x.exr")});
    }
    EXPECT_EQ(run("heightfield --size 8 --out t.exr --no-png --quiet --threads 2").exit_code, 0);
    EXPECT_EQ(run("genbrdf -i " + hf + " -o g.exr -r 8 --quiet --threads 2").exit_code, 0);
    EXPECT_EQ(run("invert --size 8 --sigma-p-um 2 --resolution 8 --lambda-um 0.5 --epochs 1 --no-plots --quiet "
                  "--threads 2 --out inv")
                  .exit_code,
              0);
    EXPECT_EQ(run("invert --resume inv --epochs 2 --no-plots --quiet --threads 1").exit_code, 0);
    EXPECT_EQ(run("recover --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --method thesis "
                  "--epochs 1 --no-plots --quiet --threads 2 --out rec")
                  .exit_code,
              0);
}

// Every command: its summary (and progress, which a file never gets) on stderr, nothing on
// stdout; --quiet: nothing at all.
TEST_F(CliTest, EveryCommandSummarisesOnStderrOnly) {
    const std::string hf = quote(make_heightfield("h.exr", "32"));
    struct Case {
        std::string args, summary;
    };
    const std::vector<Case> cases = {
        {"heightfield --size 16 --out s.exr --no-png", "s.exr: isotropic 16x16"},
        {"render --heightfield " + hf + " --resolution 8 --out r.exr", "rendered 8x8 slice"},
        {"genbrdf -i " + hf + " -o g.exr -r 8", "rendered 8x8 slice"},
        {"invert --size 8 --sigma-p-um 2 --resolution 8 --lambda-um 0.5 --epochs 1 --no-plots --force --out inv",
         "results in inv"},
        {"recover --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --method thesis --epochs 1 "
         "--no-plots --force --out rec",
         "results in rec"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.args);
        const CliResult loud = run(c.args);
        ASSERT_EQ(loud.exit_code, 0) << loud.err;
        EXPECT_EQ(loud.out, "");
        EXPECT_NE(loud.err.find(c.summary), std::string::npos) << loud.err;
        const CliResult quiet = run(c.args + " --quiet");
        ASSERT_EQ(quiet.exit_code, 0) << quiet.err;
        EXPECT_EQ(quiet.out, "");
        // One epoch of the thesis's method does not converge: its warning is the one line --quiet keeps.
        if (c.args.rfind("recover", 0) == 0)
            EXPECT_EQ(quiet.err.rfind("wavebrdf: warning: the recovery did not converge", 0), 0u) << quiet.err;
        else
            EXPECT_EQ(quiet.err, "");
    }
}

}  // namespace
