#pragma once
// Internal: the far field of a periodic K-level texel relief (design.h) as the design loop
// evaluates it: the orders of each wavelength (make_order_set), the level masks' spectra, which
// do not depend on the wavelength (LevelSpectra: K FFTs), and the orders' amplitudes from them
// with the adjoint of each step beside it.
#include <complex>
#include <array>
#include <memory>
#include <vector>

namespace wavebrdf::detail {

using Complex = std::complex<double>;

// The propagating orders of one wavelength that carry flux (the texel aperture's zeros, orders
// (m, n) with m or n a non-zero multiple of N, are left out: their amplitude is exactly 0).
struct OrderSet {
    double lambda_um = 0.0;
    double k = 0.0;       // 2π/λ, 1/µm
    double cos_i = 1.0;   // cos θ_i
    double period_um = 0.0;
    std::vector<int> m, n;
    std::vector<int> bin;     // (m mod N)·N + (n mod N): the FFT bin the order reads
    std::vector<double> q;    // cos θ_i + cos θ_o: the height's phase is −k h q
    std::vector<double> env;  // sinc²(m/N) sinc²(n/N) cos θ_o / cos θ_i: flux per |amplitude|²
    std::size_t size() const { return m.size(); }
    // ω_o − (−ω_i) = λ (m, n) / L: the order's offset from the mirror direction.
    double dx(std::size_t o) const { return lambda_um * m[o] / period_um; }
    double dy(std::size_t o) const { return lambda_um * n[o] / period_um; }
};

// Validates and builds (std::invalid_argument / std::domain_error naming the value).
// sin(πx)/(πx), 1 at 0: a square texel's far-field envelope along one axis is sinc(m/N)².
double sinc(double x);

OrderSet make_order_set(int size, double texel_um, const std::array<double, 2>& omega_i, double lambda_um);

// The spectra of K level maps p_ℓ (any real weights per texel: one-hot masks for a relief, a
// softmax for the relaxed design) on an N × N tile, F_ℓ = FFT(p_ℓ)/N², stored bin-major
// (F[bin · K + ℓ]) so that an order reads its K values together.
class LevelSpectra {
public:
    LevelSpectra(int size, int levels);
    ~LevelSpectra();
    LevelSpectra(const LevelSpectra&) = delete;
    LevelSpectra& operator=(const LevelSpectra&) = delete;

    int size() const { return m_size; }
    int levels() const { return m_levels; }
    // weights: K · N² values, level-major (weights[ℓ · N² + t]).
    void forward(const std::vector<double>& weights);
    // From the spectra's gradient B (bin-major like F; dL = Σ Re[conj(B) dF]) to the weights'
    // gradient (level-major), the adjoint of forward: g_ℓ(t) = Re Σ_bin conj(B_ℓ) e^{−2πi bin·t/N} / N².
    void adjoint(const std::vector<Complex>& spectra_gradient, std::vector<double>& weights_gradient);
    const std::vector<Complex>& spectra() const { return m_spectra; }

private:
    struct Plans;
    int m_size, m_levels;
    std::vector<Complex> m_spectra;
    std::unique_ptr<Plans> m_plans;
};

// The levels' heights h_ℓ = base_um + ℓ · step_um (ℓ = 0 … K − 1).
struct LevelHeights {
    double base_um = 0.0;
    double step_um = 0.0;
};

// Flux of every order of `orders`: Φ_o = env_o |A_o|², A_o = Σ_ℓ e^{−i k h_ℓ q_o} F[bin_o · K + ℓ];
// amplitudes kept in `amplitude` for the adjoint. OpenMP over the orders.
void order_flux(const OrderSet& orders, const LevelSpectra& spectra, const LevelHeights& heights,
                std::vector<Complex>& amplitude, std::vector<double>& flux);

// Adjoint of order_flux: adds the gradient for the flux gradient g_o = ∂L/∂Φ_o,
// B[bin · K + ℓ] += 2 g_o env_o A_o e^{+i k h_ℓ q_o}, into `buffers` (one bin-major K · N² buffer
// per OpenMP thread, each thread adding to its own; the caller zeroes them first and sums them:
// GradientBuffers).
struct GradientBuffers {
    std::vector<std::vector<Complex>> per_thread;
    // One zeroed buffer of levels · size² per thread.
    void reset(int levels, int size);
    // Their sum, into the first buffer (returned).
    std::vector<Complex>& sum();
};
void order_flux_adjoint(const OrderSet& orders, const LevelHeights& heights, const std::vector<Complex>& amplitude,
                        const std::vector<double>& flux_gradient, int levels, GradientBuffers& buffers);

// The level step's gradient: for the flux gradient g_o = ∂L/∂Φ_o, ∂L/∂Δ = Σ_o 2 g_o env_o
// Re[conj(A_o) ∂A_o/∂Δ] with ∂A_o/∂Δ = Σ_ℓ (−i k q_o ℓ) e^{−i k h_ℓ q_o} F[bin_o · K + ℓ]
// (h_ℓ = base + ℓ Δ, Δ = heights.step_um): the phase is linear in the step, so this is one more
// contraction of the spectra the forward pass read. OpenMP over the orders.
double order_flux_step_gradient(const OrderSet& orders, const LevelSpectra& spectra, const LevelHeights& heights,
                                const std::vector<Complex>& amplitude, const std::vector<double>& flux_gradient);

}  // namespace wavebrdf::detail
