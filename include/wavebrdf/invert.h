#pragma once
// The inverse renderer: heights → slices → loss → adjoint gradient → optimiser, epoch by
// epoch, with the thesis's metrics, snapshots for its figures, and checkpoints that resume
// to the same result as an uninterrupted run.
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"

namespace wavebrdf {

enum class OptimizerKind { Adam, Lbfgs };
// Fixed: every epoch uses the observations. Random: every epoch draws one new footprint
// position uniformly over the tile (the thesis's stochastic mode); its reference is rendered
// from the truth when one is known, else one of the observations is drawn instead.
enum class PositionMode { Fixed, Random };

struct InversionSettings {
    Loss loss;  // default CMSLE, ε = 1 (the thesis's first experiment)
    OptimizerKind optimizer = OptimizerKind::Adam;
    AdamOptions adam;
    LbfgsOptions lbfgs;
    int epochs = 300;
    PositionMode positions = PositionMode::Fixed;
    std::uint64_t seed = 1;
    RenderOptions render;
};

// One row of metrics.csv: every value is measured on the (fixed) observations at the estimate
// of that epoch (epoch 0 = the initial guess). height_mse is NaN without a truth.
struct EpochMetrics {
    int epoch = 0;
    double loss = 0, brdf_mse = 0, cmsle_1 = 0, cmsle_0_001 = 0, rgb_mse = 0, rgb_gamma_mse = 0;
    double height_mse = std::numeric_limits<double>::quiet_NaN();
    double seconds = 0;  // wall time since the run started (continued across resumes)
};

// --- set-up shared by `wavebrdf invert` and the Python module --------------------------------

// The built-in default truth: an isotropic surface with heights of about ±1 texel (rms 0.35
// texels, correlation length 2 texels), like the thesis's 16×16 crop of the reference
// release's isotropic.exr; texel width and vertical scale as given.
Heightfield default_inversion_truth(int rows, int cols, double texel_um, double vscale, std::uint64_t seed);

// Estimated peak memory (bytes) of an inversion of `heights` (its size and texel width) from
// `observations` (their references counted at full size even while still empty, as before
// observe() renders them) with `settings`: the references, the rendered slices and their loss
// gradients (three slices per observation), the largest render's working set twice (forward and
// adjoint, estimate_render_bytes), and the heights' optimiser state (Adam, or L-BFGS's history).
double estimate_inversion_bytes(const Heightfield& heights, const std::vector<Observation>& observations,
                                const InversionSettings& settings);

// One observation of `truth` per position: `base` (query, wavelengths, resolution) with the
// footprint moved to the position and the reference rendered. Validates every query.
std::vector<Observation> observe(const Heightfield& truth, const Observation& base,
                                 const std::vector<std::array<double, 2>>& positions_um,
                                 const RenderOptions& options = {});

// Footprint positions (um) from a JSON file: either an array of [x_um, y_um] pairs or an object
// {"positions": [[x_um, y_um], ...]} (`wavebrdf invert --positions FILE.json`). Throws
// std::runtime_error naming the file when it cannot be opened, is not JSON, or is not a
// non-empty list of number pairs.
std::vector<std::array<double, 2>> read_positions_json(const std::string& path);

// The truth's raw values plus uniform noise on [−w/2, w/2), w = frac × their range
// (`--init noisy:FRAC`), seeded: std::mt19937_64 and the library's own uniform transform, so
// every standard library gives the same values. Throws std::domain_error for frac < 0 or not
// finite.
std::vector<double> noisy_start(const Heightfield& truth, double frac, std::uint64_t seed);

// The largest Adam learning rate (a step in texel units) and the largest noise fraction of
// noisy_start that Inversion accepts: beyond them the heights leave any range a slice can
// resolve (phases of 1e16 and more lose every digit) and the run ends in non-finite values.
constexpr double kMaxInversionLr = 1e3;
constexpr double kMaxNoiseFraction = 1e3;

// Throws std::domain_error naming the value unless 0 ≤ frac ≤ kMaxNoiseFraction (noisy_start
// checks it too, so it also refuses a fraction above kMaxNoiseFraction).
void validate_noise_fraction(double frac);

// Checks settings before any work, with the messages Inversion's constructor gives: the Adam
// options (Adam's own checks, and lr ≤ kMaxInversionLr), the L-BFGS options, epochs ≥ 0 and
// L-BFGS with random positions (std::invalid_argument; std::domain_error for the values).
void validate(const InversionSettings& settings);

// The share of the observations one rank holds when an inversion is split over ranks
// (communicator.h, docs/scale.md): the heights and the optimiser's state are on every rank, the
// observations are not.
struct ObservationShard {
    const Communicator* communicator = nullptr;  // null: serial (one rank, every observation)
    // The global index of each of this rank's observations, ascending (observation_share);
    // empty with a null communicator or one rank: 0 … n − 1.
    std::vector<std::size_t> indices;
    std::size_t count = 0;  // observations over all ranks; 0: this rank's count (serial)
};

// Inversion validates its settings as validate(settings) does.
class Inversion {
public:
    // `truth` (optional, same size as `initial`) gives height_mse and random-position references.
    // Throws std::invalid_argument on empty observations, a size mismatch, L-BFGS with random
    // positions, epochs outside 0 … k_max_iterations (10^7, optim.h), or a footprint too large
    // for the heightfield (std::domain_error, validate_footprint in gabor.h).
    //
    // With a shard of several ranks (collective: every rank constructs its Inversion, runs and
    // checkpoints it in step), `observations` are this rank's share (possibly none) and every
    // loss, gradient and metric is that of all the observations (allreduce_sum in rank order:
    // every rank takes the same steps, and the run equals the one-process run up to the order
    // of the sums); random positions: every rank draws the same position (or global observation)
    // and its owner evaluates it; on_epoch's slices are this rank's. Errors in the checks are
    // agreed over the ranks (run_agreed: RankFailed on every rank, communicator.h).
    Inversion(std::vector<Observation> observations, Heightfield initial, InversionSettings settings,
              const Heightfield* truth = nullptr, ObservationShard shard = {});

    // Runs until settings.epochs. After each evaluated epoch (including epoch 0) calls
    // on_epoch(metrics, estimate, gradient, rendered slices of the observations); returning
    // false stops early (e.g. on a signal) with the state consistent for a checkpoint.
    using Callback = std::function<bool(const EpochMetrics&, const Heightfield&, const std::vector<double>&,
                                        const std::vector<std::vector<double>>&)>;
    void run(const Callback& on_epoch);

    int epoch() const { return m_epoch; }
    const Heightfield& estimate() const { return m_estimate; }
    const std::vector<EpochMetrics>& history() const { return m_history; }

    // Checkpoint: epoch, heights, optimiser state (Adam's moments and step count, L-BFGS's
    // curvature history), metrics so far and a fingerprint of the settings and observations,
    // as JSON; a run continued from it takes the same steps as the uninterrupted run, bit for
    // bit, with either optimiser. load_checkpoint throws std::runtime_error when the file does
    // not match this run (different settings, observations or size). settings.epochs is not
    // part of the run: a checkpoint continues with this Inversion's epochs (to extend a run).
    void save_checkpoint(const std::string& path) const;
    void load_checkpoint(const std::string& path);

    // The footprint position drawn for `epoch` in random mode (deterministic in the seed).
    static std::array<double, 2> random_position(std::uint64_t seed, int epoch, const Heightfield& tile);

    // The communicator (serial_communicator() without a shard) and the observations over all ranks.
    const Communicator& communicator() const { return *m_comm; }
    std::size_t observation_count() const { return m_count; }

private:
    EpochMetrics evaluate(std::vector<double>* gradient, std::vector<std::vector<double>>* rendered) const;
    std::vector<Observation> epoch_observations(int epoch) const;
    std::string fingerprint() const;

    std::vector<Observation> m_observations;
    Heightfield m_estimate;
    InversionSettings m_settings;
    const Heightfield* m_truth;
    Adam m_adam;
    LbfgsState m_lbfgs;                // L-BFGS's curvature history at m_epoch (checkpointed)
    mutable ObservationPlans m_plans;  // each observation's slice plan, built once
    int m_epoch = 0;
    double m_seconds_before = 0.0;
    std::vector<EpochMetrics> m_history;
    const Communicator* m_comm;
    std::vector<std::size_t> m_indices;              // global index of each of m_observations
    std::size_t m_count = 0;                         // observations over all ranks
    std::string m_fingerprint, m_observations_hash;  // over all ranks' observations, in order
};

}  // namespace wavebrdf
