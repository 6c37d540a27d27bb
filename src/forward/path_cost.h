#pragma once
// Internal: the cost model behind RenderPath::Auto's choice between the separable product
// (SeparableEngine / separable_field) and the FFT engine (FftEngine) for one field
// evaluation of one slice (one weight vector; GHS-type models make one per C3 node, so the
// caller multiplies both costs by the node count: the ratio, and so the choice, is the same).
//
// Calibrated on the development machine (2 cores, AVX-512, Release -march=native, float,
// one thread, CPU time, median of the engine_bench runs; docs/fft_path.md has the table):
//   separable  8·n²·K flops at 85 GFLOP/s (the complex product; 75–95 measured) plus the
//              factor build, ~1 ns per factor entry (2·n·K entries);
//   FFT        ~1 ns per spread point (K_kept · S_x · S_y complex multiply-adds),
//              ~0.37 ns per M²·log2(M²) (the row and column FFTs), ~1 ns per M² grid point
//              (zeroing, the transposing copies).
// Both paths split over the threads the same way, so the single-thread seconds are compared.
#include <cstddef>

#include "wavebrdf/brdf.h"

namespace wavebrdf::detail {

// What the choice depends on. Units: µm, cycles/µm.
struct FieldPathInputs {
    int n = 0;                              // slice size (n × n), ≥ 1
    double lambda_um = 0.5;                 // wavelength, > 0
    std::size_t kernels = 0;                // footprint kernels K
    double texel_um = 1.0;                  // texel width w (kernel σ = w/2), > 0
    double max_slope = 0.0;                 // max |slope| component over the kernels (≥ 0)
    double shift_scale = 1.0;               // b_k = shift_scale · (2/λ) · s_k (GHS nodes: S_j)
    double tolerance = 1e-6;                // RenderOptions::tolerance, 1e-12 … 1e-2
    double omega_ix = 0.0, omega_iy = 0.0;  // light direction (sets where the window sits)
    std::size_t views = 1;                  // weight vectors per call (Kirchhoff: 3)
};

struct FieldPathCost {
    double separable_s = 0.0;  // estimated seconds (one thread) of the separable product
    double fft_s = 0.0;        // estimated seconds (one thread) of the FFT engine's forward
    int fft_grid = 0;          // the FFT grid size M it assumes (max of both axes)
    int fft_span = 0;          // spread points per kernel and axis it assumes
};

// The estimates above. std::invalid_argument for n < 1, λ, texel ≤ 0 or non-finite inputs.
FieldPathCost field_path_cost(const FieldPathInputs& inputs);

// RenderPath::Fft when the FFT engine's estimate is below the separable product's, else
// RenderPath::Separable (never Auto or Direct). Same validation as field_path_cost.
RenderPath choose_field_path(const FieldPathInputs& inputs);

}  // namespace wavebrdf::detail
