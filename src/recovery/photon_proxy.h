#pragma once
// Internal: the photon plan's proxy (wavebrdf/photon_plan.h) and the estimator run on it: the
// proxy's noiseless slices and its Gauss-Newton matrix at the truth, factored, and the
// maximum-likelihood heights of noisy slices of it, found from a start by quasi-Newton steps
// preconditioned by that matrix.
#include <cstdint>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

struct PhotonProxy {
    Heightfield tile;
    std::vector<Observation> observations;  // noiseless
    double photons = 0.0;                   // per slice: the G below's
    double density_ratio = 1.0;             // the full plan's area per position over the proxy's
    // G + c·11ᵀ/n = L Lᵀ (c the mean diagonal, 1/µm²; n the texels): L, n × n row-major (lower
    // triangle). G·1 = 0 (the mean height is not observed), so its inverse is G⁺ + 11ᵀ/(n c).
    std::vector<double> factor;
    double diagonal_mean = 0.0;  // c
    std::int64_t forwards = 0;   // forward passes forming G
};

// G of the Poisson loss with `photons` per slice at `tile` (uncertainty.h), factored. Throws
// std::domain_error when G is singular on the mean-free heights (a texel no slice sees), and as
// GaussNewtonOperator does.
PhotonProxy photon_proxy(const Heightfield& tile, std::vector<Observation> observations, double photons,
                         double density_ratio);

// The error bars' mean variance (trace G⁺ / n, µm²) times the density ratio.
double proxy_bars_variance_um2(const PhotonProxy& proxy);

struct ProxySolve {
    std::vector<double> heights;  // raw units of the tile
    int gradients = 0;            // loss and gradient evaluations
    int steps = 0;                // accepted steps
    int halvings = 0;             // step halvings, over all steps
};

// The heights minimising the Poisson deviance of `observations` (slices of the proxy's geometry
// with `photons` per slice) from `start` (raw heights): L-BFGS (memory 8) whose initial inverse
// Hessian is G⁻¹ scaled to these photons, the gradient by the adjoint (observation_loss), each
// step halved (at most 4 times) until the loss falls enough (Armijo 10⁻⁴); it stops when a step
// moves the heights by ≤ tolerance_um rms, when no step lowers the loss, or after
// k_photon_mc_steps steps. `plans` keeps the slices' plans between calls.
ProxySolve proxy_maximum_likelihood(const PhotonProxy& proxy, const std::vector<Observation>& observations,
                                    double photons, std::vector<double> start, double tolerance_um,
                                    ObservationPlans& plans);

}  // namespace wavebrdf::detail
