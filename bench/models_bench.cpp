// Issue 12 benchmarks (bench/speed.sh runs them; results in bench/results/2026-11-23-models.md).
// The 1024×1024 isotropic heightfield of render_bench (rms 0.05 µm, correlation 4 µm, seed 1,
// texel 1 µm), footprint at its centre (512, 512) µm, λ = 0.5 µm, normal light, float.
//
//   model_forward/<M>, model_gradient/<M>   one 128² slice of model M (render_slice) and its
//       gradient Σ W·f → ∂/∂h with W = 1 (slice_gradient: forward + adjoint), RenderPath::Auto.
//   path/<separable|fft>/<n>/<σ_p>          one OHS n² slice on RenderOptions::path = that path
//       (tolerance 1e-6). A path the library refuses (fft until its engine lands) is reported
//       as an error ("refused: ..."), which speed.sh prints as n/a.
//   triad                                    STREAM triad a = b + s·c over 3 × 64 MiB of
//       doubles on all threads: the machine's memory bandwidth (bytes_per_second, 24 B per
//       element: STREAM's count, no write-allocate).
//
// Counters (per iteration, so a script can divide by the median time):
//   kernels    footprint kernels K (within 3σ_p)
//   flops      8·n²·K: the complex matrix product of the separable path
//   bytes_min  fft path: a lower bound on its memory traffic, 48·n² bytes (a complex-float
//              grid of at least n² points written by the spreading, read and written by the
//              two passes of the 2-D FFT, read by the per-pixel factor); with the engine's
//              real grid size M the traffic is 48·M, so the bandwidth fraction is a lower bound.
// Every benchmark runs once untimed before its first repetition (warm-up). Run:
//   build/bin/models_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <omp.h>

#include <cstdint>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "bench_surface.h"
#include "wavebrdf/adjoint.h"
#include "wavebrdf/brdf.h"

using namespace wavebrdf;

namespace {

using bench::surface;  // bench_surface.h

Query centre_query(Model model, double sigma_p_um) {
    Query q;
    q.model = model;
    q.x_um = 512.0;
    q.y_um = 512.0;
    q.sigma_p_um = sigma_p_um;
    return q;
}

double kernel_count(double sigma_p_um) { return double(footprint_kernels(surface(), 512.0, 512.0, sigma_p_um).size()); }

// Runs `body` once untimed (the first time this benchmark runs), then in the timed loop.
// A std::exception from the library (a refused path) marks the benchmark as an error.
template <typename Body>
void timed(benchmark::State& state, bool& warmed, Body body) {
    try {
        if (!warmed) body();
        warmed = true;
    } catch (const std::exception& e) {
        state.SkipWithError((std::string("refused: ") + e.what()).c_str());
        return;
    }
    for (auto _ : state) body();
}

void register_models() {
    const Model models[] = {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff};
    const int n = 128;
    for (Model model : models) {
        const std::string name = to_string(model);
        auto warm_f = std::make_shared<bool>(false), warm_g = std::make_shared<bool>(false);
        benchmark::RegisterBenchmark(("model_forward/" + name).c_str(),
                                     [model, warm_f](benchmark::State& state) {
                                         const Query q = centre_query(model, 10.0);
                                         timed(state, *warm_f, [&] {
                                             auto f = render_slice<float>(surface(), q, 0.5, n);
                                             benchmark::DoNotOptimize(f.data());
                                         });
                                         state.counters["kernels"] = kernel_count(10.0);
                                     })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
        benchmark::RegisterBenchmark(("model_gradient/" + name).c_str(),
                                     [model, warm_g](benchmark::State& state) {
                                         const Query q = centre_query(model, 10.0);
                                         const std::vector<float> weights(std::size_t(n) * n, 1.0f);
                                         std::vector<double> grad;
                                         timed(state, *warm_g, [&] {
                                             grad.clear();
                                             auto f = slice_gradient<float>(surface(), q, 0.5, n, weights, grad);
                                             benchmark::DoNotOptimize(f.data());
                                             benchmark::DoNotOptimize(grad.data());
                                         });
                                         state.counters["kernels"] = kernel_count(10.0);
                                     })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
    }
}

void register_paths() {
    const struct {
        const char* name;
        RenderPath path;
    } paths[] = {{"separable", RenderPath::Separable}, {"fft", RenderPath::Fft}};
    for (const auto& p : paths)
        for (double sigma_p_um : {10.0, 50.0})
            for (int n : {128, 256, 512, 1024}) {
                const std::string name = std::string("path/") + p.name + "/" + std::to_string(n) + "/" +
                                         std::to_string(int(sigma_p_um));
                auto warmed = std::make_shared<bool>(false);
                const RenderPath path = p.path;
                benchmark::RegisterBenchmark(name.c_str(),
                                             [=](benchmark::State& state) {
                                                 const Query q = centre_query(Model::OHS, sigma_p_um);
                                                 RenderOptions options;
                                                 options.path = path;
                                                 timed(state, *warmed, [&] {
                                                     auto f = render_slice<float>(surface(), q, 0.5, n, options);
                                                     benchmark::DoNotOptimize(f.data());
                                                 });
                                                 const double k = kernel_count(sigma_p_um);
                                                 state.counters["kernels"] = k;
                                                 state.counters["flops"] = 8.0 * n * n * k;
                                                 state.counters["bytes_min"] = 48.0 * n * n;
                                             })
                    ->Unit(benchmark::kMillisecond)
                    ->UseRealTime();
            }
}

void triad(benchmark::State& state) {
    const std::ptrdiff_t count = std::ptrdiff_t(1) << 23;  // 64 MiB per array
    std::unique_ptr<double[]> a(new double[count]), b(new double[count]), c(new double[count]);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < count; ++i) a[i] = 0.0, b[i] = 1.0, c[i] = 2.0;  // first touch per thread
    const double s = 3.0;
    auto once = [&] {
        double* __restrict pa = a.get();
        const double* __restrict pb = b.get();
        const double* __restrict pc = c.get();
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < count; ++i) pa[i] = pb[i] + s * pc[i];
        benchmark::ClobberMemory();
    };
    once();
    for (auto _ : state) once();
    state.SetBytesProcessed(std::int64_t(state.iterations()) * 24 * count);
    state.counters["threads"] = omp_get_max_threads();
}

}  // namespace

int main(int argc, char** argv) {
    register_models();
    register_paths();
    benchmark::RegisterBenchmark("triad", triad)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(0.5);
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
