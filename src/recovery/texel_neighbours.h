#pragma once
// Texel neighbourhoods on a periodic heightfield (rows × cols, row-major): the index of texel
// (i, j) for any integers i, j (wrapped around), and the median of a texel's 8 neighbours.
// Shared by the single-texel outlier repair and the white-light defect repair.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace wavebrdf::detail {

inline std::size_t periodic_index(int i, int j, int rows, int cols) {
    i = (i % rows + rows) % rows;
    j = (j % cols + cols) % cols;
    return std::size_t(i) * std::size_t(cols) + std::size_t(j);
}

// The median of texel (i, j)'s 8 neighbours (periodic): the mean of the middle two.
inline double neighbour_median(const std::vector<double>& h, int i, int j, int rows, int cols) {
    double n[8];
    int k = 0;
    for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj)
            if (di != 0 || dj != 0) n[k++] = h[periodic_index(i + di, j + dj, rows, cols)];
    std::sort(n, n + 8);
    return 0.5 * (n[3] + n[4]);
}

}  // namespace wavebrdf::detail
