#pragma once
// Inverse surface design: the far field of a periodic relief of square texels, exactly under
// scalar (thin-element, Kirchhoff) diffraction, and the appearance targets a design is scored
// against (docs/design.md).
//
// The relief: an N × N tile of square texels of width w (µm), texel t = (i, j) of constant height
// h_t (µm), repeated periodically (period L = N·w; row index i along x, column j along y as in
// docs/model.md §6). Under a plane wave from ω_i (projected, pointing towards the light) the
// reflected field is a sum of diffraction orders (m, n) leaving along
//     ω_o(m, n) = −ω_i + λ (m, n) / L                          (the grating equation)
// with the thin-element amplitude (the Kirchhoff integral over one period, normalised to the tile)
//     A_mn = sinc(m/N) sinc(n/N) · (1/N²) Σ_t e^{−i k h_t (cos θ_i + cos θ_o,mn)} e^{−2πi (m i_t + n j_t)/N}
// (k = 2π/λ, sinc x = sin πx / πx: a texel's aperture; e^{−ix} as docs/model.md §8). The phase
// depends on the order through cos θ_o,mn, so this is not one FFT; for a relief of K distinct
// heights H_ℓ it is exactly
//     A_mn = sinc·sinc · Σ_ℓ e^{−i k H_ℓ (cos θ_i + cos θ_o,mn)} · FFT(mask_ℓ)(m mod N, n mod N) / N²,
// K FFTs for every wavelength at once. Power: an order is propagating when |ω_o| < 1 and carries
// the flux Φ_mn = |A_mn|² cos θ_o,mn / cos θ_i; evanescent orders carry none. The fraction of
// the reflected power in an order is Φ_mn / Σ_propagating Φ (the relief is lossless: everything
// reflected leaves in the propagating orders). The unnormalised sum Σ Φ (`kirchhoff_total`) is 1
// for a flat mirror and shows how far the scalar model is from conserving energy elsewhere.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace wavebrdf {

// The propagating diffraction orders of one wavelength and the fraction of the reflected power
// each carries (sums to 1 unless no flux is reflected at all).
struct OrderPowers {
    double lambda_um = 0.0;
    std::vector<int> m, n;           // order indices along x (rows) and y (columns)
    std::vector<double> omega_x, omega_y;  // their directions ω_o (projected)
    std::vector<double> power;       // fraction of the reflected power, Φ_mn / Σ Φ
    double kirchhoff_total = 0.0;    // Σ Φ_mn over the propagating orders before normalising
};

// The orders of the relief `heights_um` (size × size, row-major, µm, finite) of texel width
// texel_um (1e-3 … 1e3 µm) under light from omega_i (|ω_i| < 1) at lambda_um (0.05 … 100 µm),
// by the K-level FFT identity above: exact for a relief whose heights lie on an equally spaced
// grid of at most 256 levels (every relief `design` makes; each level's texels one mask). Any
// other relief is evaluated on 256 equally spaced levels across its range, its heights rounded
// to the nearest (`quantised` says so). size 1 … 8192. Throws std::invalid_argument / std::domain_error naming the bad value.
std::vector<OrderPowers> exact_orders(const std::vector<double>& heights_um, int size, double texel_um,
                                      const std::array<double, 2>& omega_i, const std::vector<double>& lambdas_um,
                                      bool* quantised = nullptr);

// The same orders by a slow direct evaluation, independent of the FFT identity: the Kirchhoff
// integral over the tile by the midpoint rule with `samples` × `samples` points per texel (so the
// texel aperture is integrated, not taken from the sinc formula), summed texel by texel for every
// order. O(orders · N² · samples²): for tests on small tiles (size ≤ 64).
std::vector<OrderPowers> direct_orders(const std::vector<double>& heights_um, int size, double texel_um,
                                       const std::array<double, 2>& omega_i, const std::vector<double>& lambdas_um,
                                       int samples = 8);

// Colour: CIE 1976 u′v′ of XYZ (0, 0 for black), the XYZ of a linear sRGB (D65) colour, and the
// linear value of an 8-bit sRGB-encoded channel.
std::array<double, 2> xyz_to_uv(const std::array<double, 3>& xyz);
std::array<double, 3> linear_srgb_to_xyz(const std::array<double, 3>& rgb);
double srgb_decode(double encoded);

// The reflected light's colour for per-wavelength reflectances `reflectance` (fractions of the
// incident power, one per wavelength of `lambdas_um`) under the equal-energy white those
// wavelengths sample, as XYZ with Y normalised so that reflectance 1 at every wavelength has
// Y = 1 (the luminous efficiency), adapted to D65 as the slices are (spectrum.h).
std::array<double, 3> reflectance_xyz(const std::vector<double>& lambdas_um, const std::vector<double>& reflectance);

}  // namespace wavebrdf
