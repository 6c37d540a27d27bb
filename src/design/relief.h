#pragma once
// Internal: a relief as level indices on equally spaced heights, what the K-level FFT identity
// evaluates exactly (design.h).
#include <vector>

#include "design/engine.h"

namespace wavebrdf::detail {

// The most levels the exact evaluation uses: a relief whose heights are not on an equally
// spaced grid of at most this many levels is rounded onto one (LevelRelief::quantised).
constexpr int k_exact_max_levels = 256;

struct LevelRelief {
    int levels = 1;
    LevelHeights heights;     // h_ℓ = base + ℓ·step
    std::vector<int> level;   // per texel, 0 … levels − 1
    bool quantised = false;   // heights rounded onto the grid (not exact)
};

// The relief's heights as levels (exact when they lie on an equally spaced grid of at most
// max_levels levels, else rounded onto max_levels levels across their range).
LevelRelief to_level_relief(const std::vector<double>& heights_um, int max_levels);

// The level step a relief's heights give (a --start relief, read from float32 heights.exr): the
// top height over the nearest integer of top / the smallest gap, gaps under 1e-6 of the top
// being rounding, not levels (exact where the heights are on a grid from 0); the top itself where
// there is one non-zero height (level 1); 0 where every height is 0 (no step to read).
double start_step_um(const std::vector<double>& heights_um);

// Flux Φ_o of every order of every order set (design.h's definition), heights scaled by
// height_scale (a fabrication error).
std::vector<std::vector<double>> level_flux(const LevelRelief& relief, int size, const std::vector<OrderSet>& order_sets,
                                            double height_scale);

}  // namespace wavebrdf::detail
