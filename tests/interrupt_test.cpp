// Exceptions and interrupts inside the library's parallel regions (src/core/parallel.h) and the
// cancellation hook (wavebrdf/interrupt.h).
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>

#include "../src/core/parallel.h"
#include "test_util.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/interrupt.h"

namespace wavebrdf {
namespace {

// Sets the OpenMP thread count for one test and restores it afterwards (other tests run with
// the machine's count).
class Threads {
public:
    explicit Threads(int count) : m_saved(omp_get_max_threads()) { omp_set_num_threads(count); }
    ~Threads() { omp_set_num_threads(m_saved); }

private:
    int m_saved;
};

// An exception thrown by a worker thread inside the region reaches the caller after it
// (before: std::terminate, SIGABRT).
TEST(Parallel, ExceptionInColumnBlockIsRethrownAfterTheRegion) {
    const Threads threads(4);
    EXPECT_THROW(detail::for_column_blocks(1000, 1e9,
                                           [](long long first, long long) {
                                               if (first > 0) throw std::bad_alloc();
                                           }),
                 std::bad_alloc);
}

TEST(Parallel, ExceptionInOrderedSumIsRethrownAfterTheRegion) {
    const Threads threads(4);
    std::vector<double> total(3, 0.0);
    EXPECT_THROW(detail::ordered_parallel_sum(100, total, true,
                                              [](std::size_t i, std::vector<double>&) -> double {
                                                  if (i == 77) throw std::runtime_error("item 77");
                                                  return 1.0;
                                              }),
                 std::runtime_error);
}

TEST(Parallel, ExceptionInEveryThreadIsRethrownOnce) {
    const Threads threads(4);
    std::atomic<int> calls{0};
    EXPECT_THROW(detail::for_column_blocks(1000, 1e9,
                                           [&](long long, long long) {
                                               ++calls;
                                               throw std::bad_alloc();
                                           }),
                 std::bad_alloc);
    EXPECT_GE(calls.load(), 1);
}

// A slice big enough to take many polls (every model takes the separable path by default; the
// direct one is asked for by name).
Heightfield interrupt_heightfield() { return test::random_heightfield(96, 96, 0.4, 3, 1.0, 1.0); }
Query interrupt_query(Model model) {
    Query q;
    q.x_um = 48.0;
    q.y_um = 48.0;
    q.sigma_p_um = 16.0;
    q.model = model;
    return q;
}

// A poll that says stop ends a render with Interrupted on every path, the forward and the
// gradient; polling every 0 ms means the first piece of work polls.
TEST(Interrupt, PollThatSaysStopEndsRenderAndGradientWithInterrupted) {
    const Threads threads(2);
    const Heightfield hf = interrupt_heightfield();
    for (const auto& [m, path] : {std::pair{Model::OHS, RenderPath::Auto}, std::pair{Model::GHS, RenderPath::Auto},
                                  std::pair{Model::GHS, RenderPath::Direct}}) {
        RenderOptions options;
        options.path = path;
        int polls = 0;
        InterruptScope scope([&] { return ++polls >= 2; }, std::chrono::milliseconds(0));
        EXPECT_THROW(render_slice<double>(hf, interrupt_query(m), 0.5, 128, options), Interrupted) << to_string(m);
        EXPECT_EQ(polls, 2) << "the poll is not asked again once it said stop";
        std::vector<double> gradient;
        EXPECT_THROW(slice_gradient<double>(hf, interrupt_query(m), 0.5, 128, std::vector<double>(128 * 128, 1.0),
                                            gradient, options),
                     Interrupted)
            << to_string(m);
    }
}

// Without a scope, or with a poll that never says stop, the result is the same as before.
TEST(Interrupt, PollThatNeverSaysStopChangesNothing) {
    const Heightfield hf = interrupt_heightfield();
    const std::vector<double> plain = render_slice<double>(hf, interrupt_query(Model::GHS), 0.5, 32);
    int polls = 0;
    InterruptScope scope([&] { return ++polls < 0; }, std::chrono::milliseconds(0));
    EXPECT_EQ(render_slice<double>(hf, interrupt_query(Model::GHS), 0.5, 32), plain);
    EXPECT_GT(polls, 0);
}

TEST(Interrupt, ScopesNestAndRestore) {
    int outer = 0, inner = 0;
    InterruptScope a([&] { return ++outer > 100; }, std::chrono::milliseconds(0));
    {
        InterruptScope b(
            [&] {
                ++inner;
                return true;
            },
            std::chrono::milliseconds(0));
        EXPECT_THROW(check_interrupt(), Interrupted);
        EXPECT_THROW(check_interrupt(), Interrupted);
        EXPECT_EQ(inner, 1);
    }
    EXPECT_NO_THROW(check_interrupt());
    EXPECT_EQ(outer, 1);
}

// An allocation failure inside a parallel region (here thrown by the poll, which runs inside
// the region on the calling thread) reaches the caller as std::bad_alloc, not std::terminate.
TEST(Interrupt, OutOfMemoryInsideRenderRegionIsAnError) {
    const Threads threads(2);
    const Heightfield hf = interrupt_heightfield();
    for (Model m : {Model::OHS, Model::GHS}) {
        InterruptScope scope([]() -> bool { throw std::bad_alloc(); }, std::chrono::milliseconds(0));
        EXPECT_THROW(render_slice<double>(hf, interrupt_query(m), 0.5, 128), std::bad_alloc) << to_string(m);
    }
}

}  // namespace
}  // namespace wavebrdf
