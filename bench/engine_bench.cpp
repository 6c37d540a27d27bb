// The slice engines side by side (issue 12 item 2): the FFT engine (src/forward/fft_engine.h)
// against the separable product (detail::SeparableEngine, forward and adjoint, for the
// gradient), OHS, float, λ 0.5 µm, normal light, footprint at the centre of a 1024² isotropic
// heightfield (texel 1 µm, rms 0.05 µm, correlation 4 µm), over the slice size n and σ_p.
// Run: build/bin/engine_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only
// (Google Benchmark; report the medians). Counters:
//   kernels   footprint kernels K (within 3σ_p)
//   M         FFT grid size (M × M, rows; the engine picks it from the tolerance and slopes)
//   GB/s      FFT engine: bytes a pass over the grid moves (zeroing, two FFT passes of the
//             grid, read + write each, plus the spread's read + write): 7 · M² · 8 B per
//             second, against the machine's memory bandwidth (docs/fft_path.md).
#include <benchmark/benchmark.h>

#include <complex>
#include <random>
#include <vector>

#include "bench_surface.h"
#include "forward/fft_engine.h"
#include "forward/separable.h"
#include "forward/separable_engine.h"
#include "wavebrdf/adjoint.h"

using namespace wavebrdf;

namespace {

using bench::surface;  // bench_surface.h

constexpr double k_lambda_um = 0.5;

struct Slice {
    Query query;
    FootprintKernels kernels;
    detail::KernelWeights weights;
    Slice(double sigma_p_um) {
        query.x_um = query.y_um = 512.0;
        query.sigma_p_um = sigma_p_um;
        kernels = footprint_kernels(surface(), query.x_um, query.y_um, sigma_p_um);
        weights.assign(1, {});
        for (std::size_t k = 0; k < kernels.size(); ++k)
            weights[0].push_back(detail::kernel_weight(kernels, k, k_lambda_um));
    }
};

const Slice& slice(double sigma_p_um) {
    static const Slice small(10.0), large(50.0);
    return sigma_p_um < 20.0 ? small : large;
}

void separable_forward(benchmark::State& state) {
    const int n = int(state.range(0));
    const Slice& s = slice(double(state.range(1)));
    const detail::SliceGrid grid(s.query, k_lambda_um, n);
    detail::SeparableEngine<float> engine(s.kernels, grid, k_lambda_um, n);
    std::vector<detail::ComplexMatrix<float>> fields;
    for (auto _ : state) {
        engine.forward(s.weights, 1.0, fields);
        benchmark::DoNotOptimize(fields[0].data());
    }
    state.counters["kernels"] = double(s.kernels.size());
}

void separable_gradient(benchmark::State& state) {
    const int n = int(state.range(0));
    const Slice& s = slice(double(state.range(1)));
    const detail::SliceGrid grid(s.query, k_lambda_um, n);
    detail::SeparableEngine<float> engine(s.kernels, grid, k_lambda_um, n);
    std::vector<detail::ComplexMatrix<float>> cotangents(1, detail::ComplexMatrix<float>(n, n));
    std::mt19937 rng(1);
    std::normal_distribution<float> normal;
    for (Eigen::Index i = 0; i < cotangents[0].size(); ++i) cotangents[0](i) = {normal(rng), normal(rng)};
    detail::FieldGradient gradient;
    for (auto _ : state) {
        engine.adjoint(s.weights, 1.0, cotangents, gradient);
        benchmark::DoNotOptimize(gradient.shift_x.data());
    }
    state.counters["kernels"] = double(s.kernels.size());
}

void fft_counters(benchmark::State& state, const detail::FftGridInfo& info, std::size_t kernels) {
    state.counters["kernels"] = double(kernels);
    state.counters["M"] = double(info.mx);
    state.counters["span"] = double(info.span_x);
    const double bytes = 7.0 * double(info.mx) * double(info.my) * sizeof(std::complex<float>);
    state.counters["GB/s"] = benchmark::Counter(bytes * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

void fft_forward(benchmark::State& state) {
    const int n = int(state.range(0));
    const Slice& s = slice(double(state.range(1)));
    const detail::SliceGrid grid(s.query, k_lambda_um, n);
    detail::FftEngine<float> engine(s.kernels, grid, k_lambda_um, n, 1e-6);
    std::vector<detail::ComplexMatrix<float>> fields;
    engine.forward(s.weights, 1.0, fields);  // plans and grids made once, as a plan would
    for (auto _ : state) {
        engine.forward(s.weights, 1.0, fields);
        benchmark::DoNotOptimize(fields[0].data());
    }
    fft_counters(state, engine.last_grid(), s.kernels.size());
}

void fft_adjoint(benchmark::State& state) {
    const int n = int(state.range(0));
    const Slice& s = slice(double(state.range(1)));
    const detail::SliceGrid grid(s.query, k_lambda_um, n);
    detail::FftEngine<float> engine(s.kernels, grid, k_lambda_um, n, 1e-6);
    std::vector<detail::ComplexMatrix<float>> cotangents(1, detail::ComplexMatrix<float>(n, n));
    std::mt19937 rng(1);
    std::normal_distribution<float> normal;
    for (Eigen::Index i = 0; i < cotangents[0].size(); ++i) cotangents[0](i) = {normal(rng), normal(rng)};
    detail::FieldGradient gradient;
    engine.adjoint(s.weights, 1.0, cotangents, gradient);
    for (auto _ : state) {
        engine.adjoint(s.weights, 1.0, cotangents, gradient);
        benchmark::DoNotOptimize(gradient.shift_x.data());
    }
    fft_counters(state, engine.last_grid(), s.kernels.size());
}

void sizes(benchmark::internal::Benchmark* b) {
    for (int sigma : {10, 50})
        for (int n : {128, 256, 512, 1024}) b->Args({n, sigma});
    b->Unit(benchmark::kMillisecond)->UseRealTime();
}

}  // namespace

BENCHMARK(separable_forward)->Apply(sizes);
BENCHMARK(fft_forward)->Apply(sizes);
BENCHMARK(separable_gradient)->Apply(sizes);
BENCHMARK(fft_adjoint)->Apply(sizes);

BENCHMARK_MAIN();
