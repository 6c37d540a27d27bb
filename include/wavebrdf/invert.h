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

#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"

namespace wavebrdf {

enum class OptimizerKind { Adam, Lbfgs };
// Fixed: every epoch uses the observations. Random: every epoch draws one new footprint
// position uniformly over the tile (the thesis's stochastic mode); its reference is rendered
// from the truth when one is known, else one of the observations is drawn instead.
enum class PositionMode { Fixed, Random };

struct InversionSettings {
    Loss loss;                        // default CMSLE, ε = 1 (the thesis's first experiment)
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

class Inversion {
public:
    // `truth` (optional, same size as `initial`) gives height_mse and random-position references.
    // Throws std::invalid_argument on empty observations, a size mismatch, L-BFGS with random
    // positions, or epochs < 0.
    Inversion(std::vector<Observation> observations, Heightfield initial, InversionSettings settings,
              const Heightfield* truth = nullptr);

    // Runs until settings.epochs. After each evaluated epoch (including epoch 0) calls
    // on_epoch(metrics, estimate, gradient, rendered slices of the observations); returning
    // false stops early (e.g. on a signal) with the state consistent for a checkpoint.
    using Callback = std::function<bool(const EpochMetrics&, const Heightfield&, const std::vector<double>&,
                                        const std::vector<std::vector<double>>&)>;
    void run(const Callback& on_epoch);

    int epoch() const { return m_epoch; }
    const Heightfield& estimate() const { return m_estimate; }
    const std::vector<EpochMetrics>& history() const { return m_history; }

    // Checkpoint: epoch, heights, optimiser state, metrics so far and a fingerprint of the
    // settings and observations, as JSON. load_checkpoint throws std::runtime_error when the
    // file does not match this run (different settings, observations or size).
    void save_checkpoint(const std::string& path) const;
    void load_checkpoint(const std::string& path);

    // The footprint position drawn for `epoch` in random mode (deterministic in the seed).
    static std::array<double, 2> random_position(std::uint64_t seed, int epoch, const Heightfield& tile);

private:
    EpochMetrics evaluate(std::vector<double>* gradient, std::vector<std::vector<double>>* rendered) const;
    std::vector<Observation> epoch_observations(int epoch) const;
    std::string fingerprint() const;

    std::vector<Observation> m_observations;
    Heightfield m_estimate;
    InversionSettings m_settings;
    const Heightfield* m_truth;
    Adam m_adam;
    int m_epoch = 0;
    double m_seconds_before = 0.0;
    std::vector<EpochMetrics> m_history;
};

}  // namespace wavebrdf
