// MPI and HDF5 are plugins loaded on first use (src/core/plugin.h): a command that needs neither
// never loads them, and the commands that do still work (mpi_*_test.cpp run under mpiexec,
// observation_file_test reads and writes HDF5 through the plugin).
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "cli_util.h"
#include "core/plugin.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/observation_file.h"

namespace wavebrdf {
namespace {

using test::CliResult;

// The libraries the dynamic loader loads for `wavebrdf args` (its LD_DEBUG=libs trace).
std::string libraries_loaded_by_cli(const std::vector<std::string>& args) {
    const auto dir = test::fresh_dir("plugin_test");
    std::vector<std::string> env;
    for (char** e = environ; *e != nullptr; ++e)
        if (std::string(*e).rfind("LD_DEBUG", 0) != 0) env.emplace_back(*e);
    env.emplace_back("LD_DEBUG=libs");
    std::vector<std::string> argv{WAVEBRDF_CLI};
    argv.insert(argv.end(), args.begin(), args.end());
    const CliResult r = test::spawn_in(dir, argv, env);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.err;
}

TEST(PluginTest, TheCliLoadsNeitherMpiNorHdf5NorLibzipForACommandThatUsesNone) {
    const std::string trace = libraries_loaded_by_cli({"--version"});
    // The trace is there (else the absence below proves nothing): the C library is always loaded.
    ASSERT_NE(trace.find("libc.so"), std::string::npos) << trace;
    EXPECT_EQ(trace.find("libmpi"), std::string::npos) << trace;
    EXPECT_EQ(trace.find("libhdf5"), std::string::npos) << trace;
    EXPECT_EQ(trace.find("libzip"), std::string::npos) << trace;
    EXPECT_EQ(trace.find("libcrypto"), std::string::npos) << trace;
    EXPECT_EQ(trace.find("libwavebrdf_"), std::string::npos) << trace;
}

TEST(PluginTest, AProcessNotStartedByMpiexecHasTheSerialWorldWithoutLoadingMpi) {
    if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK"))
        GTEST_SKIP() << "started by mpiexec";
    EXPECT_EQ(world_communicator()->size(), 1);
    EXPECT_EQ(world_communicator().get(), &serial_communicator());
    EXPECT_FALSE(detail::library_loaded("libmpi"));
}

TEST(PluginTest, AMissingPluginIsOneErrorNamingItAndWhereItWasLookedFor) {
    try {
        detail::plugin_symbol("no_such_plugin", "entry");
        FAIL() << "a missing plugin loaded";
    } catch (const std::runtime_error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("libwavebrdf_no_such_plugin.so"), std::string::npos) << what;
        EXPECT_NE(what.find("WAVEBRDF_PLUGIN_DIR"), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
}

TEST(PluginTest, LibraryLoadedSeesWhatIsLoadedAndNotWhatIsNot) {
    EXPECT_TRUE(detail::library_loaded("libc.so"));
    EXPECT_FALSE(detail::library_loaded("libwavebrdf_no_such_plugin"));
}

#ifdef WAVEBRDF_MPIEXEC
TEST(PluginTest, UnderMpiexecTheCliLoadsTheMpiPlugin) {
    const auto dir = test::fresh_dir("plugin_test");
    std::vector<std::string> env = test::mpi_environment();
    env.emplace_back("LD_DEBUG=libs");
    const CliResult r = test::spawn_in(dir, {WAVEBRDF_MPIEXEC, "-n", "2", WAVEBRDF_CLI, "--version"}, env);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("libwavebrdf_mpi.so"), std::string::npos);
    EXPECT_NE(r.out.find("wavebrdf "), std::string::npos) << r.out;
}
#endif

}  // namespace
}  // namespace wavebrdf
