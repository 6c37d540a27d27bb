#pragma once
// A periodic heightfield in the convention of the public release of Yan et al. 2018:
// values in units of texel width, scaled by a vertical factor, on a grid of square texels.
#include <array>
#include <cstddef>
#include <vector>

namespace wavebrdf {

// Physically meaningful ranges, refused outside (1e-300 or 1e300 gave all-zero slices).
// Texel width: 0.1 nm (atomic steps) to 1 cm. Vertical scale: 0 (flat) or 1e-6 … 1e4 in
// magnitude (heights v · h in texel widths; negative v mirrors the surface).
constexpr double k_min_texel_um = 1e-4;
constexpr double k_max_texel_um = 1e4;
constexpr double k_min_vscale = 1e-6;
constexpr double k_max_vscale = 1e4;

class Heightfield {
public:
    // rows × cols values, row-major (`values[i * cols + j]` is h[i][j]); row index i runs
    // along the first surface coordinate x, column index j along y (docs/model.md §2).
    //   values    heights in units of texel width, finite
    //   texel_um  texel width w in µm, k_min_texel_um … k_max_texel_um (1e-4 … 1e4)
    //   vscale    vertical scale v (dimensionless): 0, or k_min_vscale ≤ |v| ≤ k_max_vscale
    //             (1e-6 … 1e4)
    // Throws std::invalid_argument on an empty grid or a size mismatch and
    // std::domain_error on a non-finite value or a parameter outside its range.
    Heightfield(int rows, int cols, std::vector<double> values, double texel_um = 1.0, double vscale = 1.0);

    int rows() const { return m_rows; }
    int cols() const { return m_cols; }
    double texel_um() const { return m_texel_um; }
    double vscale() const { return m_vscale; }
    // Period of the tiling along x (rows) and y (columns), in µm.
    double period_x_um() const { return m_rows * m_texel_um; }
    double period_y_um() const { return m_cols * m_texel_um; }

    // Raw value h[i][j] in texel units; indices wrap periodically.
    double value(int i, int j) const { return m_values[index(wrap(i, m_rows), wrap(j, m_cols))]; }
    // Height H = v · w · h[i][j] in µm.
    double height_um(int i, int j) const { return m_vscale * m_texel_um * value(i, j); }
    // Dimensionless slope by periodic central differences (docs/model.md §2):
    // s = v · ((h[i+1][j] − h[i−1][j]) / 2, (h[i][j+1] − h[i][j−1]) / 2).
    std::array<double, 2> slope(int i, int j) const {
        return {0.5 * m_vscale * (value(i + 1, j) - value(i - 1, j)),
                0.5 * m_vscale * (value(i, j + 1) - value(i, j - 1))};
    }

    const std::vector<double>& values() const { return m_values; }
    std::size_t index(int i, int j) const {
        return static_cast<std::size_t>(i) * static_cast<std::size_t>(m_cols) + static_cast<std::size_t>(j);
    }

    // The same geometry with other values / parameters (validated like the constructor).
    Heightfield with_values(std::vector<double> values) const;
    Heightfield with_scale(double texel_um, double vscale) const;

private:
    static int wrap(int i, int n) {
        const int r = i % n;
        return r < 0 ? r + n : r;
    }

    int m_rows;
    int m_cols;
    std::vector<double> m_values;
    double m_texel_um;
    double m_vscale;
};

// Every height H = v · w · h in µm, row-major (rows · cols values).
std::vector<double> heights_um(const Heightfield& heightfield);

}  // namespace wavebrdf
