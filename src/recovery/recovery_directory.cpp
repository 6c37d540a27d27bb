#include "wavebrdf/threads.h"
#include "wavebrdf/recovery_directory.h"

#include <array>
#include <chrono>
#include <cstdio>
#include <exception>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/convergence.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/surface_stats.h"
#include "wavebrdf/version.h"
#include "recovery/calibration_detail.h"

namespace wavebrdf {

namespace {

// run.json: what the run was asked and what the plan made of it.
nlohmann::json run_json(const PreparedRecovery& r, const RecoveryOptions& options) {
    nlohmann::json run = {{"method", to_string(r.method)},
                          {"size", std::to_string(r.rows) + "x" + std::to_string(r.cols)},
                          {"texel_um", r.texel_um},
                          {"vscale", r.vscale},
                          {"height_range_um", r.range_um},
                          {"noise", to_string(r.noise)},
                          {"loss", to_string(r.loss)},
                          {"seed", options.seed},
                          {"observations", r.total_observations},
                          {"plan", r.notes},
                          {"warnings", r.warnings},
                          {"truth", r.truth.has_value()},
                          {"calibrate", to_string(r.pipeline.calibrate)},
                          {"version", k_version},
                          {"threads", thread_count()}};
    // What the plan chose (the options' 0 / "" mean "the planner's"): the actual values.
    std::vector<std::vector<double>> lambdas;
    for (const Observation& o : r.catalogue.empty() ? r.observations : r.catalogue) lambdas.push_back(o.lambdas_um);
    run["wavelengths_um"] = distinct_wavelengths_um(lambdas);
    if (!r.observations.empty()) {
        run["sigma_p_um"] = r.observations.front().query.sigma_p_um;
        run["resolution"] = r.observations.front().resolution;
    }
    if (r.photon_plan) {
        const PhotonPlan& p = *r.photon_plan;
        run["photon_plan"] = {{"photons_per_exposure", p.photons},
                              {"exposures", p.exposures},
                              {"target_error", p.target},
                              {"max_exposures", options.max_exposures},
                              {"capped", p.capped},
                              {"predicted_error_one_exposure", p.single_rms_um / p.range_um},
                              {"predicted_error", p.rms_um / p.range_um},
                              {"predicted_rms_um", p.rms_um},
                              {"predicted_bias_um", p.bias_um},
                              {"proxy_size", std::to_string(p.proxy_rows) + "x" + std::to_string(p.proxy_cols)},
                              {"proxy_observations", p.proxy_observations},
                              {"seconds", p.seconds}};
        const PhotonPilot& q = p.pilot;
        nlohmann::json pilot = {{"ran", q.ran}, {"first_order_exposures", q.first_order_exposures}};
        if (q.ran) {
            pilot["size"] = std::to_string(q.rows) + "x" + std::to_string(q.cols);
            pilot["exposures"] = q.exposures;
            pilot["draws"] = q.errors_um.size();
            pilot["tiles"] = q.tiles;
            pilot["errors_um"] = q.errors_um;
            pilot["predicted_um"] = q.predicted_um;
            pilot["measured_rms_um"] = q.measured_rms_um;
            pilot["predicted_rms_um"] = q.predicted_rms_um;
            pilot["ratio"] = q.ratio;
            pilot["ratio_sd"] = q.ratio_sd;
            pilot["draw_sd"] = q.draw_sd;
            pilot["run_sd"] = q.run_sd;
            pilot["upper_ratio"] = q.upper_ratio;
            pilot["cpu_seconds"] = q.cpu_seconds;
        } else {
            pilot["why_not"] = q.why_not;
        }
        run["photon_plan"]["pilot"] = pilot;
    }
    if (options.simulator != Simulator::Gabor) run["simulator"] = to_string(options.simulator);
    if (!r.metric_note.empty()) run["height_rel_rmse"] = r.metric_note;
    if (r.plan_only) {  // the footprint centres, each position once (its lights and wavelengths follow it)
        std::vector<std::array<double, 2>> positions;
        for (const Observation& o : r.observations)
            if (positions.empty() || positions.back() != std::array<double, 2>{o.query.x_um, o.query.y_um})
                positions.push_back({o.query.x_um, o.query.y_um});
        run["plan_only"] = true;
        run["positions_um"] = positions;
    }
    return run;
}

// Every rank's observations on rank 0 (the catalogue with the gathered references and
// weights, in the run's order); empty elsewhere. Collective.
std::vector<Observation> gathered_observations(const PreparedRecovery& r, const Communicator& comm) {
    if (comm.size() == 1) return r.observations;
    std::vector<double> mine;
    for (std::size_t k = 0; k < r.observations.size(); ++k) {
        mine.push_back(double(r.share[k]));
        mine.push_back(double(r.observations[k].reference.size()));
        mine.insert(mine.end(), r.observations[k].reference.begin(), r.observations[k].reference.end());
        mine.push_back(double(r.observations[k].weights.size()));
        mine.insert(mine.end(), r.observations[k].weights.begin(), r.observations[k].weights.end());
    }
    const std::vector<double> all = comm.gather(mine);
    if (!comm.is_root()) return {};
    std::vector<Observation> out = r.catalogue;
    for (std::size_t at = 0; at + 1 < all.size();) {
        const std::size_t index = std::size_t(all[at]), count = std::size_t(all[at + 1]);
        out.at(index).reference.assign(all.begin() + std::ptrdiff_t(at + 2),
                                       all.begin() + std::ptrdiff_t(at + 2 + count));
        at += 2 + count;
        const std::size_t weights = std::size_t(all.at(at));
        out.at(index).weights.assign(all.begin() + std::ptrdiff_t(at + 1), all.begin() + std::ptrdiff_t(at + 1 + weights));
        at += 1 + weights;
    }
    return out;
}

// uncertainty.exr (σ of every height, µm), uncertainty_height.npy and uncertainty.json.
void write_uncertainty_files(const std::string& dir, const PreparedRecovery& r, const UncertaintyReport& bars) {
    const std::vector<std::size_t> height_shape{std::size_t(r.rows), std::size_t(r.cols)};
    // Values in µm: vscale 1/texel_um makes a raw value a height in µm.
    write_heightfield_exr(dir + "/uncertainty.exr",
                          Heightfield(r.rows, r.cols, bars.map.sigma_um, r.texel_um, 1.0 / r.texel_um),
                          "wavebrdf recover: uncertainty (standard deviation of each height, um)");
    write_npy(dir + "/uncertainty_height.npy", height_shape, bars.map.sigma_um);
    nlohmann::json summary = {{"median_sigma_um", bars.median_sigma_um},
                              {"seconds", bars.seconds},
                              {"exact", bars.map.exact},
                              {"forwards", bars.map.forwards},
                              {"probes", bars.map.probes},
                              {"products", bars.map.products},
                              {"max_cg_iterations", bars.map.max_cg_iterations},
                              {"worst_relative_residual", bars.map.worst_relative_residual},
                              {"filled", bars.map.filled},
                              {"noise_variance", bars.map.noise_variance},
                              {"loss", to_string(r.loss)}};
    if (bars.coverage_2sigma >= 0.0) {
        summary["coverage_1sigma"] = bars.coverage_1sigma;
        summary["coverage_2sigma"] = bars.coverage_2sigma;
        summary["rms_error_um"] = bars.rms_error_um;
    }
    write_text_atomically(dir + "/uncertainty.json", summary.dump(1) + "\n");
}

// run.json's "convergence": the check's verdict, its floor, the model check and its error bars.
nlohmann::json convergence_json(const ConvergenceCheck& convergence, const PreparedRecovery& r) {
    nlohmann::json c = {{"converged", convergence.converged},
                        {"floor", convergence.floor},
                        {"relative_misfit", convergence.relative_misfit},
                        {"reasons", convergence.reasons}};
    if (convergence.floor == "poisson") {
        c["deviance"] = convergence.deviance;
        c["expected_deviance"] = convergence.expected_deviance;
        c["deviance_sd"] = convergence.deviance_sd;
        c["misfit_ratio"] = convergence.misfit_ratio;
        c["slices_off_floor"] = convergence.slices_off_floor;
        c["worst_slice_excess"] = convergence.worst_slice_excess;
        c["worst_slice_x_um"] = convergence.worst_slice_x_um;
        c["worst_slice_y_um"] = convergence.worst_slice_y_um;
    }
    if (!convergence.model_selected.empty()) {
        c["model_misfit_gabor"] = convergence.model_misfit_gabor;
        c["model_misfit_field"] = convergence.model_misfit_field;
        c["model_selected"] = convergence.model_selected;
    }
    if (convergence.median_sigma_relative >= 0.0) c["median_sigma_relative"] = convergence.median_sigma_relative;
    if (convergence.predicted_error_relative >= 0.0) c["predicted_error_relative"] = convergence.predicted_error_relative;
    if (!convergence.texture_sigma_source.empty())
        c["texture"] = {{"sigma_relative", convergence.texture_sigma_relative},
                        {"sigma_source", convergence.texture_sigma_source},
                        {"texels", convergence.texture_texels},
                        {"fraction", convergence.texture_fraction},
                        {"power_share", convergence.texture_power_share},
                        {"warned", convergence.texture_warned}};
    c["judged"] = convergence.judged();
    c["check_error_bars"] = to_string(r.check_error_bars);
    if (!convergence.error_bars.empty()) {
        c["error_bars"] = convergence.error_bars;
        if (!convergence.error_bars_note.empty()) c["error_bars_note"] = convergence.error_bars_note;
        if (convergence.error_bars_predicted_seconds >= 0.0) {
            c["error_bars_predicted_seconds"] = convergence.error_bars_predicted_seconds;
            c["run_seconds"] = convergence.run_seconds;
        }
        if (convergence.error_bars_seconds >= 0.0) c["error_bars_seconds"] = convergence.error_bars_seconds;
        if (convergence.error_lower_bound_relative >= 0.0) {
            c["error_lower_bound_relative"] = convergence.error_lower_bound_relative;
            c["error_lower_bound_seconds"] = convergence.error_lower_bound_seconds;
        }
        if (convergence.error_bars_predicted_bytes >= 0.0) c["error_bars_predicted_bytes"] = convergence.error_bars_predicted_bytes;
        if (convergence.memory_limit_bytes >= 0.0) c["memory_limit_bytes"] = convergence.memory_limit_bytes;
    }
    return c;
}

}  // namespace

std::string recovery_plan_json(const PreparedRecovery& r, const RecoveryOptions& options) {
    return run_json(r, options).dump(1);
}

void write_recovery_plan(const PreparedRecovery& r, const RecoveryOptions& options, const RecoveryDirectoryOptions& out,
                         const Communicator& comm) {
    if (!r.plan_only)
        throw std::invalid_argument("write_recovery_plan: the recovery was prepared to run; expected plan_only");
    run_agreed(comm, [&] {
        if (!comm.is_root()) return;
        prepare_run_directory(RunKind::Recover, out.dir, out.force, out.option);
        write_text_atomically(out.dir + "/run.json", recovery_plan_json(r, options) + "\n");
    });
}

Heightfield run_recovery_in_directory(const PreparedRecovery& r, const RecoveryOptions& options,
                                      const RecoveryDirectoryOptions& out,
                                      const std::function<bool(const StageMetrics&)>& on_step, const Communicator& comm,
                                      UncertaintyReport* uncertainty) {
    const std::string& dir = out.dir;
    const bool root = comm.is_root();
    const std::vector<std::size_t> height_shape{std::size_t(r.rows), std::size_t(r.cols)};
    // Fail before the long work when the directory cannot be used or written (rank 0's).
    run_agreed(comm, [&] {
        if (!root) return;
        prepare_run_directory(RunKind::Recover, dir, out.force, out.option);
        check_writable(dir + "/metrics.csv");
        // "finished": false until every output is written: a run ended by a signal, a crash or
        // a full disk says so in its run.json.
        nlohmann::json run = run_json(r, options);
        run["finished"] = false;
        write_text_atomically(dir + "/run.json", run.dump(1) + "\n");
    });
    if (out.save_observations) {
        const std::string path = out.observations_path.empty() ? dir + "/observations.json" : out.observations_path;
        if (comm.size() == 1) {  // no copy: the observations as they are
            write_observations_file(path, r.observations, ReferenceStorage::Exr);
        } else {
            const std::vector<Observation> all = gathered_observations(r, comm);
            run_agreed(comm, [&] {
                if (root) write_observations_file(path, all, ReferenceStorage::Exr);
            });
        }
    }
    run_agreed(comm, [&] {
        if (root && r.truth) {
            write_heightfield_exr(dir + "/truth.exr", *r.truth, "wavebrdf recover: truth");
            write_npy(dir + "/truth_height.npy", height_shape, heights_um(*r.truth));
        }
    });

    // A metrics row per reported step.
    std::ostringstream csv;
    csv.precision(10);
    csv << "stage,iteration,loss,seconds,height_rel_rmse,height_rel_rmse_plane_removed\n";
    // The model check's misfits, for the convergence check after the run.
    ModelCheckMisfits misfits;
    bool stopped = false;
    auto record = [&](const StageMetrics& m) {
        misfits.record(m);
        csv << m.stage << ',' << m.iteration << ',' << m.loss << ',' << m.seconds << ','
            << (m.height_rel_rmse >= 0.0 ? std::to_string(m.height_rel_rmse) : std::string("nan")) << ','
            << (m.height_rel_rmse_plane_removed >= 0.0 ? std::to_string(m.height_rel_rmse_plane_removed)
                                                       : std::string("nan"))
            << '\n';
        if (on_step && !on_step(m)) stopped = true;
        return !stopped;
    };
    // A failure midway keeps the metrics of the steps that finished.
    Calibration calibration;
    const double run_start = process_cpu_seconds();
    const Heightfield estimate = [&] {
        try {
            return run_recovery(r, record, comm, &calibration);
        } catch (const std::exception& e) {
            if (!root) throw;
            bool saved = false;
            try {
                write_text_atomically(dir + "/metrics.csv", csv.str());
                saved = true;
            } catch (const std::exception&) {}
            const std::string more = saved ? "; the metrics so far are in " + dir + "/metrics.csv"
                                           : "; nothing more could be written to " + dir;
            // Agreed on every rank: stays so (rank 0 prints it).
            if (const auto* agreed = dynamic_cast<const RankFailed*>(&e))
                throw RankFailed(agreed->failed_rank(), agreed->message() + more, agreed->cause());
            throw std::runtime_error(std::string(e.what()) + more);
        }
    }();
    const double run_seconds = process_cpu_seconds() - run_start;  // CPU: the error bars' cost rule

    // calibration.json: what was refined and found (with simulated errors, the truth and the
    // errors of the estimate), every rank's observations gathered on rank 0.
    const bool write_calibration = r.pipeline.calibrate.any() || r.true_calibration.has_value();
    Calibration all_calibration, all_truth;
    if (write_calibration) {
        all_calibration = detail::gathered_calibration(calibration, r.share, r.total_observations, comm);
        if (r.true_calibration)
            all_truth = detail::gathered_calibration(*r.true_calibration, r.share, r.total_observations, comm);
    }
    if (out.calibration) *out.calibration = all_calibration;
    // Error bars at the estimate and whether it converged (collective), before rank 0 writes.
    RecoveryJudgement judged = judge_recovery(r, estimate, misfits, &calibration, stopped, run_seconds, comm);
    // A problem without error bars must not cost the estimate: it is written, and why not.
    if (r.uncertainty && !judged.error_bars && !judged.no_error_bars.empty() && root)
        std::fprintf(stderr, "wavebrdf: warning: no error bars: %s\n", judged.no_error_bars.c_str());
    const std::optional<UncertaintyReport>& bars = judged.error_bars;
    if (bars && uncertainty) *uncertainty = *bars;
    const ConvergenceCheck& convergence = judged.convergence;
    if (out.convergence) *out.convergence = convergence;
    if (!root) return estimate;  // rank 0 writes the results
    write_text_atomically(dir + "/metrics.csv", csv.str());
    if (write_calibration)
        write_text_atomically(
            dir + "/calibration.json",
            detail::calibration_json(r.pipeline.calibrate, all_calibration, r.true_calibration ? &all_truth : nullptr));
    if (bars) write_uncertainty_files(dir, r, *bars);
    write_heightfield_exr(dir + "/estimate.exr", estimate,
                          std::string("wavebrdf recover: estimate (") + to_string(r.method) + ")");
    write_heightfield_png(dir + "/estimate.png", estimate);
    write_npy(dir + "/estimate_height.npy", height_shape, heights_um(estimate));
    // One observation and the estimate's slice for it, for the report (observation 0 is the
    // first of rank 0's share).
    const Observation& first = r.observations.front();
    const std::vector<std::size_t> slice_shape{std::size_t(first.resolution), std::size_t(first.resolution),
                                               std::size_t(first.channels())};
    write_npy(dir + "/reference.npy", slice_shape, to_doubles(first.reference));
    write_npy(dir + "/final.npy", slice_shape, render_observation(estimate, first));
    nlohmann::json run = run_json(r, options);
    run["convergence"] = convergence_json(convergence, r);
    if (!convergence.converged) run["warnings"].push_back(convergence.warning());
    // The estimate's spectrum against the truth's (surface_stats.h): psd.csv and its summary.
    if (r.truth && r.metric_note.empty()) {
        const SpectrumComparison psd = compare_spectra(*r.truth, estimate);
        std::ostringstream table;
        table.precision(10);
        table << "q_per_um,truth_psd_um4,estimate_psd_um4,error_psd_um4,count\n";
        for (std::size_t k = 0; k < psd.q_per_um.size(); ++k)
            table << psd.q_per_um[k] << ',' << psd.truth_um4[k] << ',' << psd.estimate_um4[k] << ',' << psd.error_um4[k]
                  << ',' << psd.count[k] << '\n';
        write_text_atomically(dir + "/psd.csv", table.str());
        run["psd"] = {{"resolved_all", psd.resolved_all},
                      {"resolved_q_per_um", psd.resolved_q_per_um},
                      {"error_power_ratio", psd.error_power_ratio},
                      {"bins", psd.q_per_um.size()}};
        // JSON has no infinity: a wavelength only where some band was resolved.
        if (psd.resolved_q_per_um > 0.0) run["psd"]["resolved_wavelength_um"] = psd.resolved_wavelength_um;
    }
    run["finished"] = true;
    write_text_atomically(dir + "/run.json", run.dump(1) + "\n");
    return estimate;
}

}  // namespace wavebrdf
