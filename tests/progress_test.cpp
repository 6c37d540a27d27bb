#include "wavebrdf/progress.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

using wavebrdf::Progress;

TEST(ProgressTest, SilentWhenStderrIsNotATerminal) {
    if (Progress::stderr_is_terminal()) GTEST_SKIP() << "stderr is a terminal";
    testing::internal::CaptureStderr();
    {
        Progress progress("render", 27, true);
        progress.advance(12);
        progress.set_message("loss 0.5");
        progress.advance(15);
        progress.finish();
        progress.finish();
    }
    {
        Progress unfinished("render", 3, true);  // the destructor finishes it
        unfinished.advance();
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(ProgressTest, SilentWhenDisabled) {
    testing::internal::CaptureStderr();
    {
        Progress progress("render", 10, false);
        for (int k = 0; k < 10; ++k) progress.advance();
        progress.set_message("done");
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(ProgressTest, CountsAdvancesFromSeveralThreads) {
    constexpr int k_threads = 8;
    constexpr int k_per_thread = 20000;
    Progress progress("count", static_cast<long long>(k_threads) * k_per_thread, true);
    std::vector<std::thread> threads;
    for (int t = 0; t < k_threads; ++t)
        threads.emplace_back([&progress] {
            for (int k = 0; k < k_per_thread; ++k) progress.advance();
        });
    for (auto& thread : threads) thread.join();
    EXPECT_EQ(progress.done(), static_cast<long long>(k_threads) * k_per_thread);
    progress.advance(5);
    EXPECT_EQ(progress.done(), static_cast<long long>(k_threads) * k_per_thread + 5);
}

TEST(ProgressTest, CountsWithOpenMP) {
    constexpr int n = 100000;
    Progress progress("omp", n, true);
#pragma omp parallel for schedule(dynamic, 64)
    for (int k = 0; k < n; ++k) progress.advance();
    EXPECT_EQ(progress.done(), n);
}

TEST(ProgressTest, RejectsNegativeTotal) {
    EXPECT_THROW(Progress("bad", -1, true), std::invalid_argument);
    EXPECT_NO_THROW(Progress("empty", 0, true));
}
