// --path and --tolerance on every command that renders or differentiates (render, genbrdf,
// table, invert): they reach the library (the slice equals the library's render with those
// options; the fft path, refused by the library until its engine lands, is refused naming it),
// bad values are refused with one line naming the option, --help documents them and invert's
// run.json records them. Also the partial heightfield read of render/genbrdf end to end: the
// slice of a footprint across the tile's seam equals the library's from the whole file.
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"
#include "wavebrdf/render_options.h"
#include "wavebrdf/table.h"

namespace fs = std::filesystem;
using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

class RenderPathCliTest : public ::testing::Test {
protected:
    void SetUp() override { m_dir = fresh_dir("render_path_cli"); }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(m_dir);
    }
    fs::path path(const std::string& name) const { return m_dir / name; }
    CliResult run(const std::string& args) const { return run_cli(m_dir, args); }
    std::string make_heightfield(const std::string& size = "48") const {
        const CliResult r = run("heightfield --size " + size + " --texel-um 0.5 --seed 3 --out h.exr --no-png --quiet");
        EXPECT_EQ(r.exit_code, 0) << r.err;
        return path("h.exr").string();
    }
    fs::path m_dir;
};

// The command lines, one per command, that render with the options appended.
std::vector<std::string> commands() {
    return {"render --heightfield h.exr --resolution 8 --out a.exr --quiet", "genbrdf -i h.exr -o a.exr -r 8 --quiet",
            "table --heightfield h.exr --lights 2 --resolution 8 --out a.exr --quiet",
            "invert --size 4 --resolution 8 --epochs 0 --out run --quiet --no-plots"};
}

TEST_F(RenderPathCliTest, BadPathAndToleranceAreRefusedInOneLine) {
    make_heightfield();
    for (const std::string& command : commands()) {
        SCOPED_TRACE(command);
        const CliResult sideways = run(command + " --path sideways");
        expect_one_line_naming(sideways, {"--path", "'sideways'", "auto, separable, fft or direct"});
        const CliResult upper = run(command + " --path Direct");
        expect_one_line_naming(upper, {"--path", "'Direct'"});
        for (const char* tolerance : {"0.5", "1e-13", "0", "-1e-6", "nan"}) {
            const CliResult r = run(command + " --tolerance " + tolerance);
            expect_one_line_naming(r, {"--tolerance", "1e-12 to 1e-2"});
        }
        EXPECT_FALSE(fs::exists(path("a.exr")));
    }
}

// Until the FFT engine is merged the library refuses RenderPath::Fft: each command passes
// --path fft through to it (the message names the fft path), rather than dropping or
// rewriting it. (The lead flips this test when the engine lands.)
TEST_F(RenderPathCliTest, FftPathRunsOnEveryCommand) {
    make_heightfield();
    for (const std::string& command : commands()) {
        SCOPED_TRACE(command);
        const CliResult r = run(command + " --path fft --tolerance 1e-4");
        EXPECT_EQ(r.exit_code, 0) << r.err;
    }
}

TEST_F(RenderPathCliTest, PathAndToleranceReachTheRender) {
    const std::string hf = make_heightfield();
    // GHS on every path with a tolerance: bit for bit the library's render with them.
    for (const char* path_name : {"direct", "auto", "separable", "fft"}) {
        const CliResult r = run(std::string("render --heightfield h.exr --resolution 12 --model GHS --light-x 0.2 ") +
                                "--x-um 0.2 --sigma-p-um 2 --path " + path_name +
                                " --tolerance 1e-4 --out a.exr --quiet");
        ASSERT_EQ(r.exit_code, 0) << r.err;
        Query q;
        q.x_um = 0.2;
        q.sigma_p_um = 2.0;
        q.omega_i = {0.2, 0.0};
        q.model = Model::GHS;
        RenderOptions options;
        options.path = parse_render_path(path_name);
        options.tolerance = 1e-4;
        const std::vector<float> expected = render_rgb<float>(read_heightfield_exr(hf), q, {0.5}, 12, options);
        EXPECT_EQ(read_rgb_exr(path("a.exr").string()).data, expected) << path_name;
    }
    // The separable path of OHS from genbrdf, at the seam (x just below the 24 um period).
    const CliResult g = run("genbrdf -i h.exr -o g.exr -r 12 -x 23.9 -y 0.1 -p 2 --path separable --quiet");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    Query q;
    q.x_um = 23.9;
    q.y_um = 0.1;
    q.sigma_p_um = 2.0;
    RenderOptions options;
    options.path = RenderPath::Separable;
    const std::vector<float> rgb = render_rgb<float>(read_heightfield_exr(hf), q, {0.5}, 12, options);
    EXPECT_EQ(read_rgb_exr(path("g.exr").string()).data, rgb);  // its R, G, B (A is 1)
}

// `table` reads only its footprint's rows too: its values equal the library's table of the whole
// file, for a footprint across the tile's seam (y too) and on the direct path for GHS.
TEST_F(RenderPathCliTest, TableOfTheFootprintRowsEqualsTheWholeFile) {
    const std::string hf = make_heightfield();
    const CliResult r = run(
        "table --heightfield h.exr --x-um 23.8 --y-um 0.2 --sigma-p-um 1.5 --model GHS "
        "--path direct --lights 2x3 --max-light-sin 0.5 --resolution 8 --out t.exr --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    TableSpec spec;
    spec.query.x_um = 23.8;
    spec.query.y_um = 0.2;
    spec.query.sigma_p_um = 1.5;
    spec.query.model = Model::GHS;
    spec.lambdas_um = {0.5};
    spec.resolution = 8;
    spec.lights = {2, 3, 0.5};
    RenderOptions options;
    options.path = RenderPath::Direct;
    const BrdfTable expected = render_brdf_table(read_heightfield_exr(hf), spec, options);
    EXPECT_EQ(read_brdf_table(path("t.exr").string()).values, expected.values);
}

TEST_F(RenderPathCliTest, HelpListsPathAndTolerance) {
    for (const char* command : {"render", "genbrdf", "table", "invert"}) {
        const CliResult r = run(std::string(command) + " --help");
        EXPECT_EQ(r.exit_code, 0) << command;
        for (const char* text : {"--path", "auto", "separable", "fft", "direct", "--tolerance", "1e-12 to 1e-2"})
            EXPECT_NE(r.out.find(text), std::string::npos) << command << " --help does not say " << text;
    }
}

TEST_F(RenderPathCliTest, InvertRecordsPathAndToleranceInRunJson) {
    const CliResult r = run(
        "invert --size 4 --resolution 8 --epochs 1 --model GHS --path direct --tolerance 1e-5 "
        "--out run --quiet --no-plots");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json run_json = nlohmann::json::parse(read_text(path("run") / "run.json"));
    const nlohmann::json& args = run_json.contains("args") ? run_json.at("args") : run_json;
    EXPECT_EQ(args.at("path"), "direct");
    EXPECT_EQ(args.at("tolerance").get<double>(), 1e-5);
    // A resumed run keeps them, and refuses new ones.
    const CliResult resumed = run("invert --resume run --epochs 2 --quiet --no-plots");
    EXPECT_EQ(resumed.exit_code, 0) << resumed.err;
    expect_one_line_naming(run("invert --resume run --epochs 3 --path auto --quiet --no-plots"), {"--path"});
}

TEST(InversionOptionsJson, PathAndToleranceRoundTripAndDefaultWhenAbsent) {
    InversionOptions o;
    o.path = RenderPath::Direct;
    o.tolerance = 3e-7;
    const InversionOptions back = inversion_options_from_json(inversion_options_to_json(o));
    EXPECT_EQ(back.path, RenderPath::Direct);
    EXPECT_EQ(back.tolerance, 3e-7);
    // A run.json written before these options existed: the defaults it ran with.
    nlohmann::json old = nlohmann::json::parse(inversion_options_to_json(InversionOptions{}));
    old.erase("path");
    old.erase("tolerance");
    const InversionOptions defaults = inversion_options_from_json(old.dump());
    EXPECT_EQ(defaults.path, RenderPath::Auto);
    EXPECT_EQ(defaults.tolerance, 1e-6);
    // Hostile values are refused.
    nlohmann::json bad = nlohmann::json::parse(inversion_options_to_json(o));
    bad["path"] = "sideways";
    EXPECT_ANY_THROW(inversion_options_from_json(bad.dump()));
    bad["path"] = "direct";
    bad["tolerance"] = 5.0;
    EXPECT_ANY_THROW(inversion_options_from_json(bad.dump()));
}

TEST(RenderOptionsText, ParseAndPrintEveryPath) {
    for (RenderPath p : {RenderPath::Auto, RenderPath::Separable, RenderPath::Fft, RenderPath::Direct})
        EXPECT_EQ(parse_render_path(to_string(p)), p);
    try {
        parse_render_path("fast\nsecond line", "--path");
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        EXPECT_NE(message.find("--path 'fast?second line'"), std::string::npos) << message;
    }
    EXPECT_NO_THROW(validate_render_tolerance(1e-12));
    EXPECT_NO_THROW(validate_render_tolerance(1e-2));
    EXPECT_THROW(validate_render_tolerance(0.0101), std::domain_error);
    EXPECT_THROW(validate_render_tolerance(9e-13), std::domain_error);
}

}  // namespace
