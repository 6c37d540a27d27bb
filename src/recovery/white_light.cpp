#include "recovery/white_light.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>

namespace wavebrdf::detail {

int repair_defects(std::vector<double>& heights, int rows, int cols, double threshold, int max_candidates,
                   const std::function<double(const std::vector<double>&)>& loss) {
    if (rows < 3 || cols < 3 || max_candidates <= 0 || heights.size() != std::size_t(rows) * std::size_t(cols))
        return 0;
    const auto at = [&](int i, int j) {
        i = (i % rows + rows) % rows;
        j = (j % cols + cols) % cols;
        return std::size_t(i) * std::size_t(cols) + std::size_t(j);
    };
    std::vector<double> median(heights.size()), deviation(heights.size());
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            double n[8];
            int k = 0;
            for (int di = -1; di <= 1; ++di)
                for (int dj = -1; dj <= 1; ++dj)
                    if (di != 0 || dj != 0) n[k++] = heights[at(i + di, j + dj)];
            std::sort(n, n + 8);
            const std::size_t p = at(i, j);
            median[p] = 0.5 * (n[3] + n[4]);
            deviation[p] = std::abs(heights[p] - median[p]);
        }
    std::vector<double> sorted = deviation;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
    const double scale = 1.4826 * sorted[sorted.size() / 2];
    std::vector<std::pair<double, std::size_t>> candidates;
    for (std::size_t p = 0; p < heights.size(); ++p)
        if (deviation[p] > threshold * scale) candidates.push_back({deviation[p], p});
    // Largest first; ties by index (deterministic).
    std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) {
        return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    if (int(candidates.size()) > max_candidates) candidates.resize(std::size_t(max_candidates));
    if (candidates.empty()) return 0;
    double best = loss(heights);
    int kept = 0;
    for (const auto& c : candidates) {
        const std::size_t p = c.second;
        const double before = heights[p];
        heights[p] = median[p];
        const double value = loss(heights);
        if (value < best) {
            best = value;
            ++kept;
        } else {
            heights[p] = before;
        }
    }
    return kept;
}

}  // namespace wavebrdf::detail

namespace wavebrdf::detail {

namespace {

// The periodic 5-point Laplacian of x (rows × cols).
std::vector<double> periodic_laplacian(const std::vector<double>& x, int rows, int cols) {
    std::vector<double> out(x.size());
    for (int i = 0; i < rows; ++i) {
        const std::size_t up = std::size_t((i + rows - 1) % rows) * std::size_t(cols);
        const std::size_t down = std::size_t((i + 1) % rows) * std::size_t(cols);
        const std::size_t row = std::size_t(i) * std::size_t(cols);
        for (int j = 0; j < cols; ++j) {
            const std::size_t left = std::size_t((j + cols - 1) % cols), right = std::size_t((j + 1) % cols);
            out[row + std::size_t(j)] = x[up + std::size_t(j)] + x[down + std::size_t(j)] + x[row + left] +
                                        x[row + right] - 4.0 * x[row + std::size_t(j)];
        }
    }
    return out;
}

}  // namespace

double add_smoothness_penalty(const std::vector<double>& heights, int rows, int cols, double weight,
                              std::vector<double>& gradient) {
    if (!(weight > 0.0) || rows < 1 || cols < 1 || heights.size() != std::size_t(rows) * std::size_t(cols) ||
        gradient.size() != heights.size())
        return 0.0;
    const std::vector<double> lap = periodic_laplacian(heights, rows, cols);
    const double scale = weight / double(heights.size());
    double value = 0.0;
    for (double l : lap) value += l * l;
    // d/dh Σ (Δh)² = 2 Δᵀ Δ h = 2 Δ(Δh) (the periodic Laplacian is symmetric).
    const std::vector<double> lap2 = periodic_laplacian(lap, rows, cols);
    for (std::size_t p = 0; p < gradient.size(); ++p) gradient[p] += 2.0 * scale * lap2[p];
    return scale * value;
}

}  // namespace wavebrdf::detail
