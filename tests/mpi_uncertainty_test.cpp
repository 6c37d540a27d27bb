// Error bars under MPI (uncertainty.h): `wavebrdf recover --uncertainty` on K ranks writes the
// one-process uncertainty map bit for bit (every sum over observations exact and allreduced).
// Compiled only when the library is built with MPI.
#ifdef WAVEBRDF_HAS_MPI

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "cli_util.h"

namespace wavebrdf::test {
namespace {

// The child's environment: ours, plus what running OpenMPI as root here needs, `threads` threads
// per rank (1: ranks are oversubscribed on 2 cores) and no leak check (OpenMPI's init leaks by
// design).
std::vector<std::string> mpi_environment(int threads) {
    std::vector<std::string> env;
    for (char** e = environ; *e != nullptr; ++e) {
        const std::string entry(*e);
        if (entry.rfind("OMP_NUM_THREADS=", 0) == 0 || entry.rfind("ASAN_OPTIONS=", 0) == 0) continue;
        env.push_back(entry);
    }
    for (const char* extra : {"OMPI_ALLOW_RUN_AS_ROOT=1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1",
                              "ASAN_OPTIONS=detect_leaks=0", "OMPI_MCA_rmaps_base_oversubscribe=1"})
        env.emplace_back(extra);
    env.push_back("OMP_NUM_THREADS=" + std::to_string(threads));
    return env;
}

// Runs `argv` (argv[0] a path) in `dir` without a shell, stdout and stderr captured.
CliResult spawn(const fs::path& dir, std::vector<std::string> argv, int threads = 1) {
    const fs::path out = dir / "spawn.out", err = dir / "spawn.err";
    std::vector<std::string> env = mpi_environment(threads);
    std::vector<char*> args, envp;
    for (std::string& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    for (std::string& e : env) envp.push_back(e.data());
    envp.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int in = ::open("/dev/null", O_RDONLY);
        const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (in < 0 || o < 0 || e < 0 || ::chdir(dir.c_str()) != 0) std::_Exit(127);
        ::dup2(in, 0);
        ::dup2(o, 1);
        ::dup2(e, 2);
        ::execve(args[0], args.data(), envp.data());
        std::_Exit(127);
    }
    CliResult r;
    int status = 0;
    if (pid > 0 && ::waitpid(pid, &status, 0) == pid && WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
    r.out = read_text(out);
    r.err = read_text(err);
    return r;
}

// `wavebrdf args` on `ranks` ranks (0: without mpiexec) in `dir`, `threads` threads each.
CliResult run_ranks(const fs::path& dir, int ranks, const std::vector<std::string>& args, int threads = 1) {
    std::vector<std::string> argv;
    if (ranks > 0) argv = {WAVEBRDF_MPIEXEC, "-q", "-n", std::to_string(ranks), "--oversubscribe", "--bind-to", "none"};
    argv.emplace_back(WAVEBRDF_CLI);
    argv.insert(argv.end(), args.begin(), args.end());
    return spawn(dir, argv, threads);
}

// The float64 values of a .npy file written by the library (little-endian '<f8', C order).
std::vector<double> read_npy(const fs::path& path) {
    const std::string bytes = read_text(path);
    if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) return {};
    const std::size_t header = std::size_t(std::uint8_t(bytes[8])) | std::size_t(std::uint8_t(bytes[9])) << 8;
    const std::size_t start = 10 + header;
    std::vector<double> values((bytes.size() - start) / sizeof(double));
    std::memcpy(values.data(), bytes.data() + start, values.size() * sizeof(double));
    return values;
}

TEST(MpiUncertainty, ShardedErrorBarsAreTheOneProcessMap) {
    const fs::path dir = fresh_dir("mpi_uncertainty");
    const auto args = [](const std::string& out) {
        return std::vector<std::string>{"recover",     "--size",
                                        "12",          "--seed",
                                        "5305",        "--lambdas-um",
                                        "0.6",         "--height-range-um",
                                        "0.2",         "--field-iterations",
                                        "10",          "--refine-iterations",
                                        "5",           "--noise",
                                        "poisson:1e4", "--uncertainty",
                                        "--no-plots",  "--quiet",
                                        "--out",       out};
    };
    const CliResult one = run_ranks(dir, 0, args("one"));
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const std::vector<double> reference = read_npy(dir / "one" / "uncertainty_height.npy");
    ASSERT_EQ(reference.size(), 144u);
    for (double s : reference) EXPECT_GT(s, 0.0);
    EXPECT_NE(read_text(dir / "one" / "uncertainty.json").find("coverage_2sigma"), std::string::npos);
    const CliResult two = run_ranks(dir, 2, args("two"));
    ASSERT_EQ(two.exit_code, 0) << two.err;
    EXPECT_EQ(read_npy(dir / "two" / "uncertainty_height.npy"), reference);
    EXPECT_EQ(read_npy(dir / "two" / "estimate_height.npy"), read_npy(dir / "one" / "estimate_height.npy"));
}

}  // namespace
}  // namespace wavebrdf::test

#endif  // WAVEBRDF_HAS_MPI
