// The reports of `wavebrdf invert` and `wavebrdf recover` (apps/report.h) without the source
// tree: the built executable and the built Python package copied into another directory
// (<tmp>/bin/wavebrdf, <tmp>/python/wavebrdf; or as installed, <tmp>/lib/wavebrdf/python/wavebrdf;
// or on PYTHONPATH), run from a third one, draw report.png (and curves.png); without Python, NumPy or matplotlib the run writes its data, exits 0 and says
// in one line what is missing.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cli_util.h"

using namespace wavebrdf::test;

namespace {

// The small runs of invert_test.cpp and recover_cli_test.cpp (seconds each).
const std::string kInvertLine = "invert --size 8 --sigma-p-um 2 --resolution 16 --lambda-um 0.5 --epochs 2 --quiet";
const std::string kRecover =
    "recover --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 "
    "--method thesis --epochs 2 --quiet";

const fs::path k_build_python = WAVEBRDF_BUILD_PYTHON_DIR;

bool is_png_file(const fs::path& path) { return read_text(path).rfind("\x89PNG\r\n\x1a\n", 0) == 0; }

// <root>/bin/wavebrdf and <root>/python/ (a copy of the build's package); with `broken`, a
// package of that name in <root>/python that cannot be imported (it shadows the real one).
fs::path moved_layout(const fs::path& root, const std::string& broken = "") {
    fs::create_directories(root / "bin");
    fs::copy_file(WAVEBRDF_CLI, root / "bin" / "wavebrdf");
    // The package only (build/python also holds the module's object files).
    fs::create_directories(root / "python");
    fs::copy(k_build_python / "wavebrdf", root / "python" / "wavebrdf", fs::copy_options::recursive);
    if (!broken.empty()) {
        fs::create_directories(root / "python" / broken);
        std::ofstream(root / "python" / broken / "__init__.py") << "raise ImportError('no " << broken << " (test)')\n";
    }
    return root / "bin" / "wavebrdf";
}

// Runs `env -u PYTHONPATH [ENV...] EXE args` in `dir` (no PYTHONPATH of the caller's: the
// package must be found from the executable's place alone).
CliResult run_moved(const fs::path& dir, const fs::path& exe, const std::string& args, const std::string& env = "") {
    return run_in(dir, "env -u PYTHONPATH " + env + " " + quote(exe.string()) + " " + args);
}

// The layout of `cmake --install`: <root>/bin/wavebrdf and the package in the install's Python
// folder (<root>/lib/wavebrdf/python/wavebrdf; WAVEBRDF_INSTALLED_PYTHON_DIR from bin/).
fs::path installed_layout(const fs::path& root) {
    fs::create_directories(root / "bin");
    fs::copy_file(WAVEBRDF_CLI, root / "bin" / "wavebrdf");
    const fs::path python_dir = (root / "bin" / WAVEBRDF_INSTALLED_PYTHON_DIR).lexically_normal();
    fs::create_directories(python_dir);
    fs::copy(k_build_python / "wavebrdf", python_dir / "wavebrdf", fs::copy_options::recursive);
    return root / "bin" / "wavebrdf";
}

bool have_package() { return fs::is_regular_file(k_build_python / "wavebrdf" / "report.py"); }

}  // namespace

TEST(ReportTest, DrawsReportsWithoutTheSourceTree) {
    if (!have_package()) GTEST_SKIP() << "no Python package in " << k_build_python << " (WAVEBRDF_BUILD_PYTHON off)";
    if (!python_can_plot()) GTEST_SKIP() << "/usr/bin/python3 cannot import numpy and matplotlib";
    const fs::path dir = fresh_dir("report");
    const fs::path exe = moved_layout(dir / "moved");
    fs::create_directories(dir / "work");
    const CliResult invert = run_moved(dir / "work", exe, kInvertLine + " --out inv");
    ASSERT_EQ(invert.exit_code, 0) << invert.err;
    EXPECT_EQ(invert.err, "") << "no warning when the report is drawn";
    EXPECT_TRUE(is_png_file(dir / "work" / "inv" / "report.png"));
    EXPECT_TRUE(is_png_file(dir / "work" / "inv" / "curves.png"));
    const CliResult recover = run_moved(dir / "work", exe, kRecover + " --out rec");
    ASSERT_EQ(recover.exit_code, 0) << recover.err;
    EXPECT_EQ(lines_but_convergence_warning(recover.err), std::vector<std::string>{}) << "no warning when the report is drawn";
    EXPECT_TRUE(is_png_file(dir / "work" / "rec" / "report.png"));
    EXPECT_FALSE(fs::exists(dir / "work" / "rec" / "curves.png"));
    EXPECT_EQ(temporaries_under(dir / "work"), std::vector<std::string>{});
}

// The installed CLI finds the installed package (apps/report.cpp), from another directory.
TEST(ReportTest, InstalledCliDrawsReportsWithTheInstalledPackage) {
    if (!have_package()) GTEST_SKIP() << "no Python package in " << k_build_python << " (WAVEBRDF_BUILD_PYTHON off)";
    if (!python_can_plot()) GTEST_SKIP() << "/usr/bin/python3 cannot import numpy and matplotlib";
    const fs::path dir = fresh_dir("report");
    const fs::path exe = installed_layout(dir / "prefix");
    EXPECT_FALSE(fs::exists(dir / "prefix" / "python")) << "the build tree's place is not the one used";
    fs::create_directories(dir / "work");
    const CliResult invert = run_moved(dir / "work", exe, kInvertLine + " --out inv");
    ASSERT_EQ(invert.exit_code, 0) << invert.err;
    EXPECT_EQ(invert.err, "") << "no warning when the report is drawn";
    EXPECT_TRUE(is_png_file(dir / "work" / "inv" / "report.png"));
    EXPECT_TRUE(is_png_file(dir / "work" / "inv" / "curves.png"));
}

// Neither beside nor installed with the executable: the interpreter's own path (a pip-installed
// package; here PYTHONPATH) is used.
TEST(ReportTest, PackageOnTheInterpretersPathDrawsReports) {
    if (!have_package()) GTEST_SKIP() << "no Python package in " << k_build_python << " (WAVEBRDF_BUILD_PYTHON off)";
    if (!python_can_plot()) GTEST_SKIP() << "/usr/bin/python3 cannot import numpy and matplotlib";
    const fs::path dir = fresh_dir("report");
    fs::create_directories(dir / "alone" / "bin");
    fs::copy_file(WAVEBRDF_CLI, dir / "alone" / "bin" / "wavebrdf");
    fs::create_directories(dir / "site");
    fs::copy(k_build_python / "wavebrdf", dir / "site" / "wavebrdf", fs::copy_options::recursive);
    fs::create_directories(dir / "work");
    const CliResult r = run_moved(dir / "work", dir / "alone" / "bin" / "wavebrdf", kRecover + " --out rec",
                                  "PYTHONPATH=" + quote((dir / "site").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(lines_but_convergence_warning(r.err), std::vector<std::string>{}) << "no warning when the report is drawn";
    EXPECT_TRUE(is_png_file(dir / "work" / "rec" / "report.png"));
}

// Without Python, NumPy or matplotlib: the data are written, exit 0, one line naming what
// is missing (they used to give "could not draw ... (needs /usr/bin/python3 with numpy and
// matplotlib)" whatever was missing, and nothing at all without the source tree's scripts).
TEST(ReportTest, MissingPythonOrMatplotlibIsOneWarning) {
    if (!have_package()) GTEST_SKIP() << "no Python package in " << k_build_python << " (WAVEBRDF_BUILD_PYTHON off)";
    if (!python_can_plot()) GTEST_SKIP() << "/usr/bin/python3 cannot import numpy and matplotlib";
    const fs::path dir = fresh_dir("report");
    fs::create_directories(dir / "work");
    struct Case {
        std::string name, broken, env, command, expected;
    };
    const std::vector<Case> cases = {
        {"no-matplotlib", "matplotlib", "", kRecover,
         "wavebrdf: warning: report.png not drawn: matplotlib is not installed for /usr/bin/python3 (the run's data "
         "are in no-matplotlib)"},
        {"no-numpy", "numpy", "", kInvertLine,
         "wavebrdf: warning: report.png and curves.png not drawn: numpy is not installed for /usr/bin/python3 (the "
         "run's data are in no-numpy)"},
        {"no-python", "", "WAVEBRDF_PYTHON=/nonexistent/python3", kRecover,
         "wavebrdf: warning: report.png not drawn: WAVEBRDF_PYTHON=/nonexistent/python3 is not an executable file "
         "(the run's data are in no-python)"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const fs::path exe = moved_layout(dir / ("layout-" + c.name), c.broken);
        const CliResult r = run_moved(dir / "work", exe, c.command + " --out " + c.name, c.env);
        EXPECT_EQ(r.exit_code, 0) << r.err;
        EXPECT_EQ(lines_but_convergence_warning(r.err), std::vector<std::string>{c.expected});
        EXPECT_TRUE(fs::exists(dir / "work" / c.name / "estimate.exr"));
        EXPECT_TRUE(fs::exists(dir / "work" / c.name / "metrics.csv"));
        EXPECT_FALSE(fs::exists(dir / "work" / c.name / "report.png"));
    }
}

// An executable without the package beside it (and no PYTHONPATH) still runs, warns once,
// and says where it looked.
TEST(ReportTest, PackageNotBesideTheExecutableIsNamed) {
    const fs::path dir = fresh_dir("report");
    fs::create_directories(dir / "alone" / "bin");
    fs::copy_file(WAVEBRDF_CLI, dir / "alone" / "bin" / "wavebrdf");
    fs::create_directories(dir / "work");
    const CliResult r = run_moved(dir / "work", dir / "alone" / "bin" / "wavebrdf", kRecover + " --out run");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.err);
    ASSERT_FALSE(lines.empty());
    EXPECT_NE(lines.back().find("report.png not drawn"), std::string::npos) << r.err;
    if (fs::exists("/usr/bin/python3")) {
        EXPECT_NE(lines.back().find((dir / "alone" / "python").string()), std::string::npos) << r.err;
        const fs::path installed = (dir / "alone" / "bin" / WAVEBRDF_INSTALLED_PYTHON_DIR).lexically_normal();
        EXPECT_NE(lines.back().find(installed.string()), std::string::npos) << r.err;
    }
    EXPECT_TRUE(fs::exists(dir / "work" / "run" / "estimate.exr"));
}
