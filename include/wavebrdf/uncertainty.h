#pragma once
// Error bars of a recovered heightfield (docs/recovery.md, "Error bars"): the standard
// deviation of every texel's height from the curvature of the refinement's loss at the
// solution, the Laplace / Gauss–Newton approximation of the estimate's covariance:
//   G = Jᵀ W J,   Cov(h) ≈ G⁺,
// J = ∂slices/∂heights over all observations, W per slice value the Fisher information of
// the noise the loss assumes:
//   poisson:N   W = s / I   (photon counts k ~ Poisson(s·I), s = N / Σ R as in loss.h): absolute,
//               nothing is estimated;
//   amplitude   W = 1 / (4 I σ²)   (Gaussian noise of variance σ² on √R),
//   mse         W = 1 / σ²         (Gaussian noise on R),
//   cmsle:ε     W = 1 / ((I + ε)² σ²)  (Gaussian noise on log(R + ε)),
//               σ² estimated from the residuals at the solution in the loss's own variable
//               (Σ r² / (values − (texels − 1)), over the values that are not 0 in both the
//               slice and the reference).
// Observations with per-pixel weights (observation.h): a value of weight 0 is no measurement
// and is left out of G, σ² and N's Σ R; the others count with their weight w as the weighted
// loss has them (W × w, residual² × w; the values counted for σ²'s degrees of freedom are those
// of weight > 0).
// The mean height (piston) is unobservable (G·1 = 0): the map is for the heights with their
// mean removed, as height_rel_rmse compares them, i.e. diag(G⁺) on the mean-free subspace.
//
// G is formed sparse: an observation's J has a column per texel of its footprint's box only,
// one forward difference of the slice plan (double precision) each, and G = Σ Jᵀ W J is
// nonzero only between texels that share a box. Up to 4096 texels its pseudo-inverse diagonal
// is exact (dense Cholesky); above, by probing: coloured probes (texels whose rows and columns
// agree modulo `probe_spacing` share a probe, with random signs), each solved by conjugate
// gradients on the mean-free subspace with sparse products. A probe's estimate of texel i is
// exact up to the covariances of i with the texels of its colour. GaussNewtonOperator::apply
// keeps the matrix-free product (a forward difference and an adjoint per observation).
//
// Under MPI every sum over observations is exact and allreduced (core/exact_sum.h), so every
// rank computes the same map, the same bits for any number of ranks.
//
// The bars describe the noise about the loss's minimum, so the heights passed in must be at it:
// an estimate still off by an optimisation error comparable to the noise's under-covers
// (the smooth schedule's 8 final refinement iterations left ~0.36 nm rms beside the noise's
// 0.75 nm: ±2σ held 85–91 % of texels instead of ≈ 95 %). The recovery's schedule
// therefore raises the refinement to k_uncertainty_refine_iterations (40) when error bars are
// asked for (RecoverSettings::error_bars, recover.h).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/observation.h"

namespace wavebrdf {

struct UncertaintySettings {
    // Tiles of at most this many texels (0 … 16384) get the exact diagonal of G⁺: G formed (band()
    // below) and factored densely (Cholesky, (rows·cols)² doubles, ~(rows·cols)³/3 multiply-adds);
    // larger tiles are probed (below) on the formed G. 4096: up to 64², 128 MiB.
    int dense_max_texels = 4096;
    // Probing (tiles above dense_max_texels): texels (i, j) with the same (i mod d, j mod d) share
    // one probe: d² probes per round (1 … 16). A product is a sparse multiply by the formed G.
    int probe_spacing = 8;
    int rounds = 1;              // independent sign draws per colour (1 … 64), averaged
    double cg_tolerance = 1e-2;  // stop a probe's CG when ‖r‖ ≤ this · ‖b‖ (0 < tol < 1)
    int cg_iterations = 60;      // at most this many CG iterations per probe (1 … 10^4)
    // Forward-difference step of J·v: max |Δh| in µm (> 0). One-sided: the error of G·v is
    // about the phase step 4π·step/λ relatively (2.5e-6 at 1e-7 µm and 0.5 µm), the rounding
    // 1e-16 over it.
    double step_um = 1e-7;
    std::uint64_t seed = 1;  // the probes' signs
};

// G formed explicitly (1/µm²), sparse: for each texel a, G[a][b] for every texel b that
// shares an observation's gradient box with a, stored at the offset (Δrow, Δcol) = b − a
// (wrapped). An axis whose boxes (extent texels) span at least half the tile stores every
// offset 0 … size − 1 (full), else −(extent − 1) … extent − 1.
struct GaussNewtonBand {
    int rows = 0, cols = 0;
    int extent_rows = 0, extent_cols = 0;  // the largest gradient box, texels
    bool full_rows = false, full_cols = false;
    int offset_rows = 0, offset_cols = 0;  // offsets stored per axis
    std::vector<double> values;            // rows·cols · offset_rows·offset_cols, 1/µm²
    std::int64_t forwards = 0;             // forward passes forming it took (all ranks)
    std::size_t width() const { return std::size_t(offset_rows) * std::size_t(offset_cols); }
    // G·v (v: rows·cols heights in µm; std::invalid_argument on a size mismatch).
    std::vector<double> multiply(const std::vector<double>& v) const;
    // G as a dense (rows·cols)² row-major matrix (OutOfMemory when it does not fit).
    std::vector<double> dense() const;
};

// The linearised problem at a solution: G·v without forming G (the header's comment).
// Collective under MPI (construction and apply): every rank passes its share of the
// observations, the same heights, loss and vectors.
class GaussNewtonOperator {
public:
    // Keeps references to `observations` and `comm` (they must outlive the operator).
    // Observations as for recover_heights (this rank's share; validated), `estimate` the
    // heights where the curvature is taken (texel units of its geometry), `loss` the
    // refinement's (any kind; see above for W). Renders every observation once (kept: their
    // slices at the estimate, one double per slice value of this rank's share). Throws
    // std::invalid_argument when no rank has an observation or a slice's geometry does not
    // fit, std::domain_error when the residual variance is 0 or not finite (a noiseless fit
    // with a loss whose variance must be estimated; give a poisson loss instead).
    GaussNewtonOperator(const std::vector<Observation>& observations, const Heightfield& estimate, const Loss& loss,
                        double step_um = 1e-7, const Communicator& comm = serial_communicator());
    ~GaussNewtonOperator();
    GaussNewtonOperator(GaussNewtonOperator&&) noexcept;
    GaussNewtonOperator& operator=(GaussNewtonOperator&&) noexcept;

    // G·v for each of `vectors` (heights in µm, rows·cols each; the results in 1/µm² · µm):
    // one pass over the observations for all of them.
    std::vector<std::vector<double>> apply(const std::vector<std::vector<double>>& vectors) const;
    // The variance σ² the weights were divided by (1 for poisson: the Fisher information is
    // absolute), in the loss's variable (amplitude: √slice units; mse: slice units; cmsle: log).
    double noise_variance() const;
    // G formed (GaussNewtonBand): one forward pass per texel of each observation's gradient box,
    // then Jᵀ W J over its slice values, exact sums (collective: the same bits on every rank).
    GaussNewtonBand band() const;
    // G's diagonal alone, G_ii in 1/µm² (rows·cols values): band()'s forward differences, each
    // column dotted with itself only (no Jacobian kept, no products between texels, no solve).
    // `forwards`, when given, receives the forward passes it took (all ranks). Collective.
    std::vector<double> diagonal(std::int64_t* forwards = nullptr) const;
    // The slice values the variance was estimated from (all ranks), less the texels − 1
    // free heights (0 for poisson).
    double degrees_of_freedom() const;
    int rows() const;
    int cols() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

struct HeightUncertainty {
    std::vector<double> sigma_um;          // rows·cols, row-major: σ of each height (mean removed), µm
    double noise_variance = 1.0;           // GaussNewtonOperator::noise_variance
    bool exact = false;                    // the exact diagonal (dense_max_texels), else probed
    std::int64_t forwards = 0;             // forward passes over observations forming G (all ranks)
    int probes = 0;                        // CG solves (0 when exact)
    int products = 0;                      // products by the formed G (all active probes at once)
    int max_cg_iterations = 0;             // the most any probe needed
    double worst_relative_residual = 0.0;  // the largest ‖r‖/‖b‖ a probe ended with
    // Texels whose probed variance came out ≤ 0 (a probing error larger than the variance):
    // they take the mean of their neighbours' positive variances (periodic 3×3).
    int filled = 0;
};

// The standard deviations (µm) of `estimate`'s heights, mean removed, under the loss's noise
// model (the header's comment): G formed (GaussNewtonOperator::band), then its exact
// pseudo-inverse diagonal (dense Cholesky of G + c·11ᵀ/n) up to settings.dense_max_texels,
// coloured probes and CG on the formed G above. Collective under MPI:
// the same map on every rank. Throws as GaussNewtonOperator and std::domain_error for settings
// outside their ranges (naming the value).
HeightUncertainty height_uncertainty(const std::vector<Observation>& observations, const Heightfield& estimate,
                                     const Loss& loss, const UncertaintySettings& settings = {},
                                     const Communicator& comm = serial_communicator());

// A lower bound of the rms error the error bars predict, √(mean σ²) in µm, from G's diagonal
// alone (GaussNewtonOperator::diagonal, 1/µm²): σ_i² ≥ (1 − 1/n)² / G_ii for the mean-free
// heights (Cauchy–Schwarz on G⁺; G·1 = 0), so √(mean σ²) ≥ √(mean (1 − 1/n)² / G_ii). The
// Cramér–Rao bound of each texel's height were all the others known: what the slices' photons
// at that texel tell about it alone. HUGE_VAL where some G_ii is 0 (no slice value depends on
// the texel); 0 for fewer than two texels.
double fisher_rms_error_lower_bound_um(const std::vector<double>& fisher_diagonal);

// Multiply-adds per CPU second that predicted_uncertainty_seconds assumes for the band's
// products and the solve (this code's loops: the dense 64² solve ran at about this rate).
constexpr double k_uncertainty_madds_per_second = 1e9;
// A forward difference of the band (heights set on a built plan, one texel changed) took about
// half the CPU time of check_convergence's timed forward (measured at 16²: 18 064 forwards).
constexpr double k_uncertainty_forward_fraction = 0.5;
// Jᵀ W J's products are vectorised dot products over the slice values: this many times faster.
constexpr double k_uncertainty_vector_speedup = 4.0;

// The predicted CPU seconds (all threads) of height_uncertainty(observations, estimate, loss,
// settings) for this rank's share, from `pass_seconds`, the CPU time one forward of every
// observation of the share took (its slice rendered by its built plan, as check_convergence
// times it).
// The band: a forward per
// texel the slice depends on (a disk of the footprint's 3σ_p reach and one texel beyond) at
// k_uncertainty_forward_fraction of that pass's rate, and Jᵀ W J's products (texels² / 2 per slice value, vectorised); the solve: n³/2
// multiply-adds (dense, up to settings.dense_max_texels: the factor and the diagonal's substitutions) or probes × cg_iterations × n × band
// width (probed, every probe running out its iterations), at k_uncertainty_madds_per_second. An estimate for deciding whether the bars
// are worth their time (convergence.h, CheckErrorBars), not a measurement. Throws
// std::domain_error for a pass_seconds that is negative or not finite.
double predicted_uncertainty_seconds(const std::vector<Observation>& observations, const Heightfield& estimate,
                                     double pass_seconds, const UncertaintySettings& settings = {});

// The operation counts, CPU seconds and memory height_uncertainty is predicted to take for this
// rank's share (what predicted_uncertainty_seconds returns the seconds of).
struct UncertaintyCost {
    double forwards = 0.0;       // forward passes forming G (HeightUncertainty::forwards counts them)
    double product_madds = 0.0;  // Jᵀ W J's multiply-adds
    double solve_madds = 0.0;    // the dense solve's (factor and substitutions) or the probes' CG multiply-adds
    double seconds = 0.0;        // predicted_uncertainty_seconds
    // Peak bytes height_uncertainty allocates beyond what its caller holds: every observation's
    // slice and weights at the solution (two doubles a slice value), the band's exact sum (16
    // bytes a stored value, a double a value per thread and one for the band itself), one
    // observation's Jacobian per thread (a double per box texel and slice value), and then the
    // dense matrix (texels² doubles) or the probes' CG vectors. `threads`: the threads it runs on.
    double bytes = 0.0;
    // GaussNewtonOperator::diagonal alone (the lower bound above): the same forwards and a dot
    // product per box texel and slice value; its peak bytes (the slices, the exact sum of n
    // values and a scratch per thread).
    double diagonal_seconds = 0.0, diagonal_bytes = 0.0;
};
UncertaintyCost predicted_uncertainty_cost(const std::vector<Observation>& observations, const Heightfield& estimate,
                                           double pass_seconds, const UncertaintySettings& settings, int threads);

// The fraction (0 … 1) of texels whose error, (estimate − its mean) − (truth − its mean) in µm,
// lies within ±k·σ (sigma_um: rows·cols values ≥ 0; k > 0). Throws std::invalid_argument on
// a size mismatch, std::domain_error for k ≤ 0.
double error_coverage(const Heightfield& estimate, const Heightfield& truth, const std::vector<double>& sigma_um,
                      double k);

// The median of sigma_um (µm; 0 when empty).
double median_sigma_um(const std::vector<double>& sigma_um);

// What a recovery reports with its error bars (run_recovery_in_directory, Python's recover).
struct UncertaintyReport {
    HeightUncertainty map;
    double seconds = 0.0;          // wall time of height_uncertainty
    double median_sigma_um = 0.0;  // median σ over the texels, µm
    // With a truth (else −1): the fraction of texels whose error lies within ±1σ and ±2σ
    // (error_coverage) and the rms error (µm, means removed).
    double coverage_1sigma = -1.0, coverage_2sigma = -1.0, rms_error_um = -1.0;
};

// The report of `map` for `estimate`, against `truth` when not null (same size, else
// std::invalid_argument).
UncertaintyReport uncertainty_report(HeightUncertainty map, double seconds, const Heightfield& estimate,
                                     const Heightfield* truth);

}  // namespace wavebrdf
