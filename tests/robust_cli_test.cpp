// Traps a new user walks into and what hostile input finds, end to end through the CLI: each
// test is one trap, run as a user would, with the one-line refusal (or the right result) checked.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/run_directory.h"

using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

// The first bytes of a file (to tell formats apart by their signatures, not by our readers).
std::string head(const fs::path& path, std::size_t n) { return read_text(path).substr(0, n); }

const std::string kExr = std::string("\x76\x2f\x31\x01", 4);
const std::string kNpy = "\x93NUMPY";
const std::string kPng = "\x89PNG";

// A small recovery that runs in seconds (as recover_cli_test's).
const std::string kSmallRobust = "--size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --no-plots --quiet";

}  // namespace

// Every output writes the format its extension names, or refuses the name listing the ones it
// knows; nothing is written on a refusal.
TEST(RobustCliTest, OutputsWriteTheFormatTheirExtensionNames) {
    const fs::path dir = fresh_dir("robust");
    ASSERT_EQ(run_cli(dir, "heightfield --size 16 --out h.exr --quiet").exit_code, 0);
    EXPECT_EQ(head(dir / "h.exr", 4), kExr);
    EXPECT_EQ(head(dir / "h.png", 4), kPng);

    const std::string render = "render --heightfield h.exr --resolution 8 --quiet ";
    const CliResult npy = run_cli(dir, render + "--out s.npy");
    ASSERT_EQ(npy.exit_code, 0) << npy.err;
    EXPECT_EQ(head(dir / "s.npy", 6), kNpy);
    ASSERT_EQ(run_cli(dir, render + "--out s.EXR").exit_code, 0);  // case does not matter
    EXPECT_EQ(head(dir / "s.EXR", 4), kExr);

    struct Case {
        std::string args, option, known;
        fs::path not_written;
    };
    const std::vector<Case> cases{
        {render + "--out x.png", "--out x.png", ".exr, .npy", "x.png"},
        {render + "--out x.tif", "--out x.tif", ".exr, .npy", "x.tif"},
        {render + "--out x.exr --png x.jpg", "--png x.jpg", ".png", "x.exr"},
        {"heightfield --size 16 --out g.npy --quiet", "--out g.npy", ".exr", "g.npy"},
        {"heightfield --size 16 --out g.exr --png g.tif --quiet", "--png g.tif", ".png", "g.exr"},
        {"genbrdf -i h.exr -r 8 -o x.npy --quiet", "-o x.npy", ".exr", "x.npy"},
        {"table --heightfield h.exr --lights 2x2 --resolution 4 --out t.png --quiet", "--out t.png", ".exr", "t.png"},
        {"image --heightfield h.exr --plane-size-um 100 --camera 0,0,300 --resolution 4 --out i.png --quiet",
         "--out i.png", ".exr", "i.png"},
        {"image --heightfield h.exr --plane-size-um 100 --camera 0,0,300 --resolution 4 --png i.jpg --quiet",
         "--png i.jpg", ".png", "i.jpg"},
        {"lobe --lights 2x2 --resolution 4 --out l.npy --quiet", "--out l.npy", ".exr", "l.npy"},
        {"lobe --lights 2x2 --resolution 4 --out l.exr --png l.tif --quiet", "--png l.tif", ".png", "l.exr"},
        {"recover " + kSmallRobust + " --save-observations mine --out run", "--save-observations mine",
         ".json, .h5, .hdf5, .cxi", "run"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.args);
        expect_one_line_naming(run_cli(dir, c.args), {c.option, c.known});
        EXPECT_FALSE(fs::exists(dir / c.not_written));
        EXPECT_FALSE(fs::exists(dir / "g.png")) << "a refused heightfield wrote its preview";
    }
}

// The outputs of the measured-surface commands go through the same check: convert's OUT is one of
// the formats it writes (checked before the input is read), stats' CSV profiles end in .csv (a
// --psd p.png used to be CSV text under a PNG name).
TEST(RobustCliTest, SurfaceCommandOutputsWriteTheFormatTheirExtensionNames) {
    const fs::path dir = fresh_dir("robust_surface");
    ASSERT_EQ(run_cli(dir, "heightfield --size 16 --out h.exr --quiet").exit_code, 0);
    const CliResult npy = run_cli(dir, "convert h.exr c.NPY --quiet");
    ASSERT_EQ(npy.exit_code, 0) << npy.err;
    EXPECT_EQ(head(dir / "c.NPY", 6), kNpy);
    ASSERT_EQ(run_cli(dir, "convert h.exr c.x3p --quiet").exit_code, 0);
    EXPECT_EQ(head(dir / "c.x3p", 2), "PK");  // an x3p file is a zip archive
    const CliResult stats = run_cli(dir, "stats h.exr --psd p.csv --acf a.CSV --quiet");
    ASSERT_EQ(stats.exit_code, 0) << stats.err;
    EXPECT_EQ(head(dir / "p.csv", 9), "q_per_um,");
    EXPECT_EQ(head(dir / "a.CSV", 7), "lag_um,");

    struct Case {
        std::string args, option, known;
        fs::path not_written;
    };
    const std::vector<Case> cases{
        {"convert h.exr c.png --quiet", "OUT c.png", ".x3p, .sdf, .npy, .exr", "c.png"},
        // The name is checked before the input is read: the missing input is not what is reported.
        {"convert missing.x3p c.tif --quiet", "OUT c.tif", ".x3p, .sdf, .npy, .exr", "c.tif"},
        {"stats h.exr --psd p.png --quiet", "--psd p.png", ".csv", "p.png"},
        {"stats h.exr --psd p2.csv --acf a.json --quiet", "--acf a.json", ".csv", "p2.csv"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.args);
        expect_one_line_naming(run_cli(dir, c.args), {c.option, c.known});
        EXPECT_FALSE(fs::exists(dir / c.not_written));
    }
}

// recover --observations with a --size other than the surface they were made of is an error
// (it ran to a 100x worse loss with exit 0); the right size still runs.
TEST(RobustCliTest, RecoverSizeMustMatchTheObservations) {
    const fs::path dir = fresh_dir("robust");
    const std::string study = "--texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --no-plots --quiet";
    // Only its saved observations matter here: a short schedule (under the sanitizers the full one
    // took most of this test's 40 s).
    const CliResult made = run_cli(dir, "recover --size 16 " + study +
                                            " --field-iterations 3 --refine-iterations 2 --save-observations o.json --out made");
    ASSERT_EQ(made.exit_code, 0) << made.err;
    const std::string given = "--texel-um 2 --no-plots --quiet --observations o.json";
    expect_one_line_naming(run_cli(dir, "recover --size 8 " + given + " --out small"),
                           {"footprint centres span", "8x8", "--size", "period 16 um"});
    EXPECT_FALSE(fs::exists(dir / "small" / "metrics.csv"));
    // Larger than the surface: a band of the 32x32 tile (period 64 um) that no footprint reaches.
    expect_one_line_naming(run_cli(dir, "recover --size 32 " + given + " --out large"),
                           {"no observation's footprint", "32x32", "--size", "period 64 um"});
    EXPECT_FALSE(fs::exists(dir / "large" / "metrics.csv"));
    const CliResult right = run_cli(dir, "recover --size 16 " + given +
                                             " --field-iterations 3 --refine-iterations 2 "
                                             "--out right");
    EXPECT_EQ(right.exit_code, 0) << right.err;
}

// --force replaces a run of recover's own, whichever of its optional outputs it wrote
// (calibration.json with self-calibration, the uncertainty files): a directory after a run
// holds nothing the command calls foreign.
TEST(RobustCliTest, ForceReplacesARunWithEveryOptionalOutput) {
    const fs::path dir = fresh_dir("robust");
    const std::string fast = kSmallRobust + " --field-iterations 3 --refine-iterations 2";
    const CliResult first = run_cli(
        dir, "recover " + fast + " --simulate-exposure 0.8,1.25 --calibrate exposure --uncertainty --out c1");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    ASSERT_TRUE(fs::exists(dir / "c1" / "calibration.json"));
    EXPECT_EQ(foreign_files(RunKind::Recover, (dir / "c1").string()), std::vector<std::string>{});
    const CliResult forced = run_cli(dir, "recover " + fast + " --force --out c1");
    EXPECT_EQ(forced.exit_code, 0) << forced.err;
    EXPECT_FALSE(fs::exists(dir / "c1" / "calibration.json")) << "the old run's calibration survived --force";
}

// Every output is checked against every input and every other output before any work.
TEST(RobustCliTest, RecoverOutputsNeverOverwriteInputsOrEachOther) {
    const fs::path dir = fresh_dir("robust");
    ASSERT_EQ(run_cli(dir, "heightfield --size 8 --texel-um 2 --out t.exr --no-png --quiet").exit_code, 0);
    const std::string truth_before = read_text(dir / "t.exr");
    const CliResult saved = run_cli(dir, "recover " + kSmallRobust + " --save-observations in.h5 --out first");
    ASSERT_EQ(saved.exit_code, 0) << saved.err;
    const std::string input_before = read_text(dir / "in.h5");

    expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " --truth t.exr --save-observations t.exr --out a"),
                           {"--save-observations t.exr", ".json, .h5"});
    expect_one_line_naming(run_cli(dir,
                                   "recover --size 8 --texel-um 2 --no-plots --quiet --observations in.h5 "
                                   "--save-observations in.h5 --out b"),
                           {"--observations in.h5", "--save-observations in.h5", "name the same file"});
    expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " --save-observations c/run.json --out c"),
                           {"--save-observations c/run.json", "--out's run.json", "name the same file"});
    expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " --save-observations c/metrics.csv --out c"),
                           {"--save-observations c/metrics.csv", ".json, .h5"});
    expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " --truth first/truth.exr --force --out first"),
                           {"--truth first/truth.exr", "--out's truth.exr", "name the same file"});
    // An input inside --out that is no output of this run: --force would delete it first.
    ASSERT_EQ(run_cli(dir, "recover " + kSmallRobust + " --save-observations --out second").exit_code, 0);
    expect_one_line_naming(run_cli(dir,
                                   "recover --size 8 --texel-um 2 --no-plots --quiet --observations "
                                   "second/observations.json --force --out second"),
                           {"--observations second/observations.json is inside --out second", "--force"});
    EXPECT_TRUE(fs::exists(dir / "second" / "observations.json"));
    EXPECT_EQ(read_text(dir / "t.exr"), truth_before);
    EXPECT_EQ(read_text(dir / "in.h5"), input_before);
    EXPECT_TRUE(fs::exists(dir / "first" / "truth.exr"));
    for (const char* never : {"a", "b", "c"}) EXPECT_FALSE(fs::exists(dir / never)) << never;

    // A user's own folder named after the JSON is not written over.
    fs::create_directories(dir / "mine");
    std::ofstream(dir / "mine" / "notes.txt") << "mine";
    expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " --save-observations mine.json --out d"),
                           {"mine", "notes.txt", "not a slice of an observations set"});
    EXPECT_EQ(read_text(dir / "mine" / "notes.txt"), "mine");
    EXPECT_FALSE(fs::exists(dir / "mine.json"));
}

// The observation set (JSON and its slice folder) is replaced as a whole: a smaller set leaves
// no stale slices, and a write that fails midway leaves the earlier set whole.
TEST(RobustOutputsTest, ObservationSetIsReplacedAsAWhole) {
    const fs::path dir = fresh_dir("robust");
    const auto set_of = [](int count, float value) {
        std::vector<Observation> out;
        for (int i = 0; i < count; ++i) {
            Observation o;
            o.query.x_um = i;
            o.lambdas_um.assign(1, 0.5);
            o.resolution = 4;
            o.reference.assign(16, value + float(i));
            out.push_back(std::move(o));
        }
        return out;
    };
    const std::string path = (dir / "o.json").string();
    write_observations_file(path, set_of(4, 1.0f));
    write_observations_file(path, set_of(2, 7.0f));
    EXPECT_FALSE(fs::exists(dir / "o" / "slice_0002.exr")) << "a stale slice of the earlier set";
    EXPECT_FALSE(fs::exists(dir / "o" / "slice_0003.exr"));
    std::vector<Observation> bad = set_of(3, 9.0f);
    bad[2].reference.resize(5);  // the write fails at the third slice
    EXPECT_THROW(write_observations_file(path, bad), std::exception);
    const std::vector<Observation> read = read_observations_file(path);
    ASSERT_EQ(read.size(), 2u);
    EXPECT_EQ(read[1].reference, std::vector<float>(16, 8.0f)) << "the earlier set, whole";
    std::size_t entries = 0;
    for (const auto& e : fs::directory_iterator(dir)) entries += e.path().filename().string()[0] == '.';
    EXPECT_EQ(entries, 0u) << "a temporary folder was left behind";
}

// A run ended by a signal says so: one line on stderr, and run.json marks it unfinished; a
// run that ends normally marks it finished.
TEST(RobustCliTest, InterruptedRecoveryIsMarkedUnfinished) {
    const fs::path dir = fresh_dir("robust");
    const CliResult done = run_cli(dir, "recover " + kSmallRobust + " --field-iterations 3 --refine-iterations 2 --out done");
    ASSERT_EQ(done.exit_code, 0) << done.err;
    EXPECT_EQ(nlohmann::json::parse(read_text(dir / "done" / "run.json")).at("finished"), true);

    // run.json appears once the observations are simulated, early in the run (48²: after 6 s of a
    // 277 s run, Release build, busy machine; the sanitizers slow both); the loop waits up to 300 s.
    const std::string start = quote(WAVEBRDF_CLI) + " recover --size 48 --seed 2 --no-plots --quiet --out run";
    const CliResult r = run_in(dir, "{ " + start +
                                        " & pid=$!; n=0; while [ ! -f run/run.json ] && [ $n -lt 3000 ]; do sleep 0.1; "
                                        "n=$((n+1)); done; kill -TERM $pid; wait $pid; echo rc=$?; }");
    EXPECT_NE(r.out.find("rc=143"), std::string::npos) << r.out;  // 128 + SIGTERM: it did not finish first
    EXPECT_NE(r.err.find("wavebrdf: stopped by SIGTERM before the run finished"), std::string::npos) << r.err;
    ASSERT_TRUE(fs::exists(dir / "run" / "run.json"));
    EXPECT_EQ(nlohmann::json::parse(read_text(dir / "run" / "run.json")).at("finished"), false);
}

// Options are validated before any work, each named as the command line spells it.
TEST(RobustCliTest, RecoverValidatesCountsNumbersAndListsUpFront) {
    const fs::path dir = fresh_dir("robust");
    std::string many;
    for (int k = 0; k < 65; ++k) many += (k ? "," : "") + std::to_string(0.4 + 0.001 * k);
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases{
        {"--lambdas-um " + many, {"--lambdas-um lists 65 wavelengths", "at most 64"}},
        {"--refine-iterations -5", {"--refine-iterations -5 is invalid"}},
        {"--field-iterations -2", {"--field-iterations -2 is invalid"}},
        {"--refine-coarse-spacing nan", {"--refine-coarse-spacing", "is invalid"}},
        {"--refine-coarse-weight -3", {"--refine-coarse-weight -3 is invalid"}},
        {"--noise gaussian:1e300", {"gaussian:1e300", "0 to 100"}},
        {"--seed 18446744073709551616", {"seed 18446744073709551616 is invalid", "18446744073709551615"}},
    };
    for (const auto& [args, needles] : cases) {
        SCOPED_TRACE(args);
        expect_one_line_naming(run_cli(dir, "recover " + kSmallRobust + " " + args + " --out run"), needles);
        EXPECT_FALSE(fs::exists(dir / "run"));
    }
    expect_one_line_naming(run_cli(dir, "heightfield --size 8 --seed 99999999999999999999 --out h.exr"),
                           {"seed 99999999999999999999 is invalid"});
}

// Without --snapshots, an inversion's snapshots spread over its --epochs (the report of a
// 1000-epoch run showed epochs up to 300 only).
TEST(RobustCliTest, InvertSnapshotsFollowTheRunsLength) {
    const fs::path dir = fresh_dir("robust");
    const CliResult r = run_cli(
        dir, "invert --size 8 --sigma-p-um 2 --resolution 8 --epochs 600 --no-plots --quiet --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto run = nlohmann::json::parse(read_text(dir / "run" / "run.json"));
    EXPECT_EQ(run.at("snapshot_epochs").get<std::vector<int>>(), (std::vector<int>{0, 20, 60, 200, 600}));
    for (int e : {0, 20, 60, 200, 600}) {
        char name[32];
        std::snprintf(name, sizeof name, "height_%04d.npy", e);
        EXPECT_TRUE(fs::exists(dir / "run" / "snapshots" / name)) << name;
    }
}

// A misspelt command or option gets the nearest name; model names take any case.
TEST(RobustCliTest, MisspeltNamesGetASuggestion) {
    const fs::path dir = fresh_dir("robust");
    expect_one_line_naming(run_cli(dir, "rendr --heightfield h.exr"), {"rendr", "did you mean render?"});
    expect_one_line_naming(run_cli(dir, "render --heightfield h.exr --sigma-p 3 --out s.exr"),
                           {"--sigma-p", "did you mean --sigma-p-um?"});
    expect_one_line_naming(run_cli(dir, "heightfield --sise 8 --out h.exr"), {"did you mean --size?"});
    ASSERT_EQ(run_cli(dir, "heightfield --size 8 --out h.exr --quiet").exit_code, 0);
    const CliResult lower = run_cli(dir, "render --heightfield h.exr --resolution 8 --model ghs --out s.exr --quiet");
    EXPECT_EQ(lower.exit_code, 0) << lower.err;
}
