#include "report.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "run_program.h"

extern char** environ;

namespace wavebrdf::cli {

namespace {

namespace fs = std::filesystem;

// The exit statuses of `python3 -m wavebrdf.report --quiet` for a missing dependency
// (python/wavebrdf/report.py).
constexpr int k_status_no_numpy = 3;
constexpr int k_status_no_matplotlib = 4;

bool is_executable(const std::string& path) {
    std::error_code ec;
    return !path.empty() && fs::is_regular_file(path, ec) && ::access(path.c_str(), X_OK) == 0;
}

// The interpreter to run, or "" when there is none; `why` says what was looked for.
std::string find_python(std::string& why) {
    const char* chosen = std::getenv("WAVEBRDF_PYTHON");
    if (chosen != nullptr && *chosen != '\0') {
        if (is_executable(chosen)) return chosen;
        why = "WAVEBRDF_PYTHON=" + std::string(chosen) + " is not an executable file";
        return "";
    }
    if (is_executable("/usr/bin/python3")) return "/usr/bin/python3";
    if (const char* path = std::getenv("PATH")) {
        const std::string list = path;
        std::size_t start = 0;
        for (;;) {
            const std::size_t end = list.find(':', start);
            const std::string folder = list.substr(start, end - start);
            if (!folder.empty() && is_executable(folder + "/python3")) return folder + "/python3";
            if (end == std::string::npos) break;
            start = end + 1;
        }
    }
    why = "Python is not installed (no /usr/bin/python3, no python3 on PATH)";
    return "";
}

#ifndef WAVEBRDF_INSTALLED_PYTHON_DIR
#define WAVEBRDF_INSTALLED_PYTHON_DIR "../lib/wavebrdf/python"
#endif

// The folders that may hold the package, relative to the running executable's directory, in
// the order they are tried: ../python (the build tree: build/bin/wavebrdf, build/python/wavebrdf),
// then where `cmake --install` puts it (bin/wavebrdf, lib/wavebrdf/python/wavebrdf; CMake
// passes the path from the install's bin to its Python folder). Empty when the executable's path
// is unknown.
std::vector<std::string> package_dirs() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return {};
    const fs::path bin = exe.parent_path();
    return {(bin.parent_path() / "python").lexically_normal().string(),
            (bin / WAVEBRDF_INSTALLED_PYTHON_DIR).lexically_normal().string()};
}

// This process's environment with `python_dir` first on PYTHONPATH (when not empty) and
// PYTHONSAFEPATH=1, so that the current directory cannot shadow the package (Python ≥ 3.11;
// older interpreters ignore it).
std::vector<std::string> child_environment(const std::string& python_dir) {
    std::vector<std::string> env;
    std::string pythonpath = python_dir;
    for (char** e = environ; *e != nullptr; ++e) {
        if (std::strncmp(*e, "PYTHONPATH=", 11) == 0) {
            const std::string old = *e + 11;
            if (python_dir.empty())
                pythonpath = old;
            else if (!old.empty())
                pythonpath += ":" + old;
            continue;
        }
        if (std::strncmp(*e, "PYTHONSAFEPATH=", 15) == 0) continue;
        env.push_back(*e);
    }
    if (!pythonpath.empty()) env.push_back("PYTHONPATH=" + pythonpath);
    env.push_back("PYTHONSAFEPATH=1");
    return env;
}

}  // namespace

bool draw_report(RunKind kind, const std::string& dir) {
    const char* what = kind == RunKind::Invert ? "report.png and curves.png" : "report.png";
    std::string why;
    try {
        std::string found;
        const std::string python = find_python(found);
        if (python.empty()) {
            why = found;
        } else {
            // The first folder that holds the package, else "" (the interpreter's own path:
            // a pip-installed wavebrdf).
            const std::vector<std::string> candidates = package_dirs();
            std::string beside;
            for (const std::string& candidate : candidates) {
                std::error_code ec;
                if (fs::is_regular_file(candidate + "/wavebrdf/report.py", ec)) {
                    beside = candidate;
                    break;
                }
            }
            // No shell: the directory is one argument, whatever its characters; absolute, so a
            // name starting with '-' is not taken for an option.
            const int status = run_program({python, "-m", "wavebrdf.report", "--quiet", fs::absolute(dir).string()},
                                           child_environment(beside));
            if (status == 0) return true;
            if (status == k_status_no_numpy)
                why = "numpy is not installed for " + python;
            else if (status == k_status_no_matplotlib)
                why = "matplotlib is not installed for " + python;
            else if (status < 0)
                why = python + " -m wavebrdf.report could not be started or was killed";
            else
                why = python + " -m wavebrdf.report failed (exit status " + std::to_string(status) + ")";
            if (beside.empty() && status != k_status_no_numpy && status != k_status_no_matplotlib)
                why += "; the wavebrdf Python package is neither beside the executable (" +
                       (candidates.empty() ? std::string("<bin>/../python") : candidates[0]) +
                       ") nor installed with it (" +
                       (candidates.size() < 2 ? std::string("<bin>/" WAVEBRDF_INSTALLED_PYTHON_DIR) : candidates[1]) +
                       ") nor importable by " + python;
        }
    } catch (const std::exception& e) {
        why = e.what();
    }
    std::fprintf(stderr, "wavebrdf: warning: %s not drawn: %s (the run's data are in %s)\n", what, why.c_str(),
                 dir.c_str());
    return false;
}

}  // namespace wavebrdf::cli
