#pragma once
// Internal: FFTW memory and plans owned by unique_ptr. Plans are destroyed under
// fftw_planner_mutex (fftw_planner.h); callers make them under that lock too.
#include <fftw3.h>

#include <cstddef>
#include <memory>
#include <mutex>
#include <new>

#include "core/fftw_planner.h"

namespace wavebrdf::detail {

struct FftwFree {
    void operator()(void* p) const { fftw_free(p); }
};

// fftw_malloc'd (SIMD-aligned) storage for `count` values of T.
template <typename T>
using FftwBuffer = std::unique_ptr<T[], FftwFree>;

template <typename T>
FftwBuffer<T> fftw_buffer(std::size_t count) {
    void* p = fftw_malloc(sizeof(T) * count);
    if (!p) throw std::bad_alloc();
    return FftwBuffer<T>(static_cast<T*>(p));
}

struct FftwPlanDeleter {
    void operator()(fftw_plan_s* plan) const {
        std::lock_guard<std::mutex> lock(fftw_planner_mutex());
        fftw_destroy_plan(plan);
    }
};
using FftwPlan = std::unique_ptr<fftw_plan_s, FftwPlanDeleter>;

}  // namespace wavebrdf::detail
