// invert and table under MPI when the ranks disagree or one fails alone, and a run ended by
// SIGTERM: every rank stops with one message instead of hanging, and ranks given different jobs
// (mpiexec's MPMD form: `mpiexec -n 1 A : -n 1 B`) refuse to run instead of mixing their shares.
// Every run is under `timeout 120`, so a hang fails the test instead of stopping the suite.
// Compiled only when the library is built with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

// Rank 0 runs `wavebrdf first…`, rank 1 `wavebrdf second…` (each list starts with the command).
CliResult run_two_ranks(const fs::path& dir, const std::vector<std::string>& first, const std::vector<std::string>& second) {
    std::vector<std::string> argv{"/usr/bin/timeout", "120", WAVEBRDF_MPIEXEC, "-q", "--oversubscribe",
                                  "--bind-to",        "none"};
    bool later = false;  // first and second may be the same vector
    for (const auto* part : {&first, &second}) {
        if (later) argv.emplace_back(":");
        later = true;
        argv.insert(argv.end(), {"-n", "1", WAVEBRDF_CLI});
        argv.insert(argv.end(), part->begin(), part->end());
    }
    return spawn_in(dir, argv, mpi_environment(1));
}

void expect_one_error_line(const CliResult& r, const std::string& needle) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.exit_code, 124) << "the ranks hung (timeout)";
    EXPECT_EQ(r.err.find("MPI_ERR"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    // mpiexec ends the other rank once one has failed; when its SIGTERM arrives before that rank's
    // own exit, the rank says it was stopped. That line may follow, and no other.
    std::vector<std::string> lines = lines_of(r.err);
    lines.erase(std::remove_if(lines.begin(), lines.end(),
                               [](const std::string& l) { return l.find("stopped by SIGTERM") != std::string::npos; }),
                lines.end());
    EXPECT_EQ(lines.size(), 1u) << r.err;
}

std::vector<std::string> with_args(std::vector<std::string> base, const std::vector<std::string>& extra) {
    base.insert(base.end(), extra.begin(), extra.end());
    return base;
}

const std::vector<std::string> kInvert = {"invert",     "--size",  "8",          "--sigma-p-um", "2",
                                          "--resolution", "8",     "--epochs",   "3",            "--no-plots",
                                          "--quiet",    "--out",   "run"};

TEST(MpiTraps, InvertRanksGivenDifferentOptionsOrInputsRefuseToRun) {
    const fs::path dir = fresh_dir("mpi_traps");
    expect_one_error_line(run_two_ranks(dir, with_args(kInvert, {"--seed", "1"}), with_args(kInvert, {"--seed", "2"})),
                     "the ranks were given different options or inputs");
    expect_one_error_line(run_two_ranks(dir, with_args(kInvert, {"--lr", "0.01"}), with_args(kInvert, {"--lr", "0.02"})),
                     "the ranks were given different options or inputs");
    EXPECT_FALSE(fs::exists(dir / "run" / "metrics.csv"));
    // The same job on both: it runs.
    const CliResult same = run_two_ranks(dir, kInvert, kInvert);
    EXPECT_EQ(same.exit_code, 0) << same.err << same.out;
}

TEST(MpiTraps, TableRanksGivenDifferentSurfacesRefuseToRun) {
    const fs::path dir = fresh_dir("mpi_traps");
    for (const char* seed : {"1", "2"})
        ASSERT_EQ(run_cli(dir, std::string("heightfield --size 16 --seed ") + seed + " --out h" + seed +
                                   ".exr --no-png --quiet")
                      .exit_code,
                  0);
    const std::vector<std::string> table = {"table",      "--sigma-p-um", "3",   "--lights", "3x3", "--resolution",
                                            "8",          "--quiet",      "--out", "t.exr",   "--heightfield"};
    expect_one_error_line(run_two_ranks(dir, with_args(table, {"h1.exr"}), with_args(table, {"h2.exr"})),
                     "the ranks were given different slices to render");
    EXPECT_FALSE(fs::exists(dir / "t.exr"));
    const CliResult same = run_two_ranks(dir, with_args(table, {"h1.exr"}), with_args(table, {"h1.exr"}));
    EXPECT_EQ(same.exit_code, 0) << same.err << same.out;
}

// A failure on one rank alone (its file, its memory limit) ends every rank with one message.
TEST(MpiTraps, OneRankThatFailsAloneStopsEveryRank) {
    const fs::path dir = fresh_dir("mpi_traps");
    ASSERT_EQ(run_cli(dir, "heightfield --size 16 --out h.exr --no-png --quiet").exit_code, 0);
    const std::vector<std::string> table = {"table", "--heightfield", "h.exr", "--sigma-p-um", "3",     "--lights",
                                            "3x3",   "--resolution",  "8",     "--quiet",      "--out", "t.exr"};
    expect_one_error_line(run_two_ranks(dir, table, with_args(table, {"--max-memory-gb", "1e-6"})), "--max-memory-gb");
    EXPECT_FALSE(fs::exists(dir / "t.exr"));
    const std::vector<std::string> given = {"invert", "--size",    "8",       "--epochs", "3", "--no-plots",
                                            "--quiet", "--out",    "given",   "--observations"};
    ASSERT_EQ(run_cli(dir, "recover --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 "
                           "--field-iterations 3 --refine-iterations 2 --no-plots --quiet --save-observations o.json "
                           "--out made")
                  .exit_code,
              0);
    expect_one_error_line(run_two_ranks(dir, with_args(given, {"o.json"}), with_args(given, {"nope.json"})), "nope.json");
    EXPECT_FALSE(fs::exists(dir / "given" / "metrics.csv"));
}

// `wavebrdf ARGS` on two ranks under mpiexec; once `wait_for` exists, SIGTERM to both ranks (the
// processes mpiexec started, as a batch scheduler's time limit sends it to every process).
CliResult terminated_on_two_ranks(const fs::path& dir, const std::string& args, const std::string& wait_for) {
    std::string env;
    for (const std::string& e : mpi_environment(1))
        if (e.rfind("OMPI_", 0) == 0 || e.rfind("OMP_", 0) == 0) env += e + " ";
    const std::string start = env + "/usr/bin/timeout 120 " + quote(WAVEBRDF_MPIEXEC) +
                              " -q -n 2 --oversubscribe --bind-to none " + quote(WAVEBRDF_CLI) + " " + args;
    // $pid is timeout's; its child is mpiexec, whose children are the ranks.
    return run_in(dir, "{ " + start + " & pid=$!; n=0; while [ ! -f " + wait_for +
                           " ] && [ $n -lt 1000 ]; do sleep 0.1; n=$((n+1)); done; "
                           "for m in $(pgrep -P $pid); do for r in $(pgrep -P $m); do kill -TERM $r; done; done; "
                           "wait $pid; echo rc=$?; }");
}

// SIGTERM to every rank (a scheduler's time limit): every rank stops, the run says why on
// stderr, and run.json says it did not finish: invert at its next epoch (with a checkpoint),
// recover at once. (SIGTERM to mpiexec alone is forwarded too, but Open MPI may stop relaying
// the ranks' output meanwhile: their line can be lost, so it is not what this test sends.)
TEST(MpiTraps, SigtermStopsEveryRankWithAMessage) {
    const fs::path dir = fresh_dir("mpi_traps");
    for (const auto& [args, needle] : std::vector<std::pair<std::string, std::string>>{
             {"invert --size 8 --sigma-p-um 2 --resolution 8 --epochs 10000000 --no-plots --quiet "
              "--checkpoint-every 5 --out run",
              "by SIGTERM; checkpoint written"},
             // 48²: run.json (the signal's cue) comes after seconds, the run itself takes minutes.
             {"recover --size 48 --seed 2 --no-plots --quiet --out run",
              "stopped by SIGTERM before the run finished"}}) {
        SCOPED_TRACE(args);
        fs::remove_all(dir / "run");
        const CliResult r =
            terminated_on_two_ranks(dir, args, args.rfind("invert", 0) == 0 ? "run/checkpoint.json" : "run/run.json");
        EXPECT_EQ(r.out.find("rc=0"), std::string::npos) << r.out;
        EXPECT_EQ(r.out.find("rc=124"), std::string::npos) << "the ranks hung: " << r.err;
        EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err << " stdout: " << r.out;
        ASSERT_TRUE(fs::exists(dir / "run" / "run.json"));
        EXPECT_EQ(nlohmann::json::parse(read_text(dir / "run" / "run.json")).at("finished"), false);
    }
}

}  // namespace
}  // namespace wavebrdf::test

#endif
