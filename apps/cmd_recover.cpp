// `wavebrdf recover`: the heightfield from slices at several overlapping positions and
// wavelengths (recover.h), with the acquisition planned (acquisition.h) and, for studies, the
// observations simulated from a known truth with optional noise (noise.h). The thesis's
// method (baseline.h) runs on the same data with --method thesis. The run itself is
// recovery_run.h's (shared with Python's recover()), written to --out by recovery_directory.h;
// this file reads the input files, reports progress and draws the report.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "report.h"
#include "surface_options.h"
#include "unit_check.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/texel_texture.h"
#include "wavebrdf/input_digest.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/recovery_directory.h"
#include "wavebrdf/surface_stats.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/text.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf::cli {

namespace {

struct RecoverArgs {
    std::string truth, observations, size = "32", out;
    double texel_um = 2.0, vscale = 1.0;
    double height_range_um = 2.0;     // generated truth: peak-to-valley; else the planner's bound
    double correlation_texels = 4.0;  // generated truth
    std::string model = "OHS";
    double light_x = 0.0, light_y = 0.0;
    bool no_oblique_lights = false;
    double sigma_p_um = 0.0;  // 0: the planner's
    double position_uncertainty_um = 0.0;  // --position-uncertainty-um, used only where given
    int resolution = 0;       // 0: the planner's
    std::string lambdas;      // "": the planner's
    int spectral = 0;         // --spectral N: white light, RGB slices of N wavelengths (0: laser)
    double overlap = 0.6, jitter = 0.2;  // overlap: used only where given (given_overlap)
    std::string noise = "none", loss;  // loss "": matched to the noise
    std::string simulator = "gabor";
    std::string method = "pipeline";
    int field_iterations = -1, refine_iterations = -1, epochs = 1000;
    int field_tile_threshold = -1, field_tile_core = -1;  // -1: the library's
    std::string white_smoothness;                          // --white-smoothness W1,W2,... or none ("": the library's)
    int white_smoothness_iterations = -1;                  // -1: the library's
    // --refine-coarse-*: the refinement's coarse space (< 0: the library's)
    double refine_coarse_spacing = -1.0, refine_coarse_weight = -1.0;
    int refine_coarse_iterations = -1;
    std::uint64_t seed = 1;
    double max_memory_gb = 0.0;          // 0: the physical memory
    double target_error = k_default_target_error;  // photon-aware planning (photon_plan.h)
    int max_exposures = k_default_max_exposures;
    std::string calibrate = "none";      // --calibrate (calibration.h)
    int position_passes = -1;            // --position-passes (-1: the library's)
    double position_error_texels = 0.0;  // --simulate-position-error-texels
    std::string simulate_exposure;       // --simulate-exposure MIN,MAX ("": none)
    double sigma_factor = 1.0;           // --simulate-sigma-factor
    bool save_observations = false, quiet = false, no_plots = false, force = false, plan_only = false;
    bool uncertainty = false;  // error bars: uncertainty.exr (uncertainty.h)
    std::string check_error_bars = "auto";  // --check-error-bars (convergence.h)
    // Whether --texel-um / --vscale were given: when not, a --truth file's attributes apply.
    bool given_texel = false, given_vscale = false;
    // Whether --correlation-texels was given: when not, a --truth is planned for its measured roughness.
    bool given_correlation = false;
    // Whether --overlap was given: when not, the planner's default for the calibration.
    bool given_overlap = false;
    // Whether --position-uncertainty-um was given: when not, the simulated error's rms.
    bool given_position_uncertainty = false;
    // --save-observations FILE ("": observations.json in --out).
    std::string save_observations_path;
    // --resample-um, --fill, --detrend, --crop, --periodic: a measured --truth conditioned.
    ConditioningArgs conditioning;
};

std::vector<double> parse_list(const std::string& option, const std::string& text) {
    std::vector<double> out;
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) {
        try {
            std::size_t used = 0;
            out.push_back(std::stod(item, &used));
            if (used != item.size()) throw std::invalid_argument(item);
        } catch (const std::logic_error&) {
            throw std::invalid_argument(option + " '" + text + "' is invalid; expected numbers like 0.55,0.5");
        }
    }
    if (out.empty()) throw std::invalid_argument(option + " is empty; expected numbers like 0.55,0.5");
    return out;
}

// The observations of --observations. Every rank reads them all (prepare_recovery keeps its
// share): the one place to read only a rank's share instead.
std::vector<Observation> read_given_observations(const std::string& path, double max_memory_gb,
                                                 const Communicator& comm) {
    if (comm.size() == 1 || !is_hdf5_file(path)) return read_observations_file(path, 0, 1, max_memory_gb);
    // HDF5 under MPI: every observation's metadata (the index), but only this rank's slices;
    // prepare_recovery keeps the same share (observation_share of the same positions), and the
    // other ranks' observations, whose references stay empty, only as metadata.
    const ObservationIndex index = read_observation_index(path, max_memory_gb);
    std::vector<std::size_t> mine;
    std::vector<Observation> share = read_observations_file(path, comm.rank(), comm.size(), max_memory_gb, &mine);
    std::vector<Observation> all(index.size());
    for (std::size_t i = 0; i < all.size(); ++i) {
        all[i].query = index.queries[i];
        all[i].lambdas_um = index.lambdas_um[i];
        all[i].resolution = index.resolution;
    }
    for (std::size_t k = 0; k < mine.size(); ++k) all[mine[k]] = std::move(share[k]);
    return all;
}

// Under MPI (mpiexec -n K wavebrdf recover …, docs/scale.md) every rank runs this with its
// share of the observations; rank 0 alone prints and writes.
void run(const RecoverArgs& a, const Communicator& comm) {
    const bool quiet = a.quiet || !comm.is_root();
    if (a.out.empty()) throw std::invalid_argument("no output directory; expected --out DIR");
    // A new or empty directory (or, with --force, one of recover's own runs), before any work.
    if (comm.is_root()) check_run_directory(RunKind::Recover, a.out, a.force);
    if (a.truth.empty() && any_conditioning(a.conditioning))
        throw std::invalid_argument(
            "--resample-um, --fill, --detrend, --crop and --periodic condition a measured --truth; expected --truth FILE");
    // Every output against every input and every other output: one written over another
    // loses it (recovery_directory.h lists what --out holds).
    {
        check_output_format("--save-observations", a.save_observations_path, {".json", ".h5", ".hdf5", ".cxi"});
        std::vector<std::pair<std::string, std::string>> files{{"--truth", a.truth},
                                                               {"--observations", a.observations}};
        if (a.save_observations) {
            const std::string saved = a.save_observations_path.empty() ? a.out + "/observations.json"
                                                                       : a.save_observations_path;
            files.push_back({"--save-observations", saved});
            // JSON keeps its slices in the folder named after it: not the run's directory.
            if (!is_hdf5_path(saved)) {
                const std::filesystem::path p(saved);
                files.push_back({"--save-observations' slice folder", (p.parent_path() / p.stem()).string()});
                files.push_back({"--out", a.out});
            }
        }
        for (const char* name :
             {"run.json", "metrics.csv", "truth.exr", "truth_height.npy", "estimate.exr", "estimate.png",
              "estimate_height.npy", "reference.npy", "final.npy", "report.png", "calibration.json", "uncertainty.exr",
              "uncertainty.json", "uncertainty_height.npy", "psd.csv"})
            files.push_back({"--out's " + std::string(name), a.out + "/" + name});
        check_distinct_files(files);
        // --force empties --out first: an input inside it would be deleted before it is read.
        const auto inside_out = [&](const std::string& input) {
            if (input.empty()) return false;
            std::error_code ec;
            const std::filesystem::path out = std::filesystem::weakly_canonical(std::filesystem::absolute(a.out), ec);
            const std::filesystem::path in = std::filesystem::weakly_canonical(std::filesystem::absolute(input), ec);
            const auto rel = in.lexically_relative(out);
            return !rel.empty() && *rel.begin() != "..";
        };
        for (const auto& [option, input] : {std::pair<std::string, std::string>{"--truth", a.truth},
                                            std::pair<std::string, std::string>{"--observations", a.observations}})
            if (a.force && inside_out(input))
                throw std::invalid_argument(option + " " + input + " is inside --out " + a.out +
                                            ", which --force empties first; expected an input outside the run "
                                            "directory");
    }
    RecoveryOptions options;
    options.method = parse_recovery_method(a.method, "--method");
    options.noise = parse_noise(a.noise);
    options.simulator = parse_simulator(a.simulator, "--simulator");
    if (!a.loss.empty()) options.loss = parse_loss(a.loss);
    options.texel_um = a.texel_um;
    options.vscale = a.vscale;
    options.height_range_um = a.height_range_um;
    options.correlation_texels = a.correlation_texels;
    options.plan_from_truth = !a.truth.empty() && !a.given_correlation;
    options.omega_i = {a.light_x, a.light_y};
    options.oblique_lights = !a.no_oblique_lights;
    options.sigma_p_um = a.sigma_p_um;
    if (a.given_position_uncertainty) options.position_uncertainty_um = a.position_uncertainty_um;
    options.resolution = a.resolution;
    if (a.given_overlap) options.overlap = a.overlap;  // unset: the planner's default for the calibration
    options.jitter = a.jitter;
    options.field_iterations = a.field_iterations;
    options.refine_iterations = a.refine_iterations;
    options.field_tile_threshold = a.field_tile_threshold;
    if (a.white_smoothness == "none")
        options.white_smoothness = std::vector<double>{};
    else if (!a.white_smoothness.empty())
        options.white_smoothness = parse_list("--white-smoothness", a.white_smoothness);
    options.white_smoothness_iterations = a.white_smoothness_iterations;
    options.field_tile_core = a.field_tile_core;
    options.refine_coarse_spacing = a.refine_coarse_spacing;
    options.refine_coarse_weight = a.refine_coarse_weight;
    options.refine_coarse_iterations = a.refine_coarse_iterations;
    options.epochs = a.epochs;
    options.seed = a.seed;
    options.max_memory_gb = a.max_memory_gb;
    options.target_error = a.target_error;
    options.max_exposures = a.max_exposures;
    options.calibrate = parse_calibration(a.calibrate, "--calibrate");
    options.position_passes = a.position_passes;
    options.errors.position_rms_texels = a.position_error_texels;
    options.errors.sigma_p_factor = a.sigma_factor;
    options.errors.seed = a.seed;
    if (!a.simulate_exposure.empty()) {
        const std::vector<double> range = parse_list("--simulate-exposure", a.simulate_exposure);
        if (range.size() != 2)
            throw std::invalid_argument("--simulate-exposure '" + a.simulate_exposure +
                                        "' is invalid; expected MIN,MAX like 0.5,2");
        options.errors.exposure_min = range[0];
        options.errors.exposure_max = range[1];
    }
    options.uncertainty = a.uncertainty;
    options.plan_only = a.plan_only;
    if (a.plan_only && a.save_observations)
        throw std::invalid_argument("--plan-only renders no slices; expected --save-observations without it");
    options.check_error_bars = parse_check_error_bars(a.check_error_bars);
    // The planned acquisition's model and wavelengths (given observations bring their own).
    if (a.observations.empty()) {
        options.model = parse_model(a.model);
        if (!a.lambdas.empty()) options.lambdas_um = parse_list("--lambdas-um", a.lambdas);
        options.spectral = a.spectral;
    }
    // Every option the library checks, before any file is read (it checks them again).
    RecoveryInputs given;
    given.truth = !a.truth.empty();
    given.observations = !a.observations.empty();
    given.correlation = a.given_correlation;
    check_recovery_options(options, given);

    // Truth and observations (files read here; planned, simulated and checked by the library).
    std::unique_ptr<Heightfield> truth;
    std::vector<std::string> conditioning_steps;  // recorded in run.json with the plan's notes
    std::vector<Observation> observations;
    if (!a.observations.empty()) {
        // Agreed: a file one rank cannot open (or its memory) fails every rank, not that one alone.
        run_agreed(comm, [&] { observations = read_given_observations(a.observations, a.max_memory_gb, comm); });
        parse_size("--size", a.size, options.rows, options.cols);
    } else {
        if (a.truth.empty()) {
            parse_size("--size", a.size, options.rows, options.cols);
        } else if (any_conditioning(a.conditioning)) {
            // A measured truth conditioned first (--texel-um: the spacing of a file without one).
            truth = std::make_unique<Heightfield>(read_conditioned_heightfield(
                a.truth, a.conditioning, if_given(a.given_texel, a.texel_um), if_given(a.given_vscale, a.vscale),
                quiet, conditioning_steps));
            options.texel_um = truth->texel_um();
            options.vscale = truth->vscale();
        } else {
            const HeightfieldScale scale = resolve_scale_with_warnings(a.truth, if_given(a.given_texel, a.texel_um),
                                                                       if_given(a.given_vscale, a.vscale), "--texel-um",
                                                                       "--vscale", 2.0, 1.0);
            options.texel_um = scale.texel_um;
            options.vscale = scale.vscale;
            run_agreed(comm, [&] {
                truth = std::make_unique<Heightfield>(read_heightfield_exr(a.truth, scale.texel_um, scale.vscale));
            });
        }
    }
    // Every rank must run the same job: a digest of its options and inputs, agreed before the
    // first collective that depends on them (different sizes would abort in MPI itself).
    if (comm.size() > 1) {
        InputDigest d;
        for (const std::string& text : {a.size, a.method, a.noise, a.simulator, a.loss, a.model, a.lambdas, a.calibrate,
                                        a.check_error_bars,
                                        a.white_smoothness, a.simulate_exposure})
            d.add(text);
        for (double v : {options.texel_um, options.vscale, options.height_range_um, options.correlation_texels,
                         options.omega_i[0], options.omega_i[1], a.sigma_p_um, a.overlap, a.jitter, a.sigma_factor,
                         a.target_error, double(a.max_exposures),
                         a.position_error_texels, options.refine_coarse_spacing, options.refine_coarse_weight})
            d.add(v);
        for (long long v : {static_cast<long long>(options.seed), static_cast<long long>(a.resolution),
                            static_cast<long long>(a.spectral), static_cast<long long>(a.epochs),
                            static_cast<long long>(a.field_iterations), static_cast<long long>(a.refine_iterations),
                            static_cast<long long>(a.position_passes), static_cast<long long>(a.uncertainty)})
            d.add(v);
        if (truth) {
            d.add(static_cast<long long>(truth->rows()));
            d.add(truth->values());
        }
        for (const Observation& o : observations) {
            d.add(std::vector<double>{o.query.x_um, o.query.y_um, o.query.sigma_p_um, o.query.omega_i[0],
                                      o.query.omega_i[1], double(int(o.query.model)), double(o.resolution)});
            d.add(o.lambdas_um);
        }
        agree_on_inputs(comm, d.value(), "options or inputs");
    }
    PreparedRecovery r;
    // Each rank's share may fail alone (its memory check): agreed before the recovery starts.
    run_agreed(comm, [&] { r = prepare_recovery(options, truth.get(), std::move(observations), !quiet, comm); });
    if (!quiet) {
        for (const auto& n : r.notes) std::fprintf(stderr, "plan: %s\n", n.c_str());
    }
    for (const std::string& step : conditioning_steps) r.notes.push_back("truth conditioning: " + step);
    if (comm.is_root())
        for (const auto& w : r.warnings) std::fprintf(stderr, "wavebrdf: warning: %s\n", w.c_str());
    if (comm.is_root() && r.truth && !a.truth.empty()) {
        const bool planned = !r.observations.empty() && !r.observations.front().lambdas_um.empty();
        print_units(warn_units(*r.truth, planned ? r.observations.front().lambdas_um.front() : 0.5, a.truth), a.truth,
                    quiet);
    }

    // A progress bar per stage (drawn on terminals) and a one-line summary when a stage ends.
    std::unique_ptr<Progress> progress;
    StageMetrics last;
    auto end_stage = [&] {
        if (!progress) return;
        progress->finish();
        progress.reset();
        if (!quiet) {
            std::fprintf(stderr, "%s: %d iterations, loss %.4g", last.stage.c_str(), last.iteration, last.loss);
            if (last.height_rel_rmse >= 0.0)
                std::fprintf(stderr, ", height_rel_rmse %.3f%%", 100.0 * last.height_rel_rmse);
            std::fprintf(stderr, " (%.1f s)\n", last.seconds);
        }
    };
    auto on_step = [&](const StageMetrics& m) {
        if (!progress || m.stage != last.stage) {
            end_stage();
            progress = std::make_unique<Progress>(m.stage, std::max(m.total, 1), !quiet);
        }
        char message[96];
        if (m.height_rel_rmse >= 0.0)
            std::snprintf(message, sizeof message, "loss %.3g height err %.2f%%", m.loss, 100.0 * m.height_rel_rmse);
        else
            std::snprintf(message, sizeof message, "loss %.3g", m.loss);
        progress->set_message(message);
        progress->advance(std::max<long long>(0, m.iteration - (m.stage == last.stage ? last.iteration : 0)));
        last = m;
        return true;
    };
    // The run and its files (recovery_directory.h), then the report drawn from them.
    RecoveryDirectoryOptions out;
    out.dir = a.out;
    out.force = a.force;
    if (r.plan_only) {
        write_recovery_plan(r, options, out, comm);
        if (!quiet) std::fprintf(stderr, "plan only: nothing simulated or recovered; run.json in %s\n", a.out.c_str());
        return;
    }
    out.save_observations = a.save_observations;
    out.observations_path = a.save_observations_path;
    Calibration calibration;
    out.calibration = &calibration;
    UncertaintyReport bars;
    ConvergenceCheck convergence;
    out.convergence = &convergence;
    const Heightfield estimate = run_recovery_in_directory(r, options, out, on_step, comm, &bars);
    end_stage();
    if (options.uncertainty && !quiet && !bars.map.sigma_um.empty()) {
        std::fprintf(stderr, "uncertainty: median sigma %.3g um (%.1f s)", bars.median_sigma_um, bars.seconds);
        if (bars.coverage_2sigma >= 0.0)
            std::fprintf(stderr, ", rms error %.3g um, error within 1 sigma %.1f%%, within 2 sigma %.1f%%",
                         bars.rms_error_um, 100.0 * bars.coverage_1sigma, 100.0 * bars.coverage_2sigma);
        std::fprintf(stderr, "\n");
    }
    if (!comm.is_root()) return;
    // Whether it converged, without the truth: a warning even with --quiet (run.json has it too).
    if (!quiet && convergence.floor == "poisson")
        std::fprintf(stderr, "convergence: misfit %.3g x the photon-noise floor (converged below %.3g)\n",
                     convergence.misfit_ratio, k_misfit_ratio_limit);
    else if (!quiet && convergence.floor == "noiseless")
        std::fprintf(stderr, "convergence: relative misfit %.3g on noiseless slices (converged below %.0e)\n",
                     convergence.relative_misfit, k_noiseless_misfit_limit);
    else if (!quiet)
        std::fprintf(stderr,
                     "convergence: misfit not judged: loss %s states no noise level (relative misfit %.3g; for photon "
                     "counts use --loss poisson:N)\n",
                     to_string(r.loss).c_str(), convergence.relative_misfit);
    if (!quiet && convergence.predicted_error_relative >= 0.0)
        std::fprintf(stderr, "convergence: the error bars%s predict an rms height error of %.3g %% of the height range "
                             "(target <= %.0f %%)%s\n",
                     convergence.floor == "none" ? " (the noise estimated from the residuals)" : "",
                     100.0 * convergence.predicted_error_relative, 100.0 * k_predicted_error_limit,
                     convergence.floor == "none" && convergence.converged
                         ? "; a lower bound: without a noise level a wrong basin is not seen, so the run is not judged"
                         : "");
    // Where the check needed error bars and has none, the noise limit is not judged. Bars left
    // out for memory are left out under `always` too: the note says how to raise the limit.
    const bool over_memory = convergence.memory_limit_bytes >= 0.0 &&
                             !check_error_bars_fit(convergence.error_bars_predicted_bytes,
                                                   convergence.memory_limit_bytes);
    // In their place G's diagonal bounds what they would predict from below: above the target
    // it judges (a warning), within it the noise limit is still not judged.
    const double bound = convergence.error_lower_bound_relative;
    if (!quiet && bound >= 0.0)
        std::fprintf(stderr,
                     "convergence: the error bars not computed (%s); their lower bound from the slices' Fisher "
                     "information: %.3g %% of the height range (target <= %.0f %%)\n",
                     convergence.error_bars_note.c_str(), 100.0 * bound, 100.0 * k_predicted_error_limit);
    if (!quiet && !(bound > k_predicted_error_limit) &&
        (convergence.error_bars == "skipped" || convergence.error_bars == "off" ||
         convergence.error_bars == "unavailable"))
        std::fprintf(stderr, "convergence: the %s not judged: %s%s\n",
                     convergence.judged() ? "noise limit is" : "recovery is", convergence.error_bars_note.c_str(),
                     convergence.error_bars == "unavailable" || over_memory
                         ? ""
                         : " (--check-error-bars always or --uncertainty computes them)");
    if (!quiet && !convergence.texture_sigma_source.empty())
        std::fprintf(stderr,
                     "convergence: texture: %.3g %% of the texels stand off their 3x3 median by more than the rms height and "
                     "%.0f sigma (%.3g %% of the height range, from the %s) (warned from %.0f %% where 2 sigma exceeds "
                     "the target)\n",
                     100.0 * convergence.texture_fraction, k_texture_sigmas, 100.0 * convergence.texture_sigma_relative,
                     convergence.texture_sigma_source.c_str(), 100.0 * k_texture_fraction);
    if (!convergence.converged) std::fprintf(stderr, "wavebrdf: warning: %s\n", convergence.warning().c_str());
    if (!quiet && options.calibrate.any()) {
        std::fprintf(stderr, "calibrated %s: sigma_p scale %.4f", to_string(options.calibrate).c_str(),
                     calibration.sigma_p_scale);
        if (r.true_calibration) std::fprintf(stderr, " (true %.4f)", r.true_calibration->sigma_p_scale);
        if (!calibration.exposures.empty()) {
            double lo = calibration.exposures.front(), hi = lo;
            for (double e : calibration.exposures) lo = std::min(lo, e), hi = std::max(hi, e);
            std::fprintf(stderr, ", exposures %.3g to %.3g", lo, hi);
        }
        std::fprintf(stderr, "; calibration.json in %s\n", a.out.c_str());
    }
    if (!quiet && r.truth && r.metric_note.empty())
        std::fprintf(stderr, "height_rel_rmse with the best-fit plane removed %.3f%%\n",
                     100.0 * height_rel_rmse_plane_removed(estimate, *r.truth));
    if (!quiet && r.truth && r.metric_note.empty()) {
        // The estimate's spectrum against the truth's (psd.csv, run.json "psd").
        const SpectrumComparison psd = compare_spectra(*r.truth, estimate);
        if (psd.resolved_all)
            std::fprintf(stderr, "spectrum: the error's power below the truth's in every band (to q %.3g rad/um)",
                         psd.resolved_q_per_um);
        else if (psd.resolved_q_per_um > 0.0)
            std::fprintf(stderr,
                         "spectrum: the error's power below the truth's up to q %.3g rad/um (wavelength %.3g um)",
                         psd.resolved_q_per_um, psd.resolved_wavelength_um);
        else
            std::fprintf(stderr, "spectrum: the error's power reaches the truth's already in the longest band");
        std::fprintf(stderr, "; error power %.3g of the truth's; psd.csv in %s\n", psd.error_power_ratio,
                     a.out.c_str());
    }
    if (!a.no_plots) draw_report(RunKind::Recover, a.out);
    if (!quiet) {
        if (r.truth && !r.metric_note.empty())
            std::fprintf(stderr, "height_rel_rmse %s; results in %s\n", r.metric_note.c_str(), a.out.c_str());
        else if (r.truth)
            std::fprintf(stderr, "height_rel_rmse %.3f%%; results in %s\n", 100.0 * height_rel_rmse(estimate, *r.truth),
                         a.out.c_str());
        else
            std::fprintf(stderr, "results in %s\n", a.out.c_str());
    }
}

}  // namespace

void add_recover_command(CLI::App& app) {
    auto a = std::make_shared<RecoverArgs>();
    CLI::App* cmd = app.add_subcommand(
        "recover", "Recover the true heightfield from slices at overlapping positions and several wavelengths");
    cmd->footer(k_slice_unit_help);
    cmd->add_option("--truth", a->truth,
                    "true heightfield EXR: observations are planned and rendered from it (default: a generated one)");
    cmd->add_option("--observations", a->observations,
                    "measured or rendered slices with their query parameters (JSON, or HDF5: .h5 .hdf5 .cxi)");
    const std::pair<CLI::Option*, CLI::Option*> grid = add_grid_options(cmd, a->size, a->texel_um, a->vscale);
    CLI::Option* texel = grid.first;
    CLI::Option* vscale = grid.second;
    cmd->add_option("--height-range-um", a->height_range_um,
                    "generated truth: peak-to-valley height in um; with --observations: a bound for unwrapping")
        ->capture_default_str();
    CLI::Option* correlation =
        cmd->add_option("--correlation-texels", a->correlation_texels,
                        "generated truth: correlation length in texels; with --truth: plan for this (and the "
                        "truth's range) instead of the truth's measured roughness (range, slopes, Sal, Str)")
            ->capture_default_str();
    cmd->add_option("--model", a->model, "OHS, ROHS, GHS or RGHS (GHS-type: the field stage through the separable proxy, docs/recovery.md)")->capture_default_str();
    add_light_options(cmd, a->light_x, a->light_y);
    cmd->add_flag("--no-oblique-lights", a->no_oblique_lights,
                  "steep surfaces: observe under the one light only (default, OHS and ROHS: the planner adds 4 "
                  "oblique lights so that steep facets reflect into a slice)");
    cmd->add_option("--sigma-p-um", a->sigma_p_um,
                    "footprint sigma_p in um (0: the planner's, 1.5 texels or the position uncertainty if larger)")
        ->capture_default_str();
    CLI::Option* position_uncertainty =
        cmd->add_option("--position-uncertainty-um", a->position_uncertainty_um,
                        "how far the stage may put a footprint from where it says, um rms per coordinate: the "
                        "planner makes sigma_p at least this and the position loop searches lost positions 4x as "
                        "far (default: the simulated error's rms with --simulate-position-error-texels, else 0)");
    cmd->add_option("--resolution", a->resolution, "slice size n (0: the planner's: 48, raised where the footprint needs it)")
        ->capture_default_str();
    cmd->add_option("--lambdas-um", a->lambdas, "wavelengths in um, comma-separated (default: the planner's ladder)");
    cmd->add_option("--spectral", a->spectral,
                    "white light: every planned observation an RGB slice of a broadband source sampled at N "
                    "wavelengths (2 to 256, as render's --spectral); 0: laser")
        ->capture_default_str();
    CLI::Option* overlap = cmd->add_option("--overlap", a->overlap,
                    "worst-case linear overlap of neighbouring windows (jitter included), 0.6 to 0.95 (default: "
                    "0.6; 0.8 with --calibrate positions or all)");
    cmd->add_option("--jitter", a->jitter, "position jitter, fraction of the raster step, 0 to 0.3")
        ->capture_default_str();
    cmd->add_option("--noise", a->noise, "simulated noise: none, poisson:N (photons per slice) or gaussian:REL")
        ->capture_default_str();
    cmd->add_option("--simulator", a->simulator,
                    "how a truth's observations are simulated: gabor (the model) or scalar (the exact field, "
                    "scalar_diffraction.h)")
        ->capture_default_str();
    cmd->add_option("--loss", a->loss,
                    "loss (default: matched to the noise; amplitude without noise, thesis: cmsle:1)");
    cmd->add_option("--method", a->method,
                    "pipeline (field retrieval, unwrapping, refinement) or thesis (Adam, one observation per epoch)")
        ->capture_default_str();
    cmd->add_option("--field-iterations", a->field_iterations,
                    "field retrieval iterations per wavelength (default: the schedule's: a smooth surface without "
                    "--calibrate 25, at the longest wavelength only; else 50, a rough surface up to 200)");
    cmd->add_option("--refine-iterations", a->refine_iterations,
                    "refinement L-BFGS iterations, the whole refinement when given (default: the schedule's: a smooth "
                    "surface without --calibrate 8 on every slice after 40 on the longest wavelength's; else 40)");
    cmd->add_option("--field-tile-threshold", a->field_tile_threshold,
                    "field stage on tiles along an axis of more than N texels (0: never; default: the library's)");
    cmd->add_option("--field-tile-core", a->field_tile_core,
                    "field tiles' core size in texels, 8 to 4096 (default: the library's)");
    cmd->add_option("--refine-coarse-spacing", a->refine_coarse_spacing,
                    "refinement's coarse space: B-spline node spacing in texels, doubled per level (0: off; default: "
                    "the library's)");
    cmd->add_option("--refine-coarse-weight", a->refine_coarse_weight,
                    "refinement's coarse space: weight of the coarse variables in the joint L-BFGS (0: none; "
                    "default: the library's)");
    cmd->add_option("--refine-coarse-iterations", a->refine_coarse_iterations,
                    "refinement's coarse space: L-BFGS iterations on the coarse coefficients alone after each round "
                    "(default: the library's)");
    cmd->add_option("--white-smoothness", a->white_smoothness,
                    "white light: the smoothness continuation's weights, largest first, comma-separated (at most "
                    "64, each 0 to 1e12), or none (default: the library's, 10,1,0.1,0.01)");
    cmd->add_option("--white-smoothness-iterations", a->white_smoothness_iterations,
                    "white light: L-BFGS iterations per smoothness weight (default: the library's, 20)");
    cmd->add_option("--epochs", a->epochs, "thesis method: Adam epochs")->capture_default_str();
    cmd->add_option("--seed", a->seed, "seed (generated truth, jitter, noise, thesis draws)")
        ->check(std::function<std::string(const std::string&)>(seed_error))
        ->capture_default_str();
    add_memory_option(cmd, a->max_memory_gb);
    cmd->add_option("--calibrate", a->calibrate,
                    "self-calibration: parts of the acquisition refined with the heights, comma-separated: "
                    "positions, exposure, sigma; or all, none")
        ->capture_default_str();
    cmd->add_option("--position-passes", a->position_passes,
                    "with --calibrate positions: at most N passes of the position loop (registration at the "
                    "heights, then the field stage and the refinement again) after the first recovery, 0 to 100; "
                    "0: off (default: the library's, 40, stopped earlier when the loss stalls)");
    cmd->add_option("--simulate-position-error-texels", a->position_error_texels,
                    "study: footprint positions off by a Gaussian of this rms per coordinate (texels, 0 to 10)")
        ->capture_default_str();
    cmd->add_option("--simulate-exposure", a->simulate_exposure,
                    "study: each slice scaled by an exposure drawn log-uniformly in MIN,MAX (e.g. 0.5,2)");
    cmd->add_option("--simulate-sigma-factor", a->sigma_factor,
                    "study: the true sigma_p is this factor times the stated one (0.25 to 4)")
        ->capture_default_str();
    cmd->add_option("--out", a->out, "output directory")->required();
    cmd->add_flag("--force", a->force,
                  "replace the earlier run in --out (only a directory that holds nothing but recover's outputs)");
    auto* save = cmd->add_option("--save-observations", a->save_observations_path,
                                 "also write the observations: observations.json + EXR slices in --out, or to FILE "
                                 "(.h5 .hdf5 .cxi: one HDF5 file; else JSON + EXR slices)")
                     ->expected(0, 1)
                     ->type_name("[FILE]");
    cmd->add_flag("--uncertainty", a->uncertainty,
                  "also compute error bars: uncertainty.exr (sigma of every height, um) from the curvature of the "
                  "loss at the estimate");
    cmd->add_option("--check-error-bars", a->check_error_bars,
                    "the convergence check's own error bars, where it needs them (photon counts with the misfit on "
                    "the floor, or a loss without a noise level): auto (computed when predicted to take at most "
                    "the recovery's CPU time), always, or off; either way within --max-memory-gb")
        ->default_str("auto");
    cmd->add_option("--target-error", a->target_error,
                    "photon noise: the rms height error the planner aims at, a fraction of the truth's peak to "
                    "valley (0: off); where the planned slices' predicted error (their error bars and bias, "
                    "within 1.5x of the target scaled by a pilot of the recovery on 32x32 to 64x64 tiles) is more, every "
                    "slice is taken as several exposures of the --noise photons, summed")
        ->capture_default_str();
    cmd->add_option("--max-exposures", a->max_exposures,
                    "photon noise: at most this many exposures per slice for --target-error (1 to 10000)")
        ->capture_default_str();
    cmd->add_flag("--plan-only", a->plan_only,
                  "plan the acquisition and the photons (with the pilot) as the run would, print the plan, write "
                  "run.json alone in --out and stop before simulating a slice");
    cmd->add_flag("--no-plots", a->no_plots, "do not draw report.png");
    cmd->add_flag("--quiet", a->quiet, "no progress or summary");
    add_conditioning_options(cmd, a->conditioning);
    cmd->callback([a, texel, vscale, save, overlap, position_uncertainty, correlation] {
        a->given_correlation = correlation->count() > 0;
        a->save_observations = save->count() > 0;
        a->given_overlap = overlap->count() > 0;
        a->given_position_uncertainty = position_uncertainty->count() > 0;
        a->given_texel = texel->count() > 0;
        a->given_vscale = vscale->count() > 0;
        // Under mpiexec, every rank with its share; errors printed once (run_on_world).
        run_on_world([&](const Communicator& world) { run(*a, world); });
    });
}

}  // namespace wavebrdf::cli
