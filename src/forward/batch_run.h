#pragma once
// Internal: what the batch's forward (forward/batch.cpp) and gradient (adjoint/batch_gradient.cpp)
// share: the checks and memory bound before any work, the loop that spreads items over the
// threads, and each thread's slice plan, reused while consecutive items differ only in heights.
#include <omp.h>

#include <cstddef>
#include <memory>
#include <vector>

#include "core/parallel.h"
#include "wavebrdf/batch.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::detail {

// Validates the heightfields (at least one, one geometry) and the batch, and refuses what does
// not fit options.max_memory_gb. Returns the number of threads the batch runs on (≥ 1; 1 when
// called inside a parallel region or for at most one item).
int prepare_batch(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                  const RenderOptions& options, std::size_t float_bytes, bool gradients);

// True when items a and b need the same plan (everything but the heights equal).
inline bool same_plan(const BatchItem& a, const BatchItem& b) {
    return a.band == b.band && a.query.x_um == b.query.x_um && a.query.y_um == b.query.y_um &&
           a.query.sigma_p_um == b.query.sigma_p_um && a.query.omega_i == b.query.omega_i &&
           a.query.model == b.query.model;
}

// One thread's plan: rebuilt when the query or band changes, given new heights when only the
// heightfield changes (set_heights is term for term the constructor's gathering, so the same
// values bit for bit).
template <typename Float>
class BatchPlan {
public:
    BatchPlan(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
              const RenderOptions& options, bool differentiable)
        : m_heightfields(heightfields), m_batch(batch), m_options(options), m_differentiable(differentiable) {}

    SlicePlan<Float>& plan_for(const BatchItem& item) {
        if (m_plan && same_plan(*m_last, item)) {
            if (m_last->heightfield != item.heightfield) m_plan->set_heights(*m_heightfields[item.heightfield]);
        } else {
            m_plan.reset();  // free the last plan before building the next
            m_plan = std::make_unique<SlicePlan<Float>>(*m_heightfields[item.heightfield], item.query,
                                                        m_batch.bands[item.band], m_batch.resolution, m_batch.channels,
                                                        m_options, m_differentiable);
        }
        m_last = &item;
        return *m_plan;
    }

private:
    const std::vector<const Heightfield*>& m_heightfields;
    const SliceBatch& m_batch;
    const RenderOptions& m_options;
    bool m_differentiable;
    std::unique_ptr<SlicePlan<Float>> m_plan;
    const BatchItem* m_last = nullptr;
};

// body(item, thread) for every item, on `threads` threads (one parallel region, a static
// schedule: thread t gets the t-th contiguous block of items, so consecutive items share
// plans). Exceptions and interrupts end the region and are rethrown after it (RegionGuard).
template <typename Body>
void for_each_item(std::size_t count, int threads, Body&& body) {
    RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        const int t = omp_get_thread_num();
#pragma omp for schedule(static)
        for (std::size_t b = 0; b < count; ++b) guard.run([&] { body(b, t); });
    }
    guard.rethrow();
}

// The heightfields of a call, by address (the one-heightfield overloads copy nothing).
inline std::vector<const Heightfield*> addresses(const std::vector<Heightfield>& heightfields) {
    std::vector<const Heightfield*> out;
    out.reserve(heightfields.size());
    for (const Heightfield& hf : heightfields) out.push_back(&hf);
    return out;
}

template <typename Float>
std::vector<Float> render_batch(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                                const RenderOptions& options);
template <typename Float>
void batch_gradient(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                    const std::vector<double>& weights, std::vector<std::vector<double>>& gradients,
                    const RenderOptions& options, std::vector<Float>* slices);

}  // namespace wavebrdf::detail
