#pragma once
// Helpers shared by the end-to-end tests of the `wavebrdf` executable (cli_test.cpp,
// invert_test.cpp): running it with stdout and stderr captured, per-test scratch directories,
// and the check every bad input must pass.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace wavebrdf::test {

namespace fs = std::filesystem;

struct CliResult {
    int exit_code = -1;  // the process's exit status; -1 when it did not exit normally
    std::string out;     // stdout
    std::string err;     // stderr
};

inline std::string read_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Single-quoted for /bin/sh (an embedded ' becomes '\'').
inline std::string quote(const std::string& text) {
    std::string q = "'";
    for (char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

// Text without its trailing newlines, split into lines.
inline std::vector<std::string> lines_of(std::string text) {
    while (!text.empty() && text.back() == '\n') text.pop_back();
    std::vector<std::string> lines;
    if (text.empty()) return lines;
    std::size_t start = 0;
    for (;;) {
        const std::size_t end = text.find('\n', start);
        lines.push_back(text.substr(start, end - start));
        if (end == std::string::npos) return lines;
        start = end + 1;
    }
}

// The lines of a short test recovery's stderr but its convergence warning: a recovery of a few
// epochs or iterations does not converge and says so (convergence.h), which is not what such a
// test checks.
inline std::vector<std::string> lines_but_convergence_warning(const std::string& err) {
    std::vector<std::string> kept;
    for (std::string& line : lines_of(err))
        if (line.rfind("wavebrdf: warning: the recovery did not converge", 0) != 0) kept.push_back(std::move(line));
    return kept;
}

// A fresh directory per test under WAVEBRDF_TEST_TMP/group (named after the test and the
// process, since ctest may run tests in parallel), so leftovers of one test cannot satisfy
// another's checks.
inline fs::path fresh_dir(const std::string& group) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path dir = fs::path(WAVEBRDF_TEST_TMP) / group /
                         (std::string(info->name()) + "-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

// Runs the shell command `command` (the tests' own text; quote paths with quote()) in `dir`,
// stdout and stderr to files (so stderr is not a terminal, as in a script), stdin from /dev/null.
inline CliResult run_in(const fs::path& dir, const std::string& command) {
    const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
    const std::string line = "cd " + quote(dir.string()) + " && " + command + " > " + quote(out.string()) + " 2> " +
                             quote(err.string()) + " < /dev/null";
    const int status = std::system(line.c_str());
    CliResult r;
    r.exit_code = status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = read_text(out);
    r.err = read_text(err);
    fs::remove(out);
    fs::remove(err);
    return r;
}

// Runs `wavebrdf args` in `dir` as run_in does.
inline CliResult run_cli(const fs::path& dir, const std::string& args) {
    return run_in(dir, quote(WAVEBRDF_CLI) + " " + args);
}

// A failed run: non-zero exit (not a crash) and exactly one line on stderr (a trailing newline
// aside) that contains every one of `needles`. Returns false when the line count is wrong.
inline bool expect_one_line_naming(const CliResult& r, const std::vector<std::string>& needles) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.exit_code, -1) << "did not exit normally (crashed?)";
    const std::vector<std::string> lines = lines_of(r.err);
    EXPECT_EQ(lines.size(), 1u) << "stderr:\n" << r.err;
    if (lines.size() != 1) return false;
    for (const std::string& needle : needles)
        EXPECT_NE(lines[0].find(needle), std::string::npos) << "message does not name '" << needle << "': " << lines[0];
    return true;
}

// Starts `wavebrdf args...` in `dir` without a shell (each string one argument, as given),
// stdin, stdout and stderr on /dev/null; returns its pid (or -1) for kill() and waitpid().
inline pid_t start_cli(const fs::path& dir, const std::vector<std::string>& args) {
    std::vector<std::string> argv{WAVEBRDF_CLI};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> pointers;
    for (std::string& a : argv) pointers.push_back(a.data());
    pointers.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid != 0) return pid;
    const int null = ::open("/dev/null", O_RDWR);
    if (null < 0 || ::chdir(dir.c_str()) != 0) std::_Exit(127);
    ::dup2(null, 0);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(pointers[0], pointers.data());
    std::_Exit(127);
}

// Whether /usr/bin/python3 can import numpy and matplotlib (what the report plotters need).
inline bool python_can_plot() {
    // The CLI finds the package beside its executable (<bin>/../python); a sanitizer build has
    // no Python package there.
    if (!fs::is_regular_file(fs::path(WAVEBRDF_CLI).parent_path().parent_path() / "python" / "wavebrdf" / "report.py"))
        return false;
    const pid_t pid = ::fork();
    if (pid < 0) return false;
    if (pid == 0) {
        const int null = ::open("/dev/null", O_RDWR);
        if (null >= 0) {
            ::dup2(null, 1);
            ::dup2(null, 2);
        }
        ::execl("/usr/bin/python3", "python3", "-c", "import numpy, matplotlib", static_cast<char*>(nullptr));
        std::_Exit(127);
    }
    int status = 0;
    return ::waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

// Names of the temporary files (`*.tmp*`) anywhere under `dir`.
inline std::vector<std::string> temporaries_under(const fs::path& dir) {
    std::vector<std::string> found;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
         it.increment(ec))
        if (it->path().filename().string().find(".tmp") != std::string::npos) found.push_back(it->path().string());
    return found;
}

// The float64 values of a .npy file written by the library (little-endian '<f8', C order).
inline std::vector<double> read_npy(const fs::path& path) {
    const std::string bytes = read_text(path);
    if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) return {};
    const std::size_t header = std::size_t(std::uint8_t(bytes[8])) | std::size_t(std::uint8_t(bytes[9])) << 8;
    const std::size_t start = 10 + header;
    std::vector<double> values((bytes.size() - start) / sizeof(double));
    std::memcpy(values.data(), bytes.data() + start, values.size() * sizeof(double));
    return values;
}

// The environment of a process an MPI test starts: ours, plus what running OpenMPI as root here
// needs, oversubscription allowed, `threads` OpenMP threads per rank (1: ranks are
// oversubscribed on 2 cores) and no ASan leak check (OpenMPI's initialisation leaks by design).
inline std::vector<std::string> mpi_environment(int threads = 1) {
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

// Runs `argv` (argv[0] a path) in `dir` without a shell, with the environment `env`, stdin
// from /dev/null, stdout and stderr captured (through files in `dir`, removed afterwards).
inline CliResult spawn_in(const fs::path& dir, std::vector<std::string> argv, std::vector<std::string> env) {
    const fs::path out = dir / "spawn.out", err = dir / "spawn.err";
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
    fs::remove(out);
    fs::remove(err);
    return r;
}

#ifdef WAVEBRDF_MPIEXEC
// `wavebrdf args` in `dir` on `ranks` ranks under mpiexec (1 or fewer: the executable alone,
// without mpiexec), `threads` OpenMP threads each, in mpi_environment.
inline CliResult run_cli_on_ranks(const fs::path& dir, int ranks, const std::vector<std::string>& args,
                                  int threads = 1) {
    std::vector<std::string> argv;
    if (ranks > 1) argv = {WAVEBRDF_MPIEXEC, "-q", "-n", std::to_string(ranks), "--oversubscribe", "--bind-to", "none"};
    argv.emplace_back(WAVEBRDF_CLI);
    argv.insert(argv.end(), args.begin(), args.end());
    return spawn_in(dir, argv, mpi_environment(threads));
}
#endif

}  // namespace wavebrdf::test
