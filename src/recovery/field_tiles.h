// The field stage on overlapping tiles (issue 13): memory bounded by a tile, time linear in
// the number of tiles (docs/scale.md, "Field tiles").
#pragma once

#include <complex>
#include <functional>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// How the surface is cut. Along an axis of more than `threshold` texels the surface is cut into
// cores of about `core` texels (≥ 8), each retrieved on a tile of core + 2·margin texels, margin
// = ⌈(3σ_p + w)/w⌉ + ramp (the footprint's reach plus the feathering ramp, ≥ 1 texel); an axis
// of threshold texels or fewer is one periodic tile (no margin).
struct FieldTiling {
    int threshold = 64;
    int core = 48;
    int ramp = 4;
};

// Whether retrieve_field_tiled cuts a rows × cols surface at all (some axis above threshold).
bool field_tiles_apply(int rows, int cols, const FieldTiling& tiling);

// retrieve_field (recover.h) of the rows × cols surface, tile by tile: each tile's retrieval
// sees the observations whose footprints (3σ_p cut) lie inside it, shifted to its origin, and
// starts from `initial` (the whole surface's object, (rows·refine)·(cols·refine)) cut to it.
// The tiles' objects are aligned by one phase each, fitted on the overlaps (in raster order,
// each against the blend of those before it), and blended with feathering weights sin² over
// the ramp, 0 within the footprint's reach of a tile's edge (a partition of unity across
// neighbouring tiles). Returns the blend, relative_loss the tiles' mean weighted by their
// observations, iterations the tiles' sum. on_iteration gets each tile's iterations (its stop
// ends the whole). Collective over comm as retrieve_field (every rank runs every tile, with its
// share of the tile's observations). Throws std::invalid_argument for settings out of range, a
// size mismatch or no observation anywhere; what retrieve_field throws.
FieldRetrievalResult retrieve_field_tiled(const std::vector<const Observation*>& observations, double lambda_um,
                                          int rows, int cols, double texel_um,
                                          const std::vector<std::complex<double>>& initial,
                                          const FieldRetrievalSettings& settings, const FieldTiling& tiling,
                                          const std::function<bool(int, double)>& on_iteration,
                                          const Communicator& comm);

}  // namespace wavebrdf::detail
