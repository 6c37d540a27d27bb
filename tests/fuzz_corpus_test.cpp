// The fuzzers' seed corpus (fuzz/corpus/) stays valid input: each seed is accepted by the reader
// it seeds, and the checkpoint seed matches the run the checkpoint fuzzer loads it into. A
// format change that breaks a seed fails here rather than silently leaving the fuzzer at the
// first rejection (fuzz/README.md says how to regenerate the seeds).
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "test_util.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/table.h"

namespace fs = std::filesystem;

namespace {

const fs::path k_corpus = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "corpus";

std::vector<fs::path> seeds(const std::string& target) {
    std::vector<fs::path> out;
    for (const auto& entry : fs::directory_iterator(k_corpus / target)) out.push_back(entry.path());
    return out;
}

TEST(FuzzCorpus, EverySeedEachExrReaderAccepts) {
    const auto files = seeds("exr");
    ASSERT_GE(files.size(), 4u);
    for (const fs::path& file : files) {
        int accepted = 0;
        try {
            const wavebrdf::Heightfield h = wavebrdf::read_heightfield_exr(file.string());
            EXPECT_GE(h.rows(), 3) << file;
            ++accepted;
        } catch (const std::runtime_error&) {}
        try {
            const wavebrdf::RgbImage image = wavebrdf::read_rgb_exr(file.string());
            EXPECT_GE(image.rows, 3) << file;
            ++accepted;
        } catch (const std::runtime_error&) {}
        EXPECT_GE(accepted, 1) << file << " is rejected by both EXR readers";
    }
}

TEST(FuzzCorpus, EveryPositionsSeedReads) {
    for (const fs::path& file : seeds("positions_json"))
        EXPECT_FALSE(wavebrdf::read_positions_json(file.string()).empty()) << file;
}

TEST(FuzzCorpus, EveryObservationsSeedReadsBesideTheFuzzersRefExr) {
    // Like fuzz/observations_json_fuzz.cpp: the input beside a valid 4x4 RGB ref.exr.
    const fs::path dir = fs::path(WAVEBRDF_TEST_TMP) / "fuzz_corpus" / std::to_string(::getpid());
    fs::remove_all(dir);
    fs::create_directories(dir);
    wavebrdf::RgbImage image;
    image.rows = image.cols = 4;
    image.data.assign(4 * 4 * 3, 0.25f);
    wavebrdf::write_rgb_exr((dir / "ref.exr").string(), image);
    for (const fs::path& file : seeds("observations_json")) {
        fs::copy_file(file, dir / "observations.json", fs::copy_options::overwrite_existing);
        EXPECT_NO_THROW(wavebrdf::read_observations_json((dir / "observations.json").string())) << file;
    }
    fs::remove_all(dir);
}

std::string file_text(const fs::path& file) {
    std::ifstream in(file);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

// As fuzz/run_json_fuzz.cpp checks of every input it accepts: read, written back and read again,
// the options are the same.
TEST(FuzzCorpus, EveryRunJsonSeedReadsAndRoundTrips) {
    const auto files = seeds("run_json");
    ASSERT_GE(files.size(), 3u);
    for (const fs::path& file : files) {
        const wavebrdf::InversionOptions options = wavebrdf::inversion_options_from_json(file_text(file));
        const std::string written = wavebrdf::inversion_options_to_json(options);
        EXPECT_EQ(wavebrdf::inversion_options_to_json(wavebrdf::inversion_options_from_json(written)), written)
            << file;
    }
    const wavebrdf::InversionOptions full =
        wavebrdf::inversion_options_from_json(file_text(k_corpus / "run_json" / "reference_weights.json"));
    EXPECT_EQ(full.weights_path, "/tmp/w.exr");
    EXPECT_EQ(full.wavelengths_um.size(), 3u);
    EXPECT_EQ(full.rows, 16);
    EXPECT_EQ(full.cols, 24);
}

// The inversion of fuzz/checkpoint_fuzz.cpp.
wavebrdf::Inversion checkpoint_fuzzers_inversion() {
    return wavebrdf::Inversion(
        wavebrdf::read_observations_json((k_corpus / "observations_json" / "inline_mono.json").string()),
        wavebrdf::Heightfield(4, 4, std::vector<double>(16, 0.0)), wavebrdf::InversionSettings{});
}

TEST(FuzzCorpus, CheckpointSeedLoadsIntoTheFuzzersRun) {
    wavebrdf::Inversion inversion = checkpoint_fuzzers_inversion();
    inversion.load_checkpoint((k_corpus / "checkpoint" / "invert_4x4.json").string());
    EXPECT_EQ(inversion.epoch(), 3);
}

TEST(FuzzCorpus, OtherRunCheckpointSeedReachesTheDifferenceReport) {
    wavebrdf::Inversion inversion = checkpoint_fuzzers_inversion();
    wavebrdf::test::expect_throw_naming<std::runtime_error>(
        [&] { inversion.load_checkpoint((k_corpus / "checkpoint" / "other_run.json").string()); },
        "texel_um 2.0 in the checkpoint");
}

}  // namespace

#ifdef WAVEBRDF_HAS_HDF5
TEST(FuzzCorpus, EveryHdf5ObservationSeedIsRead) {
    const auto files = seeds("observations_hdf5_bytes");
    ASSERT_GE(files.size(), 2u);
    for (const fs::path& file : files) EXPECT_FALSE(wavebrdf::read_observations_file(file.string()).empty()) << file;
}
#endif

TEST(FuzzCorpus, EveryIridescentSpecSeedIsRead) {
    const auto files = seeds("iridescent_spec");
    ASSERT_GE(files.size(), 2u);
    for (const fs::path& file : files)
        EXPECT_GE(wavebrdf::parse_design_target("iridescent:" + file.string()).pairs.size(), 1u) << file;
}

// Each PNG seed (grey 8 and 16 bit, RGB, RGBA, a palette; written by Python's zlib) is read as a
// pattern target's image and as a plate's picture.
TEST(FuzzCorpus, EveryPngPictureSeedIsReadByBothReaders) {
    const auto files = seeds("png_picture");
    ASSERT_GE(files.size(), 5u);
    for (const fs::path& file : files) {
        const wavebrdf::DesignTarget t = wavebrdf::parse_design_target("pattern:" + file.string());
        EXPECT_GE(t.image_rows, 2) << file;
        const wavebrdf::PlatePicture p = wavebrdf::read_plate_picture(file.string());
        EXPECT_EQ(p.rows, t.image_rows) << file;
        EXPECT_EQ(p.cols, t.image_cols) << file;
    }
}

TEST(FuzzCorpus, EveryTableSeedIsRead) {
    const auto files = seeds("table");
    ASSERT_GE(files.size(), 2u);
    for (const fs::path& file : files) EXPECT_GE(wavebrdf::read_brdf_table(file.string()).spec.resolution, 1) << file;
}
