#pragma once
// Dense Cholesky factorisation in place: the error bars (recovery/uncertainty.cpp) and the
// photon plan's mode variances (recovery/photon_plan.cpp) factor a Gauss-Newton matrix, the cone
// bound (design/cone_bound.cpp) its Newton systems, the position field (recovery/recover_positions.cpp)
// its normal equations.
#include <cstddef>
#include <vector>

namespace wavebrdf::detail {

// Overwrites the lower triangle of the n×n symmetric row-major `a` with L, a = L Lᵀ (the strict
// upper triangle is left as it was). Each entry is one dot product on one thread in a fixed
// order, so the bits do not depend on the thread count; `parallel` splits the rows below each
// pivot over threads. Returns n on success, else the index j of the first pivot that is not
// finite and > 0 (then a[j·n + j] holds that pivot and rows ≥ j are partly overwritten).
std::size_t cholesky_in_place(std::vector<double>& a, std::size_t n, bool parallel);

// Solves L Lᵀ x = b in place (b becomes x) for a factor `l` from cholesky_in_place.
void cholesky_solve(const std::vector<double>& l, std::size_t n, std::vector<double>& b);

}  // namespace wavebrdf::detail
