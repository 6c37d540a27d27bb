// inversion_run.h: the parsers, run.json both ways, prepare / run with its status, and the run
// directory, which `wavebrdf invert` and Python's invert() call (one implementation: the CLI's
// metrics.csv is the library run's, tests/python/test_invert.py compares Python's with it).
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {
namespace {

using namespace test;

// A small, fast inversion (the CLI tests' kSmall: 8 x 8 heights, sigma_p 2, 16 x 16 slices).
InversionOptions small_options() {
    InversionOptions o;
    o.rows = o.cols = 8;
    o.sigma_p_um = 2.0;
    o.resolution = 16;
    o.lambda_um = 0.5;
    o.epochs = 6;
    return o;
}

// metrics.csv's rows without the wall-time column.
std::vector<std::string> without_seconds(const std::string& csv) {
    std::vector<std::string> rows;
    for (const std::string& line : lines_of(csv)) rows.push_back(line.substr(0, line.rfind(',')));
    return rows;
}

TEST(InversionRun, ParsersReadEachSpecOnceAndNameTheOption) {
    EXPECT_EQ(parse_positions_spec("fixed").kind, PositionsKind::Fixed);
    EXPECT_EQ(parse_positions_spec("random").kind, PositionsKind::Random);
    expect_throw_naming<std::runtime_error>([] { parse_positions_spec("missing.json", "--positions"); },
                                            "missing.json: cannot open");
    EXPECT_EQ(parse_init_spec("flat").kind, InitKind::Flat);
    const InitSpec noisy = parse_init_spec("noisy:0.25");
    EXPECT_EQ(noisy.kind, InitKind::Noisy);
    EXPECT_EQ(noisy.noise_fraction, 0.25);
    EXPECT_EQ(to_string(noisy), "noisy:0.25");
    const InitSpec file = parse_init_spec("start.exr");
    EXPECT_EQ(file.kind, InitKind::File);
    EXPECT_EQ(file.path, "start.exr");
    expect_throw_naming<std::invalid_argument>([] { parse_init_spec("noisy:x", "--init"); },
                                               "--init 'noisy:x' is invalid; expected flat, noisy:FRAC or FILE.exr");
    expect_throw_naming<std::invalid_argument>([] { parse_init_spec("noisy:x", "init"); }, "init 'noisy:x'");
    expect_throw_naming<std::domain_error>([] { parse_init_spec("noisy:-1", "--init"); }, "--init noisy:-1: ");
    expect_throw_naming<std::domain_error>([] { parse_init_spec("noisy:1e300", "--init"); }, "0 to 1000");
    EXPECT_EQ(parse_epoch_list("30,0,10"), (std::set<int>{0, 10, 30}));
    EXPECT_EQ(format_epoch_list({0, 10, 30}), "0,10,30");
    expect_throw_naming<std::invalid_argument>([] { parse_epoch_list("1,x", "--snapshots"); },
                                               "--snapshots '1,x' is invalid");
    expect_throw_naming<std::invalid_argument>([] { parse_epoch_list("-1", "snapshots"); }, "snapshots '-1'");
    EXPECT_EQ(parse_optimizer("lbfgs"), OptimizerKind::Lbfgs);
    expect_throw_naming<std::invalid_argument>([] { parse_optimizer("sgd", "--optimizer"); },
                                               "--optimizer 'sgd' is unknown; expected adam or lbfgs");
    int rows = 0, cols = 0;
    parse_size("--size", "10x12", rows, cols);
    EXPECT_EQ(rows, 10);
    EXPECT_EQ(cols, 12);
    expect_throw_naming<std::invalid_argument>([&] { parse_size("size", "0", rows, cols); }, "size '0'");
    EXPECT_EQ(option_name(OptionStyle::Cli, "lambda_um"), "--lambda-um");
    EXPECT_EQ(option_name(OptionStyle::Python, "lambda_um"), "lambda_um");
}

TEST(InversionRun, PrepareChecksEveryOptionInTheFrontEndsStyle) {
    InversionOptions o = small_options();
    o.epochs = -1;
    expect_throw_naming<std::invalid_argument>([&] { prepare_inversion(o); }, "--epochs -1");
    o.names = OptionStyle::Python;
    expect_throw_naming<std::invalid_argument>([&] { prepare_inversion(o); }, "epochs -1");
    o = small_options();
    o.spectral = 8;
    expect_throw_naming<std::invalid_argument>([&] { prepare_inversion(o); }, "--lambda-um and --spectral exclude");
    o = small_options();
    o.checkpoint_every = 0;
    expect_throw_naming<std::invalid_argument>([&] { prepare_inversion(o); }, "--checkpoint-every 0");
    o = small_options();
    o.init = parse_init_spec("noisy:0.1");
    expect_throw_naming<std::invalid_argument>([&] { prepare_inversion(o, std::nullopt, std::vector<Observation>{}); },
                                               "--init noisy:FRAC needs --truth");
    o = small_options();
    o.max_memory_gb = 0.0001;
    expect_throw_naming<OutOfMemory>([&] { prepare_inversion(o); },
                                     "invert (8x8 heights, 1 observation(s) of 16x16) needs about");
    // Given initial heights of the wrong size.
    o = small_options();
    o.init.kind = InitKind::Heights;
    o.names = OptionStyle::Python;
    expect_throw_naming<std::invalid_argument>(
        [&] { prepare_inversion(o, std::nullopt, std::nullopt, Heightfield(3, 3, std::vector<double>(9, 0.0))); },
        "init is 3x3; expected 8x8");
}

// run.json's "args" both ways: every option survives, input files become absolute, and the
// integer fields are checked (8.7 is not a resolution).
TEST(InversionRun, RunJsonRoundTrip) {
    const fs::path dir = fresh_dir("inversion_run");
    const std::string positions = (dir / "p.json").string();
    std::ofstream(positions) << "[[1, 2], [3.5, 4]]";
    InversionOptions o = small_options();
    o.rows = 10;
    o.cols = 12;
    o.texel_um = 0.8;
    o.vscale = 2.0;
    o.x_um = 1.5;
    o.lambda_um.reset();
    o.spectral = 3;
    o.omega_i = {0.1, -0.2};
    o.optimizer = OptimizerKind::Adam;
    o.adam.lr = 0.005;
    o.adam.decay = 0.01;
    o.loss = parse_loss("cmsle:0.01");
    o.positions = parse_positions_spec(positions);
    o.init = parse_init_spec("noisy:0.1");
    o.seed = 0xFFFFFFFFFFFFFFF0ull;
    o.snapshots = {0, 2};
    o.checkpoint_every = 7;
    const std::string text = inversion_options_to_json(o);
    const InversionOptions back = inversion_options_from_json(text);
    EXPECT_EQ(inversion_options_to_json(back), text);
    EXPECT_EQ(back.rows, 10);
    EXPECT_EQ(back.cols, 12);
    EXPECT_EQ(back.x_um, std::optional<double>(1.5));
    EXPECT_FALSE(back.y_um.has_value());
    EXPECT_FALSE(back.lambda_um.has_value());
    EXPECT_EQ(back.spectral, std::optional<int>(3));
    EXPECT_EQ(back.seed, 0xFFFFFFFFFFFFFFF0ull);
    EXPECT_EQ(back.positions.kind, PositionsKind::List);
    EXPECT_EQ(back.positions.positions_um.size(), 2u);
    EXPECT_EQ(back.init.noise_fraction, 0.1);
    EXPECT_EQ(back.snapshots, (std::set<int>{0, 2}));
    EXPECT_EQ(back.checkpoint_every, 7);
    EXPECT_TRUE(fs::path(back.positions.path).is_absolute());
    EXPECT_EQ(to_string(back.loss), "cmsle:0.01");

    nlohmann::json j = nlohmann::json::parse(text);
    j["resolution"] = 8.7;
    expect_throw_naming<std::runtime_error>([&] { inversion_options_from_json(j.dump(), "run/run.json"); },
                                            "run/run.json: field 'resolution' is 8.7");
    j = nlohmann::json::parse(text);
    j.erase("lr");
    expect_throw_naming<std::runtime_error>([&] { inversion_options_from_json(j.dump(), "run/run.json"); },
                                            "run/run.json: corrupt");
    // What run.json cannot hold is refused.
    o.positions.path.clear();
    EXPECT_THROW(inversion_options_to_json(o), std::invalid_argument);
    fs::remove_all(dir);
}

// The CLI writes the library's run: `wavebrdf invert` with some options gives, row for row,
// the metrics of prepare_inversion + InversionRun with the same options, and of
// run_inversion_in_directory (its own code path).
TEST(InversionRun, CliLibraryAndDirectoryRunAreOneRun) {
    const fs::path dir = fresh_dir("inversion_run");
    const CliResult cli = run_cli(dir,
                                  "invert --size 8 --sigma-p-um 2 --resolution 16 --lambda-um 0.5 --epochs 6 "
                                  "--init noisy:0.2 --seed 5 --lr 0.02 --loss cmsle:0.1 --no-plots --quiet --out cli");
    ASSERT_EQ(cli.exit_code, 0) << cli.err;

    InversionOptions o = small_options();
    o.init = parse_init_spec("noisy:0.2");
    o.seed = 5;
    o.adam.lr = 0.02;
    o.loss = parse_loss("cmsle:0.1");
    InversionRun run(prepare_inversion(o));
    int calls = 0;
    EXPECT_EQ(run.run([&](const EpochMetrics&, const Heightfield&, const std::vector<double>&,
                          const std::vector<std::vector<double>>&) { return ++calls > 0; }),
              InversionStatus::Completed);
    EXPECT_EQ(calls, 7);
    EXPECT_EQ(run.inversion().epoch(), 6);
    EXPECT_EQ(without_seconds(metrics_csv(run.inversion().history())),
              without_seconds(read_text(dir / "cli/metrics.csv")));

    const InversionDirectoryResult direct = run_inversion_in_directory(o, (dir / "lib").string());
    EXPECT_EQ(direct.status, InversionStatus::Completed);
    EXPECT_EQ(direct.epoch, 6);
    EXPECT_EQ(without_seconds(read_text(dir / "lib/metrics.csv")), without_seconds(read_text(dir / "cli/metrics.csv")));
    EXPECT_EQ(read_text(dir / "lib/estimate.exr"), read_text(dir / "cli/estimate.exr"));
    for (const char* name : {"run.json", "checkpoint.json", "truth.exr", "reference_000.exr", "final_000.png",
                             "snapshots/height_0000.npy"})
        EXPECT_TRUE(fs::exists(dir / "lib" / name)) << name;
    fs::remove_all(dir);
}

// A callback or stop predicate that says stop gives Stopped (no exit), with a checkpoint in a
// directory run, and resuming it finishes the same run as an uninterrupted one.
TEST(InversionRun, StoppedStatusAndResume) {
    const fs::path dir = fresh_dir("inversion_run");
    InversionOptions o = small_options();
    InversionRun run(prepare_inversion(o));
    const InversionStatus status = run.run([](const EpochMetrics& m, const Heightfield&, const std::vector<double>&,
                                              const std::vector<std::vector<double>>&) { return m.epoch < 2; });
    EXPECT_EQ(status, InversionStatus::Stopped);
    EXPECT_EQ(run.inversion().epoch(), 2);

    const InversionDirectoryResult whole = run_inversion_in_directory(o, (dir / "whole").string());
    InversionDirectoryControl control;
    int polls = 0;
    control.stop = [&] { return ++polls == 3; };
    const InversionDirectoryResult part = run_inversion_in_directory(o, (dir / "part").string(), control);
    EXPECT_EQ(part.status, InversionStatus::Stopped);
    EXPECT_EQ(part.epoch, 2);
    EXPECT_TRUE(fs::exists(dir / "part/checkpoint.json"));
    EXPECT_THROW(run_inversion_in_directory(o, (dir / "part").string()), std::invalid_argument) << "not empty";
    expect_throw_naming<std::invalid_argument>([&] { resume_inversion_in_directory((dir / "part").string(), 1, 0.0); },
                                               "--epochs 1 is below");
    const InversionDirectoryResult rest = resume_inversion_in_directory((dir / "part").string(), std::nullopt, 0.0);
    EXPECT_EQ(rest.status, InversionStatus::Completed);
    EXPECT_EQ(rest.epoch, 6);
    EXPECT_EQ(without_seconds(read_text(dir / "part/metrics.csv")),
              without_seconds(read_text(dir / "whole/metrics.csv")));
    EXPECT_EQ(read_text(dir / "part/estimate.exr"), read_text(dir / "whole/estimate.exr"));
    expect_throw_naming<std::runtime_error>([&] { resume_inversion_in_directory((dir / "none").string(), 3, 0.0); },
                                            "none/run.json: cannot open");
    fs::remove_all(dir);
}

}  // namespace
}  // namespace wavebrdf
