#pragma once
// A recovery run written to its output directory (`wavebrdf recover --out DIR`): the run of
// recovery_run.h with the files of RunKind::Recover (run_directory.h) around it, so that the
// directory's layout lives in the library next to the run, not in a front end:
//
//   run.json             the run's settings and plan: method, size, texel_um, vscale,
//                        height_range_um, noise, loss, seed, observations (count), plan (notes),
//                        warnings, truth (bool), height_rel_rmse (only when undefined: why),
//                        convergence (converged, floor, relative_misfit, reasons; Poisson:
//                        deviance, expected_deviance, deviance_sd, misfit_ratio; the model
//                        check's misfits; with error bars median_sigma_relative: convergence.h;
//                        a recovery that did not converge also adds its warning to warnings),
//                        psd (with a truth: resolved_all, resolved_q_per_um,
//                        resolved_wavelength_um where some band is resolved, error_power_ratio,
//                        bins: surface_stats.h's compare_spectra),
//                        finished (false until every other output is written: a run that was
//                        interrupted, crashed or failed says so)
//   metrics.csv          stage,iteration,loss,seconds,height_rel_rmse,height_rel_rmse_plane_removed
//                        (one row per StageMetrics)
//   calibration.json     with self-calibration or simulated acquisition errors: what was
//                        refined ("refined"), the values found (exposures, position_offsets_um per
//                        observation in the run's order, sigma_p_scale) and, with a truth, "truth"
//                        and "errors" (calibration_detail.h)
//   truth.exr, truth_height.npy              the truth, when known (heights in µm in the .npy)
//   psd.csv                                  with a truth: q_per_um, truth_psd_um4,
//                                            estimate_psd_um4, error_psd_um4, count (the radial
//                                            PSDs of compare_spectra)
//   estimate.exr, estimate.png, estimate_height.npy   the estimate
//   reference.npy, final.npy                 observation 0 and the estimate's slice for it
//                                            (resolution × resolution × channels)
//   uncertainty.exr, uncertainty_height.npy  with options.uncertainty: σ of every height in µm
//                                            (uncertainty.h; the EXR's values are µm: its
//                                            vscale is 1/texel_um)
//   uncertainty.json                         its summary: median_sigma_um, seconds, probes,
//                                            products, noise_variance; with a truth
//                                            coverage_1sigma, coverage_2sigma, rms_error_um
//   observations.json, observations/         with save_observations (EXR references), unless
//                                            observations_path names another file
//
// The report (report.png) is drawn from these files by the Python package (wavebrdf.report).
#include <functional>
#include <string>

#include "wavebrdf/convergence.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf {

// Where and how a recovery run is written.
struct RecoveryDirectoryOptions {
    std::string dir;                 // the output directory (created when missing)
    bool force = false;              // replace an earlier recover run there (run_directory.h)
    bool save_observations = false;  // also observations.json + observations/slice_NNNN.exr
    // With save_observations: where they go instead ("": DIR/observations.json); an HDF5
    // extension (.h5 .hdf5 .cxi) writes one HDF5 file, any other JSON with EXR slices
    // beside it (write_observations_file, observation_file.h).
    std::string observations_path;
    std::string option = "--out";  // names `dir` in messages
    // When given, receives the acquisition as the pipeline refined it (calibration.h; on rank 0
    // every observation's entries in the run's order, elsewhere only sigma_p_scale).
    Calibration* calibration = nullptr;
    // When given, receives whether the recovery converged, judged without the truth
    // (convergence.h; on every rank).
    ConvergenceCheck* convergence = nullptr;
};

// The plan of `prepared` (prepare_recovery with options.plan_only) into out.dir: prepares the
// directory as run_recovery_in_directory does and writes run.json alone (the plan, the photon
// plan with its pilot, "plan_only": true, the footprint centres as "positions_um"; no metrics).
// Throws std::invalid_argument for a recovery prepared to run. Collective (rank 0 writes).
void write_recovery_plan(const PreparedRecovery& prepared, const RecoveryOptions& options,
                         const RecoveryDirectoryOptions& out, const Communicator& comm = serial_communicator());

// run.json's text for `prepared` before the run (the plan, the photon plan with its pilot; with
// options.plan_only also "plan_only" and the footprint centres as "positions_um"): what
// write_recovery_plan writes, for callers without a directory (the Python module).
std::string recovery_plan_json(const PreparedRecovery& prepared, const RecoveryOptions& options);

// Runs `prepared` (prepare_recovery with `options`) into out.dir: prepares the directory
// (prepare_run_directory: a new or empty one, or with out.force one of recover's own runs),
// checks that metrics.csv can be written, writes run.json, the observations (when asked) and
// the truth before the recovery, then runs it (run_recovery: on_step sees every StageMetrics,
// returning false stops early and the estimate so far is written) and writes metrics.csv, the
// estimate, reference.npy and final.npy. Returns the estimate. A failure of the recovery
// itself is rethrown as std::runtime_error with its message and where the metrics so far
// went ("…; the metrics so far are in DIR/metrics.csv"); the directory's and the writers'
// own exceptions (std::invalid_argument for a directory that may not be used,
// std::runtime_error for one that cannot be written) pass through.
// `comm` (the one given to prepare_recovery): collective; rank 0 alone touches the directory
// and writes every file (the observations gathered to it); the others run the recovery. The
// checks before the recovery are agreed (run_agreed: a failure on any rank throws RankFailed
// on every rank). Returns the estimate on every rank.
// With prepared.uncertainty the error bars are computed after the recovery (height_uncertainty
// with the run's loss; collective) and written; `uncertainty`, when not null, receives their
// report (on every rank). When the loss leaves no noise to estimate (height_uncertainty's
// std::domain_error / std::invalid_argument, alike on every rank) the estimate is still written,
// the bars are not, rank 0 warns on stderr and `uncertainty` is left as it was.
Heightfield run_recovery_in_directory(const PreparedRecovery& prepared, const RecoveryOptions& options,
                                      const RecoveryDirectoryOptions& out,
                                      const std::function<bool(const StageMetrics&)>& on_step = {},
                                      const Communicator& comm = serial_communicator(),
                                      UncertaintyReport* uncertainty = nullptr);

}  // namespace wavebrdf
