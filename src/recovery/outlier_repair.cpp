#include "recovery/outlier_repair.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "recovery/texel_neighbours.h"

namespace wavebrdf::detail {

namespace {

// The quadratic through texel (i, j)'s 8 neighbours (least squares, periodic) at its centre:
// ½ Σ edge neighbours − ¼ Σ corner neighbours, exact for any quadratic surface, so its residual on
// a smooth surface is the fourth-order terms only (≈ 0.003 µm at 32² and 64², seeds 4 and 10631–
// 10640) where the 8 neighbours' median is off by the curvature (≈ 0.04 µm).
double quadratic8(const std::vector<double>& h, int i, int j, int rows, int cols) {
    const double edges = h[periodic_index(i - 1, j, rows, cols)] + h[periodic_index(i + 1, j, rows, cols)] +
                         h[periodic_index(i, j - 1, rows, cols)] + h[periodic_index(i, j + 1, rows, cols)];
    const double corners = h[periodic_index(i - 1, j - 1, rows, cols)] + h[periodic_index(i - 1, j + 1, rows, cols)] +
                           h[periodic_index(i + 1, j - 1, rows, cols)] + h[periodic_index(i + 1, j + 1, rows, cols)];
    return 0.5 * edges - 0.25 * corners;
}

}  // namespace

OutlierRepairCounts repair_outlier_texels(
    std::vector<double>& heights, int rows, int cols, double threshold, double min_residual, int max_candidates,
    const std::vector<double>& wrap_heights,
    const std::function<double(const std::vector<double>&, std::size_t)>& local_loss) {
    OutlierRepairCounts counts;
    if (rows < 3 || cols < 3 || !(threshold > 0.0) || max_candidates <= 0 ||
        heights.size() != std::size_t(rows) * std::size_t(cols))
        return counts;
    std::vector<double> residual(heights.size());
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const std::size_t p = periodic_index(i, j, rows, cols);
            residual[p] = std::abs(heights[p] - quadratic8(heights, i, j, rows, cols));
        }
    std::vector<double> sorted = residual;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
    const double bound = std::max(threshold * 1.4826 * sorted[sorted.size() / 2], min_residual);
    std::vector<std::pair<double, std::size_t>> candidates;
    for (std::size_t p = 0; p < heights.size(); ++p)
        if (residual[p] > bound) candidates.push_back({residual[p], p});
    // Largest first; ties by index (deterministic).
    std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) {
        return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    if (int(candidates.size()) > max_candidates) candidates.resize(std::size_t(max_candidates));
    for (const auto& c : candidates) {
        const std::size_t p = c.second;
        const int i = int(p / std::size_t(cols)), j = int(p % std::size_t(cols));
        const double at = heights[p];
        // A texel next to one repaired before stood out through it: tested again first.
        const double prediction = quadratic8(heights, i, j, rows, cols);
        if (!(std::abs(at - prediction) > bound)) continue;
        ++counts.flagged;
        std::vector<double> trials{prediction, neighbour_median(heights, i, j, rows, cols)};
        for (double w : wrap_heights)
            if (w > 0.0 && std::isfinite(w)) trials.insert(trials.end(), {at - w, at + w});
        double best = local_loss(heights, p);
        ++counts.evaluations;
        double best_value = at;
        for (double v : trials) {
            heights[p] = v;
            const double loss = local_loss(heights, p);
            ++counts.evaluations;
            if (loss < best) {
                best = loss;
                best_value = v;
            }
        }
        heights[p] = best_value;
        if (best_value != at) ++counts.kept;
    }
    return counts;
}

}  // namespace wavebrdf::detail
