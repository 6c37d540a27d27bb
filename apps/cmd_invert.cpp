// `wavebrdf invert`: the inverse renderer from the command line. Defaults are the thesis's
// first experiment (16×16 heights, normal incidence, 32×32 spectral slice, flat start, Adam
// 0.01/0.9/0.99 with decay 0.005, 300 epochs, CMSLE ε = 1) on a generated truth.
#include <signal.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "cli_signals.h"
#include "commands.h"
#include "report.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/render_options.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::cli {

namespace {

namespace fs = std::filesystem;

struct InvertArgs {
    std::string truth, observations, reference, weights, init = "flat", size = "16";
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
    RenderPathArgs render;  // --path, --tolerance
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
const std::set<std::string> kResumeOptions = {"--resume",   "--epochs",        "--quiet",
                                              "--no-plots", "--max-memory-gb", "--threads"};

bool was_given(const InvertArgs& a, const char* option) {
    return std::find(a.given.begin(), a.given.end(), option) != a.given.end();
}

// --reference: what the options do not say is read from the slice's attributes (the query it
// was rendered with, its resolution, and the heightfield's size and scale when known). A slice
// without attributes (a measurement) needs the query that the defaults would otherwise guess.
void apply_reference_attributes(const InvertArgs& a, InversionOptions& o) {
    const SliceFile slice = read_slice_exr(a.reference);
    if (!was_given(a, "--resolution")) o.resolution = slice.image.rows;
    if (!slice.attributes) {
        const bool wavelength = a.given_lambda || a.given_spectral;
        if (!was_given(a, "--sigma-p-um") || !wavelength)
            throw std::invalid_argument(
                "--reference " + a.reference +
                " has no wavebrdf slice attributes (a measured slice?); expected its query as options: --sigma-p-um "
                "and --lambda-um or --spectral (and --light-x/--light-y, --model, --x-um/--y-um where not the "
                "defaults)");
        return;
    }
    const SliceAttributes& s = *slice.attributes;
    if (!a.given_x) o.x_um = s.query.x_um;
    if (!a.given_y) o.y_um = s.query.y_um;
    if (!was_given(a, "--sigma-p-um")) o.sigma_p_um = s.query.sigma_p_um;
    if (!was_given(a, "--light-x")) o.omega_i[0] = s.query.omega_i[0];
    if (!was_given(a, "--light-y")) o.omega_i[1] = s.query.omega_i[1];
    if (!was_given(a, "--model")) o.model = s.query.model;
    if (!a.given_lambda && !a.given_spectral) {
        if (s.lambdas_um.size() == 1) {
            o.lambda_um = s.lambdas_um[0];
        } else if (s.lambdas_um == spectral_wavelengths_um(int(s.lambdas_um.size()))) {
            o.spectral = int(s.lambdas_um.size());
        } else {
            o.wavelengths_um = s.lambdas_um;
        }
    }
    if (s.heightfield_rows > 0) {
        if (!was_given(a, "--size")) o.rows = s.heightfield_rows, o.cols = s.heightfield_cols;
        if (!was_given(a, "--texel-um")) o.texel_um = s.texel_um;
        if (!was_given(a, "--vscale")) o.vscale = s.vscale;
    }
}

// The flags as the library's options; every text parsed here, once.
InversionOptions to_options(const InvertArgs& a) {
    InversionOptions o;
    o.truth_path = a.truth;
    o.observations_path = a.observations;
    o.reference_path = a.reference;
    o.weights_path = a.weights;
    // The size matters for the generated truth and with --observations (a given truth brings its own).
    if (a.truth.empty()) parse_size("--size", a.size, o.rows, o.cols);
    o.texel_um = a.texel_um;
    o.vscale = a.vscale;
    if (!a.truth.empty()) {
        // A truth file's attributes apply where --texel-um / --vscale are not given.
        const auto given = [&](const char* option) {
            return std::find(a.given.begin(), a.given.end(), option) != a.given.end();
        };
        const HeightfieldScale scale = resolve_scale_with_warnings(a.truth, if_given(given("--texel-um"), a.texel_um),
                                                                   if_given(given("--vscale"), a.vscale), "--texel-um",
                                                                   "--vscale");
        o.texel_um = scale.texel_um;
        o.vscale = scale.vscale;
    }
    if (a.given_x) o.x_um = a.x_um;
    if (a.given_y) o.y_um = a.y_um;
    o.sigma_p_um = a.sigma_p_um;
    o.model = parse_model(a.model);
    if (a.given_lambda) o.lambda_um = a.lambda_um;
    if (a.given_spectral) o.spectral = a.spectral;
    o.omega_i = {a.light_x, a.light_y};
    o.resolution = a.resolution;
    o.epochs = a.epochs;
    o.optimizer = parse_optimizer(a.optimizer, "--optimizer");
    o.adam.lr = a.lr;
    o.adam.beta1 = a.beta1;
    o.adam.beta2 = a.beta2;
    o.adam.decay = a.decay;
    o.loss = parse_loss(a.loss);
    o.positions = parse_positions_spec(a.positions, "--positions");
    o.init = parse_init_spec(a.init, "--init");
    o.seed = a.seed;
    o.path = parse_render_path(a.render.path, "--path");
    o.tolerance = a.render.tolerance;  // checked by prepare_inversion, named --tolerance
    // Not given, for a run longer than 300 epochs: spread over its length (0, E/30, E/10, E/3, E,
    // as 0,10,30,100,300 is for 300), so its report shows its end, not only its first 300 epochs.
    const bool given_snapshots = std::find(a.given.begin(), a.given.end(), "--snapshots") != a.given.end();
    std::string snapshots = a.snapshots;
    if (!given_snapshots && a.epochs > 300) {
        std::set<long long> epochs;
        for (double fraction : {0.0, 1.0 / 30.0, 0.1, 1.0 / 3.0, 1.0})
            epochs.insert(std::llround(fraction * double(std::max(a.epochs, 0))));
        snapshots.clear();
        for (long long e : epochs) snapshots += (snapshots.empty() ? "" : ",") + std::to_string(e);
    }
    o.snapshots = parse_epoch_list(snapshots, "--snapshots");
    o.checkpoint_every = a.checkpoint_every;
    o.max_memory_gb = a.max_memory_gb;
    o.names = OptionStyle::Cli;
    if (!a.reference.empty()) apply_reference_attributes(a, o);
    return o;
}

void run_on(const InvertArgs& a, const Communicator* comm) {
    const bool root = comm == nullptr || comm->is_root();
    const bool resuming = !a.resume.empty();
    const std::string dir = resuming ? a.resume : a.out;
    InversionOptions options;
    // The options, checked on every rank alike (a bad one fails every rank, reported once).
    run_agreed(comm ? *comm : serial_communicator(), [&] {
        if (resuming)
            for (const std::string& option : a.given)
                if (!kResumeOptions.count(option))
                    throw std::invalid_argument(
                        option + " cannot be combined with --resume: a resumed run keeps the options in " + a.resume +
                        "/run.json; expected only --epochs (to extend it), --quiet, --no-plots, --max-memory-gb or "
                        "--threads");
        if (dir.empty()) throw std::invalid_argument("no output directory; expected --out DIR (or --resume DIR)");
        if (!resuming) options = to_options(a);
    });
    options.communicator = comm;
    InversionDirectoryResult result;
    int sig = 0;
    {
        // The first SIGINT/SIGTERM stops at the end of the epoch with a checkpoint; a second one
        // ends the process at once (temporary files removed, cli_signals.h).
        GracefulStop stop;
        InversionDirectoryControl control;
        control.force = a.force;
        control.show_progress = !a.quiet;  // rank 0's only
        control.stop = [&stop] { return stop.signal() != 0; };
        control.communicator = comm;
        if (resuming) {
            const bool extend = std::find(a.given.begin(), a.given.end(), "--epochs") != a.given.end();
            result = resume_inversion_in_directory(dir, extend ? std::optional<int>(a.epochs) : std::nullopt,
                                                   a.max_memory_gb, control);
        } else {
            result = run_inversion_in_directory(options, dir, control);
        }
        sig = stop.signal();
    }
    if (!root) {  // rank 0 reports; the others end as it does
        if (result.status == InversionStatus::Stopped) throw ExitStatus{128 + (sig != 0 ? sig : SIGINT)};
        return;
    }
    if (!a.no_plots) draw_report(RunKind::Invert, dir);
    const auto& h = result.history;
    if (!a.quiet && !h.empty()) {
        const EpochMetrics& first = h.front();
        const EpochMetrics& last = h.back();
        std::fprintf(stderr, "epoch %d: loss %.4g (%.2f%% of epoch 0), BRDF MSE %.2f%% of epoch 0", last.epoch,
                     last.loss, 100.0 * last.loss / first.loss, 100.0 * last.brdf_mse / first.brdf_mse);
        if (!std::isnan(last.height_mse)) std::fprintf(stderr, ", height MSE %.4g um^2", last.height_mse);
        std::fprintf(stderr, ", %.1f s; results in %s\n", last.seconds, dir.c_str());
    }
    // Split over ranks, a signal to any rank stops the run: rank 0 reports it (SIGINT when it
    // was another rank's).
    const bool elsewhere = comm != nullptr && result.status == InversionStatus::Stopped && sig == 0;
    if (elsewhere) sig = SIGINT;
    if (result.status == InversionStatus::Stopped && sig != 0) {
        // The signal named: under mpiexec the exit status alone says nothing of why it stopped.
        const char* by = elsewhere ? "a signal to another rank" : sig == SIGTERM ? "SIGTERM" : "SIGINT";
        std::fprintf(stderr,
                     "wavebrdf: interrupted at epoch %d by %s; checkpoint written, continue with: wavebrdf invert "
                     "--resume %s\n",
                     result.epoch, by, dir.c_str());
        throw ExitStatus{128 + sig};
    }
}

}  // namespace

void add_invert_command(CLI::App& app) {
    auto a = std::make_shared<InvertArgs>();
    CLI::App* cmd = app.add_subcommand(
        "invert", "Recover heights whose BRDF slices match references (the thesis's inverse renderer)");
    cmd->footer(k_slice_unit_help);
    a->command = cmd;
    cmd->add_option("--truth", a->truth,
                    "true heightfield EXR: references are rendered from it (default: a generated 16x16 surface)");
    cmd->add_option("--observations", a->observations,
                    "reference slices with their query parameters (JSON, or HDF5: .h5 .hdf5 .cxi)");
    cmd->add_option("--reference", a->reference,
                    "one reference slice EXR (render's, or measured) to fit; its query from its attributes where "
                    "the options do not give it");
    cmd->add_option("--weights", a->weights,
                    "with --reference: per-pixel weights EXR of the slice's size (R channel, >= 0; 0 masks a dead, "
                    "saturated or unmeasured pixel out of the loss)");
    add_grid_options(cmd, a->size, a->texel_um, a->vscale);
    auto* x_um = cmd->add_option("--x-um", a->x_um,
                                 "footprint centre x in um, any finite value (periodic; default: tile centre)");
    auto* y_um = cmd->add_option("--y-um", a->y_um,
                                 "footprint centre y in um, any finite value (periodic; default: tile centre)");
    cmd->add_option("--sigma-p-um", a->sigma_p_um, "footprint sigma_p in um")->capture_default_str();
    cmd->add_option("--model", a->model, "OHS, GHS, ROHS, RGHS or Kirchhoff")->capture_default_str();
    auto* lambda = cmd->add_option("--lambda-um", a->lambda_um, "single wavelength in um (default: --spectral 8)");
    auto* spectral = cmd->add_option("--spectral", a->spectral, "N wavelengths, CIE 1931 to linear sRGB (default 8)");
    add_light_options(cmd, a->light_x, a->light_y);
    cmd->add_option("--resolution", a->resolution, "slice size n")->capture_default_str();
    cmd->add_option("--init", a->init,
                    "flat, noisy:FRAC (truth + uniform noise of width FRAC x height range) or FILE.exr")
        ->capture_default_str();
    cmd->add_option("--epochs", a->epochs, "epochs (Adam steps or L-BFGS iterations), 0 to 10^7")
        ->capture_default_str();
    cmd->add_option("--optimizer", a->optimizer, "adam or lbfgs")->capture_default_str();
    cmd->add_option("--lr", a->lr, "Adam learning rate (heights in texel units)")->capture_default_str();
    cmd->add_option("--beta1", a->beta1, "Adam beta1")->capture_default_str();
    cmd->add_option("--beta2", a->beta2, "Adam beta2")->capture_default_str();
    cmd->add_option("--decay", a->decay, "learning-rate decay per epoch: lr * exp(-decay * epoch)")
        ->capture_default_str();
    cmd->add_option("--loss", a->loss, "cmsle:EPS, mse, amplitude or poisson:N (N photons per slice)")
        ->capture_default_str();
    cmd->add_option("--positions", a->positions,
                    "fixed, random (a new position per epoch) or FILE.json ([[x_um, y_um], ...])")
        ->capture_default_str();
    add_render_path_options(cmd, a->render);
    cmd->add_option("--seed", a->seed, "seed (generated truth, noise, random positions)")
        ->check(std::function<std::string(const std::string&)>(seed_error))
        ->capture_default_str();
    cmd->add_option("--out", a->out, "output directory");
    cmd->add_option("--resume", a->resume,
                    "continue the run in this directory with its own options (--epochs N extends it to N epochs)");
    cmd->add_flag("--force", a->force,
                  "replace the earlier run in --out (only a directory that holds nothing but invert's outputs)");
    cmd->add_option("--snapshots", a->snapshots,
                    "epochs to keep heights, slices and gradients for the report (default: 0,10,30,100,300; for "
                    "--epochs E > 300: 0, E/30, E/10, E/3 and E)");
    cmd->add_option("--checkpoint-every", a->checkpoint_every, "epochs between checkpoints")->capture_default_str();
    cmd->add_flag("--no-plots", a->no_plots, "do not draw report.png and curves.png");
    cmd->add_flag("--quiet", a->quiet, "no progress bar or summary");
    add_memory_option(cmd, a->max_memory_gb);
    cmd->callback([a, lambda, spectral, x_um, y_um] {
        a->given_x = x_um->count() > 0;
        a->given_y = y_um->count() > 0;
        a->given_lambda = lambda->count() > 0;
        a->given_spectral = spectral->count() > 0;
        a->given.clear();
        for (const CLI::Option* option : a->command->get_options())
            if (option->count() > 0) a->given.push_back(option->get_name());
        // Under mpiexec the run is split over the ranks (inversion_run.h), errors printed once.
        run_on_world([&](const Communicator& world) { run_on(*a, world.size() > 1 ? &world : nullptr); });
    });
}

}  // namespace wavebrdf::cli
