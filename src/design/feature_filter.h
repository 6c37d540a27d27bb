#pragma once
// Internal: the grayscale relief's filtered parameterisation (no lateral detail finer than a
// minimum feature F, by construction rather than by a penalty). On the periodic N × N tile of
// texel w the heights are
//     h = H · G(σ(z)),   σ(z) = 1 / (1 + e^{−z})   (z: the free latent field, one value a texel)
// with G the circular low-pass filter whose transfer function is the autocorrelation of the
// disc |ν| ≤ 1/(2F) of spatial frequencies ν = (m, n)/L (L = N w), normalised to 1 at ν = 0.
// Its kernel is the squared modulus of the disc's inverse DFT, so it is non-negative and sums
// to 1: h stays within [0, H] whatever z is; and the transfer vanishes exactly for |ν| > 1/F,
// so the relief's DFT has no content above 1/F (the texel's own aperture aside). G is real and
// even, so it is its own adjoint.
#include <memory>
#include <vector>

namespace wavebrdf::detail {

class FeatureFilter {
public:
    // size N (2 … 2048), texel_um > 0, min_feature_um ≥ 2 texel_um (finer is below the tile's
    // Nyquist limit); std::domain_error naming the value otherwise.
    FeatureFilter(int size, double texel_um, double min_feature_um);
    ~FeatureFilter();
    FeatureFilter(const FeatureFilter&) = delete;
    FeatureFilter& operator=(const FeatureFilter&) = delete;

    int size() const { return m_size; }
    // The transfer function per DFT bin (m mod N, n mod N), row-major: real, in [0, 1].
    const std::vector<double>& transfer() const { return m_transfer; }
    // out = G in (N² values each; out may be in).
    void apply(const std::vector<double>& in, std::vector<double>& out) const;

private:
    struct Plans;
    int m_size;
    std::vector<double> m_transfer;
    std::unique_ptr<Plans> m_plans;
};

// h = H · G(σ(z)).
void filtered_heights(const FeatureFilter& filter, double height_range_um, const std::vector<double>& z,
                      std::vector<double>& heights_um);
// The adjoint: ∂L/∂z = σ'(z) · H · G(∂L/∂h).
void filtered_heights_adjoint(const FeatureFilter& filter, double height_range_um, const std::vector<double>& z,
                              const std::vector<double>& heights_gradient, std::vector<double>& z_gradient);

}  // namespace wavebrdf::detail
