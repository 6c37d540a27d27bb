// Ranks that disagree (mpiexec's MPMD form: `mpiexec -n 1 A : -n 1 B`): a rank that fails
// alone stops every rank with one message, and ranks given different options or files refuse
// to run instead of giving a wrong answer with exit 0 or aborting in MPI (MPI_ERR_TRUNCATE).
// Every run is under `timeout 120`, so a hang fails the test instead of stopping the suite.
// Compiled only when the library is built with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

const std::vector<std::string> kSmallArgs = {"--texel-um",          "2",   "--sigma-p-um",       "3",
                                         "--height-range-um",   "0.1", "--field-iterations", "3",
                                         "--refine-iterations", "2",   "--no-plots",         "--quiet"};

// Rank 0 runs `wavebrdf recover first…`, rank 1 `wavebrdf recover second…`, both with --out run
// (and kSmallArgs's options when `small`).
CliResult run_two(const fs::path& dir, const std::vector<std::string>& first, const std::vector<std::string>& second,
                  bool small = true) {
    std::vector<std::string> argv{"/usr/bin/timeout", "120", WAVEBRDF_MPIEXEC, "-q", "--oversubscribe",
                                  "--bind-to",        "none"};
    for (const auto* part : {&first, &second}) {
        if (part == &second) argv.emplace_back(":");
        argv.insert(argv.end(), {"-n", "1", WAVEBRDF_CLI, "recover"});
        argv.insert(argv.end(), part->begin(), part->end());
        if (small) argv.insert(argv.end(), kSmallArgs.begin(), kSmallArgs.end());
        argv.insert(argv.end(), {"--out", "run"});
    }
    return spawn_in(dir, argv, mpi_environment(1));
}

void expect_one_error(const CliResult& r, const std::string& needle) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.exit_code, 124) << "the ranks hung (timeout)";
    EXPECT_EQ(r.err.find("MPI_ERR"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

TEST(MpiRobust, RanksGivenDifferentOptionsRefuseToRun) {
    const fs::path dir = fresh_dir("mpi_robust");
    expect_one_error(run_two(dir, {"--size", "8", "--seed", "1"}, {"--size", "8", "--seed", "2"}),
                     "the ranks were given different options or inputs");
    expect_one_error(run_two(dir, {"--size", "8"}, {"--size", "12"}), "the ranks were given different");
    expect_one_error(run_two(dir, {"--size", "8", "--model", "OHS"}, {"--size", "8", "--model", "GHS"}),
                     "the ranks were given different");
    // The same job on both: it runs.
    const CliResult same = run_two(dir, {"--size", "8"}, {"--size", "8"});
    EXPECT_EQ(same.exit_code, 0) << same.err;
}

TEST(MpiRobust, OneRankThatCannotReadItsInputStopsEveryRank) {
    const fs::path dir = fresh_dir("mpi_robust");
    const CliResult saved = spawn_in(dir,
                                     {WAVEBRDF_CLI,
                                      "recover",
                                      "--size",
                                      "8",
                                      "--texel-um",
                                      "2",
                                      "--sigma-p-um",
                                      "3",
                                      "--height-range-um",
                                      "0.1",
                                      "--field-iterations",
                                      "3",
                                      "--refine-iterations",
                                      "2",
                                      "--no-plots",
                                      "--quiet",
                                      "--save-observations",
                                      "o.json",
                                      "--out",
                                      "made"},
                                     mpi_environment(1));
    ASSERT_EQ(saved.exit_code, 0) << saved.err;
    const std::vector<std::string> given{"--size", "8", "--texel-um", "2", "--no-plots", "--quiet", "--observations"};
    std::vector<std::string> good = given, bad = given;
    good.emplace_back("o.json");
    bad.emplace_back("nope.h5");
    expect_one_error(run_two(dir, good, bad, false), "nope.h5");
}

}  // namespace
}  // namespace wavebrdf::test

#endif
