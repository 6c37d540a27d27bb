// `wavebrdf invert`: the inverse renderer from the command line. Defaults are the thesis's
// first experiment (16×16 heights, normal incidence, 32×32 spectral slice, flat start, Adam
// 0.01/0.9/0.99 with decay 0.005, 300 epochs, CMSLE ε = 1) on a generated truth.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "cli_signals.h"
#include "commands.h"
#include "report.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/spectrum.h"
#include "../src/core/json_fields.h"

namespace wavebrdf::cli {

namespace {

namespace fs = std::filesystem;

struct InvertArgs {
    std::string truth, observations, init = "flat", size = "16";
    double texel_um = 1.0, vscale = 1.0, x_um = 0.0, y_um = 0.0, sigma_p_um = 4.0;
    // Whether --x-um / --y-um were given (default: the tile centre). Not NaN as "absent":
    // --x-um nan is an error like any non-finite position.
    bool given_x = false, given_y = false;
    std::string model = "OHS";
    double lambda_um = 0.0;  // used only when given_lambda
    int spectral = 0;        // used only when given_spectral
    // Whether the option was given, not its value: --spectral 0 and --lambda-um 0 are errors,
    // not "absent". Not in run.json: a stored run has a non-zero value exactly when given.
    bool given_lambda = false, given_spectral = false;
    double light_x = 0.0, light_y = 0.0;
    int resolution = 32, epochs = 300;
    std::string optimizer = "adam", loss = "cmsle:1", positions = "fixed";
    double lr = 0.01, beta1 = 0.9, beta2 = 0.99, decay = 0.005;
    std::uint64_t seed = 1;
    std::string out, resume, snapshots = "0,10,30,100,300";
    int checkpoint_every = 50;
    bool quiet = false, no_plots = false;
    double max_memory_gb = 0.0;  // 0: the physical memory; not in run.json (a resumed run may move it)
    // Not in run.json: --force (replace the run in --out) and the options given on the
    // command line ("--lr", ...), which --resume checks.
    bool force = false;
    std::vector<std::string> given;
    const CLI::App* command = nullptr;  // to list them
};

// The options a resumed run accepts: the rest come from its run.json.
const std::set<std::string> kResumeOptions = {"--resume", "--epochs", "--quiet", "--no-plots", "--max-memory-gb"};

// `path` as stored in run.json: absolute, so that --resume finds it from any directory.
std::string absolute_path(const std::string& path) {
    return path.empty() ? path : fs::absolute(path).lexically_normal().string();
}

nlohmann::json to_json(const InvertArgs& a) {
    return {{"truth", a.truth}, {"observations", a.observations}, {"init", a.init}, {"size", a.size},
            {"texel_um", a.texel_um}, {"vscale", a.vscale},
            {"x_um", a.given_x ? nlohmann::json(a.x_um) : nlohmann::json(nullptr)},
            {"y_um", a.given_y ? nlohmann::json(a.y_um) : nlohmann::json(nullptr)},
            {"sigma_p_um", a.sigma_p_um}, {"model", a.model}, {"lambda_um", a.lambda_um},
            {"spectral", a.spectral}, {"light_x", a.light_x}, {"light_y", a.light_y},
            {"resolution", a.resolution}, {"epochs", a.epochs}, {"optimizer", a.optimizer},
            {"loss", a.loss}, {"positions", a.positions}, {"lr", a.lr}, {"beta1", a.beta1},
            {"beta2", a.beta2}, {"decay", a.decay}, {"seed", a.seed}, {"snapshots", a.snapshots},
            {"checkpoint_every", a.checkpoint_every}};
}

InvertArgs from_json(const nlohmann::json& j) {
    InvertArgs a;
    a.truth = j.at("truth");
    a.observations = j.at("observations");
    a.init = j.at("init");
    a.size = j.at("size");
    a.texel_um = j.at("texel_um");
    a.vscale = j.at("vscale");
    a.given_x = !j.at("x_um").is_null();
    a.given_y = !j.at("y_um").is_null();
    if (a.given_x) a.x_um = j.at("x_um").get<double>();
    if (a.given_y) a.y_um = j.at("y_um").get<double>();
    a.sigma_p_um = j.at("sigma_p_um");
    a.model = j.at("model");
    a.lambda_um = j.at("lambda_um");
    // Integers must be integers in range (get<int> would read 8.7 as 8 and wrap 2^40 + 8 to 8).
    a.spectral = detail::json_int32(j, "spectral", 0, k_max_spectral_samples, "");
    a.given_lambda = a.lambda_um != 0.0;
    a.given_spectral = a.spectral != 0;
    a.light_x = j.at("light_x");
    a.light_y = j.at("light_y");
    a.resolution = detail::json_int32(j, "resolution", 1, 8192, "");
    a.epochs = detail::json_int32(j, "epochs", 0, k_max_iterations, "");
    a.optimizer = j.at("optimizer");
    a.loss = j.at("loss");
    a.positions = j.at("positions");
    a.lr = j.at("lr");
    a.beta1 = j.at("beta1");
    a.beta2 = j.at("beta2");
    a.decay = j.at("decay");
    // Seeds are 64-bit unsigned: the upper half is a JSON unsigned integer, the rest as checked.
    a.seed = j.at("seed").is_number_unsigned()
                 ? j.at("seed").get<std::uint64_t>()
                 : static_cast<std::uint64_t>(detail::json_int(j, "seed", 0, std::numeric_limits<long long>::max(), ""));
    a.snapshots = j.at("snapshots");
    a.checkpoint_every = detail::json_int32(j, "checkpoint_every", 1, std::numeric_limits<int>::max(), "");
    return a;
}

std::set<int> parse_epoch_list(const std::string& text) {
    std::set<int> out;
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) {
        try {
            std::size_t used = 0;
            const int e = std::stoi(item, &used);
            if (used != item.size() || e < 0) throw std::invalid_argument(item);
            out.insert(e);
        } catch (const std::logic_error&) {
            throw std::invalid_argument("--snapshots '" + text + "' is invalid; expected epochs like 0,10,30");
        }
    }
    return out;
}

std::string metrics_csv(const std::vector<EpochMetrics>& history) {
    std::ostringstream out;
    out.precision(10);
    out << "epoch,loss,brdf_mse,cmsle_1,cmsle_0.001,rgb_mse,rgb_gamma_mse,height_mse,seconds\n";
    for (const EpochMetrics& m : history)
        out << m.epoch << ',' << m.loss << ',' << m.brdf_mse << ',' << m.cmsle_1 << ',' << m.cmsle_0_001 << ','
            << m.rgb_mse << ',' << m.rgb_gamma_mse << ',' << (std::isnan(m.height_mse) ? std::string("nan") : [&] {
                   std::ostringstream s;
                   s.precision(10);
                   s << m.height_mse;
                   return s.str();
               }()) << ',' << m.seconds << '\n';
    return out.str();
}

void run(InvertArgs a) {
    const bool resuming = !a.resume.empty();
    const bool quiet = a.quiet;
    const bool no_plots = a.no_plots;
    const double max_memory_gb = a.max_memory_gb;
    const MemoryLimit memory = memory_limit(max_memory_gb);
    std::string dir = a.out;
    if (resuming) {
        for (const std::string& option : a.given)
            if (!kResumeOptions.count(option))
                throw std::invalid_argument(option + " cannot be combined with --resume: a resumed run keeps the options in " +
                                            a.resume + "/run.json; expected only --epochs (to extend it), --quiet, --no-plots or --max-memory-gb");
        const bool extend = std::find(a.given.begin(), a.given.end(), "--epochs") != a.given.end();
        const int epochs = a.epochs;
        dir = a.resume;
        std::ifstream in(dir + "/run.json");
        if (!in) throw std::runtime_error(dir + "/run.json: cannot open; expected a directory written by 'wavebrdf invert --out'");
        try {
            a = from_json(nlohmann::json::parse(in).at("args"));
        } catch (const nlohmann::json::exception& e) {
            throw std::runtime_error(dir + "/run.json: corrupt (" + std::string(e.what()) + ")");
        } catch (const std::runtime_error& e) {  // an integer field out of range (from_json)
            throw std::runtime_error(dir + "/run.json: " + std::string(e.what()));
        }
        if (!fs::exists(dir + "/checkpoint.json"))
            throw std::runtime_error(dir + "/checkpoint.json: missing; nothing to resume");
        if (extend) a.epochs = epochs;
    }
    if (dir.empty()) throw std::invalid_argument("no output directory; expected --out DIR (or --resume DIR)");
    // A new run goes into a new or empty directory (or, with --force, one of invert's own runs).
    if (!resuming) check_run_directory(RunKind::Invert, dir, a.force);

    // Settings.
    InversionSettings settings;
    settings.loss = parse_loss(a.loss);
    if (a.optimizer == "adam") settings.optimizer = OptimizerKind::Adam;
    else if (a.optimizer == "lbfgs") settings.optimizer = OptimizerKind::Lbfgs;
    else throw std::invalid_argument("--optimizer '" + a.optimizer + "' is unknown; expected adam or lbfgs");
    settings.adam.lr = a.lr;
    settings.adam.beta1 = a.beta1;
    settings.adam.beta2 = a.beta2;
    settings.adam.decay = a.decay;
    validate_iterations(a.epochs, "--epochs");
    settings.epochs = a.epochs;
    settings.seed = a.seed;
    std::vector<std::array<double, 2>> position_list;
    if (a.positions == "random") settings.positions = PositionMode::Random;
    else if (a.positions != "fixed") position_list = read_positions_json(a.positions);
    const std::set<int> snapshots = parse_epoch_list(a.snapshots);
    if (a.checkpoint_every < 1)
        throw std::invalid_argument("--checkpoint-every " + std::to_string(a.checkpoint_every) + " is invalid; expected >= 1");
    validate(settings);  // the Adam options with their own messages, bounds, L-BFGS vs random positions
    // --init noisy:FRAC, checked before the truth is read or rendered.
    double noisy_frac = -1.0;
    if (a.init.rfind("noisy:", 0) == 0) {
        if (!a.observations.empty()) throw std::invalid_argument("--init noisy:FRAC needs --truth (noise is added to the truth)");
        try {
            std::size_t used = 0;
            noisy_frac = std::stod(a.init.substr(6), &used);
            if (used != a.init.size() - 6) throw std::invalid_argument(a.init);
        } catch (const std::logic_error&) {
            throw std::invalid_argument("--init '" + a.init + "' is invalid; expected flat, noisy:FRAC or FILE.exr");
        }
        try {
            validate_noise_fraction(noisy_frac);
        } catch (const std::exception& e) {
            throw std::domain_error("--init " + a.init + ": " + e.what());
        }
    }

    // Wavelengths.
    std::vector<double> lambdas;
    if (a.given_spectral && a.given_lambda)
        throw std::invalid_argument("--lambda-um and --spectral exclude each other");
    if (a.given_lambda) {
        try {
            validate_lambda(a.lambda_um);
        } catch (const std::exception& e) {
            throw std::domain_error("--lambda-um: " + std::string(e.what()));
        }
        lambdas = {a.lambda_um};
    } else {
        const int count = a.given_spectral ? a.spectral : 8;
        if (count < 1 || count > 256)
            throw std::domain_error("--spectral " + std::to_string(count) + " is out of range; expected 1 to 256");
        lambdas = spectral_wavelengths_um(count);
    }
    validate_resolution(a.resolution);

    // Truth, observations, initial guess.
    if (!a.truth.empty() && !a.observations.empty())
        throw std::invalid_argument("--truth and --observations exclude each other");
    std::unique_ptr<Heightfield> truth;
    std::vector<Observation> observations;
    int rows = 0, cols = 0;
    if (!a.observations.empty()) {
        observations = read_observations_json(a.observations, max_memory_gb);
        parse_size("--size", a.size, rows, cols);
        if (settings.positions == PositionMode::Random && observations.size() < 2)
            throw std::invalid_argument("--positions random with --observations needs at least two observations");
    } else {
        if (a.truth.empty()) {
            // The built-in default: a generated 16×16 isotropic surface (heights about ±1 texel,
            // like the thesis's crop of the release's isotropic.exr).
            int r = 0, c = 0;
            parse_size("--size", a.size, r, c);
            truth = std::make_unique<Heightfield>(default_inversion_truth(r, c, a.texel_um, a.vscale, a.seed));
        } else {
            truth = std::make_unique<Heightfield>(read_heightfield_exr(a.truth, a.texel_um, a.vscale));
        }
        rows = truth->rows();
        cols = truth->cols();
        Observation base;
        base.query.model = parse_model(a.model);
        base.query.sigma_p_um = a.sigma_p_um;
        base.query.omega_i = {a.light_x, a.light_y};
        base.lambdas_um = lambdas;
        base.resolution = a.resolution;
        if (position_list.empty())
            position_list.push_back({a.given_x ? a.x_um : 0.5 * truth->period_x_um(),
                                     a.given_y ? a.y_um : 0.5 * truth->period_y_um()});
        // Before the references are rendered: the whole inversion's estimate against the limit.
        std::vector<Observation> planned(position_list.size(), base);
        for (std::size_t i = 0; i < planned.size(); ++i) {
            planned[i].query.x_um = position_list[i][0];
            planned[i].query.y_um = position_list[i][1];
        }
        require_memory(estimate_inversion_bytes(*truth, planned, settings), memory,
                       "invert (" + std::to_string(rows) + "x" + std::to_string(cols) + " heights, " +
                           std::to_string(planned.size()) + " observation(s) of " + std::to_string(a.resolution) + "x" +
                           std::to_string(a.resolution) + ")");
        observations = observe(*truth, base, position_list, settings.render);
    }

    std::vector<double> init(static_cast<std::size_t>(rows) * cols, 0.0);
    if (a.init == "flat") {
    } else if (noisy_frac >= 0.0) {
        init = noisy_start(*truth, noisy_frac, a.seed);
    } else {
        const Heightfield file = read_heightfield_exr(a.init, a.texel_um, a.vscale);
        if (file.rows() != rows || file.cols() != cols)
            throw std::invalid_argument("--init " + a.init + " is " + std::to_string(file.rows()) + "x" +
                                        std::to_string(file.cols()) + "; expected " + std::to_string(rows) + "x" +
                                        std::to_string(cols));
        init = file.values();
    }
    const Heightfield initial(rows, cols, init, a.texel_um, a.vscale);
    if (!a.observations.empty())
        require_memory(estimate_inversion_bytes(initial, observations, settings), memory,
                       "invert (" + std::to_string(rows) + "x" + std::to_string(cols) + " heights, " +
                           std::to_string(observations.size()) + " observation(s))");
    Inversion inversion(observations, initial, settings, truth.get());

    // Output directory.
    if (!resuming) prepare_run_directory(RunKind::Invert, dir, a.force);
    fs::create_directories(dir + "/snapshots");
    check_writable(dir + "/metrics.csv");
    const int channels = observations[0].channels();
    if (resuming) {
        inversion.load_checkpoint(dir + "/checkpoint.json");
        if (a.epochs < inversion.epoch())
            throw std::invalid_argument("--epochs " + std::to_string(a.epochs) + " is below the checkpoint's epoch " +
                                        std::to_string(inversion.epoch()) + "; expected at least that many");
        // The new target, for a later --resume.
        std::ifstream in(dir + "/run.json");
        nlohmann::json run = nlohmann::json::parse(in);
        if (run["args"]["epochs"] != a.epochs) {
            run["args"]["epochs"] = a.epochs;
            write_text_atomically(dir + "/run.json", run.dump(1) + "\n");
        }
    } else {
        // Input files by absolute path, so that --resume finds them from any directory.
        InvertArgs stored = a;
        stored.truth = absolute_path(a.truth);
        stored.observations = absolute_path(a.observations);
        if (a.init != "flat" && noisy_frac < 0.0) stored.init = absolute_path(a.init);
        if (a.positions != "fixed" && a.positions != "random") stored.positions = absolute_path(a.positions);
        nlohmann::json run = {{"args", to_json(stored)},
                              {"title", "wavebrdf invert: " + a.loss + ", " + a.optimizer + ", " +
                                            std::to_string(rows) + "x" + std::to_string(cols) + " heights, " +
                                            std::to_string(a.resolution) + "^2 slices, " +
                                            std::to_string(observations.size()) + " observation(s), positions " + a.positions},
                              {"snapshot_epochs", std::vector<int>(snapshots.begin(), snapshots.end())},
                              {"channels", channels},
                              {"resolution", observations[0].resolution},
                              {"texel_um", a.texel_um},
                              {"truth", truth != nullptr},
                              {"observations", observations.size()}};
        write_text_atomically(dir + "/run.json", run.dump(1) + "\n");
        const Observation& o = observations[0];
        write_npy(dir + "/reference.npy",
                  {std::size_t(o.resolution), std::size_t(o.resolution), std::size_t(channels)}, o.reference);
        if (truth) {
            write_npy(dir + "/truth_height.npy", {std::size_t(rows), std::size_t(cols)}, heights_um(*truth));
            write_heightfield_exr(dir + "/truth.exr", *truth);
        }
        for (std::size_t i = 0; i < observations.size(); ++i) {
            char name[64];
            std::snprintf(name, sizeof name, "/reference_%03zu", i);
            const RgbImage image = to_image(observations[i].reference, observations[i].resolution, channels);
            write_rgb_exr(dir + name + ".exr", image);
            write_rgb_png(dir + name + ".png", image, auto_exposure(observations[i].reference), true);
        }
    }

    // The first SIGINT/SIGTERM stops at the end of the epoch with a checkpoint; a second one
    // ends the process at once (temporary files removed, cli_signals.h).
    std::optional<GracefulStop> stop;
    stop.emplace();
    Progress progress("invert", settings.epochs + 1, !quiet);
    progress.advance(inversion.epoch());
    int last_checkpoint = inversion.epoch();
    auto checkpoint = [&] {
        inversion.save_checkpoint(dir + "/checkpoint.json");
        write_text_atomically(dir + "/metrics.csv", metrics_csv(inversion.history()));
    };
    // A failure midway (an exception from the run or from writing its outputs) keeps what was
    // finished: the checkpoint and metrics of the last completed epoch and its estimate, each
    // written on its own so that one failing write does not lose the others.
    const auto run_epochs = [&](const Inversion::Callback& on_epoch) {
        try {
            inversion.run(on_epoch);
        } catch (const std::exception& e) {
            std::vector<std::string> saved;
            const auto keep = [&](const char* what, auto&& write) {
                try {
                    write();
                    saved.push_back(what);
                } catch (const std::exception&) {
                }
            };
            keep("checkpoint.json", [&] { inversion.save_checkpoint(dir + "/checkpoint.json"); });
            keep("metrics.csv", [&] { write_text_atomically(dir + "/metrics.csv", metrics_csv(inversion.history())); });
            keep("estimate.exr", [&] { write_heightfield_exr(dir + "/estimate.exr", inversion.estimate()); });
            std::string list;
            for (const std::string& name : saved) list += (list.empty() ? "" : ", ") + name;
            throw std::runtime_error(std::string(e.what()) + "; the run stopped at epoch " +
                                     std::to_string(inversion.epoch()) + " and " +
                                     (saved.empty() ? std::string("nothing more could be written to ") + dir
                                                    : "its " + list + " are in " + dir));
        }
    };
    run_epochs([&](const EpochMetrics& m, const Heightfield& estimate, const std::vector<double>& gradient,
                      const std::vector<std::vector<double>>& slices) {
        if (snapshots.count(m.epoch)) {
            char name[64];
            std::snprintf(name, sizeof name, "%04d.npy", m.epoch);
            const std::string base = dir + "/snapshots/";
            write_npy(base + "height_" + name, {std::size_t(rows), std::size_t(cols)}, heights_um(estimate));
            const int n = observations[0].resolution;
            write_npy(base + "slice_" + name, {std::size_t(n), std::size_t(n), std::size_t(channels)}, slices[0]);
            std::vector<double> g = gradient.empty() ? std::vector<double>(estimate.values().size(), 0.0) : gradient;
            write_npy(base + "gradient_" + name, {std::size_t(rows), std::size_t(cols)}, g);
        }
        char message[96];
        std::snprintf(message, sizeof message, "epoch %d loss %.4g", m.epoch, m.loss);
        progress.set_message(message);
        progress.advance(1);
        if (stop->signal() != 0) {
            checkpoint();
            return false;
        }
        if (m.epoch - last_checkpoint >= a.checkpoint_every) {
            checkpoint();
            last_checkpoint = m.epoch;
        }
        return true;
    });
    progress.finish();
    checkpoint();

    // Final outputs.
    const Heightfield& estimate = inversion.estimate();
    write_heightfield_exr(dir + "/estimate.exr", estimate);
    write_heightfield_png(dir + "/estimate.png", estimate);
    for (std::size_t i = 0; i < observations.size(); ++i) {
        char name[64];
        std::snprintf(name, sizeof name, "/final_%03zu", i);
        const auto slice = render_observation(estimate, observations[i], settings.render);
        const RgbImage image = to_image(slice, observations[i].resolution, channels);
        write_rgb_exr(dir + name + ".exr", image);
        write_rgb_png(dir + name + ".png", image, auto_exposure(observations[i].reference), true);
    }
    const int sig = stop->signal();
    stop.reset();
    if (!no_plots) draw_report(RunKind::Invert, dir);
    const auto& h = inversion.history();
    if (!quiet && !h.empty()) {
        const EpochMetrics& first = h.front();
        const EpochMetrics& last = h.back();
        std::fprintf(stderr, "epoch %d: loss %.4g (%.2f%% of epoch 0), BRDF MSE %.2f%% of epoch 0", last.epoch,
                     last.loss, 100.0 * last.loss / first.loss, 100.0 * last.brdf_mse / first.brdf_mse);
        if (!std::isnan(last.height_mse)) std::fprintf(stderr, ", height MSE %.4g um^2", last.height_mse);
        std::fprintf(stderr, ", %.1f s; results in %s\n", last.seconds, dir.c_str());
    }
    if (sig != 0) {
        std::fprintf(stderr, "wavebrdf: interrupted at epoch %d; checkpoint written, continue with: wavebrdf invert --resume %s\n",
                     inversion.epoch(), dir.c_str());
        std::exit(128 + sig);
    }
}

}  // namespace

void add_invert_command(CLI::App& app) {
    auto a = std::make_shared<InvertArgs>();
    CLI::App* cmd = app.add_subcommand("invert", "Recover heights whose BRDF slices match references (the thesis's inverse renderer)");
    a->command = cmd;
    cmd->add_option("--truth", a->truth, "true heightfield EXR: references are rendered from it (default: a generated 16x16 surface)");
    cmd->add_option("--observations", a->observations, "reference slices with their query parameters (JSON)");
    cmd->add_option("--size", a->size, "heightfield size NxM for the generated truth or with --observations")->capture_default_str();
    cmd->add_option("--texel-um", a->texel_um, "texel width w in um")->capture_default_str();
    cmd->add_option("--vscale", a->vscale, "vertical scale v")->capture_default_str();
    auto* x_um = cmd->add_option("--x-um", a->x_um, "footprint centre x in um, any finite value (periodic; default: tile centre)");
    auto* y_um = cmd->add_option("--y-um", a->y_um, "footprint centre y in um, any finite value (periodic; default: tile centre)");
    cmd->add_option("--sigma-p-um", a->sigma_p_um, "footprint sigma_p in um")->capture_default_str();
    cmd->add_option("--model", a->model, "OHS, GHS, ROHS, RGHS or Kirchhoff")->capture_default_str();
    auto* lambda = cmd->add_option("--lambda-um", a->lambda_um, "single wavelength in um (default: --spectral 8)");
    auto* spectral = cmd->add_option("--spectral", a->spectral, "N wavelengths, CIE 1931 to linear sRGB (default 8)");
    cmd->add_option("--light-x", a->light_x, "projected light direction x")->capture_default_str();
    cmd->add_option("--light-y", a->light_y, "projected light direction y")->capture_default_str();
    cmd->add_option("--resolution", a->resolution, "slice size n")->capture_default_str();
    cmd->add_option("--init", a->init, "flat, noisy:FRAC (truth + uniform noise of width FRAC x height range) or FILE.exr")->capture_default_str();
    cmd->add_option("--epochs", a->epochs, "epochs (Adam steps or L-BFGS iterations), 0 to 10^7")->capture_default_str();
    cmd->add_option("--optimizer", a->optimizer, "adam or lbfgs")->capture_default_str();
    cmd->add_option("--lr", a->lr, "Adam learning rate (heights in texel units)")->capture_default_str();
    cmd->add_option("--beta1", a->beta1, "Adam beta1")->capture_default_str();
    cmd->add_option("--beta2", a->beta2, "Adam beta2")->capture_default_str();
    cmd->add_option("--decay", a->decay, "learning-rate decay per epoch: lr * exp(-decay * epoch)")->capture_default_str();
    cmd->add_option("--loss", a->loss, "cmsle:EPS, mse, amplitude or poisson:N (N photons per slice)")->capture_default_str();
    cmd->add_option("--positions", a->positions, "fixed, random (a new position per epoch) or FILE.json ([[x_um, y_um], ...])")->capture_default_str();
    cmd->add_option("--seed", a->seed, "seed (generated truth, noise, random positions)")->capture_default_str();
    cmd->add_option("--out", a->out, "output directory");
    cmd->add_option("--resume", a->resume,
                    "continue the run in this directory with its own options (--epochs N extends it to N epochs)");
    cmd->add_flag("--force", a->force,
                  "replace the earlier run in --out (only a directory that holds nothing but invert's outputs)");
    cmd->add_option("--snapshots", a->snapshots, "epochs to keep heights, slices and gradients for the report")->capture_default_str();
    cmd->add_option("--checkpoint-every", a->checkpoint_every, "epochs between checkpoints")->capture_default_str();
    cmd->add_flag("--no-plots", a->no_plots, "do not draw report.png and curves.png");
    cmd->add_flag("--quiet", a->quiet, "no progress bar or summary");
    cmd->add_option("--max-memory-gb", a->max_memory_gb,
                    "refuse a run whose estimated peak memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->callback([a, lambda, spectral, x_um, y_um] {
        a->given_x = x_um->count() > 0;
        a->given_y = y_um->count() > 0;
        a->given_lambda = lambda->count() > 0;
        a->given_spectral = spectral->count() > 0;
        a->given.clear();
        for (const CLI::Option* option : a->command->get_options())
            if (option->count() > 0) a->given.push_back(option->get_name());
        run(*a);
    });
}

}  // namespace wavebrdf::cli
