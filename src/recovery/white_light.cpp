#include "recovery/white_light.h"

#include <Eigen/Dense>
#include <cstddef>

#include "wavebrdf/spectrum.h"

namespace wavebrdf::detail {

std::array<double, 9> xyz_from_rgb(const std::vector<double>& lambdas_um) {
    const std::vector<double> mix = spectral_mix_weights(lambdas_um);
    const Eigen::Index n = Eigen::Index(lambdas_um.size());
    Eigen::MatrixXd m(3, n), w(3, n);
    for (Eigen::Index l = 0; l < n; ++l) {
        const std::array<double, 3> xyz = cie1931_xyz(lambdas_um[std::size_t(l)]);
        for (int c = 0; c < 3; ++c) {
            m(c, l) = mix[std::size_t(c) * std::size_t(n) + std::size_t(l)];
            w(c, l) = xyz[std::size_t(c)];
        }
    }
    // A = W Mᵀ (M Mᵀ)⁻¹: the least-squares A with A M ≈ W.
    const Eigen::Matrix3d mmt = m * m.transpose();
    Eigen::Matrix3d a = (w * m.transpose()) * mmt.inverse();
    // A constant spectrum c has RGB (c, c, c): scale each row to map it to 1.
    for (int c = 0; c < 3; ++c) {
        const double s = a.row(c).sum();
        if (s != 0.0) a.row(c) /= s;
    }
    std::array<double, 9> out{};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out[std::size_t(3 * r + c)] = a(r, c);
    return out;
}

void apply_colour_map(const std::array<double, 9>& a, std::vector<double>& values) {
    for (std::size_t p = 0; p + 2 < values.size(); p += 3) {
        const double r = values[p], g = values[p + 1], b = values[p + 2];
        values[p] = a[0] * r + a[1] * g + a[2] * b;
        values[p + 1] = a[3] * r + a[4] * g + a[5] * b;
        values[p + 2] = a[6] * r + a[7] * g + a[8] * b;
    }
}

void apply_colour_map_adjoint(const std::array<double, 9>& a, std::vector<double>& weights) {
    for (std::size_t p = 0; p + 2 < weights.size(); p += 3) {
        const double x = weights[p], y = weights[p + 1], z = weights[p + 2];
        weights[p] = a[0] * x + a[3] * y + a[6] * z;
        weights[p + 1] = a[1] * x + a[4] * y + a[7] * z;
        weights[p + 2] = a[2] * x + a[5] * y + a[8] * z;
    }
}

}  // namespace wavebrdf::detail

#include <algorithm>
#include <cmath>
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
