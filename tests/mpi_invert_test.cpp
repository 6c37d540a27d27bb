// `mpiexec -n K wavebrdf invert` and `wavebrdf table` split over ranks (inversion_run.h,
// table.h, docs/scale.md): the K-rank runs against the one-process run of the same options,
// started here with an argument vector (no shell), K = 2 and 3 (oversubscribed on two cores):
// the same heights bit for bit (exact sums over observations) and the same table file.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/observation.h"

namespace {

namespace fs = std::filesystem;
using wavebrdf::test::fresh_dir;
using wavebrdf::test::read_text;

using Ran = wavebrdf::test::CliResult;

// `wavebrdf args…` on `ranks` ranks (1: the executable alone, without mpiexec).
Ran wavebrdf_on(int ranks, const fs::path& dir, const std::vector<std::string>& args) {
    return wavebrdf::test::run_cli_on_ranks(dir, ranks, args);
}

std::vector<double> checkpoint_heights(const fs::path& run) {
    return nlohmann::json::parse(read_text(run / "checkpoint.json")).at("heights").get<std::vector<double>>();
}

// max |a − b| / max |a|.
double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
    EXPECT_EQ(a.size(), b.size());
    double diff = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        diff = std::max(diff, std::fabs(a[i] - b[i]));
        scale = std::max(scale, std::fabs(a[i]));
    }
    return diff / scale;
}

std::set<std::string> files_under(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& entry : fs::recursive_directory_iterator(dir))
        names.insert(fs::relative(entry.path(), dir).string());
    return names;
}

std::size_t count_of(const std::string& text, const std::string& needle) {
    std::size_t n = 0;
    for (auto at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
    return n;
}

// Five footprints on a 12² tile, three wavelengths, 12² slices: a few hundred ms per epoch set.
std::vector<std::string> tiny_inversion(const fs::path& dir) {
    const std::string positions = (dir / "positions.json").string();
    std::ofstream(positions) << "[[3, 3], [9, 4], [5, 11], [12, 12], [7, 7]]\n";
    return {"invert",       "--size", "12",          "--resolution", "12",         "--spectral",  "3",
            "--sigma-p-um", "2",      "--positions", positions,      "--no-plots", "--snapshots", "0,3"};
}

std::vector<std::string> with(std::vector<std::string> args, const std::vector<std::string>& more) {
    args.insert(args.end(), more.begin(), more.end());
    return args;
}

TEST(MpiInvertTest, TwoAndThreeRanksEqualTheOneProcessRun) {
    const fs::path dir = fresh_dir("mpi_invert");
    const auto args = with(tiny_inversion(dir), {"--epochs", "6", "--checkpoint-every", "2"});
    ASSERT_EQ(wavebrdf_on(1, dir, with(args, {"--quiet", "--out", "one"})).exit_code, 0);
    const std::vector<double> one = checkpoint_heights(dir / "one");
    // One process on two threads: the same bits (the sums over observations are exact and
    // order-independent, core/exact_sum.h).
    ASSERT_EQ(wavebrdf::test::run_cli_on_ranks(dir, 1, with(args, {"--quiet", "--out", "one_t2"}), 2).exit_code, 0);
    EXPECT_EQ(checkpoint_heights(dir / "one_t2"), one) << "1 process, 2 threads";
    for (int ranks : {2, 3}) {
        const std::string out = "k" + std::to_string(ranks);
        // Not --quiet: the summary line comes from rank 0 alone.
        const Ran r = wavebrdf_on(ranks, dir, with(args, {"--out", out}));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_EQ(count_of(r.err, "results in"), 1u) << r.err;
        // The one-process heights bit for bit (the bound is 1e-9).
        EXPECT_EQ(checkpoint_heights(dir / out), one)
            << ranks << " ranks; max relative difference " << relative_difference(one, checkpoint_heights(dir / out));
        // Rank 0 writes everything the one-process run writes, and nothing else (no second
        // writer's leftovers); the references and the checkpoint's fingerprint are the same.
        EXPECT_EQ(files_under(dir / "one"), files_under(dir / out));
        for (const char* file : {"reference_000.exr", "reference_004.exr", "reference.npy", "truth_height.npy"})
            EXPECT_EQ(read_text(dir / "one" / file), read_text(dir / out / file)) << file;
        EXPECT_EQ(nlohmann::json::parse(read_text(dir / "one" / "checkpoint.json")).at("fingerprint"),
                  nlohmann::json::parse(read_text(dir / out / "checkpoint.json")).at("fingerprint"));
        EXPECT_EQ(nlohmann::json::parse(read_text(dir / out / "run.json")).at("observations"), 5);
    }
    fs::remove_all(dir);
}

TEST(MpiInvertTest, LbfgsAndACheckpointResumedOnOtherRanksEqualTheOneProcessRun) {
    const fs::path dir = fresh_dir("mpi_invert");
    const auto args = with(tiny_inversion(dir), {"--optimizer", "lbfgs", "--quiet"});
    ASSERT_EQ(wavebrdf_on(1, dir, with(args, {"--epochs", "4", "--out", "one"})).exit_code, 0);
    // Two ranks to epoch 2, then three ranks on from its checkpoint to epoch 4.
    Ran r = wavebrdf_on(2, dir, with(args, {"--epochs", "2", "--out", "k"}));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = wavebrdf_on(3, dir, {"invert", "--resume", "k", "--epochs", "4", "--quiet", "--no-plots"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(checkpoint_heights(dir / "k"), checkpoint_heights(dir / "one"))
        << relative_difference(checkpoint_heights(dir / "one"), checkpoint_heights(dir / "k"));
    fs::remove_all(dir);
}

TEST(MpiInvertTest, RandomObservationsPerEpochAreTheSameGlobalChoice) {
    // Given observations (read whole, each rank keeping its share) and one drawn per epoch: every
    // rank draws the same and only its owner evaluates it.
    const fs::path dir = fresh_dir("mpi_invert");
    const wavebrdf::Heightfield truth = wavebrdf::default_inversion_truth(12, 12, 1.0, 1.0, 3);
    wavebrdf::Observation base;
    base.query.sigma_p_um = 2.0;
    base.lambdas_um = {0.45, 0.55, 0.65};
    base.resolution = 12;
    const auto observations = wavebrdf::observe(truth, base, {{{2, 2}}, {{9, 3}}, {{4, 10}}, {{11, 11}}});
    wavebrdf::write_observations_json((dir / "observations.json").string(), observations);
    const std::vector<std::string> args = {
        "invert", "--observations", "observations.json", "--size",      "12", "--positions", "random", "--epochs",
        "8",      "--quiet",        "--no-plots",        "--snapshots", "0"};
    ASSERT_EQ(wavebrdf_on(1, dir, with(args, {"--out", "one"})).exit_code, 0);
    const Ran r = wavebrdf_on(2, dir, with(args, {"--out", "k"}));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(checkpoint_heights(dir / "k"), checkpoint_heights(dir / "one"))
        << relative_difference(checkpoint_heights(dir / "one"), checkpoint_heights(dir / "k"));
    EXPECT_GT(relative_difference(checkpoint_heights(dir / "one"), std::vector<double>(144, 0.0)), 0.0);
    fs::remove_all(dir);
}

TEST(MpiInvertTest, ABadOptionFailsEveryRankWithOneMessage) {
    const fs::path dir = fresh_dir("mpi_invert");
    for (const std::vector<std::string>& bad :
         {std::vector<std::string>{"invert", "--epochs", "-3", "--out", "x"},       // the library's check
          std::vector<std::string>{"invert", "--no-such-option", "--out", "x"}}) {  // CLI11's
        const Ran r = wavebrdf_on(2, dir, bad);
        EXPECT_NE(r.exit_code, 0);
        EXPECT_EQ(count_of(r.err, "wavebrdf: error"), 1u) << r.err;
    }
    EXPECT_FALSE(fs::exists(dir / "x"));
    fs::remove_all(dir);
}

TEST(MpiTableTest, RanksWriteTheOneProcessTableBitForBit) {
    // Each light's slice does not depend on which others are rendered with it: the table of K
    // ranks (rendered lights split in blocks, gathered by rank 0) is the same file.
    const fs::path dir = fresh_dir("mpi_table");
    ASSERT_EQ(wavebrdf_on(1, dir, {"heightfield", "--size", "16", "--no-png", "--quiet", "--out", "h.exr"}).exit_code,
              0);
    const std::vector<std::string> args = {"table", "--heightfield", "h.exr", "--x-um",   "7",   "--y-um",
                                           "9",     "--sigma-p-um",  "3",     "--lights", "5x4", "--resolution",
                                           "12",    "--spectral",    "3"};
    for (const char* precision : {"float", "double"}) {
        const std::string one = std::string("one_") + precision + ".exr";
        ASSERT_EQ(wavebrdf_on(1, dir, with(args, {"--precision", precision, "--quiet", "--out", one})).exit_code, 0);
        const int ranks = std::string(precision) == "float" ? 2 : 3;
        const std::string many = std::string("many_") + precision + ".exr";
        const Ran r = wavebrdf_on(ranks, dir, with(args, {"--precision", precision, "--out", many}));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_EQ(count_of(r.err, "rendered 5x4 lights"), 1u) << r.err;  // rank 0's summary only
        const std::string expected = read_text(dir / one);
        EXPECT_GT(expected.size(), 1000u);
        EXPECT_TRUE(expected == read_text(dir / many)) << precision << " on " << ranks << " ranks";
    }
    const Ran bad = wavebrdf_on(2, dir, with(args, {"--lights", "0x4", "--out", "bad.exr"}));
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_EQ(count_of(bad.err, "wavebrdf: error"), 1u) << bad.err;
    fs::remove_all(dir);
}

}  // namespace

#endif  // WAVEBRDF_HAS_MPI
