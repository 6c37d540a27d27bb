// The field stage on overlapping tiles: memory bounded by a tile, time linear in the number of
// tiles (docs/scale.md, "One machine: large surfaces").
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

// Where the tiles lie: along each axis the tiles' origins (texels, maybe negative: the surface
// is periodic) and extents, whether the axis is cut, the footprint's reach and the ramp (texels),
// and the refine factor q (fine samples per texel). Tile (kx, ky) is index kx · count_y + ky.
struct FieldTileLayout {
    int rows = 0, cols = 0, refine = 1, reach = 0, ramp = 1;
    bool cut_x = false, cut_y = false;
    std::vector<int> origin_x, extent_x, origin_y, extent_y;
};

// The layout retrieve_field_tiled uses for a rows × cols surface (reach in texels ≥ 0, refine
// ≥ 1). Throws std::invalid_argument for settings out of range (core 8 to 4096, ramp 1 to core/2).
FieldTileLayout field_tile_layout(int rows, int cols, int refine, int reach, const FieldTiling& tiling);

// How the tiles' objects are aligned before they are blended.
enum class FieldTileAlignment {
    raster,  // one phase per tile, each against the blend of the tiles before it (the first version)
    joint,   // a phase and a tilt per tile, fitted on all overlaps at once (least squares)
};

// The blend of the tiles' objects (objects[t]: (extent_x·q)·(extent_y·q) values in the tile's
// frame, or empty: the tile stays out) on the whole (rows·q)·(cols·q) surface. Each object is
// first multiplied by e^{i(a + b·x + c·y)} (x, y in texels from the tile's centre): with `joint`,
// (a, b, c) of every tile fitted at once by weighted least squares on every pairwise overlap
// (weights: the product of the two tiles' feathering weights; the phase differences, wrapped,
// synchronised first by their complex averages; a tilt is fixed by the overlaps around a
// periodic ring of tiles, the tiles' mean tilt is kept where no ring fixes it); with `raster`
// only a, tile after tile. Modifies `objects` (the aligned tiles). Returns the blend, divided by
// the sum of the weights (0 where that is 0). Throws std::invalid_argument for an object of the
// wrong size. T: double or float (the tiles' objects as stored; the fit and the blend are in
// double either way, a rotated float object is rounded back to float).
template <typename T>
std::vector<std::complex<double>> blend_field_tiles(const FieldTileLayout& layout,
                                                    std::vector<std::vector<std::complex<T>>>& objects,
                                                    FieldTileAlignment alignment = FieldTileAlignment::joint);

// retrieve_field (recover.h) of the rows × cols surface, tile by tile: each tile's retrieval
// sees the observations whose footprints (3σ_p cut) lie inside it, shifted to its origin, and
// starts from `initial` (the whole surface's object, (rows·refine)·(cols·refine)) cut to it.
// The tiles' objects are aligned (blend_field_tiles, joint: a phase and a tilt each, fitted on
// all overlaps at once) and blended with feathering weights sin² over
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
