// The refinement's coarse space (docs/scale.md, "One machine: large surfaces"): smooth
// periodic cubic B-splines at several spacings over the surface, so that the refinement's L-BFGS
// can move the longest undulations, which the slices barely pin, by steps of their own size.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

namespace wavebrdf::detail {

// Levels of periodic uniform cubic B-splines over a periodic rows × cols surface: level l has
// M_l = round(side / (spacing · 2^l)) nodes along each axis (at least 4; levels are added while
// both axes keep 4 or more), node a at a · side / M_l texels, basis function
// β((i·M/side) − a) β((j·M/side) − b) (β the centred cubic B-spline, support ±2 nodes: the
// functions of a level sum to 1 at every texel). The map from the coefficients c (all levels,
// level after level, each row-major M_rows × M_cols) to heights is
//     B c = weight · P Σ_l B_l c_l,   P: the mean removed (the piston is no slice's: the gauge),
// and its adjoint Bᵀ g = weight · Σ_l B_lᵀ P g. For a field smooth on the scale of level l's
// spacing s_l, B_l B_lᵀ f ≈ s_l² f: L-BFGS on (x, c) with h = x + B c (coarse_objective) takes
// steps ~ weight² s_l² times longer along the smooth directions (a BPX-like preconditioner).
class CoarseBasis {
public:
    // rows, cols ≥ 1; spacing_texels ≥ 1 (the finest level's node spacing); weight finite > 0.
    // Throws std::invalid_argument naming the bad value. A surface too small for one level of 4
    // nodes per axis has no levels (size() 0: apply and adjoint do nothing).
    CoarseBasis(int rows, int cols, double spacing_texels, double weight = 1.0);

    std::size_t size() const { return m_size; }  // coefficients, all levels
    int levels() const { return int(m_levels.size()); }
    // Nodes along the rows and the columns of level l.
    int nodes_rows(int level) const { return m_levels[std::size_t(level)].m_rows; }
    int nodes_cols(int level) const { return m_levels[std::size_t(level)].m_cols; }

    // h += B c (c: size() values; h: rows · cols, row-major).
    void apply(const double* c, std::vector<double>& h) const;
    // gc = Bᵀ g (g: rows · cols; gc: size() values, overwritten).
    void adjoint(const std::vector<double>& g, double* gc) const;

private:
    // One axis of a level: for each texel the 4 nodes whose β reaches it and their weights.
    struct Axis {
        std::vector<int> node;       // texels × 4
        std::vector<double> weight;  // texels × 4
    };
    struct Level {
        int m_rows = 0, m_cols = 0;
        Axis m_row_axis, m_col_axis;
        std::size_t m_offset = 0;  // its first coefficient in c
    };
    static Axis make_axis(int texels, int nodes);
    int m_rows, m_cols;
    double m_weight;
    std::size_t m_size = 0;
    std::vector<Level> m_levels;
};

using Objective = std::function<double(const std::vector<double>&, std::vector<double>&)>;

// The objective f(x + B c) of z = (x, c) (x: the heights, c: the coarse coefficients), with its
// gradient (∇f, Bᵀ∇f) (no new adjoint): a change of variables for the refinement's L-BFGS.
Objective coarse_objective(const Objective& objective, const CoarseBasis& basis);

// The heights of z = (x, c): x + B c (z of rows · cols + basis.size() values).
std::vector<double> coarse_heights(const std::vector<double>& z, const CoarseBasis& basis);

// f(h0 + B c) of c alone, with its gradient Bᵀ∇f (the coarse-only correction of fixed heights h0).
Objective coarse_only_objective(const Objective& objective, const CoarseBasis& basis, const std::vector<double>& h0);

}  // namespace wavebrdf::detail
