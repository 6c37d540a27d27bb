#include "recovery/white_light.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/text.h"
#include "recovery/texel_neighbours.h"

namespace wavebrdf::detail {

namespace {

// The median of each texel's 8 neighbours (periodic).
std::vector<double> neighbour_medians(const std::vector<double>& h, int rows, int cols) {
    std::vector<double> out(h.size());
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) out[periodic_index(i, j, rows, cols)] = neighbour_median(h, i, j, rows, cols);
    return out;
}

}  // namespace

int repair_defects(std::vector<double>& heights, int rows, int cols, double threshold, int max_candidates,
                   const std::function<double(const std::vector<double>&)>& loss) {
    if (rows < 3 || cols < 3 || max_candidates <= 0 || heights.size() != std::size_t(rows) * std::size_t(cols))
        return 0;
    const std::vector<double> median = neighbour_medians(heights, rows, cols);
    std::vector<double> deviation(heights.size());
    for (std::size_t p = 0; p < heights.size(); ++p) deviation[p] = std::abs(heights[p] - median[p]);
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

void check_white_smoothness(const std::vector<double>& weights, const std::string& name) {
    if (weights.size() > k_max_white_smoothness_weights)
        throw std::invalid_argument(name + ": " + std::to_string(weights.size()) +
                                    " weights are too many; expected at most " +
                                    std::to_string(k_max_white_smoothness_weights));
    for (double w : weights)
        if (!(w >= 0.0 && w <= 1e12))
            throw std::invalid_argument(name + " weight " + format_shortest(w) +
                                        " is invalid; expected a finite value 0 to 1e12");
}

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

namespace wavebrdf::detail {

namespace {

// h − the median of its 8 neighbours, per texel (periodic).
std::vector<double> median_residual(const std::vector<double>& h, int rows, int cols) {
    std::vector<double> out = neighbour_medians(h, rows, cols);
    for (std::size_t p = 0; p < h.size(); ++p) out[p] = h[p] - out[p];
    return out;
}

// `h` with the texels in `unknown` (sorted indices) replaced by the biharmonic fill (Δ²h = 0 on
// them, the other texels fixed): Gauss–Seidel in index order from the mean of the known texels
// next to them (deterministic). The 13-point stencil: 20 h − 8 Σ(4 neighbours) + 2 Σ(diagonal)
// + Σ(2 apart) = 0.
std::vector<double> biharmonic_fill(std::vector<double> h, const std::vector<std::size_t>& unknown, int rows,
                                    int cols) {
    if (unknown.empty()) return h;
    std::vector<char> is_unknown(h.size(), 0);
    for (std::size_t p : unknown) is_unknown[p] = 1;
    double sum = 0.0;
    int count = 0;
    for (std::size_t p : unknown) {
        const int i = int(p / std::size_t(cols)), j = int(p % std::size_t(cols));
        const int d[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
        for (const auto& o : d) {
            const std::size_t q = periodic_index(i + o[0], j + o[1], rows, cols);
            if (!is_unknown[q]) {
                sum += h[q];
                ++count;
            }
        }
    }
    const double start = count > 0 ? sum / count : 0.0;
    for (std::size_t p : unknown) h[p] = start;
    for (int sweep = 0; sweep < 4000; ++sweep) {
        double change = 0.0;
        for (std::size_t p : unknown) {
            const int i = int(p / std::size_t(cols)), j = int(p % std::size_t(cols));
            const auto v = [&](int di, int dj) { return h[periodic_index(i + di, j + dj, rows, cols)]; };
            const double n4 = v(-1, 0) + v(1, 0) + v(0, -1) + v(0, 1);
            const double nd = v(-1, -1) + v(-1, 1) + v(1, -1) + v(1, 1);
            const double n2 = v(-2, 0) + v(2, 0) + v(0, -2) + v(0, 2);
            const double next = (8.0 * n4 - 2.0 * nd - n2) / 20.0;
            change = std::max(change, std::abs(next - h[p]));
            h[p] = next;
        }
        if (change <= 1e-13 * (1.0 + std::abs(start))) break;
    }
    return h;
}

}  // namespace

int repair_defect_regions(std::vector<double>& heights, int rows, int cols, double wrap_height, double threshold,
                          int max_evaluations, int max_region_texels,
                          const std::function<double(const std::vector<double>&)>& loss) {
    if (rows < 3 || cols < 3 || !(wrap_height > 0.0) || max_evaluations <= 0 || max_region_texels <= 0 ||
        heights.size() != std::size_t(rows) * std::size_t(cols))
        return 0;
    const std::vector<double> residual = median_residual(heights, rows, cols);
    std::vector<double> deviation(residual.size());
    for (std::size_t p = 0; p < residual.size(); ++p) deviation[p] = std::abs(residual[p]);
    std::vector<double> sorted = deviation;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
    const double scale = 1.4826 * sorted[sorted.size() / 2];
    // The flagged texels grown by one (8 neighbours).
    std::vector<char> mask(heights.size(), 0);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            if (deviation[periodic_index(i, j, rows, cols)] > threshold * scale)
                for (int di = -1; di <= 1; ++di)
                    for (int dj = -1; dj <= 1; ++dj) mask[periodic_index(i + di, j + dj, rows, cols)] = 1;
    // Its 4-connected components (periodic), each with its largest flagged deviation.
    struct Region {
        double deviation = 0.0;
        std::vector<std::size_t> texels;
    };
    std::vector<Region> regions;
    std::vector<char> seen(heights.size(), 0);
    for (std::size_t start = 0; start < heights.size(); ++start) {
        if (!mask[start] || seen[start]) continue;
        Region r;
        std::vector<std::size_t> stack{start};
        seen[start] = 1;
        while (!stack.empty()) {
            const std::size_t p = stack.back();
            stack.pop_back();
            r.texels.push_back(p);
            if (deviation[p] > threshold * scale) r.deviation = std::max(r.deviation, deviation[p]);
            const int i = int(p / std::size_t(cols)), j = int(p % std::size_t(cols));
            const int d[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
            for (const auto& o : d) {
                const std::size_t q = periodic_index(i + o[0], j + o[1], rows, cols);
                if (mask[q] && !seen[q]) {
                    seen[q] = 1;
                    stack.push_back(q);
                }
            }
        }
        std::sort(r.texels.begin(), r.texels.end());
        if (int(r.texels.size()) <= max_region_texels) regions.push_back(std::move(r));
    }
    if (regions.empty()) return 0;
    // Largest deviation first; ties by first texel (deterministic).
    std::sort(regions.begin(), regions.end(), [](const Region& a, const Region& b) {
        return a.deviation != b.deviation ? a.deviation > b.deviation : a.texels.front() < b.texels.front();
    });
    double best = loss(heights);
    int evaluations = 0, changed = 0;
    for (const Region& r : regions) {
        if (evaluations >= max_evaluations) break;
        // The core: texels at least half a wrap from the fill over the whole region; the fill
        // again over the core alone (the rest of the region known), and each core texel's
        // nearest whole number of wraps from it.
        const std::vector<double> fill_region = biharmonic_fill(heights, r.texels, rows, cols);
        std::vector<std::size_t> core;
        for (std::size_t p : r.texels)
            if (std::abs(heights[p] - fill_region[p]) >= 0.5 * wrap_height) core.push_back(p);
        if (core.empty())
            for (std::size_t p : r.texels)
                if (deviation[p] > threshold * scale) core.push_back(p);
        if (core.empty()) continue;
        const std::vector<double> fill = biharmonic_fill(heights, core, rows, cols);
        std::vector<std::vector<double>> candidates;
        std::vector<double> own = heights;
        bool moved = false;
        for (std::size_t p : core) {
            const double k = std::round((heights[p] - fill[p]) / wrap_height);
            own[p] = heights[p] - k * wrap_height;
            moved = moved || k != 0.0;
        }
        if (moved) candidates.push_back(own);
        candidates.push_back(fill);
        for (double k : {1.0, -1.0, 2.0, -2.0}) {
            std::vector<double> shifted = heights;
            for (std::size_t p : core) shifted[p] -= k * wrap_height;
            if (!moved || shifted != own) candidates.push_back(std::move(shifted));
        }
        int chosen = -1;
        double chosen_value = best;
        for (std::size_t c = 0; c < candidates.size() && evaluations < max_evaluations; ++c) {
            const double value = loss(candidates[c]);
            ++evaluations;
            if (value < chosen_value) {
                chosen_value = value;
                chosen = int(c);
            }
        }
        if (chosen >= 0) {
            heights = candidates[std::size_t(chosen)];
            best = chosen_value;
            ++changed;
        }
    }
    return changed;
}

}  // namespace wavebrdf::detail
