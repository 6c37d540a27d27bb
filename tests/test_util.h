#pragma once
// Small helpers shared by the C++ tests: seeded random heightfields without the generators,
// and the peak memory of work run in a child process.
#include <omp.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "wavebrdf/constants.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/model.h"

// WAVEBRDF_ASAN: defined under AddressSanitizer (gcc and clang), for tests whose measurement
// it distorts (peak memory: its shadow memory counts).
#if defined(__SANITIZE_ADDRESS__)
#define WAVEBRDF_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define WAVEBRDF_ASAN 1
#endif
#endif

namespace wavebrdf::test {

// Expects `fn` to throw `Exception` with `text` inside its message.
template <typename Exception, typename Fn>
void expect_throw_naming(Fn fn, const std::string& text) {
    try {
        fn();
        ADD_FAILURE() << "no exception; expected one naming '" << text << "'";
    } catch (const Exception& e) {
        EXPECT_NE(std::string(e.what()).find(text), std::string::npos)
            << "message '" << e.what() << "' does not name '" << text << "'";
    }
}

// The peak resident memory (bytes) of a forked child process that runs `work` (returns true on
// success), or -1 when the fork fails or the child does not succeed (false or an exception).
// The parent's OpenMP threads do not survive fork (a team would wait for them forever): the
// child runs on one thread, which changes only per-thread buffers.
template <typename Work>
double child_peak_memory_bytes(Work work) {
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    if (pid < 0) return -1.0;
    if (pid == 0) {
        omp_set_num_threads(1);
        int code = 0;
        try {
            code = work() ? 0 : 4;
        } catch (...) {
            code = 3;
        }
        ::_exit(code);
    }
    int status = 0;
    struct rusage usage {};
    if (::wait4(pid, &status, 0, &usage) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1.0;
    return double(usage.ru_maxrss) * 1024.0;  // kB on Linux
}

// Expects a memory estimate within a factor of two of the measured peak, either way, and
// prints both ("<what>: estimate …, measured peak …").
inline void expect_estimate_within_factor_of_two(double estimate, double measured, const std::string& what) {
    EXPECT_GT(measured, 0.5 * estimate) << what << ": estimate " << format_bytes(estimate) << ", measured "
                                        << format_bytes(measured);
    EXPECT_LT(measured, 2.0 * estimate) << what << ": estimate " << format_bytes(estimate) << ", measured "
                                        << format_bytes(measured);
    std::printf("%s: estimate %s, measured peak %s\n", what.c_str(), format_bytes(estimate).c_str(),
                format_bytes(measured).c_str());
}

// Smooth random heights (sum of a few random periodic sinusoids), in texel units.
inline Heightfield random_heightfield(int rows, int cols, double amplitude, std::uint64_t seed, double texel_um = 1.0,
                                      double vscale = 1.0) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<double> v(static_cast<std::size_t>(rows) * cols, 0.0);
    const double two_pi = 2.0 * k_pi;
    for (int m = 0; m < 6; ++m) {
        const int fx = static_cast<int>(uni(rng) * 4), fy = static_cast<int>(uni(rng) * 4);
        const double phase = uni(rng) * two_pi, a = amplitude * (0.5 + uni(rng));
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j)
                v[static_cast<std::size_t>(i) * cols + j] +=
                    a * std::sin(two_pi * (fx * i / double(rows) + fy * j / double(cols)) + phase);
    }
    // White noise on top, so that no symmetry hides a sign or index error.
    for (auto& x : v) x += 0.2 * amplitude * (uni(rng) - 0.5);
    return Heightfield(rows, cols, std::move(v), texel_um, vscale);
}

inline Query make_query(Model model, double x, double y, double sigma_p, double wx = 0.0, double wy = 0.0) {
    Query q;
    q.model = model;
    q.x_um = x;
    q.y_um = y;
    q.sigma_p_um = sigma_p;
    q.omega_i = {wx, wy};
    return q;
}

// `size` values drawn uniformly from [lo, hi), seeded.
inline std::vector<double> uniform_vector(std::size_t size, double lo, double hi, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(lo, hi);
    std::vector<double> v(size);
    for (double& x : v) x = uni(rng);
    return v;
}

inline double max_abs(const std::vector<double>& v) {
    double m = 0.0;
    for (double x : v) m = std::max(m, std::abs(x));
    return m;
}

inline double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
    double m = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
    return m;
}

}  // namespace wavebrdf::test
