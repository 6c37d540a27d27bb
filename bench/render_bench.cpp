// Forward-renderer benchmarks (issue: 128×128 slice with 8 wavelengths of a 1024×1024
// heightfield at σ_p = 10 µm; a 256×256 slice), and gradients (gradient_tile_*: the cases of
// the PyTorch baseline, bench/torch_reference.py). Run: build/bin/render_bench (Google
// Benchmark; report the median of --benchmark_repetitions). Counters:
//   kernels   footprint kernels K (within 3σ_p)
//   GFLOP/s   8·n²·K flops per wavelength (one complex multiply-add per pixel and kernel,
//             the matrix product that dominates the separable path)
#include <benchmark/benchmark.h>
#include <omp.h>

#include <array>
#include <cmath>

#include "bench_surface.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/batch.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;

namespace {

using bench::surface;  // bench_surface.h

Query query(Model model) {
    Query q;
    q.model = model;
    q.x_um = 512.0;
    q.y_um = 512.0;
    q.sigma_p_um = 10.0;
    return q;
}

template <typename Float>
void run_slice(benchmark::State& state, Model model, int resolution, int wavelengths) {
    const Query q = query(model);
    const std::vector<double> lambdas = wavelengths == 1 ? std::vector<double>{0.5}
                                                         : spectral_wavelengths_um(wavelengths);
    const auto kernels = footprint_kernels(surface(), q.x_um, q.y_um, q.sigma_p_um).size();
    for (auto _ : state) {
        auto rgb = render_rgb<Float>(surface(), q, lambdas, resolution);
        benchmark::DoNotOptimize(rgb.data());
    }
    const double flops = 8.0 * resolution * resolution * double(kernels) * wavelengths;
    state.counters["kernels"] = double(kernels);
    state.counters["GFLOP/s"] = benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

void slice_float(benchmark::State& s, Model m, int n, int l) { run_slice<float>(s, m, n, l); }
void slice_double(benchmark::State& s, Model m, int n, int l) { run_slice<double>(s, m, n, l); }

}  // namespace

BENCHMARK_CAPTURE(slice_float, ohs_128_spectral8_float, Model::OHS, 128, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(slice_double, ohs_128_spectral8_double, Model::OHS, 128, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(slice_float, ohs_256_mono_float, Model::OHS, 256, 1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(slice_double, ohs_256_mono_double, Model::OHS, 256, 1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(slice_float, rohs_128_spectral8_float, Model::ROHS, 128, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(slice_float, ohs_1024_mono_float, Model::OHS, 1024, 1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(slice_float, ghs_direct_128_mono_float, Model::GHS, 128, 1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(slice_float, kirchhoff_direct_64_mono_float, Model::Kirchhoff, 64, 1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Gradient of Σ W·f for one slice against the forward alone (issue: at most 3× the forward).
static void gradient_float(benchmark::State& state, Model model, int resolution) {
    const Query q = query(model);
    const std::vector<float> weights(static_cast<std::size_t>(resolution) * resolution, 1.0f);
    std::vector<double> grad;
    for (auto _ : state) {
        grad.assign(surface().values().size(), 0.0);
        auto f = slice_gradient<float>(surface(), q, 0.5, resolution, weights, grad);
        benchmark::DoNotOptimize(f.data());
    }
}
BENCHMARK_CAPTURE(gradient_float, ohs_128_mono_float, Model::OHS, 128)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(slice_float, ohs_128_mono_float, Model::OHS, 128, 1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gradient_float, ohs_256_mono_float, Model::OHS, 256)->Unit(benchmark::kMillisecond)->UseRealTime();

// Gradient on a whole small tile, footprint at its centre (the PyTorch-autograd baseline,
// bench/torch_reference.py): the thesis's size (16×16 heights, σ_p = 4 µm, so all 256 texels
// are kernels, 32×32 slice) and 256×256 heights at σ_p = 10 µm with a 128×128 slice. OHS,
// λ = 0.5 µm, Σ W·f with W = 1.
namespace {

// The same generator as surface(), on a size × size tile.
Heightfield isotropic_tile(int size) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = p.cols = size;
    p.rms_height_um = 0.05;
    p.correlation_um = 4.0;
    p.seed = 1;
    return generate_heightfield(p);
}

const Heightfield& tile(int size) {
    static const Heightfield thesis = isotropic_tile(16), large = isotropic_tile(256);
    return size == 16 ? thesis : large;
}

template <typename Float>
void run_tile_gradient(benchmark::State& state, int size, double sigma_p_um, int resolution) {
    const Heightfield& hf = tile(size);
    Query q;
    q.model = Model::OHS;
    q.x_um = q.y_um = 0.5 * size * hf.texel_um();
    q.sigma_p_um = sigma_p_um;
    const std::vector<Float> weights(static_cast<std::size_t>(resolution) * resolution, Float(1));
    std::vector<double> grad;
    for (auto _ : state) {
        grad.assign(hf.values().size(), 0.0);
        auto f = slice_gradient<Float>(hf, q, 0.5, resolution, weights, grad);
        benchmark::DoNotOptimize(f.data());
        benchmark::DoNotOptimize(grad.data());
    }
    state.counters["kernels"] = double(footprint_kernels(hf, q.x_um, q.y_um, q.sigma_p_um).size());
}

void gradient_tile_float(benchmark::State& s, int size, double sigma_p_um, int n) {
    run_tile_gradient<float>(s, size, sigma_p_um, n);
}
void gradient_tile_double(benchmark::State& s, int size, double sigma_p_um, int n) {
    run_tile_gradient<double>(s, size, sigma_p_um, n);
}

}  // namespace

BENCHMARK_CAPTURE(gradient_tile_float, thesis_16_sigma4_32_float, 16, 4.0, 32)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(gradient_tile_double, thesis_16_sigma4_32_double, 16, 4.0, 32)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(gradient_tile_float, tile_256_sigma10_128_float, 256, 10.0, 128)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(gradient_tile_double, tile_256_sigma10_128_double, 256, 10.0, 128)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The slice plan (slice_plan.h) against the one-call functions on the same case: one loss
// evaluation = forward and adjoint of every wavelength of an RGB slice, as an inversion epoch
// does. plan_*: the plan is built once before the loop and each iteration sets new heights;
// onecall_*: every iteration rebuilds everything (kernels, grids, phase tables, c1, mix).
namespace {

template <typename Float>
void run_plan_epoch(benchmark::State& state, int size, double sigma_p_um, int resolution, int wavelengths,
                    bool planned) {
    const Heightfield& hf = tile(size);
    Query q;
    q.model = Model::OHS;
    q.x_um = q.y_um = 0.5 * size * hf.texel_um();
    q.sigma_p_um = sigma_p_um;
    const std::vector<double> lambdas = spectral_wavelengths_um(wavelengths);
    const std::vector<double> weights(static_cast<std::size_t>(resolution) * resolution * 3, 1.0);
    std::vector<double> heights = hf.values();
    SlicePlan<Float> plan(hf, q, lambdas, resolution, 3);
    std::vector<double> grad;
    for (auto _ : state) {
        heights[0] += 1e-9;  // new heights every evaluation
        grad.clear();
        if (planned) {
            plan.set_heights(heights);
            benchmark::DoNotOptimize(plan.forward().data());
            plan.adjoint(weights, grad);
        } else {
            SlicePlan<Float> fresh(hf.with_values(heights), q, lambdas, resolution, 3);
            benchmark::DoNotOptimize(fresh.forward().data());
            fresh.adjoint(weights, grad);
        }
        benchmark::DoNotOptimize(grad.data());
    }
}

void plan_epoch(benchmark::State& s, int size, double sigma, int n, int l) {
    run_plan_epoch<double>(s, size, sigma, n, l, true);
}
void onecall_epoch(benchmark::State& s, int size, double sigma, int n, int l) {
    run_plan_epoch<double>(s, size, sigma, n, l, false);
}

}  // namespace

BENCHMARK_CAPTURE(plan_epoch, thesis_16_sigma4_32_spectral8, 16, 4.0, 32, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(onecall_epoch, thesis_16_sigma4_32_spectral8, 16, 4.0, 32, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(plan_epoch, tile_256_sigma10_128_spectral8, 256, 10.0, 128, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(onecall_epoch, tile_256_sigma10_128_spectral8, 256, 10.0, 128, 8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();

// Batches (batch.h): many small slices, 64×64 of a 64×64 tile (σ_p = 10 µm at its centre, OHS,
// λ = 0.5 µm, RGB, float), by the single-slice library call (render_rgb, its matrix products
// over all threads) one at a time, and 1024 of them (32×32 lights) by one render_batch call
// (threaded across the items). Counter slices/s: slices per second of wall time.
namespace {

const Heightfield& small_tile() {
    static const Heightfield hf = isotropic_tile(64);
    return hf;
}

Query small_query() {
    Query q;
    q.model = Model::OHS;
    q.x_um = q.y_um = 32.0;
    q.sigma_p_um = 10.0;
    return q;
}

// 32 × 32 lights on a grid over |ω_i| ≤ 0.7 (corners pulled onto the circle).
std::vector<std::array<double, 2>> light_grid(int side) {
    std::vector<std::array<double, 2>> lights;
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
            double x = -0.7 + 1.4 * i / (side - 1), y = -0.7 + 1.4 * j / (side - 1);
            const double r = std::sqrt(x * x + y * y);
            if (r > 0.7) x *= 0.7 / r, y *= 0.7 / r;
            lights.push_back({x, y});
        }
    return lights;
}

void small_slice_single(benchmark::State& state) {
    const std::vector<std::array<double, 2>> lights = light_grid(32);
    Query q = small_query();
    std::size_t l = 0;
    for (auto _ : state) {
        q.omega_i = lights[l++ % lights.size()];
        auto rgb = render_rgb<float>(small_tile(), q, {0.5}, 64);
        benchmark::DoNotOptimize(rgb.data());
    }
    state.counters["slices/s"] = benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate);
    state.counters["threads"] = omp_get_max_threads();
}

void small_slice_batch(benchmark::State& state) {
    const SliceBatch batch = batch_product(small_query(), light_grid(32), {{32.0, 32.0}}, {{0.5}}, 64);
    for (auto _ : state) {
        auto rgb = render_batch<float>(small_tile(), batch);
        benchmark::DoNotOptimize(rgb.data());
    }
    state.counters["slices/s"] = benchmark::Counter(double(batch.items.size()),
                                                    benchmark::Counter::kIsIterationInvariantRate);
    state.counters["threads"] = omp_get_max_threads();
}

}  // namespace

BENCHMARK(small_slice_single)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(small_slice_batch)->Unit(benchmark::kMillisecond)->UseRealTime();
