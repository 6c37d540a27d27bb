#pragma once
// Internal: the blur fabrication error in the design loop. A written relief blurred by a Gaussian
// of σ (the writer's spot) is no longer on the levels; the loop scores it as the grayscale design
// does, on k_grayscale_levels equally spaced levels across [0, top level] with each texel's weight
// split linearly between the two levels around its height (the phasor interpolated: within
// (kqΔ)²/8 of exact), and takes its gradient back through the blur (a symmetric kernel on the
// periodic tile: its own adjoint) to the heights.
#include <memory>
#include <vector>

#include "design/evaluator.h"

namespace wavebrdf::detail {

// A Gaussian blur of σ texels on the periodic size × size tile (separable; the kernel cut at
// ceil(4σ), at most size/2, and normalised). Symmetric, so it is its own adjoint.
std::vector<double> periodic_blur(const std::vector<double>& h, int size, double sigma_texels);

class BlurTerm {
public:
    // The design `p` (levels, order sets, target); sigma_texels > 0.
    BlurTerm(const PreparedDesign& p, double sigma_texels);
    ~BlurTerm();
    // The loss of the blurred relief whose texels hold `level` (indices into p.levels_um); with
    // `height_gradient`, ∂loss/∂h for the relief's heights before the blur (size²).
    double evaluate(const std::vector<int>& level, std::vector<double>* height_gradient, Fractions* fractions = nullptr);
    // The same from heights (µm, size², within [0, top level]).
    double evaluate_heights(const std::vector<double>& heights_um, std::vector<double>* height_gradient,
                            Fractions* fractions = nullptr);

private:
    PreparedDesign m_grid;  // p on the 256-level grid
    std::vector<double> m_levels_um;
    double m_sigma;
    double m_step;
    std::unique_ptr<Evaluator> m_evaluator;
};

// Bytes the blur term adds to a design of this size (the grid's level spectra and their gradients).
double blur_term_bytes(int size);

}  // namespace wavebrdf::detail
