// Per-pixel weights of observations (masks of dead, saturated or unmeasured pixels): the
// weighted loss against the loss of the unmasked pixels alone, its gradient against finite
// differences, masked values that change nothing, the files that carry weights (JSON, HDF5),
// and `invert --reference SLICE.exr [--weights W.exr]`.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/observation_file.h"

namespace fs = std::filesystem;
using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// A 0/1 mask of `pixels` with about a third masked out (never all), seeded.
std::vector<float> some_mask(std::size_t pixels, std::uint64_t seed) {
    const std::vector<double> u = uniform_vector(pixels, 0.0, 1.0, seed);
    std::vector<float> w(pixels);
    for (std::size_t p = 0; p < pixels; ++p) w[p] = u[p] < 0.35 ? 0.0f : 1.0f;
    w[0] = 1.0f;
    w[1] = 0.0f;
    return w;
}

std::vector<Loss> every_loss() {
    return {parse_loss("cmsle:0.1"), parse_loss("mse"), parse_loss("amplitude"), parse_loss("poisson:1e4")};
}

// ---------------------------------------------------------------------------------------------
// The loss of one slice

// With a 0/1 mask the weighted loss is loss_value of the unmasked pixels alone (compacted: an
// independent evaluation by the unweighted code), and its gradient is that loss's gradient on
// the unmasked values and exactly 0 on the masked ones; for every loss and channel count.
TEST(WeightedLoss, MaskEqualsTheLossOfTheUnmaskedPixelsAlone) {
    for (int channels : {1, 3})
        for (const Loss& loss : every_loss()) {
            const std::size_t pixels = 64, c = std::size_t(channels);
            std::vector<double> estimate = uniform_vector(pixels * c, 0.0, 2.0, 3);
            std::vector<double> reference = uniform_vector(pixels * c, 0.0, 2.0, 4);
            estimate[5] = -0.1;  // the clamp is active there
            const std::vector<float> w = some_mask(pixels, 5);
            std::vector<double> e_kept, r_kept;
            for (std::size_t p = 0; p < pixels; ++p)
                if (w[p] > 0.0f)
                    for (std::size_t k = 0; k < c; ++k) {
                        e_kept.push_back(estimate[p * c + k]);
                        r_kept.push_back(reference[p * c + k]);
                    }
            std::vector<double> g, g_kept;
            const double weighted = weighted_loss_value(loss, estimate, reference, channels, w, &g);
            const double kept = loss_value(loss, e_kept, r_kept, channels, &g_kept);
            SCOPED_TRACE(to_string(loss) + ", channels " + std::to_string(channels));
            EXPECT_NEAR(weighted, kept, 1e-13 * std::abs(kept));
            std::size_t at = 0;
            for (std::size_t p = 0; p < pixels; ++p)
                for (std::size_t k = 0; k < c; ++k) {
                    if (w[p] > 0.0f)
                        EXPECT_NEAR(g[p * c + k], g_kept[at++], 1e-13 * (1.0 + std::abs(g[p * c + k])));
                    else
                        EXPECT_EQ(g[p * c + k], 0.0);
                }
        }
}

// Non-binary weights: the weighted mean Σ w_p ℓ_p / Σ w_p, by a direct sum of per-pixel MSE terms.
TEST(WeightedLoss, WeightsGiveTheWeightedMeanOverPixels) {
    const std::vector<double> e{1.0, 2.0, 3.0, 4.0}, r{0.5, 2.5, 1.0, 4.0};
    const std::vector<float> w{0.25f, 1.0f, 2.0f, 0.0f};
    const double expected = (0.25 * 0.25 + 1.0 * 0.25 + 2.0 * 4.0 + 0.0) / 3.25;
    EXPECT_NEAR(weighted_loss_value(parse_loss("mse"), e, r, 1, w), expected, 1e-15);
}

TEST(WeightedLoss, BadWeightsAreRefused) {
    const std::vector<double> e{1.0, 2.0}, r{1.0, 2.0};
    const Loss mse = parse_loss("mse");
    expect_throw_naming<std::logic_error>([&] { weighted_loss_value(mse, e, r, 1, {1.0f}); }, "one per pixel");
    expect_throw_naming<std::logic_error>(
        [&] {
            weighted_loss_value(mse, e, r, 1, {1.0f, -1.0f});
        },
        "expected a finite weight >= 0");
    expect_throw_naming<std::logic_error>(
        [&] {
            weighted_loss_value(mse, e, r, 1, {1.0f, float(kNaN)});
        },
        "finite weight");
    expect_throw_naming<std::logic_error>(
        [&] {
            weighted_loss_value(mse, e, r, 1, {0.0f, 0.0f});
        },
        "every weight is 0");
}

// ---------------------------------------------------------------------------------------------
// The loss of observations against heights

Observation masked_observation(const Heightfield& truth, int channels) {
    Observation o;
    o.query = make_query(Model::OHS, 3.0, 5.0, 2.0, 0.1, -0.05);
    o.lambdas_um = channels == 1 ? std::vector<double>{0.55} : std::vector<double>{0.45, 0.55, 0.65};
    o.resolution = 12;
    o.reference = to_reference(render_observation(truth, o));
    o.weights = some_mask(std::size_t(o.resolution) * std::size_t(o.resolution), 9);
    return o;
}

// The gradient with respect to the heights equals central finite differences of the weighted
// loss (double precision, several texels), for one and three channels.
TEST(ObservationWeights, GradientMatchesFiniteDifferences) {
    const Heightfield truth = random_heightfield(8, 8, 0.3, 21);
    const Heightfield start = random_heightfield(8, 8, 0.3, 22);
    for (int channels : {1, 3}) {
        const std::vector<Observation> obs{masked_observation(truth, channels)};
        const Loss loss = parse_loss("cmsle:0.1");
        std::vector<double> g;
        observation_loss(start, obs, loss, &g);
        for (std::size_t k : {0u, 9u, 27u, 50u, 63u}) {
            const double h = 1e-5;
            std::vector<double> up = start.values(), down = start.values();
            up[k] += h;
            down[k] -= h;
            const double fd = (observation_loss(start.with_values(up), obs, loss, nullptr) -
                               observation_loss(start.with_values(down), obs, loss, nullptr)) /
                              (2.0 * h);
            EXPECT_NEAR(g[k], fd, 1e-6 * (1.0 + std::abs(fd))) << "texel " << k << ", channels " << channels;
        }
    }
}

// A masked pixel's reference may change to anything (another value, NaN, infinity): the loss
// and the gradient are the same bits. An unmasked pixel's change does move them (the test can fail).
TEST(ObservationWeights, MaskedPixelsChangeNothing) {
    const Heightfield truth = random_heightfield(8, 8, 0.3, 31);
    const Heightfield start = random_heightfield(8, 8, 0.3, 32);
    const std::vector<Observation> obs{masked_observation(truth, 3)};
    const Loss loss = parse_loss("mse");
    std::vector<double> g0;
    const double l0 = observation_loss(start, obs, loss, &g0);
    for (float value : {100.0f, float(kNaN), std::numeric_limits<float>::infinity()}) {
        std::vector<Observation> changed = obs;
        for (std::size_t p = 0; p < changed[0].weights.size(); ++p)
            if (changed[0].weights[p] == 0.0f)
                for (std::size_t k = 0; k < 3; ++k) changed[0].reference[3 * p + k] = value;
        std::vector<double> g1;
        EXPECT_EQ(observation_loss(start, changed, loss, &g1), l0) << value;
        EXPECT_EQ(g1, g0) << value;
    }
    std::vector<Observation> unmasked_change = obs;
    unmasked_change[0].reference[0] += 1.0f;  // pixel 0 has weight 1
    EXPECT_NE(observation_loss(start, unmasked_change, loss, nullptr), l0);
    // Without weights a NaN is refused, naming the pixel.
    std::vector<Observation> unweighted = obs;
    unweighted[0].weights.clear();
    unweighted[0].reference[3 * 1] = float(kNaN);
    expect_throw_naming<std::logic_error>([&] { observation_loss(start, unweighted, loss, nullptr); }, "pixel (0, 1)");
}

TEST(ObservationWeights, ValidateNamesTheBadWeight) {
    const Heightfield truth = random_heightfield(8, 8, 0.3, 41);
    Observation o = masked_observation(truth, 1);
    Observation bad = o;
    bad.weights.pop_back();
    expect_throw_naming<std::logic_error>([&] { validate(bad, 2); },
                                          "observation 2: weights has 143 values; expected one per pixel");
    bad = o;
    bad.weights[13] = -0.5f;
    expect_throw_naming<std::logic_error>([&] { validate(bad); }, "weight of pixel (1, 1) is -0.5");
    bad = o;
    bad.weights.assign(bad.weights.size(), 0.0f);
    expect_throw_naming<std::logic_error>([&] { validate(bad); }, "every weight is 0");
}

// ---------------------------------------------------------------------------------------------
// Files

void expect_same_observation(const Observation& a, const Observation& b) {
    EXPECT_EQ(a.reference.size(), b.reference.size());
    for (std::size_t i = 0; i < a.reference.size(); ++i)
        if (!std::isnan(a.reference[i]) || !std::isnan(b.reference[i])) {
            EXPECT_EQ(a.reference[i], b.reference[i]);
        }
    EXPECT_EQ(a.weights, b.weights);
}

TEST(ObservationWeights, JsonAndHdf5CarryTheWeights) {
    const fs::path dir = fresh_dir("weights");
    const Heightfield truth = random_heightfield(8, 8, 0.3, 51);
    Observation masked = masked_observation(truth, 1);
    masked.weights[20] = 0.5f;          // not only 0 and 1
    masked.reference[1] = float(kNaN);  // pixel 1 is masked: a dead pixel may be NaN
    Observation plain = masked_observation(truth, 1);
    plain.weights.clear();
    const std::vector<Observation> set{masked, plain};
    for (const auto storage : {ReferenceStorage::Inline, ReferenceStorage::Exr}) {
        const std::string file = (dir / (storage == ReferenceStorage::Inline ? "inline.json" : "exr.json")).string();
        write_observations_json(file, set, storage);
        const std::vector<Observation> back = read_observations_json(file);
        ASSERT_EQ(back.size(), 2u);
        expect_same_observation(back[0], masked);
        EXPECT_TRUE(back[1].weights.empty());
    }
    // A JSON written by hand: a weights list of the wrong length is named.
    nlohmann::json doc = nlohmann::json::parse(read_text(dir / "inline.json"));
    doc["observations"][1]["weights"] = {1.0, 0.0};
    std::ofstream(dir / "short.json") << doc.dump();
    expect_throw_naming<std::runtime_error>([&] { read_observations_json((dir / "short.json").string()); },
                                            "observation 1: field 'weights' has 2 values; expected one per pixel");
    if (!built_with_hdf5()) GTEST_SKIP() << "built without HDF5";
    const std::string h5 = (dir / "set.h5").string();
    write_observations_hdf5(h5, set);
    const std::vector<Observation> back = read_observations_hdf5(h5, {1, 0});
    ASSERT_EQ(back.size(), 2u);
    expect_same_observation(back[1], masked);
    // In an HDF5 file every observation has weights once one has: the others' are all 1.
    EXPECT_EQ(back[0].weights, std::vector<float>(plain.reference.size(), 1.0f));
    // Without weights no weights dataset is written, and none is read back.
    write_observations_hdf5(h5, {plain});
    EXPECT_TRUE(read_observations_hdf5(h5, {0})[0].weights.empty());
}

// ---------------------------------------------------------------------------------------------
// `invert --reference`

// A grey float RGB EXR written with OpenEXR directly (it may hold NaN), without attributes.
void write_raw_grey_exr(const std::string& file, int n, const std::vector<float>& values) {
    Imf::Header header(n, n);
    Imf::FrameBuffer frame;
    for (const char* c : {"R", "G", "B"}) {
        header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        frame.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(values.data())),
                                   sizeof(float), sizeof(float) * static_cast<std::size_t>(n)));
    }
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(n);
}

class InvertReferenceTest : public ::testing::Test {
protected:
    void SetUp() override {
        m_dir = fresh_dir("invert_reference");
        write_heightfield_exr(path("truth.exr").string(), random_heightfield(8, 8, 0.3, 61, 1.5));
        // The slice a user has: rendered by another command, its query in its attributes.
        const CliResult r = run_cli(m_dir,
                                    "render --heightfield truth.exr --out slice.exr --resolution 16 --sigma-p-um 2.5 "
                                    "--lambda-um 0.6 --light-x 0.2 --light-y -0.1 --x-um 5 --y-um 7 --quiet");
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(m_dir);
    }
    fs::path path(const std::string& name) const { return m_dir / name; }
    CliResult invert(const std::string& args) const {
        return run_cli(m_dir, "invert --epochs 0 --no-plots --quiet " + args);
    }
    // Epoch 0's loss in metrics.csv of `run`.
    double first_loss(const std::string& run) const {
        const std::vector<std::string> lines = lines_of(read_text(path(run) / "metrics.csv"));
        if (lines.size() < 2) return kNaN;
        std::stringstream in(lines[1]);
        std::string epoch, loss;
        std::getline(in, epoch, ',');
        std::getline(in, loss, ',');
        return std::stod(loss);
    }
    nlohmann::json args(const std::string& run) const {
        return nlohmann::json::parse(read_text(path(run) / "run.json")).at("args");
    }
    fs::path m_dir;
};

// Started from the true heights, the loss against the slice is 0 up to the slice's float
// rounding exactly when the query read from its attributes is the one it was rendered with; a
// query given by an option that differs (σ_p) gives a loss far from 0.
TEST_F(InvertReferenceTest, QueryIsReadFromTheSlicesAttributes) {
    const CliResult ok = invert("--reference slice.exr --init truth.exr --out run");
    ASSERT_EQ(ok.exit_code, 0) << ok.err;
    const nlohmann::json a = args("run");
    EXPECT_EQ(a.at("sigma_p_um").get<double>(), 2.5);
    EXPECT_EQ(a.at("lambda_um").get<double>(), 0.6);
    EXPECT_EQ(a.at("light_x").get<double>(), 0.2);
    EXPECT_EQ(a.at("x_um").get<double>(), 5.0);
    EXPECT_EQ(a.at("resolution").get<int>(), 16);
    EXPECT_EQ(a.at("size").get<std::string>(), "8");
    EXPECT_EQ(a.at("texel_um").get<double>(), 1.5);
    EXPECT_LT(first_loss("run"), 1e-12);

    const CliResult other = invert("--reference slice.exr --init truth.exr --sigma-p-um 2 --out other");
    ASSERT_EQ(other.exit_code, 0) << other.err;
    EXPECT_GT(first_loss("other"), 1e-6);
}

// A mask over pixels whose values were spoilt (NaN, a saturated 1e6): the loss from the true
// heights stays 0; without the mask the spoilt slice is refused (NaN) or far off (1e6).
TEST_F(InvertReferenceTest, WeightsMaskSpoiltPixels) {
    SliceFile slice = read_slice_exr(path("slice.exr").string());
    std::vector<float> w(256, 1.0f);
    for (int p : {17, 18, 100}) {
        w[std::size_t(p)] = 0.0f;
        for (int c = 0; c < 3; ++c) slice.image.data[3 * std::size_t(p) + std::size_t(c)] = 1e6f;
    }
    write_slice_exr(path("saturated.exr").string(), slice.image, *slice.attributes);
    write_raw_grey_exr(path("mask.exr").string(), 16, w);
    const CliResult masked = invert("--reference saturated.exr --weights mask.exr --init truth.exr --out masked");
    ASSERT_EQ(masked.exit_code, 0) << masked.err;
    EXPECT_LT(first_loss("masked"), 1e-12);
    EXPECT_TRUE(args("masked").at("weights").get<std::string>().find("mask.exr") != std::string::npos);
    const CliResult unmasked = invert("--reference saturated.exr --init truth.exr --out unmasked");
    ASSERT_EQ(unmasked.exit_code, 0) << unmasked.err;
    EXPECT_GT(first_loss("unmasked"), 1e-3);
}

TEST_F(InvertReferenceTest, BadReferencesAndWeightsAreOneLine) {
    std::vector<float> w(256, 1.0f);
    w[3] = -1.0f;
    write_raw_grey_exr(path("negative.exr").string(), 16, w);
    write_raw_grey_exr(path("small.exr").string(), 8, std::vector<float>(64, 1.0f));
    write_raw_grey_exr(path("zeros.exr").string(), 16, std::vector<float>(256, 0.0f));
    write_raw_grey_exr(path("measured.exr").string(), 16, std::vector<float>(256, 0.5f));
    const auto fails = [&](const std::string& options, const std::vector<std::string>& needles) {
        const CliResult r = invert(options + " --out o");
        expect_one_line_naming(r, needles);
        EXPECT_FALSE(fs::exists(path("o"))) << options;
    };
    fails("--reference slice.exr --weights negative.exr", {"--reference", "weight of pixel (0, 3) is -1"});
    fails("--reference slice.exr --weights small.exr", {"--weights", "small.exr", "8x8", "16x16"});
    fails("--reference slice.exr --weights zeros.exr", {"every weight is 0"});
    fails("--weights small.exr --size 8", {"--weights", "needs --reference"});
    fails("--reference missing.exr", {"missing.exr"});
    fails("--reference slice.exr --resolution 8", {"--reference", "16x16", "--resolution is 8"});
    fails("--reference measured.exr", {"measured.exr", "no wavebrdf slice attributes", "--sigma-p-um"});
    fails("--reference slice.exr --truth truth.exr", {"--truth", "--reference", "exclude"});
    // A measured slice without attributes, its query given: runs.
    const CliResult ok = invert("--reference measured.exr --sigma-p-um 2 --lambda-um 0.5 --size 8 --out m");
    EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

}  // namespace
