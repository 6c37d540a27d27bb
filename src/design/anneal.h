#pragma once
// Internal: simulated annealing of an anti-mirror's relief on its levels (docs/design.md, "the
// annealed last stage"; experiments/2026-12-01-antimirror-annealing.md). One texel moved from
// level a to b changes every order's amplitude by
//   ΔA_o = √env_o (e^{−i k q_o h_b} − e^{−i k q_o h_a}) e^{−2πi (m_o i + n_o j)/N} / N²,
// so one pass over the orders of every wavelength gives the totals of every group (the cone, the
// region's bins, the rest) for all K levels of the texel at once. A heat-bath sweep sets each
// texel, in a random order, to a level drawn with probability ∝ exp(objective / T); the objective
// is the region's band mean less the augmented-Lagrangian terms of the cone and uniformity aims
// (per wavelength, multipliers moved after every sweep). A greedy descent follows; the relief kept
// is the best one within the aims at every wavelength.
//
// Each thread owns whole wavelengths and every sum over orders runs in a fixed order, so the
// result does not depend on the number of threads.
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "design/engine.h"
#include "design/target.h"

namespace wavebrdf::detail {

// What the annealed objective holds each wavelength to: the cone's fraction and the region's
// uniformity (std/mean of its 16 bins).
struct AnnealAims {
    double cone = 0.0019;
    double uniformity = 0.245;
};

// The aims inside the user's limits: 0.95 of the cone's limit, as the loop aims, and 0.98 of the
// uniformity's (the annealed relief is scored exactly, not as a relaxed mixture, so a narrower
// margin suffices; the study measured 0.0019 / 0.245 against 0.00199 / 0.249: 85.90 / 85.94 %).
AnnealAims anneal_aims(double cone_limit, double uniformity_limit);

struct AnnealSchedule {
    int sweeps = 400;
    // Temperature, geometric from t_start to t_end over the sweeps, in units of the objective
    // (the region's band mean).
    double t_start = 1e-4, t_end = 1e-6;
    // The augmented Lagrangian's ρ on g = x / aim − 1 per wavelength and aim.
    double rho = 0.05;
    // Best-improvement passes after the sweeps (from the last relief and from the best one).
    int greedy_passes = 5;
    std::uint64_t seed = 1;
};
constexpr int k_anneal_default_sweeps = 400;

// A relief's scores under the annealed objective (from the incremental totals).
struct AnnealScore {
    double objective = 0.0;         // region − the constraint terms
    double region = 0.0;            // the region's fraction, mean over the wavelengths
    double cone_worst = 0.0;        // the cone's fraction, worst wavelength
    double uniformity_worst = 0.0;  // worst wavelength
    bool within_aims = false;       // both aims held at every wavelength
};

// The incremental evaluator and its moves: the relief's order amplitudes and every group's total
// per wavelength, kept up to date move by move.
class ReliefAnnealer {
public:
    // sets: the order sets of every wavelength; target: the anti-mirror target assigned to them
    // (its groups: 0 the cone, 1 … 16 the region's bins); size N; levels K (2 … 256) of heights
    // ℓ · step_um.
    ReliefAnnealer(const std::vector<OrderSet>& sets, const Target& target, int size, int levels, double step_um,
                   const AnnealAims& aims, double rho);
    ~ReliefAnnealer();
    ReliefAnnealer(const ReliefAnnealer&) = delete;
    ReliefAnnealer& operator=(const ReliefAnnealer&) = delete;

    // Sets the relief (N² level indices, row-major) and evaluates it afresh.
    void set_relief(const std::vector<int>& level);
    // Re-evaluates the current relief afresh (clears the rounding the moves accumulate).
    void refresh();
    const std::vector<int>& level() const;
    // The current relief's score under the augmented Lagrangian (use_hinge false) or the greedy
    // descent's hinge penalty Σ max(0, x / aim − 1) (true).
    AnnealScore score(bool use_hinge = false) const;
    // The target's fractions (its groups) from the incremental totals.
    Fractions fractions() const;
    // One heat-bath sweep at temperature T: every texel once, in an order drawn from rng. Calls
    // on_move after every move kept. Returns the number of moves kept.
    long heat_sweep(double temperature, std::mt19937_64& rng, const std::function<void()>& on_move);
    // One best-improvement pass under the hinge penalty (texels in order). Returns the moves kept.
    long greedy_pass();
    // λ ← max(0, λ + ρ g) at the current totals, per wavelength and aim.
    void update_multipliers();
    // Whether a move's pass over the orders may be shared among the OpenMP threads (by whole
    // wavelengths; the result is the same either way): true by default where the pass is long
    // enough. The threads meet twice a texel, which on a busy machine can cost more than it saves,
    // so anneal_relief times both and keeps the faster.
    bool can_share() const;
    void set_shared(bool shared);

private:
    struct Impl;
    std::unique_ptr<Impl> m;
};

// One progress report (every sweep).
struct AnnealProgress {
    int sweep = 0;  // 1 … sweeps
    double temperature = 0.0;
    AnnealScore current;
    long moved = 0;           // moves kept in this sweep
    double best_region = -1;  // the best relief within the aims so far (−1: none yet)
};

struct AnnealOutcome {
    std::vector<int> level;  // the relief kept
    AnnealScore start, kept;
    std::string kept_from;   // "start", "sweeps" (the best within the aims seen), "greedy from the last", "greedy from the best"
    long moves = 0, greedy_moves = 0;
    double cpu_seconds = 0.0;  // the process's CPU time
};

// Anneals `start` (N² levels) with `schedule`; on_progress after every sweep (returning false stops
// the sweeps; the descent and the choice still follow). The relief kept: the one within the aims
// of the highest region among the start, the best seen during the sweeps and the descents' ends;
// where none is within them, the one of the highest hinge objective.
AnnealOutcome anneal_relief(const std::vector<OrderSet>& sets, const Target& target, int size, int levels,
                            double step_um, const AnnealAims& aims, const AnnealSchedule& schedule,
                            const std::vector<int>& start,
                            const std::function<bool(const AnnealProgress&)>& on_progress = {});

// Estimated CPU seconds of `sweeps` sweeps over an N² tile with `orders` propagating orders (all
// wavelengths) on K levels: each sweep tries every texel against every order.
double anneal_cpu_estimate_s(double orders, int size, int levels, int sweeps);

}  // namespace wavebrdf::detail
