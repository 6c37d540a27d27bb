// The output-directory rule of invert and recover (run_directory.h): which names are a run's
// own (temporary files included), a non-empty directory refused without force, force deleting
// only own outputs, and foreign files (or a FIFO or directory link under an own name) refusing
// even with force.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/run_directory.h"

using namespace wavebrdf;
using namespace wavebrdf::test;

TEST(RunDirectoryTest, OwnNames) {
    for (const char* name :
         {"run.json", "metrics.csv", "checkpoint.json", "checkpoint.json.tmp", "metrics.csv.tmp-1234", "report.png",
          "curves.png", ".report.png.ab12_x.tmp", "reference_000.exr", "final_1234.png", "snapshots",
          "snapshots/height_0010.npy", "snapshots/gradient_10000.npy", "estimate.exr", "truth.exr", "truth_height.npy"})
        EXPECT_TRUE(is_run_output(RunKind::Invert, name)) << name;
    for (const char* name : {"notes.txt", "run.json.bak", "reference_0.exr", "snapshots/notes.txt", "snapshots/x/y",
                             "observations.json", "final.npy", "sub/run.json"})
        EXPECT_FALSE(is_run_output(RunKind::Invert, name)) << name;
    for (const char* name : {"run.json", "final.npy", "report.png.tmp.png", "estimate_height.npy", "observations",
                             "observations/slice_0003.exr", "observations.json"})
        EXPECT_TRUE(is_run_output(RunKind::Recover, name)) << name;
    for (const char* name : {"checkpoint.json", "snapshots", "observations/notes.txt", "final_000.exr"})
        EXPECT_FALSE(is_run_output(RunKind::Recover, name)) << name;
}

TEST(RunDirectoryTest, ForceDeletesOnlyOwnOutputs) {
    const fs::path dir = fresh_dir("run_directory");
    const std::string run = (dir / "run").string();
    EXPECT_NO_THROW(check_run_directory(RunKind::Invert, run, false)) << "a new directory";
    prepare_run_directory(RunKind::Invert, run, false);
    EXPECT_TRUE(fs::is_directory(run));
    EXPECT_NO_THROW(check_run_directory(RunKind::Invert, run, false)) << "an empty directory";

    fs::create_directories(dir / "run" / "snapshots");
    std::ofstream(dir / "run" / "run.json") << "{}";
    std::ofstream(dir / "run" / "snapshots" / "height_0010.npy") << "x";
    expect_throw_naming<std::invalid_argument>([&] { check_run_directory(RunKind::Invert, run, false); }, "--force");
    expect_throw_naming<std::invalid_argument>([&] { check_run_directory(RunKind::Recover, run, true); },
                                               "'snapshots'");
    prepare_run_directory(RunKind::Invert, run, true);
    EXPECT_TRUE(fs::is_directory(run));
    EXPECT_TRUE(fs::is_empty(run));

    std::ofstream(dir / "run" / "run.json") << "{}";
    fs::create_directories(dir / "run" / "snapshots");
    std::ofstream(dir / "run" / "snapshots" / "mine.txt") << "x";
    expect_throw_naming<std::invalid_argument>([&] { prepare_run_directory(RunKind::Invert, run, true); },
                                               "snapshots/mine.txt");
    EXPECT_TRUE(fs::exists(dir / "run" / "run.json"));
    fs::remove(dir / "run" / "snapshots" / "mine.txt");

    // A FIFO under an own name, and a link to a directory as snapshots/, are not the run's.
    ASSERT_EQ(::mkfifo((dir / "run" / "metrics.csv").c_str(), 0600), 0);
    expect_throw_naming<std::invalid_argument>([&] { check_run_directory(RunKind::Invert, run, true); }, "metrics.csv");
    fs::remove(dir / "run" / "metrics.csv");
    fs::remove(dir / "run" / "snapshots");
    fs::create_directory(dir / "elsewhere");
    std::ofstream(dir / "elsewhere" / "height_0000.npy") << "keep";
    fs::create_directory_symlink(dir / "elsewhere", dir / "run" / "snapshots");
    expect_throw_naming<std::invalid_argument>([&] { prepare_run_directory(RunKind::Invert, run, true); }, "snapshots");
    EXPECT_TRUE(fs::exists(dir / "elsewhere" / "height_0000.npy"));

    std::ofstream(dir / "file") << "x";
    expect_throw_naming<std::invalid_argument>(
        [&] { check_run_directory(RunKind::Invert, (dir / "file").string(), true); }, "not a directory");
    fs::remove_all(dir);
}
