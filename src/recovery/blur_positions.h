#pragma once
// Internal: the blurred fit (recover.h, stage 0) with the footprint positions corrected in it
// (self-calibration of positions, docs/recovery.md, "Self-calibration: positions").
//
// Fitted at wrong positions, the blurred heights absorb the position errors (measured: 8.4 %
// instead of 2.1 % at 1 texel rms) and the field stage starts in a wrong basin. Here every
// blur stage alternates L-BFGS on the heights with a per-position registration at the fixed
// heights (each position's offset by a grid search of its slices' blurred loss over shifts,
// wide at the first stage, then a half-texel grid around the offset so far), then L-BFGS on
// heights and offsets together (the centre's derivative from SlicePlan::adjoint_with_position
// through the blur). It runs on every position (overlapping windows: heights fitted at one
// position's wrong centre disagree with its neighbours', so they cannot absorb its offset).
#include <array>
#include <cstddef>
#include <functional>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// The registration: search_radius_texels and search_step_texels of the first blur stage's
// grid (shifts of the offset so far), the later stages' (a finer grid around the offset so far).
struct BlurRegistration {
    double first_radius_texels = 4.0, first_step_texels = 1.0;
    double later_radius_texels = 1.0, later_step_texels = 0.5;
    // Blur stages before this one fit the heights only (the widest blurs carry too little of a
    // position: measured, registering there moved 1-texel offsets to 2 texels rms).
    int first_stage = 2;
};

// One registration at fixed heights: every position's offset (offsets_um, 2 per position, µm,
// every rank's) moved to the point of the grid {offset + step·(a, b): |a|, |b| ≤ radius/step}
// (texels) where its observations' blurred loss (blur width `blur_width` lobes, exposure per
// observation as given in root_exposures or 1) is smallest (ties: the first). group: this
// rank's single-wavelength observations; position[g] the index of g's position. Collective:
// the per-position losses are allreduced (each is the sum of its own observations', which lie
// on one rank per wavelength). Returns the rms change (texels) over positions and coordinates.
// Throws std::invalid_argument for radius < 0, step ≤ 0 or radius/step > 16.
double register_positions_blurred(const std::vector<const Observation*>& group,
                                  const std::vector<std::size_t>& position, const Heightfield& heights,
                                  double blur_width, double radius_texels, double step_texels,
                                  std::vector<double>& offsets_um, const Communicator& comm);

// fit_blurred (recover.h) on `group` (this rank's single-wavelength observations, position[g]
// the index of g's position into offsets_um, 2 per position, every rank's, µm) with the
// positions corrected at every blur stage as described at the top. offsets_um is read (the
// start, e.g. 0) and receives the offsets found (true − stated centre, µm; their mean is left
// in, consistent with the heights returned: the field stage's gauge removes it with a shift of
// the object). on_iteration(stage, iteration, loss) as fit_blurred's. Collective.
Heightfield fit_blurred_with_positions(const std::vector<const Observation*>& group,
                                       const std::vector<std::size_t>& position, const Heightfield& initial,
                                       const BlurredFitSettings& settings, std::vector<double>& offsets_um,
                                       const std::function<bool(int, int, double)>& on_iteration,
                                       const Communicator& comm, const BlurRegistration& registration = {});

}  // namespace wavebrdf::detail
