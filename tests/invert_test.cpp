// The inverse renderer: the library's Inversion on a tiny problem (the optimisers reduce the
// loss, epoch-0 metrics are those of the initial guess, checkpoints resume bit for bit and
// refuse another run's state, random positions follow the seed), and `wavebrdf invert` end to
// end (its outputs, SIGTERM → checkpoint → --resume to the same result, and one clear line,
// a non-zero exit and nothing written for every bad input).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/threads.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/version.h"

namespace fs = std::filesystem;
using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

// ---------------------------------------------------------------------------------------------
// The tiny problem: 8×8 heights, σ_p 2 µm, one 16×16 single-wavelength slice (λ 0.5 µm) at the
// tile centre, from a flat start.

Heightfield tiny_truth() { return test::random_heightfield(8, 8, 0.3, 11); }

Observation tiny_observation(const Heightfield& truth, double x_um = 4.0, double y_um = 4.0) {
    Observation o;
    o.query.x_um = x_um;
    o.query.y_um = y_um;
    o.query.sigma_p_um = 2.0;
    o.lambdas_um = {0.5};
    o.resolution = 16;
    o.reference = to_reference(render_observation(truth, o));
    return o;
}

Heightfield flat() { return Heightfield(8, 8, std::vector<double>(64, 0.0)); }

InversionSettings tiny_invert_settings(int epochs) {
    InversionSettings s;
    s.epochs = epochs;
    return s;
}

// Runs `f`, expecting exception E whose message contains every one of `needles`.
template <typename E, typename F>
void expect_throw_naming_each(F&& f, const std::vector<std::string>& needles) {
    try {
        f();
        ADD_FAILURE() << "no exception thrown";
    } catch (const E& e) {
        const std::string what = e.what();
        for (const std::string& needle : needles)
            EXPECT_NE(what.find(needle), std::string::npos) << "message does not name '" << needle << "': " << what;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
    }
}

// ---------------------------------------------------------------------------------------------
// The fixture: a fresh directory per test and the CLI helpers of cli_util.h.

// A single-wavelength tiny run, fast enough (< 1 s) for every test below.
const std::string kSmall = " --size 8 --sigma-p-um 2 --resolution 16 --no-plots --quiet";

class InvertTest : public ::testing::Test {
protected:
    void SetUp() override { m_dir = fresh_dir("invert"); }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(m_dir);
    }

    fs::path path(const std::string& name) const { return m_dir / name; }

    CliResult run(const std::string& args) const { return run_cli(m_dir, args); }

    // `invert` with the tiny defaults; --epochs 20 and --lambda-um 0.5 unless `extra` sets them.
    // With --resume only --no-plots --quiet are added (the run keeps its own options).
    CliResult invert(const std::string& extra) const {
        if (extra.find("--resume") != std::string::npos) return run("invert " + extra + " --no-plots --quiet");
        std::string args = "invert" + kSmall + " " + extra;
        if (extra.find("--epochs") == std::string::npos && extra.find("--resume") == std::string::npos)
            args += " --epochs 20";
        if (extra.find("--lambda-um") == std::string::npos && extra.find("--spectral") == std::string::npos &&
            extra.find("--resume") == std::string::npos)
            args += " --lambda-um 0.5";
        return run(args);
    }

    // Non-zero exit, exactly one stderr line naming every one of `needles`, and nothing at
    // any of `absent` (nor a temporary file in the test directory).
    void expect_clean_failure(const CliResult& r, const std::vector<std::string>& needles,
                              const std::vector<fs::path>& absent) const {
        if (!expect_one_line_naming(r, needles)) return;
        for (const fs::path& p : absent) EXPECT_FALSE(fs::exists(p)) << p << " was left behind";
        for (const auto& entry : fs::recursive_directory_iterator(m_dir))
            EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos)
                << "temporary file left behind: " << entry.path();
    }

    // metrics.csv as rows of fields.
    std::vector<std::vector<std::string>> metrics(const std::string& run_dir) const {
        std::vector<std::vector<std::string>> rows;
        for (const std::string& line : lines_of(read_text(path(run_dir) / "metrics.csv"))) {
            std::vector<std::string> fields;
            std::stringstream in(line);
            std::string f;
            while (std::getline(in, f, ',')) fields.push_back(f);
            rows.push_back(fields);
        }
        return rows;
    }

    // A single-wavelength 16×16 observation of a tiny truth, as JSON with the reference inline.
    std::string write_observations(const std::string& name) const {
        const Heightfield truth = tiny_truth();
        write_observations_json(path(name).string(), {tiny_observation(truth)});
        return name;
    }

    fs::path m_dir;
};

// ---------------------------------------------------------------------------------------------
// Library

TEST_F(InvertTest, AdamReducesTheLossAndEpochZeroIsTheInitialGuess) {
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    const InversionSettings settings = tiny_invert_settings(20);
    Inversion inversion(obs, flat(), settings, &truth);
    std::vector<EpochMetrics> seen;
    inversion.run([&](const EpochMetrics& m, const Heightfield&, const std::vector<double>& gradient,
                      const std::vector<std::vector<double>>& slices) {
        EXPECT_EQ(gradient.size(), 64u);
        EXPECT_EQ(slices.size(), 1u);
        seen.push_back(m);
        return true;
    });
    ASSERT_EQ(seen.size(), 21u);
    ASSERT_EQ(inversion.history().size(), 21u);
    EXPECT_EQ(inversion.epoch(), 20);
    for (int e = 0; e <= 20; ++e) EXPECT_EQ(seen[e].epoch, e);

    // Epoch 0 is measured at the initial guess.
    const double initial = observation_loss(flat(), obs, settings.loss, nullptr, settings.render);
    EXPECT_EQ(seen[0].loss, initial);
    EXPECT_EQ(seen[0].cmsle_1, initial) << "the default loss is CMSLE with eps = 1";
    const Loss mse{LossKind::MSE, 1.0};
    EXPECT_DOUBLE_EQ(seen[0].brdf_mse, observation_loss(flat(), obs, mse, nullptr, settings.render));
    std::vector<double> truth_um = truth.values();
    for (double& v : truth_um) v *= truth.vscale() * truth.texel_um();
    EXPECT_DOUBLE_EQ(seen[0].height_mse, height_mse(std::vector<double>(64, 0.0), truth_um));

    EXPECT_GT(initial, 0.0);
    EXPECT_LT(seen.back().loss, 0.5 * initial) << "Adam did not reduce the loss";
    EXPECT_EQ(seen.back().loss, observation_loss(inversion.estimate(), obs, settings.loss, nullptr, settings.render))
        << "the last metrics are those of the final estimate";
}

TEST_F(InvertTest, LbfgsReducesTheLoss) {
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    InversionSettings settings = tiny_invert_settings(25);
    settings.optimizer = OptimizerKind::Lbfgs;
    Inversion inversion(obs, flat(), settings, &truth);
    inversion.run({});
    const auto& h = inversion.history();
    ASSERT_EQ(h.size(), 26u) << "one L-BFGS iteration per epoch";
    const double initial = observation_loss(flat(), obs, settings.loss, nullptr, settings.render);
    EXPECT_EQ(h.front().epoch, 0);
    EXPECT_EQ(h.front().loss, initial);
    // Every accepted step decreases the loss (Armijo); from the flat start the first steps are
    // short, so it takes a couple of dozen iterations to halve it.
    for (std::size_t e = 1; e < h.size(); ++e) EXPECT_LT(h[e].loss, h[e - 1].loss) << "epoch " << e;
    EXPECT_LT(h.back().loss, 0.5 * initial) << "L-BFGS did not reduce the loss";
    EXPECT_LT(observation_loss(inversion.estimate(), obs, settings.loss, nullptr, settings.render), 0.5 * initial);
}

TEST_F(InvertTest, CheckpointResumesBitForBit) {
    const fs::path& dir = m_dir;
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    const InversionSettings settings = tiny_invert_settings(12);

    Inversion whole(obs, flat(), settings, &truth);
    whole.run({});

    const std::string checkpoint = (dir / "checkpoint.json").string();
    {
        Inversion first(obs, flat(), settings, &truth);
        first.run([](const EpochMetrics& m, const Heightfield&, const std::vector<double>&,
                     const std::vector<std::vector<double>>&) { return m.epoch < 5; });
        ASSERT_EQ(first.epoch(), 5);
        first.save_checkpoint(checkpoint);
    }
    EXPECT_FALSE(fs::exists(checkpoint + ".tmp"));
    Inversion second(obs, flat(), settings, &truth);
    second.load_checkpoint(checkpoint);
    EXPECT_EQ(second.epoch(), 5);
    ASSERT_EQ(second.history().size(), 6u);
    std::vector<int> reported;
    second.run([&](const EpochMetrics& m, const Heightfield&, const std::vector<double>&,
                   const std::vector<std::vector<double>>&) {
        reported.push_back(m.epoch);
        return true;
    });
    EXPECT_EQ(reported, (std::vector<int>{6, 7, 8, 9, 10, 11, 12})) << "epoch 5 is reported once, before the stop";
    EXPECT_EQ(second.estimate().values(), whole.estimate().values()) << "not bitwise identical";
    ASSERT_EQ(second.history().size(), whole.history().size());
    for (std::size_t e = 0; e < whole.history().size(); ++e) {
        EXPECT_EQ(second.history()[e].epoch, whole.history()[e].epoch);
        EXPECT_EQ(second.history()[e].loss, whole.history()[e].loss) << "epoch " << e;
        EXPECT_EQ(second.history()[e].height_mse, whole.history()[e].height_mse) << "epoch " << e;
    }
}

// Every optimiser (and random positions) resumes bit for bit, whether the first part was
// stopped by its callback or ran to a smaller epoch count that the resume extends. L-BFGS
// without its curvature history in the checkpoint took other steps after a resume.
TEST_F(InvertTest, CheckpointResumesBitForBitWithEveryOptimiser) {
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    struct Case {
        const char* name;
        OptimizerKind optimizer;
        PositionMode positions;
    };
    for (const Case& c : {Case{"adam", OptimizerKind::Adam, PositionMode::Fixed},
                          Case{"lbfgs", OptimizerKind::Lbfgs, PositionMode::Fixed},
                          Case{"adam random", OptimizerKind::Adam, PositionMode::Random}}) {
        SCOPED_TRACE(c.name);
        InversionSettings settings = tiny_invert_settings(14);
        settings.optimizer = c.optimizer;
        settings.positions = c.positions;
        settings.lbfgs.history = 4;
        Inversion whole(obs, flat(), settings, &truth);
        whole.run({});
        ASSERT_EQ(whole.epoch(), 14);
        for (const bool extend : {false, true}) {
            SCOPED_TRACE(extend ? "run to 7 epochs, extended to 14" : "stopped at epoch 7");
            const std::string checkpoint = (m_dir / (std::string(c.name) + (extend ? "-e.json" : "-s.json"))).string();
            {
                InversionSettings first_settings = settings;
                if (extend) first_settings.epochs = 7;
                Inversion first(obs, flat(), first_settings, &truth);
                first.run([&](const EpochMetrics& m, const Heightfield&, const std::vector<double>&,
                              const std::vector<std::vector<double>>&) { return extend || m.epoch < 7; });
                ASSERT_EQ(first.epoch(), 7);
                first.save_checkpoint(checkpoint);
            }
            Inversion second(obs, flat(), settings, &truth);
            second.load_checkpoint(checkpoint);
            second.run({});
            EXPECT_EQ(second.estimate().values(), whole.estimate().values()) << "not bitwise identical";
            ASSERT_EQ(second.history().size(), whole.history().size());
            for (std::size_t e = 0; e < whole.history().size(); ++e) {
                EXPECT_EQ(second.history()[e].loss, whole.history()[e].loss) << "epoch " << e;
                EXPECT_EQ(second.history()[e].height_mse, whole.history()[e].height_mse) << "epoch " << e;
            }
        }
    }
}

TEST_F(InvertTest, CheckpointOfAnotherRunIsRefused) {
    const fs::path& dir = m_dir;
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    const InversionSettings settings = tiny_invert_settings(3);
    const std::string checkpoint = (dir / "checkpoint.json").string();
    {
        Inversion run(obs, flat(), settings, &truth);
        run.run({});
        run.save_checkpoint(checkpoint);
    }
    // The same run loads it.
    {
        Inversion same(obs, flat(), settings, &truth);
        EXPECT_NO_THROW(same.load_checkpoint(checkpoint));
    }

    InversionSettings other_lr = settings;
    other_lr.adam.lr = 0.02;
    expect_throw_naming_each<std::runtime_error>(
        [&] { Inversion(obs, flat(), other_lr, &truth).load_checkpoint(checkpoint); },
        {"checkpoint.json", "different run", "lr 0.01 in the checkpoint, 0.02 now"});

    InversionSettings other_seed = settings;
    other_seed.seed = 2;
    expect_throw_naming_each<std::runtime_error>(
        [&] { Inversion(obs, flat(), other_seed, &truth).load_checkpoint(checkpoint); }, {"different run", "seed"});

    const std::vector<Observation> other_obs = {tiny_observation(truth, 3.0, 4.0)};
    expect_throw_naming_each<std::runtime_error>(
        [&] { Inversion(other_obs, flat(), settings, &truth).load_checkpoint(checkpoint); },
        {"different run", "observations"});

    // Another size is another run too.
    const Heightfield big(8, 9, std::vector<double>(72, 0.0));
    expect_throw_naming_each<std::runtime_error>([&] { Inversion(obs, big, settings).load_checkpoint(checkpoint); },
                                            {"different run", "size"});
}

TEST_F(InvertTest, CorruptCheckpointThrows) {
    const fs::path& dir = m_dir;
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    const InversionSettings settings = tiny_invert_settings(3);
    const std::string good = (dir / "good.json").string();
    {
        Inversion run(obs, flat(), settings, &truth);
        run.run({});
        run.save_checkpoint(good);
    }
    const std::string text = read_text(good);
    auto load = [&](const std::string& name, const std::string& content) {
        const std::string file = (dir / name).string();
        std::ofstream(file, std::ios::binary) << content;
        Inversion(obs, flat(), settings, &truth).load_checkpoint(file);
    };
    expect_throw_naming_each<std::runtime_error>([&] { load("garbage.json", "not a checkpoint {"); },
                                            {"garbage.json", "corrupt"});
    expect_throw_naming_each<std::runtime_error>([&] { load("cut.json", text.substr(0, text.size() / 2)); },
                                            {"cut.json", "corrupt"});
    expect_throw_naming_each<std::runtime_error>([&] { load("empty.json", ""); }, {"empty.json"});
    nlohmann::json j = nlohmann::json::parse(text);
    j["format"] = "something-else";
    expect_throw_naming_each<std::runtime_error>([&] { load("format.json", j.dump()); }, {"format.json", "format"});
    j = nlohmann::json::parse(text);
    j["heights"].erase(0);
    expect_throw_naming_each<std::runtime_error>([&] { load("short.json", j.dump()); }, {"short.json"});
    // Issue 9: integers must be integers in range (get<int> read 2.5 as 2, wrapped 2^40 + 8).
    for (const auto& [field, value] : std::vector<std::pair<const char*, nlohmann::json>>{
             {"epoch", 2.5}, {"epoch", -1}, {"rows", 1099511627784LL}, {"adam_steps", 1.5}}) {
        j = nlohmann::json::parse(text);
        j[field] = value;
        expect_throw_naming_each<std::runtime_error>([&] { load("int.json", j.dump()); },
                                                {"int.json", std::string("'") + field + "'"});
    }
    j = nlohmann::json::parse(text);
    j["metrics"][0][0] = 0.5;
    expect_throw_naming_each<std::runtime_error>([&] { load("metric.json", j.dump()); }, {"metric.json", "metrics epoch"});
    j = nlohmann::json::parse(text);
    j.erase("adam_m");
    expect_throw_naming_each<std::runtime_error>([&] { load("no_m.json", j.dump()); }, {"no_m.json", "adam_m"});
    expect_throw_naming_each<std::runtime_error>(
        [&] { Inversion(obs, flat(), settings, &truth).load_checkpoint((dir / "missing.json").string()); },
        {"missing.json"});
}

// --init noisy:FRAC: the truth plus noise uniform on [-w/2, w/2), w = FRAC x the truth's range,
// drawn from the seed's std::mt19937_64 (specified bit for bit) through the library's own
// transform of 53 bits, never a std:: distribution, so every standard library gives the same
// start. Same seed, same start; another seed, another start; the noise fills its interval.
TEST_F(InvertTest, NoisyStartIsTheSameOnEveryStandardLibrary) {
    // Values from -1 to 1: the width 0.25 x 2 = 0.5 and every width x (u - 0.5) are exact, so
    // the comparison below does not depend on how the compiler contracts a * b + c.
    std::vector<double> values(256);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = std::sin(0.37 * double(i));
    values[0] = -1.0;
    values[1] = 1.0;
    const Heightfield truth(16, 16, values, 1.0, 1.0);
    const std::vector<double>& t = truth.values();
    const double frac = 0.25, width = 0.5;
    const std::uint64_t seed = 42;
    const std::vector<double> start = noisy_start(truth, frac, seed);
    ASSERT_EQ(start.size(), t.size());
    EXPECT_EQ(noisy_start(truth, frac, seed), start);
    EXPECT_NE(noisy_start(truth, frac, seed + 1), start);

    std::mt19937_64 rng(seed ^ 0x5eedULL);
    double low = 0.0, high = 0.0;
    for (std::size_t i = 0; i < t.size(); ++i) {
        const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;  // [0, 1), 53 bits
        EXPECT_EQ(start[i], t[i] + width * (u - 0.5)) << "value " << i;
        const double noise = start[i] - t[i];
        EXPECT_GE(noise, -0.5 * width - 1e-15);
        EXPECT_LE(noise, 0.5 * width + 1e-15);
        low = std::min(low, noise);
        high = std::max(high, noise);
    }
    EXPECT_LT(low, -0.4 * width) << "256 samples reach near both ends of the interval";
    EXPECT_GT(high, 0.4 * width);
    EXPECT_EQ(noisy_start(truth, 0.0, seed), t) << "no noise at FRAC 0";
}

TEST_F(InvertTest, RandomPositionsFollowTheSeed) {
    const Heightfield tile = flat();
    std::set<std::pair<double, double>> distinct;
    int differ = 0;
    for (int epoch = 0; epoch < 20; ++epoch) {
        const auto a = Inversion::random_position(7, epoch, tile);
        const auto b = Inversion::random_position(7, epoch, tile);
        EXPECT_EQ(a, b) << "epoch " << epoch;
        for (int k = 0; k < 2; ++k) {
            EXPECT_GE(a[k], 0.0);
            EXPECT_LT(a[k], 8.0);
        }
        distinct.insert({a[0], a[1]});
        if (Inversion::random_position(8, epoch, tile) != a) ++differ;
    }
    EXPECT_EQ(distinct.size(), 20u) << "every epoch draws a new position";
    EXPECT_EQ(differ, 20) << "another seed gives other positions";

    // A random-position run is itself reproducible from its seed, and depends on it.
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    InversionSettings settings = tiny_invert_settings(4);
    settings.positions = PositionMode::Random;
    auto run = [&](std::uint64_t seed) {
        settings.seed = seed;
        Inversion inversion(obs, flat(), settings, &truth);
        inversion.run({});
        return inversion.estimate().values();
    };
    const std::vector<double> first = run(3);
    EXPECT_EQ(run(3), first);
    EXPECT_NE(run(4), first);
}

TEST_F(InvertTest, InvalidSettingsThrow) {
    const Heightfield truth = tiny_truth();
    const std::vector<Observation> obs = {tiny_observation(truth)};
    InversionSettings lbfgs_random = tiny_invert_settings(3);
    lbfgs_random.optimizer = OptimizerKind::Lbfgs;
    lbfgs_random.positions = PositionMode::Random;
    expect_throw_naming_each<std::invalid_argument>([&] { Inversion(obs, flat(), lbfgs_random, &truth); },
                                               {"L-BFGS", "--positions fixed"});
    expect_throw_naming_each<std::invalid_argument>([&] { Inversion(obs, flat(), tiny_invert_settings(-1), &truth); },
                                               {"epochs -1"});
    expect_throw_naming_each<std::invalid_argument>([&] { Inversion({}, flat(), tiny_invert_settings(3), &truth); },
                                               {"no observations"});
    const Heightfield other(8, 9, std::vector<double>(72, 0.0));
    expect_throw_naming_each<std::invalid_argument>([&] { Inversion(obs, flat(), tiny_invert_settings(3), &other); }, {"8x9"});
}

// ---------------------------------------------------------------------------------------------
// CLI

const char* kHeader = "epoch,loss,brdf_mse,cmsle_1,cmsle_0.001,rgb_mse,rgb_gamma_mse,height_mse,seconds";

// A grey float RGB EXR (R = G = B = `values`, rows·cols of them) written with OpenEXR directly,
// so it may hold NaN (wavebrdf's writer would not).
void write_raw_rgb_exr(const std::string& file, int rows, int cols, const std::vector<float>& values) {
    Imf::Header header(cols, rows);
    Imf::FrameBuffer frame;
    for (const char* c : {"R", "G", "B"}) {
        header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        frame.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(values.data())),
                                   sizeof(float), sizeof(float) * static_cast<std::size_t>(cols)));
    }
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

TEST_F(InvertTest, CliWritesMetricsImagesCheckpointAndSnapshots) {
    const CliResult r = invert("--out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "") << "--quiet";
    EXPECT_EQ(r.out, "");
    const auto rows = metrics("run");
    ASSERT_EQ(rows.size(), 22u) << "header and epochs + 1 rows";
    EXPECT_EQ(lines_of(read_text(path("run/metrics.csv")))[0], kHeader);
    for (std::size_t e = 1; e < rows.size(); ++e) {
        ASSERT_EQ(rows[e].size(), 9u) << "row " << e;
        EXPECT_EQ(rows[e][0], std::to_string(e - 1));
        for (const std::string& field : rows[e]) EXPECT_TRUE(std::isfinite(std::stod(field))) << field;
    }
    EXPECT_LT(std::stod(rows.back()[1]), std::stod(rows[1][1])) << "the loss went down";
    for (const char* name :
         {"estimate.exr", "estimate.png", "reference_000.exr", "reference_000.png", "final_000.exr", "final_000.png",
          "checkpoint.json", "run.json", "truth.exr", "reference.npy", "snapshots/height_0000.npy",
          "snapshots/slice_0000.npy", "snapshots/gradient_0000.npy", "snapshots/height_0010.npy"})
        EXPECT_TRUE(fs::exists(path("run") / name)) << name;
    EXPECT_FALSE(fs::exists(path("run/snapshots/height_0030.npy"))) << "only 20 epochs";
    EXPECT_FALSE(fs::exists(path("run/report.png"))) << "--no-plots";
    const Heightfield estimate = read_heightfield_exr(path("run/estimate.exr").string());
    EXPECT_EQ(estimate.rows(), 8);
    EXPECT_EQ(estimate.cols(), 8);
    EXPECT_EQ(read_rgb_exr(path("run/final_000.exr").string()).rows, 16);
    EXPECT_EQ(nlohmann::json::parse(read_text(path("run/checkpoint.json"))).at("epoch"), 20);
    for (const auto& entry : fs::recursive_directory_iterator(path("run")))
        EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
}

// Starts `wavebrdf invert <options> --out <dir>` (stderr to `err_file`), waits until epoch 10's
// snapshot exists (the SIGTERM handler is installed by then), sends SIGTERM and returns the
// wait status.
int run_and_terminate(const std::string& options, const fs::path& dir, const std::string& err_file) {
    const pid_t pid = ::fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        const std::string command = "exec " + quote(WAVEBRDF_CLI) + " invert" + options + " --out " +
                                    quote(dir.string()) + " > /dev/null 2> " + quote(err_file) + " < /dev/null";
        ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
        std::_Exit(127);
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!fs::exists(dir / "snapshots/height_0010.npy") && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ::kill(pid, SIGTERM);
    int status = 0;
    if (::waitpid(pid, &status, 0) != pid) return -1;
    return status;
}

// SIGTERM mid-run: exit 128 + 15 with a checkpoint; --resume finishes it with the same
// estimate (byte for byte) and the same metrics (but wall time) as an uninterrupted run.
TEST_F(InvertTest, CliSigtermCheckpointsAndResumeMatchesAnUninterruptedRun) {
    const fs::path run_dir = path("interrupted");
    const std::string err_file = path("interrupted.err").string();
    // The signal must land before the last epoch; on a machine fast enough to finish first,
    // try again with a longer run.
    int epochs = 100, status = 0, stopped = -1;
    std::string options;
    for (int attempt = 0; attempt < 3; ++attempt, epochs *= 4) {
        fs::remove_all(run_dir);
        options = kSmall + " --lambda-um 0.5 --epochs " + std::to_string(epochs) + " --snapshots 0,10";
        status = run_and_terminate(options, run_dir, err_file);
        ASSERT_NE(status, -1);
        if (!fs::exists(run_dir / "checkpoint.json")) break;
        stopped = nlohmann::json::parse(read_text(run_dir / "checkpoint.json")).at("epoch");
        if (stopped < epochs) break;  // (else it finished first, and may even have been killed)
    }
    ASSERT_TRUE(WIFEXITED(status)) << "killed by the signal instead of exiting";
    EXPECT_EQ(WEXITSTATUS(status), 143);
    const std::string err = read_text(err_file);
    EXPECT_NE(err.find("interrupted at epoch"), std::string::npos) << err;
    EXPECT_NE(err.find("--resume"), std::string::npos) << err;
    ASSERT_TRUE(fs::exists(run_dir / "checkpoint.json"));
    EXPECT_GE(stopped, 10);
    ASSERT_LT(stopped, epochs) << "the run finished before the signal";
    EXPECT_EQ(metrics("interrupted").size(), static_cast<std::size_t>(stopped) + 2);

    const CliResult resumed = run("invert --resume " + quote(run_dir.string()) + " --quiet --no-plots");
    ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
    EXPECT_EQ(resumed.err, "");
    const CliResult whole = run("invert" + options + " --out whole");
    ASSERT_EQ(whole.exit_code, 0) << whole.err;

    const std::string a = read_text(run_dir / "estimate.exr"), b = read_text(path("whole/estimate.exr"));
    ASSERT_FALSE(b.empty());
    EXPECT_TRUE(a == b) << "estimate.exr differs from the uninterrupted run's";
    const auto ra = metrics("interrupted"), rb = metrics("whole");
    ASSERT_EQ(ra.size(), static_cast<std::size_t>(epochs) + 2);
    ASSERT_EQ(rb.size(), static_cast<std::size_t>(epochs) + 2);
    for (std::size_t e = 0; e < rb.size(); ++e) {
        ASSERT_EQ(ra[e].size(), 9u);
        ASSERT_EQ(rb[e].size(), 9u);
        for (std::size_t c = 0; c < 8; ++c) EXPECT_EQ(ra[e][c], rb[e][c]) << "row " << e << ", column " << c + 1;
    }
}

// The report plotter is started without a shell: a hostile --out runs nothing (it used to
// run `touch PWNED` through std::system), and an ordinary name with a quote gets its report.
TEST_F(InvertTest, CliHostileOutNamesRunNoShellAndGetTheirReport) {
    const bool can_plot = python_can_plot();
    for (const std::string name : {"x'; touch PWNED; echo '", "bob's run $(touch PWNED2)"}) {
        SCOPED_TRACE(name);
        const CliResult r = run(
            "invert --size 8 --sigma-p-um 2 --resolution 16 --lambda-um 0.5 --epochs 2 --quiet --out " + quote(name));
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_TRUE(fs::exists(path(name) / "estimate.exr"));
        if (can_plot) {
            EXPECT_TRUE(fs::exists(path(name) / "report.png")) << r.err;
            EXPECT_EQ(r.err, "") << "no warning when the plot is drawn";
        }
    }
    for (const auto& entry : fs::recursive_directory_iterator(m_dir))
        EXPECT_TRUE(entry.path().filename() != "PWNED" && entry.path().filename() != "PWNED2") << entry.path();
}

// Signals never leave temporary files: SIGTERM while the references are being written (the
// process ends by the signal; its handler removes the temporary, which used to stay behind),
// and, during the epochs, two signals at once: the first stops with a checkpoint, the second
// ends the process now (which comes first is the kernel's choice; SIGINT may be ignored when
// the tests run in the background).
TEST_F(InvertTest, CliSignalsLeaveNoTemporaryFiles) {
    bool caught = false;
    for (const char* resolution : {"1024", "2048"}) {
        fs::remove_all(path("early"));
        const pid_t pid = start_cli(
            m_dir, {"invert", "--size", "8", "--sigma-p-um", "2", "--lambda-um", "0.5", "--resolution", resolution,
                    "--epochs", "3", "--no-plots", "--quiet", "--out", "early"});
        ASSERT_GT(pid, 0);
        int status = 0;
        for (;;) {
            if (!temporaries_under(path("early")).empty()) {
                ::kill(pid, SIGTERM);
                caught = true;
                break;
            }
            if (::waitpid(pid, &status, WNOHANG) == pid) break;
        }
        if (!caught) continue;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        EXPECT_TRUE((WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) ||
                    (WIFEXITED(status) && WEXITSTATUS(status) == 143))
            << "status " << status;
        EXPECT_EQ(temporaries_under(path("early")), std::vector<std::string>{});
        break;
    }
    EXPECT_TRUE(caught) << "never saw a write in progress";

    const pid_t pid = start_cli(
        m_dir, {"invert", "--size", "8", "--sigma-p-um", "2", "--lambda-um", "0.5", "--resolution", "16", "--epochs",
                "1000000", "--checkpoint-every", "1", "--no-plots", "--quiet", "--out", "late"});
    ASSERT_GT(pid, 0);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!fs::exists(path("late/checkpoint.json")) && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // into the stream of checkpoint writes
    ::kill(pid, SIGTERM);
    ::kill(pid, SIGINT);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE((WIFEXITED(status) && (WEXITSTATUS(status) == 143 || WEXITSTATUS(status) == 130)) ||
                (WIFSIGNALED(status) && (WTERMSIG(status) == SIGINT || WTERMSIG(status) == SIGTERM)))
        << "status " << status;
    EXPECT_EQ(temporaries_under(path("late")), std::vector<std::string>{});
    EXPECT_NO_THROW({ [[maybe_unused]] const auto whole = nlohmann::json::parse(read_text(path("late/checkpoint.json"))); })
        << "a whole checkpoint";
}

TEST_F(InvertTest, CliRunsFromObservationsButNoisyInitNeedsATruth) {
    write_observations("obs.json");
    const CliResult ok = invert("--observations obs.json --epochs 3 --out run");
    ASSERT_EQ(ok.exit_code, 0) << ok.err;
    const auto rows = metrics("run");
    ASSERT_EQ(rows.size(), 5u);
    EXPECT_EQ(rows[1][7], "nan") << "no truth, no height MSE";
    EXPECT_FALSE(fs::exists(path("run/truth.exr")));
    EXPECT_TRUE(fs::exists(path("run/estimate.exr")));

    expect_clean_failure(invert("--observations obs.json --init noisy:0.1 --out noisy"), {"noisy", "--truth"},
                         {path("noisy")});
}

TEST_F(InvertTest, CliBadObservations) {
    const fs::path out = path("o");
    expect_clean_failure(invert("--observations missing.json --out o"), {"missing.json", "cannot open"}, {out});

    std::ofstream(path("bad.json")) << "{\"observations\": [";
    expect_clean_failure(invert("--observations bad.json --out o"), {"bad.json", "not valid JSON"}, {out});

    nlohmann::json doc = nlohmann::json::parse(read_text(path(write_observations("good.json"))));
    nlohmann::json j = doc;
    j["observations"][0].erase("sigma_p_um");
    std::ofstream(path("no_sigma.json")) << j.dump();
    expect_clean_failure(invert("--observations no_sigma.json --out o"),
                         {"no_sigma.json", "observation 0", "sigma_p_um"}, {out});

    j = doc;
    j["observations"][0]["reference"] = {0.1, 0.2, 0.3, 0.4, 0.5};
    std::ofstream(path("short.json")) << j.dump();
    expect_clean_failure(invert("--observations short.json --out o"), {"short.json", "reference", "5 values"}, {out});

    // A reference EXR of the wrong size, then one holding a NaN, by a path relative to the JSON.
    fs::create_directory(path("refs"));
    write_raw_rgb_exr(path("refs/small.exr").string(), 8, 8, std::vector<float>(64, 0.1f));
    j = doc;
    j["observations"][0]["reference"] = "small.exr";
    std::ofstream(path("refs/small.json")) << j.dump();
    expect_clean_failure(invert("--observations refs/small.json --out o"), {"small.json", "8x8", "16"}, {out});

    std::vector<float> values(256, 0.1f);  // R = G = B
    values[37] = std::numeric_limits<float>::quiet_NaN();
    write_raw_rgb_exr(path("refs/nan.exr").string(), 16, 16, values);
    j = doc;
    j["observations"][0]["reference"] = "nan.exr";
    std::ofstream(path("refs/nan.json")) << j.dump();
    // Value 37 of a single-channel-per-pixel write is pixel (row 2, column 5) of the 16-wide image.
    expect_clean_failure(invert("--observations refs/nan.json --out o"),
                         {"nan.json", "pixel (2, 5) channel 0", "not finite"}, {out});

    // --truth and --observations exclude each other.
    write_heightfield_exr(path("truth.exr").string(), tiny_truth());
    expect_clean_failure(invert("--observations good.json --truth truth.exr --out o"), {"--truth", "--observations"},
                         {out});
}

// Issue 9: run.json's integers were read with implicit conversions (8.7 became 8, 2^40 + 8
// wrapped to 8). A resume refuses them, naming the file and the field, and changes nothing.
TEST_F(InvertTest, CliResumeRefusesNonIntegerFieldsInRunJson) {
    const CliResult first = invert("--epochs 2 --out run");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    const std::string original = read_text(path("run/run.json"));
    const std::vector<std::pair<const char*, nlohmann::json>> cases = {
        {"resolution", 8.7},  {"resolution", 1099511627784LL}, {"epochs", 2147483647LL},
        {"spectral", 100000}, {"checkpoint_every", 0},         {"seed", -1},
        {"epochs", "3"}};
    for (const auto& [field, value] : cases) {
        SCOPED_TRACE(std::string(field) + " = " + value.dump());
        nlohmann::json run_json = nlohmann::json::parse(original);
        run_json["args"][field] = value;
        std::ofstream(path("run/run.json")) << run_json.dump(1);
        expect_clean_failure(invert("--resume run"), {"run/run.json", std::string("'") + field + "'"}, {});
    }
}

TEST_F(InvertTest, CliResumeNeedsARunDirectory) {
    fs::create_directory(path("empty"));
    expect_clean_failure(invert("--resume empty"), {"empty/run.json"}, {});
    EXPECT_TRUE(fs::is_empty(path("empty")));
    expect_clean_failure(invert("--resume nowhere"), {"nowhere/run.json"}, {path("nowhere")});
}

// run.json's lr edited: the checkpoint is from another run, and the message says what differs;
// nothing in the directory changes.
TEST_F(InvertTest, CliResumeRefusesTheCheckpointOfAnotherRun) {
    const CliResult first = invert("--epochs 3 --out run");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    nlohmann::json run_json = nlohmann::json::parse(read_text(path("run/run.json")));
    run_json["args"]["lr"] = 0.02;
    std::ofstream(path("run/run.json")) << run_json.dump(1);
    std::vector<std::pair<std::string, std::string>> before;
    for (const auto& entry : fs::recursive_directory_iterator(path("run")))
        before.emplace_back(entry.path().string(), entry.is_regular_file() ? read_text(entry.path()) : "");
    expect_clean_failure(invert("--resume run"),
                         {"checkpoint.json", "different run", "lr 0.01 in the checkpoint, 0.02 now"}, {});
    std::vector<std::pair<std::string, std::string>> after;
    for (const auto& entry : fs::recursive_directory_iterator(path("run")))
        after.emplace_back(entry.path().string(), entry.is_regular_file() ? read_text(entry.path()) : "");
    std::sort(before.begin(), before.end());
    std::sort(after.begin(), after.end());
    EXPECT_TRUE(before == after) << "the failed resume changed the run directory";
}

TEST_F(InvertTest, CliBadOptions) {
    const fs::path out = path("o");
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
        // Values that used to fail only after the run had written its files.
        {"--lr 1e300", {"lr", "1e+300", "at most 1000"}},
        {"--init noisy:1e300", {"--init noisy:1e300", "0 to 1000"}},
        {"--optimizer sgd", {"--optimizer", "'sgd'"}},
        {"--loss foo", {"'foo'"}},
        {"--positions random --optimizer lbfgs", {"L-BFGS", "--positions"}},
        {"--epochs -1", {"--epochs -1"}},
        {"--init noisy:x", {"--init", "noisy:x"}},
        {"--init noisy:-1", {"--init", "noisy:-1"}},
        {"--init missing.exr", {"missing.exr"}},
        {"--lr 0", {"lr", "got 0"}},
        {"--beta1 1", {"beta1", "got 1"}},
        {"--spectral 0", {"--spectral 0"}},
        {"--spectral 257", {"--spectral 257"}},
        {"--lambda-um 0", {"--lambda-um", "wavelength 0"}},
        {"--lambda-um 0.5 --spectral 8", {"--lambda-um", "--spectral"}},
        {"--positions missing.json", {"missing.json"}},
        {"--size 0", {"--size"}},
        {"--snapshots 1,x", {"--snapshots"}},
        {"--checkpoint-every 0", {"--checkpoint-every 0"}},
        {"--epochs abc", {"--epochs", "abc"}},
        // Issue 9: 2147483647 overflowed the progress total; NaN meant "tile centre"; a footprint
        // far larger than the tile gave zeros.
        {"--epochs 2147483647", {"--epochs 2147483647", "0 to 10000000"}},
        {"--x-um nan", {"query position (nan"}},
        {"--y-um nan", {"query position", "nan)"}},
        {"--texel-um 0.01", {"sigma_p 2 um", "0.08 x 0.08 um", "0.8 um"}},  // kSmall: 8 x 8, sigma_p 2
        {"--texel-um 1e-300", {"texel width 1e-300 um", "0.0001 to 10000 um"}},
        {"--vscale 1e300", {"vertical scale 1e+300", "1e-06 <= |vscale| <= 10000"}},
        // Issue 9: the inversion's memory is estimated before the references are rendered.
        {"--max-memory-gb 0.0001", {"invert (8x8 heights, 1 observation(s) of 16x16) needs about", "(max-memory-gb)"}},
        {"--max-memory-gb -1", {"max-memory-gb -1"}},
    };
    for (const auto& [extra, needles] : cases) {
        SCOPED_TRACE(extra);
        expect_clean_failure(invert(extra + " --out o"), needles, {out});
    }
    expect_clean_failure(invert(""), {"--out"}, {});
}

// metrics.csv without its wall-time column, and estimate.exr's bytes, of a run directory.
std::pair<std::vector<std::vector<std::string>>, std::string> run_result(const fs::path& dir) {
    std::vector<std::vector<std::string>> rows;
    for (const std::string& line : lines_of(read_text(dir / "metrics.csv"))) {
        std::vector<std::string> fields;
        std::stringstream in(line);
        std::string f;
        while (std::getline(in, f, ',')) fields.push_back(f);
        if (!fields.empty()) fields.pop_back();
        rows.push_back(fields);
    }
    return {rows, read_text(dir / "estimate.exr")};
}

// N epochs straight against K epochs and `--resume DIR --epochs N`, bit for bit, for Adam,
// L-BFGS (which restarted its curvature history on resume) and random positions; the inputs
// by relative paths, the resume from another working directory (run.json stores them
// absolute; --epochs was ignored and relative paths were not found).
TEST_F(InvertTest, CliResumeExtendsARunBitForBitFromAnyDirectory) {
    write_heightfield_exr(path("truth.exr").string(), tiny_truth());
    write_heightfield_exr(path("init.exr").string(), test::random_heightfield(8, 8, 0.1, 5));
    std::ofstream(path("pos.json")) << "[[4, 4], [2, 6]]";
    fs::create_directory(path("elsewhere"));
    for (const std::string& variant :
         {std::string("--truth truth.exr"),
          std::string("--truth truth.exr --optimizer lbfgs --positions pos.json --init init.exr"),
          std::string("--truth truth.exr --positions random --init noisy:0.5")}) {
        SCOPED_TRACE(variant);
        fs::remove_all(path("whole"));
        fs::remove_all(path("part"));
        const CliResult whole = invert(variant + " --epochs 12 --out whole");
        ASSERT_EQ(whole.exit_code, 0) << whole.err;
        const CliResult part = invert(variant + " --epochs 5 --out part");
        ASSERT_EQ(part.exit_code, 0) << part.err;
        const CliResult resumed = run_cli(path("elsewhere"), "invert --resume ../part --epochs 12 --quiet --no-plots");
        ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
        EXPECT_EQ(nlohmann::json::parse(read_text(path("part/run.json"))).at("args").at("epochs"), 12)
            << "the new target is kept for a later --resume";
        const auto a = run_result(path("whole")), b = run_result(path("part"));
        ASSERT_EQ(a.first.size(), 14u);
        EXPECT_EQ(a.first, b.first) << "metrics differ from the uninterrupted run's";
        EXPECT_FALSE(a.second.empty());
        EXPECT_TRUE(a.second == b.second) << "estimate.exr differs from the uninterrupted run's";
    }
    // --epochs below the checkpoint's epoch is refused.
    expect_clean_failure(invert("--resume part --epochs 3"), {"--epochs 3", "12"}, {});
}

// Issue 11: run.json records the version, the threads and the actual wavelengths (the options'
// lambda_um / spectral not given are null, not 0); a run.json of 0.1 (0 for "not given", no
// version) still resumes; a truth file's texel width applies without --texel-um, and the run's
// heightfields and slices say what they are.
TEST_F(InvertTest, CliRunJsonRecordsVersionThreadsWavelengthsAndOldOnesResume) {
    write_heightfield_exr(path("truth.exr").string(), tiny_truth().with_scale(0.5, 1.0));
    ASSERT_EQ(invert("--truth truth.exr --spectral 3 --epochs 4 --out run").exit_code, 0);
    const nlohmann::json written = nlohmann::json::parse(read_text(path("run/run.json")));
    EXPECT_EQ(written.at("version"), k_version);
    EXPECT_EQ(written.at("threads"), thread_count());
    EXPECT_GE(written.at("threads").get<int>(), 1);
    EXPECT_EQ(written.at("wavelengths_um").get<std::vector<double>>(), spectral_wavelengths_um(3));
    EXPECT_TRUE(written.at("args").at("lambda_um").is_null());
    EXPECT_EQ(written.at("args").at("spectral"), 3);
    EXPECT_EQ(written.at("args").at("texel_um"), 0.5) << "the truth file's texel width";
    EXPECT_EQ(written.at("texel_um"), 0.5);
    EXPECT_EQ(read_heightfield_exr(path("run/estimate.exr").string()).texel_um(), 0.5);
    EXPECT_NE(read_heightfield_attributes(path("run/estimate.exr").string()).made_by.find("invert"), std::string::npos);
    const SliceFile reference = read_slice_exr(path("run/reference_000.exr").string());
    ASSERT_TRUE(reference.attributes.has_value());
    EXPECT_EQ(reference.attributes->lambdas_um, spectral_wavelengths_um(3));
    EXPECT_EQ(reference.attributes->texel_um, 0.5);
    EXPECT_EQ(reference.attributes->heightfield_rows, 8);
    EXPECT_EQ(reference.attributes->query.sigma_p_um, 2.0);
    EXPECT_EQ(reference.attributes->unit, k_slice_unit);
    ASSERT_TRUE(read_slice_exr(path("run/final_000.exr").string()).attributes.has_value());

    // One wavelength: lambda_um given, spectral null; the list has it.
    ASSERT_EQ(invert("--truth truth.exr --epochs 4 --out mono").exit_code, 0);
    const nlohmann::json mono = nlohmann::json::parse(read_text(path("mono/run.json")));
    EXPECT_EQ(mono.at("wavelengths_um").get<std::vector<double>>(), std::vector<double>{0.5});
    EXPECT_EQ(mono.at("args").at("lambda_um"), 0.5);
    EXPECT_TRUE(mono.at("args").at("spectral").is_null());

    // --texel-um given and different: it wins, with one warning line naming both values.
    const CliResult r = run("invert" + kSmall + " --truth truth.exr --epochs 2 --lambda-um 0.5 --texel-um 1 --out one");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "wavebrdf: warning: --texel-um 1 disagrees with truth.exr's texel_um 0.5; using 1\n");
    EXPECT_EQ(nlohmann::json::parse(read_text(path("one/run.json"))).at("args").at("texel_um"), 1.0);

    // A run.json as 0.1 wrote it: 0 for "not given", no version, threads or wavelengths.
    nlohmann::json old = written;
    old["args"]["lambda_um"] = 0.0;
    old.erase("version");
    old.erase("threads");
    old.erase("wavelengths_um");
    std::ofstream(path("run/run.json")) << old.dump(1);
    const CliResult resumed = invert("--resume run --epochs 6");
    ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
    EXPECT_EQ(nlohmann::json::parse(read_text(path("run/checkpoint.json"))).at("epoch"), 6);
    nlohmann::json old_mono = mono;
    old_mono["args"]["spectral"] = 0;
    std::ofstream(path("mono/run.json")) << old_mono.dump(1);
    const CliResult resumed_mono = invert("--resume mono --epochs 6");
    ASSERT_EQ(resumed_mono.exit_code, 0) << resumed_mono.err;
}

// --resume with any option but --epochs, --quiet and --no-plots is refused by name, before
// anything is written (they used to be ignored silently, and --out other wrote into DIR).
TEST_F(InvertTest, CliResumeRefusesOtherOptions) {
    const CliResult first = invert("--epochs 3 --out run");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    const std::string metrics_before = read_text(path("run/metrics.csv"));
    for (const auto& [extra, option] :
         std::vector<std::pair<std::string, std::string>>{{"--lr 0.5", "--lr"},
                                                          {"--out other", "--out"},
                                                          {"--optimizer lbfgs", "--optimizer"},
                                                          {"--force", "--force"},
                                                          {"--truth t.exr", "--truth"}}) {
        SCOPED_TRACE(extra);
        expect_clean_failure(run("invert --resume run --epochs 6 " + extra), {option, "--resume"}, {path("other")});
    }
    EXPECT_EQ(read_text(path("run/metrics.csv")), metrics_before);
    EXPECT_EQ(nlohmann::json::parse(read_text(path("run/run.json"))).at("args").at("epochs"), 3);
}

// A new run into a non-empty --out is refused (old snapshots mixed into the new report);
// --force replaces a directory of invert's own outputs, but never deletes other files.
TEST_F(InvertTest, CliOutMustBeNewOrEmptyUnlessForced) {
    const CliResult first = invert("--epochs 12 --snapshots 0,10 --out run");
    ASSERT_EQ(first.exit_code, 0) << first.err;
    ASSERT_TRUE(fs::exists(path("run/snapshots/height_0010.npy")));
    const std::string metrics_before = read_text(path("run/metrics.csv"));
    expect_clean_failure(invert("--epochs 3 --out run"), {"--out run", "--force", "--resume"}, {});
    EXPECT_EQ(read_text(path("run/metrics.csv")), metrics_before) << "the refused run changed the directory";

    const CliResult forced = invert("--epochs 3 --out run --force");
    ASSERT_EQ(forced.exit_code, 0) << forced.err;
    EXPECT_FALSE(fs::exists(path("run/snapshots/height_0010.npy"))) << "the old run's snapshot survived --force";
    EXPECT_EQ(metrics("run").size(), 5u);

    std::ofstream(path("run/notes.txt")) << "mine";
    expect_clean_failure(invert("--epochs 3 --out run --force"), {"--out run", "notes.txt"}, {});
    EXPECT_EQ(read_text(path("run/notes.txt")), "mine");
    EXPECT_TRUE(fs::exists(path("run/run.json"))) << "--force deleted files though a foreign one was there";

    fs::create_directory(path("mine"));
    std::ofstream(path("mine/data.csv")) << "1,2";
    expect_clean_failure(invert("--out mine"), {"--out mine", "data.csv"}, {path("mine/run.json")});
    fs::create_directory(path("empty"));
    EXPECT_EQ(invert("--epochs 1 --out empty").exit_code, 0) << "an empty directory is fine";
}

// A failure midway (here the checkpoint outgrows a file-size limit, as on a full disk) keeps
// what the run finished: metrics.csv up to the last epoch and estimate.exr, named in the one
// error line (it used to write neither).
TEST_F(InvertTest, CliFailureMidwayKeepsTheFinishedWork) {
    const std::string command = "cd " + quote(m_dir.string()) + " && trap '' XFSZ && ulimit -f 40 && exec " +
                                quote(WAVEBRDF_CLI) + " invert" + kSmall +
                                " --lambda-um 0.5 --epochs 1000 --checkpoint-every 1 --out run > out.txt 2> err.txt";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 1);
    const CliResult r{1, "", read_text(path("err.txt"))};
    ASSERT_TRUE(expect_one_line_naming(r, {"checkpoint", "stopped at epoch", "metrics.csv", "estimate.exr"}));
    const std::string line = lines_of(r.err)[0];
    const int stopped = std::stoi(line.substr(line.find("stopped at epoch ") + 17));
    EXPECT_GT(stopped, 10);
    EXPECT_LT(stopped, 1000);
    EXPECT_EQ(metrics("run").size(), static_cast<std::size_t>(stopped) + 2) << "header and epochs 0.." << stopped;
    EXPECT_EQ(read_heightfield_exr(path("run/estimate.exr").string()).rows(), 8);
}

}  // namespace
