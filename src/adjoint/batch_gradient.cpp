// The batch's gradient (batch.h): each item's forward and SlicePlan adjoint on one thread,
// per-thread partial gradients per heightfield, added in thread order after the region.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "forward/batch_run.h"
#include "wavebrdf/batch.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {

namespace detail {

template <typename Float>
void batch_gradient(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                    const std::vector<double>& weights, std::vector<std::vector<double>>& gradients,
                    const RenderOptions& options, std::vector<Float>* slices) {
    const int threads = prepare_batch(heightfields, batch, options, sizeof(Float), true);
    const std::size_t values = static_cast<std::size_t>(batch.resolution) * static_cast<std::size_t>(batch.resolution) *
                               static_cast<std::size_t>(batch.channels);
    const std::size_t items = batch.items.size();
    if (weights.size() != values * items)
        throw std::invalid_argument("batch weights have " + std::to_string(weights.size()) +
                                    " entries; expected items * resolution^2 * channels = " + std::to_string(items) +
                                    " * " + std::to_string(values / batch.channels) + " * " +
                                    std::to_string(batch.channels));
    const std::size_t cells = static_cast<std::size_t>(heightfields.front()->rows()) *
                              static_cast<std::size_t>(heightfields.front()->cols());
    if (gradients.empty()) gradients.resize(heightfields.size());
    if (gradients.size() != heightfields.size())
        throw std::invalid_argument("batch gradients has " + std::to_string(gradients.size()) +
                                    " entries; expected one per heightfield (" + std::to_string(heightfields.size()) +
                                    ") or none");
    for (std::size_t k = 0; k < gradients.size(); ++k) {
        if (gradients[k].empty()) gradients[k].assign(cells, 0.0);
        if (gradients[k].size() != cells)
            throw std::invalid_argument("gradient " + std::to_string(k) + " has " +
                                        std::to_string(gradients[k].size()) +
                                        " values; expected rows*cols = " + std::to_string(cells) + " (or empty)");
    }
    if (slices)
        *slices = allocating("the batch's slices", double(values) * double(items) * sizeof(Float),
                             [&] { return std::vector<Float>(values * items); });
    // Partial gradients per thread and heightfield, allocated when first touched.
    std::vector<std::vector<std::vector<double>>> partial(static_cast<std::size_t>(threads),
                                                          std::vector<std::vector<double>>(heightfields.size()));
    std::vector<BatchPlan<Float>> plans;
    plans.reserve(static_cast<std::size_t>(threads));
    for (int t = 0; t < threads; ++t) plans.emplace_back(heightfields, batch, options, true);
    for_each_item(items, threads, [&](std::size_t b, int t) {
        const BatchItem& item = batch.items[b];
        SlicePlan<Float>& plan = plans[static_cast<std::size_t>(t)].plan_for(item);
        const std::vector<Float>& slice = plan.forward();
        if (slices) std::copy(slice.begin(), slice.end(), slices->begin() + static_cast<std::ptrdiff_t>(b * values));
        const auto first = weights.begin() + static_cast<std::ptrdiff_t>(b * values);
        const std::vector<double> w(first, first + static_cast<std::ptrdiff_t>(values));
        plan.adjoint(w, partial[static_cast<std::size_t>(t)][item.heightfield]);  // sized and zeroed when empty
    });
    for (const auto& thread : partial)
        for (std::size_t k = 0; k < thread.size(); ++k)
            for (std::size_t c = 0; c < thread[k].size(); ++c) gradients[k][c] += thread[k][c];
}

template void batch_gradient<float>(const std::vector<const Heightfield*>&, const SliceBatch&,
                                    const std::vector<double>&, std::vector<std::vector<double>>&, const RenderOptions&,
                                    std::vector<float>*);
template void batch_gradient<double>(const std::vector<const Heightfield*>&, const SliceBatch&,
                                     const std::vector<double>&, std::vector<std::vector<double>>&,
                                     const RenderOptions&, std::vector<double>*);

}  // namespace detail

template <typename Float>
void batch_gradient(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                    const std::vector<double>& weights, std::vector<std::vector<double>>& gradients,
                    const RenderOptions& options, std::vector<Float>* slices) {
    detail::batch_gradient<Float>(detail::addresses(heightfields), batch, weights, gradients, options, slices);
}

template <typename Float>
void batch_gradient(const Heightfield& heightfield, const SliceBatch& batch, const std::vector<double>& weights,
                    std::vector<double>& gradient, const RenderOptions& options, std::vector<Float>* slices) {
    std::vector<std::vector<double>> gradients(1);
    gradients[0] = std::move(gradient);
    try {
        detail::batch_gradient<Float>({&heightfield}, batch, weights, gradients, options, slices);
    } catch (...) {
        gradient = std::move(gradients[0]);  // left as given
        throw;
    }
    gradient = std::move(gradients[0]);
}

template void batch_gradient<float>(const std::vector<Heightfield>&, const SliceBatch&, const std::vector<double>&,
                                    std::vector<std::vector<double>>&, const RenderOptions&, std::vector<float>*);
template void batch_gradient<double>(const std::vector<Heightfield>&, const SliceBatch&, const std::vector<double>&,
                                     std::vector<std::vector<double>>&, const RenderOptions&, std::vector<double>*);
template void batch_gradient<float>(const Heightfield&, const SliceBatch&, const std::vector<double>&,
                                    std::vector<double>&, const RenderOptions&, std::vector<float>*);
template void batch_gradient<double>(const Heightfield&, const SliceBatch&, const std::vector<double>&,
                                     std::vector<double>&, const RenderOptions&, std::vector<double>*);

}  // namespace wavebrdf
