// recovery_directory.h: a recovery run written to its directory by the library (what
// `wavebrdf recover --out` used to write itself): every file of the layout, run.json's fields,
// one metrics row per reported step, the saved observations reading back, an early stop, and
// a directory that may not be used refused before any work.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "wavebrdf/threads.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recovery_directory.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/version.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

std::string read_file_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

fs::path fresh(const std::string& name) {
    const fs::path dir = fs::path(WAVEBRDF_TEST_TMP) / "recovery_directory" / name;
    fs::remove_all(dir);
    fs::create_directories(dir.parent_path());
    return dir;
}

// The small study of recover_cli_test.cpp, by the thesis's method (a few epochs: seconds).
RecoveryOptions small_directory_options() {
    RecoveryOptions options;
    options.rows = options.cols = 8;
    options.texel_um = 2.0;
    options.sigma_p_um = 3.0;
    options.height_range_um = 0.1;
    options.seed = 3;
    options.method = RecoveryMethod::Thesis;
    options.epochs = 30;
    return options;
}

TEST(RecoveryDirectory, WritesEveryFileOfTheLayout) {
    const RecoveryOptions options = small_directory_options();
    const PreparedRecovery prepared = prepare_recovery(options);
    RecoveryDirectoryOptions out;
    out.dir = fresh("all").string();
    out.save_observations = true;
    std::vector<StageMetrics> seen;
    const Heightfield estimate = run_recovery_in_directory(prepared, options, out, [&](const StageMetrics& m) {
        seen.push_back(m);
        return true;
    });
    const fs::path dir = out.dir;
    for (const char* name : {"run.json", "metrics.csv", "truth.exr", "truth_height.npy", "estimate.exr", "estimate.png",
                             "estimate_height.npy", "reference.npy", "final.npy", "observations.json"})
        EXPECT_TRUE(fs::is_regular_file(dir / name)) << name;
    EXPECT_TRUE(fs::is_regular_file(dir / "observations" / "slice_0000.exr"));

    const nlohmann::json run = nlohmann::json::parse(read_file_text(dir / "run.json"));
    EXPECT_EQ(run.at("method"), "thesis");
    EXPECT_EQ(run.at("size"), "8x8");
    EXPECT_EQ(run.at("texel_um"), 2.0);
    EXPECT_EQ(run.at("seed"), 3);
    EXPECT_EQ(run.at("observations"), prepared.observations.size());
    EXPECT_EQ(run.at("plan"), prepared.notes);
    EXPECT_EQ(run.at("loss"), to_string(prepared.loss));
    EXPECT_EQ(run.at("truth"), true);
    EXPECT_FALSE(run.contains("height_rel_rmse"));
    // Issue 11: the version, the threads and the actual wavelengths, footprint and resolution.
    EXPECT_EQ(run.at("version"), k_version);
    EXPECT_EQ(run.at("threads"), thread_count());
    std::vector<double> lambdas;
    for (const Observation& o : prepared.observations)
        for (double l : o.lambdas_um)
            if (std::find(lambdas.begin(), lambdas.end(), l) == lambdas.end()) lambdas.push_back(l);
    ASSERT_FALSE(lambdas.empty());
    EXPECT_EQ(run.at("wavelengths_um").get<std::vector<double>>(), lambdas);
    EXPECT_EQ(run.at("sigma_p_um"), 3.0);
    EXPECT_EQ(run.at("resolution"), prepared.observations.front().resolution);
    // The heightfields say their scale; the saved observations their query.
    EXPECT_EQ(read_heightfield_exr((dir / "estimate.exr").string()).texel_um(), 2.0);
    EXPECT_EQ(read_heightfield_exr((dir / "truth.exr").string()).texel_um(), 2.0);
    const SliceFile slice = read_slice_exr((dir / "observations" / "slice_0000.exr").string());
    ASSERT_TRUE(slice.attributes.has_value());
    EXPECT_EQ(slice.attributes->query.x_um, prepared.observations.front().query.x_um);
    EXPECT_EQ(slice.attributes->lambdas_um, prepared.observations.front().lambdas_um);

    // One row per step the callback saw, in the order it saw them.
    const std::string csv = read_file_text(dir / "metrics.csv");
    ASSERT_EQ(csv.rfind("stage,iteration,loss,seconds,height_rel_rmse,height_rel_rmse_plane_removed\n", 0), 0u) << csv;
    ASSERT_EQ(std::count(csv.begin(), csv.end(), '\n'), std::ptrdiff_t(seen.size() + 1)) << csv;
    ASSERT_FALSE(seen.empty());
    EXPECT_NE(csv.find("\nthesis," + std::to_string(seen.back().iteration) + ","), std::string::npos) << csv;

    // The estimate on disk is the one returned; the saved observations are the run's.
    EXPECT_EQ(read_heightfield_exr((dir / "estimate.exr").string(), 2.0).rows(), estimate.rows());
    const std::vector<Observation> saved = read_observations_json((dir / "observations.json").string());
    ASSERT_EQ(saved.size(), prepared.observations.size());
    EXPECT_EQ(saved.back().query.x_um, prepared.observations.back().query.x_um);
    EXPECT_EQ(saved.back().lambdas_um, prepared.observations.back().lambdas_um);
}

TEST(RecoveryDirectory, EarlyStopStillWritesTheEstimate) {
    const RecoveryOptions options = small_directory_options();
    const PreparedRecovery prepared = prepare_recovery(options);
    RecoveryDirectoryOptions out;
    out.dir = fresh("stopped").string();
    int calls = 0;
    run_recovery_in_directory(prepared, options, out, [&](const StageMetrics&) { return ++calls < 1; });
    EXPECT_EQ(calls, 1);
    const std::string csv = read_file_text(fs::path(out.dir) / "metrics.csv");
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 2) << csv;
    EXPECT_TRUE(fs::is_regular_file(fs::path(out.dir) / "estimate.exr"));
    EXPECT_FALSE(fs::exists(fs::path(out.dir) / "observations.json")) << "not asked for";
}

TEST(RecoveryDirectory, ForeignFilesRefuseTheDirectoryBeforeAnyWork) {
    const RecoveryOptions options = small_directory_options();
    const PreparedRecovery prepared = prepare_recovery(options);
    const fs::path dir = fresh("foreign");
    fs::create_directories(dir);
    std::ofstream(dir / "notes.txt") << "mine";
    RecoveryDirectoryOptions out;
    out.dir = dir.string();
    out.force = true;
    bool ran = false;
    EXPECT_THROW(run_recovery_in_directory(prepared, options, out, [&](const StageMetrics&) { return ran = true; }),
                 std::invalid_argument);
    EXPECT_FALSE(ran);
    EXPECT_FALSE(fs::exists(dir / "run.json"));
    EXPECT_EQ(read_file_text(dir / "notes.txt"), "mine");
}

}  // namespace
}  // namespace wavebrdf
