#pragma once
// Internal: random numbers that depend on the seed only. std::mt19937_64 is specified bit for
// bit by the standard; its distributions are not (implementation-defined), so the transforms
// from raw bits to uniform, normal and Poisson samples are our own.
#include <cmath>
#include <cstdint>
#include <random>

#include "wavebrdf/constants.h"

namespace wavebrdf::detail {

// SplitMix64 (Steele, Lea and Flood 2014): the generator's output after one step from state `x`,
// a well-mixed 64-bit hash of x. The only copy in the library.
inline std::uint64_t splitmix64(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

// Independent generator seeds for the parts of one computation: SplitMix64's output number
// stream + 1 from state `seed`.
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
    return splitmix64(seed + 0x9E3779B97F4A7C15ull * stream);
}

// [0, 1) from the top 53 bits of `bits`.
inline double unit_interval(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

// Uniform in [0, 1) with 53 random bits.
inline double uniform01(std::mt19937_64& rng) { return unit_interval(rng()); }

// Fills `out[0..n)` with independent standard normal samples (Box–Muller, both outputs used).
inline void fill_standard_normal(double* out, std::size_t n, std::mt19937_64& rng) {
    constexpr double two_pi = 2.0 * k_pi;
    for (std::size_t k = 0; k < n; k += 2) {
        // u1 in (0, 1] so that log(u1) is finite.
        const double u1 = static_cast<double>((rng() >> 11) + 1) * 0x1.0p-53;
        const double u2 = uniform01(rng);
        const double r = std::sqrt(-2.0 * std::log(u1));
        out[k] = r * std::cos(two_pi * u2);
        if (k + 1 < n) out[k + 1] = r * std::sin(two_pi * u2);
    }
}

// A Poisson sample of mean `mean` ≥ 0. Below 10: Knuth's product of uniforms (exact, O(mean)).
// From 10: Hörmann's transformed rejection with squeeze, PTRS (W. Hörmann, "The transformed
// rejection method for generating Poisson random variables", Insurance: Mathematics and
// Economics 12, 1993; constants from the paper), exact and O(1).
inline double poisson_sample(double mean, std::mt19937_64& rng) {
    if (!(mean > 0.0)) return 0.0;
    if (mean < 10.0) {
        const double limit = std::exp(-mean);
        double product = uniform01(rng), count = 0.0;
        while (product > limit) {
            product *= uniform01(rng);
            count += 1.0;
        }
        return count;
    }
    const double log_mean = std::log(mean);
    const double b = 0.931 + 2.53 * std::sqrt(mean);
    const double a = -0.059 + 0.02483 * b;
    const double inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
    const double v_r = 0.9277 - 3.6224 / (b - 2.0);
    for (;;) {
        const double u = uniform01(rng) - 0.5;
        const double v = uniform01(rng);
        const double us = 0.5 - std::abs(u);
        const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
        if (us >= 0.07 && v <= v_r) return k;
        if (k < 0.0 || (us < 0.013 && v > us)) continue;
        if (std::log(v) + std::log(inv_alpha) - std::log(a / (us * us) + b) <=
            -mean + k * log_mean - std::lgamma(k + 1.0))
            return k;
    }
}

}  // namespace wavebrdf::detail
