// The FFT engine: spread / fold / FFT forward, FFT / gather adjoint (forward/fft_engine.h).
#include "forward/fft_engine.h"

#include <fftw3.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

#include "core/fftw_planner.h"
#include "core/parallel.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/memory.h"

namespace wavebrdf::detail {

namespace {

// FFTW's planner is not thread-safe: every plan is made and destroyed under this lock
// (executing a plan is thread-safe).

template <typename Float>
struct Fftw;

template <>
struct Fftw<double> {
    using Plan = fftw_plan;
    using Complex = fftw_complex;
    static Plan many(int size, int count, std::complex<double>* data, int stride, int dist) {
        Complex* p = reinterpret_cast<Complex*>(data);
        return fftw_plan_many_dft(1, &size, count, p, nullptr, stride, dist, p, nullptr, stride, dist, FFTW_FORWARD,
                                  FFTW_ESTIMATE);
    }
    static void execute(Plan plan, std::complex<double>* data) {
        Complex* p = reinterpret_cast<Complex*>(data);
        fftw_execute_dft(plan, p, p);
    }
    static void destroy(Plan plan) { fftw_destroy_plan(plan); }
    static void* malloc(std::size_t bytes) { return fftw_malloc(bytes); }
    static void free(void* p) { fftw_free(p); }
};

template <>
struct Fftw<float> {
    using Plan = fftwf_plan;
    using Complex = fftwf_complex;
    static Plan many(int size, int count, std::complex<float>* data, int stride, int dist) {
        Complex* p = reinterpret_cast<Complex*>(data);
        return fftwf_plan_many_dft(1, &size, count, p, nullptr, stride, dist, p, nullptr, stride, dist, FFTW_FORWARD,
                                   FFTW_ESTIMATE);
    }
    static void execute(Plan plan, std::complex<float>* data) {
        Complex* p = reinterpret_cast<Complex*>(data);
        fftwf_execute_dft(plan, p, p);
    }
    static void destroy(Plan plan) { fftwf_destroy_plan(plan); }
    static void* malloc(std::size_t bytes) { return fftwf_malloc(bytes); }
    static void free(void* p) { fftwf_free(p); }
};

long long wrap(long long m, long long size) {
    const long long r = m % size;
    return r < 0 ? r + size : r;
}

// v[j] = G1(x_j − δ) · e^{−i2π(β x_j − b δ)}, x_j = (m0 + j)·h, j = 0…count−1: the kernel's
// 1-D factor (normalised Gaussian of σ, its slope's linear phase, the demodulation β = b + U0).
// Gaussians by gaussian_samples' recurrence, the phase by a rotation restarted every 32 steps.
void kernel_vector(long long m0, int count, double h, double delta, double sigma, double beta, double b,
                   std::complex<double>* v, double* g) {
    gaussian_samples(0.5 / (sigma * sigma), double(m0) * h - delta, h, count, g);
    const double norm = 1.0 / (std::sqrt(2.0 * k_pi) * sigma);
    const std::complex<double> rotation = std::polar(1.0, -2.0 * k_pi * beta * h);
    std::complex<double> phase;
    for (int j = 0; j < count; ++j) {
        if (j % 32 == 0)
            phase = std::polar(1.0, -2.0 * k_pi * (beta * double(m0 + j) * h - b * delta));
        else
            phase *= rotation;
        v[j] = (norm * g[j]) * phase;
    }
}

// The kernel's y vector folded modulo `size`: out[i] ↔ column wrap(first + i); `length`
// entries (≤ size). Returns the first column.
template <typename Float>
long long fold(const std::complex<double>* v, int count, long long m0, long long size, std::complex<Float>* out,
               int& length) {
    if (count <= size) {
        for (int j = 0; j < count; ++j) out[j] = std::complex<Float>(v[j]);
        length = count;
        return wrap(m0, size);
    }
    std::fill(out, out + size, std::complex<Float>(0));
    for (long long j = 0, at = wrap(m0, size); j < count; ++j, at = at + 1 == size ? 0 : at + 1)
        out[at] += std::complex<Float>(v[j]);
    length = static_cast<int>(size);
    return 0;
}

// a[q] += c · y[q], q < count (interleaved real/imaginary parts, so that it vectorises).
template <typename Float>
inline void add_scaled(std::complex<Float>* a, std::complex<Float> c, const std::complex<Float>* y, int count) {
    Float* af = reinterpret_cast<Float*>(a);
    const Float* yf = reinterpret_cast<const Float*>(y);
    const Float cr = c.real(), ci = c.imag();
#pragma omp simd
    for (int q = 0; q < count; ++q) {
        const Float yr = yf[2 * q], yi = yf[2 * q + 1];
        af[2 * q] += cr * yr - ci * yi;
        af[2 * q + 1] += cr * yi + ci * yr;
    }
}

}  // namespace

long long good_fft_size(long long at_least) {
    long long best = std::numeric_limits<long long>::max();
    const long long target = std::max<long long>(at_least, 1);
    for (long long a = 1; a < best && a / 2 < target; a *= 2)
        for (long long b = a; b < best && b / 3 < target; b *= 3)
            for (long long c = b; c < best; c *= 5)
                if (c >= target) {
                    best = std::min(best, c);
                    break;
                }
    return best;
}

// The kernels a call spreads and the grid it spreads them on.
template <typename Float>
struct FftEngine<Float>::Layout {
    FftGridInfo info;
    std::vector<std::size_t> kept;  // kernel indices
    std::vector<long long> x0, y0;  // first spread index per kept kernel (unwrapped)
    std::vector<double> bx, by;     // b_k per kept kernel (cycles/µm)
};

// The grids (one per weight vector) and their FFTW plans: rows (length my, all mx of them) and
// columns (length mx, the first n), each split into one block per thread.
template <typename Float>
struct FftEngine<Float>::Workspace {
    using Traits = Fftw<Float>;
    int mx = 0, my = 0, threads = 0;
    std::vector<std::complex<Float>*> grids;
    std::vector<std::pair<int, typename Traits::Plan>> row_plans;  // (first row, plan)
    // The column pass works on blocks of k_block columns copied (transposed) into a buffer per
    // thread: FFTW's strided transforms of a power-of-two stride ran 30× slower than its
    // contiguous ones (cache-set conflicts), and the copy out lands in the field's columns.
    static constexpr int k_block = 16;
    std::vector<std::complex<Float>*> buffers;  // per thread, k_block × mx
    typename Traits::Plan col_plan = nullptr;
    ~Workspace() { clear(); }
    void clear() {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        for (auto& p : row_plans) Traits::destroy(p.second);
        if (col_plan) Traits::destroy(col_plan);
        col_plan = nullptr;
        row_plans.clear();
        for (auto* g : grids) Traits::free(g);
        grids.clear();
        for (auto* b : buffers) Traits::free(b);
        buffers.clear();
        mx = my = threads = 0;
    }
};

template <typename Float>
FftEngine<Float>::FftEngine(const FootprintKernels& kernels, const SliceGrid& grid, double lambda_um, int n,
                            double tolerance)
    : m_kernels(kernels), m_n(n), m_lambda_um(lambda_um), m_tolerance(tolerance), m_work(new Workspace) {
    if (!(lambda_um > 0.0) || !std::isfinite(lambda_um))
        throw std::domain_error("FFT engine: wavelength " + std::to_string(lambda_um) + " µm; expected > 0");
    if (n < 1 || n > 65536)
        throw std::invalid_argument("FFT engine: slice size " + std::to_string(n) + "; expected 1…65536");
    if (!(tolerance >= 1e-12 && tolerance <= 1e-2))
        throw std::domain_error("FFT engine: tolerance " + std::to_string(tolerance) + "; expected 1e-12…1e-2");
    if (grid.ux.size() != std::size_t(n) || grid.uy.size() != std::size_t(n))
        throw std::invalid_argument("FFT engine: the slice grid has " + std::to_string(grid.ux.size()) +
                                    " entries; expected n = " + std::to_string(n));
    const double sigma = kernels.sigma_um;
    if (!(sigma > 0.0) || !std::isfinite(sigma))
        throw std::domain_error("FFT engine: kernel sigma " + std::to_string(sigma) + " µm; expected > 0");
    const std::size_t count = kernels.size();
    if (kernels.dx_um.size() != count || kernels.dy_um.size() != count || kernels.slope_x.size() != count ||
        kernels.slope_y.size() != count)
        throw std::invalid_argument("FFT engine: the kernels' arrays differ in length; expected " +
                                    std::to_string(count) + " each");
    for (std::size_t k = 0; k < count; ++k)
        if (!std::isfinite(kernels.dx_um[k]) || !std::isfinite(kernels.dy_um[k]))
            throw std::domain_error("FFT engine: kernel " + std::to_string(k) + " has a non-finite position");
    m_du = 2.0 / (double(n) * lambda_um);
    m_u0x = grid.ux[0];
    m_u0y = grid.uy[0];
    // The per-kernel bound: errors of many kernels add incoherently on a rough surface and
    // coherently on a smooth one, where the peak grows the same way. With t = tolerance the
    // tests measured errors of 0.1–0.2 · tolerance; t = tolerance / 4 keeps a margin of ~20.
    const double t = tolerance / 4.0;
    const double log_t = std::log(1.0 / t);
    m_radius_x_um = sigma * std::sqrt(2.0 * log_t);
    m_radius_u = std::sqrt(log_t / (2.0 * k_pi * k_pi * sigma * sigma));
}

template <typename Float>
FftEngine<Float>::~FftEngine() = default;

template <typename Float>
typename FftEngine<Float>::Layout FftEngine<Float>::layout(double shift_scale) const {
    if (!std::isfinite(shift_scale))
        throw std::domain_error("FFT engine: shift scale " + std::to_string(shift_scale) + "; expected finite");
    Layout out;
    const std::size_t count = m_kernels.size();
    const double scale = shift_scale * 2.0 / m_lambda_um;
    const double u1x = m_u0x + double(m_n - 1) * m_du, u1y = m_u0y + double(m_n - 1) * m_du;
    const double r = m_radius_u / m_du;  // spectral radius in grid steps
    double hi_x = double(m_n - 1), lo_x = 0.0, hi_y = double(m_n - 1), lo_y = 0.0;
    out.kept.reserve(count);
    for (std::size_t k = 0; k < count; ++k) {
        const double bx = scale * m_kernels.slope_x[k], by = scale * m_kernels.slope_y[k];
        if (!std::isfinite(bx) || !std::isfinite(by))
            throw std::domain_error("FFT engine: kernel " + std::to_string(k) + " has a non-finite slope");
        // Distance of the spectrum's centre −b from the window, per axis.
        const double dx = std::max({0.0, m_u0x + bx, -bx - u1x}), dy = std::max({0.0, m_u0y + by, -by - u1y});
        if (dx * dx + dy * dy > m_radius_u * m_radius_u) continue;
        out.kept.push_back(k);
        out.bx.push_back(bx);
        out.by.push_back(by);
        const double cx = (-bx - m_u0x) / m_du, cy = (-by - m_u0y) / m_du;
        hi_x = std::max(hi_x, cx + r);
        lo_x = std::min(lo_x, cx - r);
        hi_y = std::max(hi_y, cy + r);
        lo_y = std::min(lo_y, cy - r);
    }
    // No alias of any kept spectrum may reach the window: M > hi and M > n − 1 − lo.
    const double need_x = std::max(hi_x, double(m_n - 1) - lo_x), need_y = std::max(hi_y, double(m_n - 1) - lo_y);
    const double limit = 1e9;  // far beyond any memory; keeps the integer arithmetic exact
    if (!(need_x < limit && need_y < limit))
        throw_out_of_memory("the FFT engine's grid (more than 1e9 points per axis)", 1e18);
    long long mx = good_fft_size(static_cast<long long>(std::floor(need_x)) + 1);
    long long my = good_fft_size(static_cast<long long>(std::floor(need_y)) + 1);
    // The grid is a function of the current slopes only (not of earlier calls), so a plan reused
    // across heights gives the very values a fresh one does; the workspace is re-planned when
    // the size changes (FFTW_ESTIMATE plans take well under a millisecond).
    if (mx > std::numeric_limits<int>::max() / 2 || my > std::numeric_limits<int>::max() / 2)
        throw_out_of_memory("the FFT engine's grid", double(mx) * double(my) * sizeof(std::complex<Float>));
    const double period = 1.0 / m_du;
    out.info.mx = static_cast<int>(mx);
    out.info.my = static_cast<int>(my);
    out.info.hx_um = period / double(mx);
    out.info.hy_um = period / double(my);
    out.info.kept = out.kept.size();
    const double hx = out.info.hx_um, hy = out.info.hy_um;
    out.x0.resize(out.kept.size());
    out.y0.resize(out.kept.size());
    // A kernel far wider than the period (σ ≫ nλ/2) would need vectors of many periods: refused
    // before allocating them (the separable path serves such slices; the cost model says so).
    const double widest = 2.0 * m_radius_x_um / std::min(hx, hy) + 1.0;
    if (widest > 1e8)
        throw_out_of_memory("the FFT engine's kernel vectors (" + std::to_string(widest) + " points)",
                            widest * 4.0 * sizeof(std::complex<double>));
    out.info.span_x = static_cast<int>(std::floor(2.0 * m_radius_x_um / hx)) + 1;
    out.info.span_y = static_cast<int>(std::floor(2.0 * m_radius_x_um / hy)) + 1;
    for (std::size_t i = 0; i < out.kept.size(); ++i) {
        const std::size_t k = out.kept[i];
        out.x0[i] = static_cast<long long>(std::ceil((m_kernels.dx_um[k] - m_radius_x_um) / hx));
        out.y0[i] = static_cast<long long>(std::ceil((m_kernels.dy_um[k] - m_radius_x_um) / hy));
    }
    return out;
}

template <typename Float>
FftGridInfo FftEngine<Float>::plan_grid(double shift_scale) const {
    return layout(shift_scale).info;
}

template <typename Float>
void FftEngine<Float>::prepare(const Layout& layout, std::size_t grids) {
    using Traits = Fftw<Float>;
    const int mx = layout.info.mx, my = layout.info.my;
    const double entries = double(mx) * double(my);
    const int threads = worth_parallel(static_cast<long long>(entries)) ? omp_get_max_threads() : 1;
    Workspace& w = *m_work;
    if (w.mx != mx || w.my != my || w.threads != threads || w.grids.size() < grids) {
        const double bytes = entries * double(std::max(grids, w.grids.size())) * sizeof(std::complex<Float>);
        const std::string what = "the FFT engine's " + std::to_string(mx) + "x" + std::to_string(my) + " grids";
        const std::uint64_t physical = physical_memory_bytes();
        if (physical > 0 && bytes > double(physical)) throw_out_of_memory(what, bytes);
        const std::size_t keep = std::max(grids, w.grids.size());
        w.clear();
        allocating(what, bytes, [&] {
            for (std::size_t v = 0; v < keep; ++v) {
                void* p = Traits::malloc(static_cast<std::size_t>(entries) * sizeof(std::complex<Float>));
                if (!p) throw std::bad_alloc();
                w.grids.push_back(static_cast<std::complex<Float>*>(p));
            }
            for (int t = 0; t < threads; ++t) {
                void* p = Traits::malloc(std::size_t(Workspace::k_block) * std::size_t(mx) *
                                         sizeof(std::complex<Float>));
                if (!p) throw std::bad_alloc();
                w.buffers.push_back(static_cast<std::complex<Float>*>(p));
            }
        });
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        for (int t = 0; t < threads; ++t) {
            const int r0 = int(static_cast<long long>(mx) * t / threads),
                      r1 = int(static_cast<long long>(mx) * (t + 1) / threads);
            if (r1 > r0)
                w.row_plans.emplace_back(r0, Traits::many(my, r1 - r0, w.grids[0] + std::size_t(r0) * my, 1, my));
        }
        w.col_plan = Traits::many(mx, Workspace::k_block, w.buffers[0], 1, mx);
        for (auto& p : w.row_plans)
            if (!p.second)
                throw std::runtime_error("FFT engine: FFTW could not plan a transform of " + std::to_string(my));
        if (!w.col_plan)
            throw std::runtime_error("FFT engine: FFTW could not plan a transform of " + std::to_string(mx));
        w.mx = mx;
        w.my = my;
        w.threads = threads;
    }
}

template <typename Float>
void FftEngine<Float>::check_weights(const KernelWeights& weights) const {
    if (weights.empty()) throw std::invalid_argument("FFT engine: no weight vectors; expected at least one");
    for (std::size_t v = 0; v < weights.size(); ++v)
        if (weights[v].size() != m_kernels.size())
            throw std::invalid_argument("FFT engine: weight vector " + std::to_string(v) + " has " +
                                        std::to_string(weights[v].size()) + " entries; expected " +
                                        std::to_string(m_kernels.size()));
}

namespace {

// The thread's share of the rows [first, last) of the grid: rows balanced by the number of
// kernel rows that land on them (kernels concentrate where the footprint is).
std::vector<int> row_bands(const std::vector<long long>& x0, int span, int mx, int threads) {
    std::vector<long long> load(std::size_t(mx) + 1, 0);
    for (long long first : x0) {
        if (span >= mx) {
            load[0] += span / mx + 1;
            continue;
        }
        const long long a = wrap(first, mx), b = a + span;
        load[std::size_t(a)] += 1;
        if (b <= mx)
            load[std::size_t(b)] -= 1;
        else {
            load[std::size_t(mx)] -= 1;
            load[0] += 1;
            load[std::size_t(b - mx)] -= 1;
        }
    }
    std::vector<long long> cumulative(std::size_t(mx) + 1, 0);
    long long running = 0;
    for (int r = 0; r < mx; ++r) {
        running += load[std::size_t(r)];
        cumulative[std::size_t(r) + 1] = cumulative[std::size_t(r)] + running + 1;  // +1: zeroing
    }
    std::vector<int> bands(std::size_t(threads) + 1, 0);
    bands[std::size_t(threads)] = mx;
    for (int t = 1; t < threads; ++t) {
        const long long target = cumulative[std::size_t(mx)] * t / threads;
        bands[std::size_t(t)] = static_cast<int>(std::lower_bound(cumulative.begin(), cumulative.end(), target) -
                                                 cumulative.begin());
        bands[std::size_t(t)] = std::clamp(bands[std::size_t(t)], bands[std::size_t(t) - 1], mx);
    }
    return bands;
}

}  // namespace

template <typename Float>
void FftEngine<Float>::forward(const KernelWeights& weights, double shift_scale,
                               std::vector<ComplexMatrix<Float>>& fields) {
    using Complex = std::complex<Float>;
    using Traits = Fftw<Float>;
    check_weights(weights);
    const Layout lay = layout(shift_scale);
    const std::size_t views = weights.size();
    prepare(lay, views);
    m_info = lay.info;
    Workspace& w = *m_work;
    const int mx = w.mx, my = w.my, threads = w.threads, n = m_n;
    const double hx = lay.info.hx_um, hy = lay.info.hy_um, area = hx * hy;
    const int span_x = lay.info.span_x, span_y = lay.info.span_y;
    const std::vector<int> bands = row_bands(lay.x0, span_x, mx, threads);
    fields.resize(views);
    for (auto& f : fields)
        allocating("the " + std::to_string(n) + "x" + std::to_string(n) + " slice's field",
                   double(n) * n * sizeof(Complex), [&] { f.resize(n, n); });
    const double sigma = m_kernels.sigma_um;
    RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        // Every phase loops over the blocks, should the team be smaller than asked for.
        const int first_block = omp_get_thread_num(), stride = omp_get_num_threads();
        std::vector<std::complex<double>> vx, vy;
        std::vector<double> gauss;
        std::vector<Complex> yf;
        std::vector<std::complex<double>> coef(views);
        guard.run([&] {
            vx.resize(std::size_t(span_x));
            vy.resize(std::size_t(span_y));
            gauss.resize(std::size_t(std::max(span_x, span_y)));
            yf.resize(std::size_t(std::max(span_y, my)));
            for (int t = first_block; t < threads; t += stride) {
                const int r0 = bands[std::size_t(t)], r1 = bands[std::size_t(t) + 1];
                for (std::size_t v = 0; v < views; ++v)
                    std::fill(w.grids[v] + std::size_t(r0) * my, w.grids[v] + std::size_t(r1) * my, Complex(0));
            }
        });
#pragma omp barrier
        for (int t = first_block; t < threads; t += stride)
            guard.run([&] {
                const int r0 = bands[std::size_t(t)], r1 = bands[std::size_t(t) + 1];
                if (r1 <= r0) return;
                for (std::size_t i = 0; i < lay.kept.size(); ++i) {
                    // Does any of this kernel's rows fall in the band?
                    // (Rows advance with a wrap test, not a division: this runs per kernel and row.)
                    const long long row0 = wrap(lay.x0[i], mx);
                    bool any = span_x >= mx;
                    for (long long j = 0, row = row0; j < span_x && !any; ++j, row = row + 1 == mx ? 0 : row + 1)
                        any = row >= r0 && row < r1;
                    if (!any) continue;
                    const std::size_t k = lay.kept[i];
                    kernel_vector(lay.x0[i], span_x, hx, m_kernels.dx_um[k], sigma, lay.bx[i] + m_u0x, lay.bx[i],
                                  vx.data(), gauss.data());
                    kernel_vector(lay.y0[i], span_y, hy, m_kernels.dy_um[k], sigma, lay.by[i] + m_u0y, lay.by[i],
                                  vy.data(), gauss.data());
                    int length = 0;
                    const long long c0 = fold(vy.data(), span_y, lay.y0[i], my, yf.data(), length);
                    const int first_run = static_cast<int>(std::min<long long>(length, my - c0));
                    for (std::size_t v = 0; v < views; ++v) coef[v] = weights[v][k] * area;
                    for (long long j = 0, row = row0; j < span_x; ++j, row = row + 1 == mx ? 0 : row + 1) {
                        if (row < r0 || row >= r1) continue;
                        for (std::size_t v = 0; v < views; ++v) {
                            const Complex c(coef[v] * vx[std::size_t(j)]);
                            Complex* out = w.grids[v] + std::size_t(row) * my;
                            add_scaled(out + c0, c, yf.data(), first_run);
                            add_scaled(out, c, yf.data() + first_run, length - first_run);
                        }
                    }
                }
            });
#pragma omp barrier
        // FFT along y (all rows), then along x (the first n columns only).
        for (int t = first_block; t < threads; t += stride)
            guard.run([&] {
                if (std::size_t(t) < w.row_plans.size())
                    for (std::size_t v = 0; v < views; ++v)
                        Traits::execute(w.row_plans[std::size_t(t)].second,
                                        w.grids[v] + std::size_t(w.row_plans[std::size_t(t)].first) * my);
            });
#pragma omp barrier
        // Along x, the first n columns: blocks copied into the thread's buffer (transposed),
        // transformed there and written to the field's columns (rows j < n).
        const int blocks = (n + Workspace::k_block - 1) / Workspace::k_block;
#pragma omp for schedule(static)
        for (int blk = 0; blk < blocks; ++blk)
            guard.run([&] {
                Complex* buf = w.buffers[std::size_t(omp_get_thread_num())];
                const int c0 = blk * Workspace::k_block, width = std::min(Workspace::k_block, n - c0);
                for (std::size_t v = 0; v < views; ++v) {
                    const Complex* g = w.grids[v];
                    for (int x = 0; x < mx; ++x) {
                        const Complex* row = g + std::size_t(x) * my + c0;
                        for (int b = 0; b < width; ++b) buf[std::size_t(b) * mx + x] = row[b];
                    }
                    for (int b = width; b < Workspace::k_block; ++b)
                        std::fill(buf + std::size_t(b) * mx, buf + std::size_t(b + 1) * mx, Complex(0));
                    Traits::execute(w.col_plan, buf);
                    for (int b = 0; b < width; ++b)
                        std::copy(buf + std::size_t(b) * mx, buf + std::size_t(b) * mx + n, &fields[v](0, c0 + b));
                }
            });
    }
    guard.rethrow();
}

template <typename Float>
void FftEngine<Float>::adjoint(const KernelWeights& weights, double shift_scale,
                               const std::vector<ComplexMatrix<Float>>& cotangents, FieldGradient& gradient) {
    using Complex = std::complex<Float>;
    using Traits = Fftw<Float>;
    check_weights(weights);
    const std::size_t views = weights.size();
    if (cotangents.size() != views)
        throw std::invalid_argument("FFT engine: " + std::to_string(cotangents.size()) +
                                    " cotangents; expected one per weight vector (" + std::to_string(views) + ")");
    for (const auto& b : cotangents)
        if (b.rows() != m_n || b.cols() != m_n)
            throw std::invalid_argument("FFT engine: a cotangent of " + std::to_string(b.rows()) + "x" +
                                        std::to_string(b.cols()) + "; expected " + std::to_string(m_n) + "x" +
                                        std::to_string(m_n));
    const Layout lay = layout(shift_scale);
    prepare(lay, views);
    m_info = lay.info;
    Workspace& w = *m_work;
    const int mx = w.mx, my = w.my, threads = w.threads, n = m_n;
    const double hx = lay.info.hx_um, hy = lay.info.hy_um, area = hx * hy;
    const int span_x = lay.info.span_x, span_y = lay.info.span_y;
    const std::size_t count = m_kernels.size();
    gradient.weight.assign(views, std::vector<std::complex<double>>(count, 0.0));
    gradient.shift_x.assign(count, 0.0);
    gradient.shift_y.assign(count, 0.0);
    const double sigma = m_kernels.sigma_um;
    RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        const int first_block = omp_get_thread_num(), stride = omp_get_num_threads();
        // B_v along x (its n columns, zero-padded to mx) into the thread's buffer, transformed
        // there and written into the grid's first n columns; the others are zeroed. Then along y.
        const int blocks = (n + Workspace::k_block - 1) / Workspace::k_block;
#pragma omp for schedule(static)
        for (int blk = 0; blk < blocks; ++blk)
            guard.run([&] {
                Complex* buf = w.buffers[std::size_t(omp_get_thread_num())];
                const int c0 = blk * Workspace::k_block, width = std::min(Workspace::k_block, n - c0);
                for (std::size_t v = 0; v < views; ++v) {
                    for (int b = 0; b < Workspace::k_block; ++b) {
                        Complex* col = buf + std::size_t(b) * mx;
                        if (b < width) std::copy(&cotangents[v](0, c0 + b), &cotangents[v](0, c0 + b) + n, col);
                        std::fill(col + (b < width ? n : 0), col + mx, Complex(0));
                    }
                    Traits::execute(w.col_plan, buf);
                    Complex* g = w.grids[v];
                    for (int x = 0; x < mx; ++x) {
                        Complex* row = g + std::size_t(x) * my + c0;
                        for (int b = 0; b < width; ++b) row[b] = buf[std::size_t(b) * mx + x];
                    }
                }
            });
#pragma omp for schedule(static)
        for (int x = 0; x < mx; ++x)
            guard.run([&] {
                for (std::size_t v = 0; v < views; ++v)
                    std::fill(w.grids[v] + std::size_t(x) * my + n, w.grids[v] + std::size_t(x + 1) * my, Complex(0));
            });
        for (int t = first_block; t < threads; t += stride)
            guard.run([&] {
                if (std::size_t(t) < w.row_plans.size())
                    for (std::size_t v = 0; v < views; ++v)
                        Traits::execute(w.row_plans[std::size_t(t)].second,
                                        w.grids[v] + std::size_t(w.row_plans[std::size_t(t)].first) * my);
            });
#pragma omp barrier
        std::vector<std::complex<double>> vx, vy, vyd, sum(views), sum_x(views), sum_y(views);
        std::vector<double> gauss;
        std::vector<Complex> yf, yfd, acc;
        guard.run([&] {
            vx.resize(std::size_t(span_x));
            vy.resize(std::size_t(span_y));
            vyd.resize(std::size_t(span_y));
            gauss.resize(std::size_t(std::max(span_x, span_y)));
            yf.resize(std::size_t(std::max(span_y, my)));
            yfd.resize(std::size_t(std::max(span_y, my)));
            acc.resize(2 * views * std::size_t(std::max(span_y, my)));
        });
#pragma omp for schedule(dynamic, 64)
        for (std::size_t i = 0; i < lay.kept.size(); ++i)
            guard.run([&] {
                const std::size_t k = lay.kept[i];
                const double dx = m_kernels.dx_um[k], dy = m_kernels.dy_um[k];
                kernel_vector(lay.x0[i], span_x, hx, dx, sigma, lay.bx[i] + m_u0x, lay.bx[i], vx.data(), gauss.data());
                kernel_vector(lay.y0[i], span_y, hy, dy, sigma, lay.by[i] + m_u0y, lay.by[i], vy.data(), gauss.data());
                for (int j = 0; j < span_y; ++j)
                    vyd[std::size_t(j)] = (double(lay.y0[i] + j) * hy - dy) * vy[std::size_t(j)];
                int length = 0;
                const long long c0 = fold(vy.data(), span_y, lay.y0[i], my, yf.data(), length);
                fold(vyd.data(), span_y, lay.y0[i], my, yfd.data(), length);
                const int first_run = static_cast<int>(std::min<long long>(length, my - c0));
                // Rows first: t_v = Σ_rows vx · A_v[row] and tx_v = Σ_rows (x − δ_x) vx · A_v[row]
                // over the kernel's columns (vectorised like the forward's spread), then one dot
                // product per sum with the y vectors.
                for (std::size_t v = 0; v < views; ++v) {
                    Complex* t = acc.data() + 2 * std::size_t(v) * std::size_t(length);
                    std::fill(t, t + 2 * std::size_t(length), Complex(0));
                }
                for (long long j = 0, row = wrap(lay.x0[i], mx); j < span_x; ++j, row = row + 1 == mx ? 0 : row + 1) {
                    const std::complex<double> ax = vx[std::size_t(j)];
                    const double x = double(lay.x0[i] + j) * hx - dx;
                    const Complex cx(ax), cxx(x * ax);
                    for (std::size_t v = 0; v < views; ++v) {
                        const Complex* in = w.grids[v] + std::size_t(row) * my;
                        Complex* t = acc.data() + 2 * std::size_t(v) * std::size_t(length);
                        Complex* tx = t + length;
                        add_scaled(t, cx, in + c0, first_run);
                        add_scaled(t + first_run, cx, in, length - first_run);
                        add_scaled(tx, cxx, in + c0, first_run);
                        add_scaled(tx + first_run, cxx, in, length - first_run);
                    }
                }
                for (std::size_t v = 0; v < views; ++v) {
                    const Complex* t = acc.data() + 2 * std::size_t(v) * std::size_t(length);
                    const Complex* tx = t + length;
                    std::complex<double> s0 = 0.0, sx = 0.0, sy = 0.0;
                    for (int q = 0; q < length; ++q) {
                        const std::complex<double> tq(t[q]);
                        s0 += std::complex<double>(yf[std::size_t(q)]) * tq;
                        sy += std::complex<double>(yfd[std::size_t(q)]) * tq;
                        sx += std::complex<double>(yf[std::size_t(q)]) * std::complex<double>(tx[q]);
                    }
                    sum[v] = s0;
                    sum_x[v] = sx;
                    sum_y[v] = sy;
                }
                // ∂G/∂b_x ↔ −i2π(x − δ_x) · kernel.
                const std::complex<double> minus_i2pi(0.0, -2.0 * k_pi);
                double gx = 0.0, gy = 0.0;
                for (std::size_t v = 0; v < views; ++v) {
                    gradient.weight[v][k] = area * sum[v];
                    gx += 2.0 * std::real(weights[v][k] * area * minus_i2pi * sum_x[v]);
                    gy += 2.0 * std::real(weights[v][k] * area * minus_i2pi * sum_y[v]);
                }
                gradient.shift_x[k] = gx;
                gradient.shift_y[k] = gy;
            });
    }
    guard.rethrow();
}

template class FftEngine<float>;
template class FftEngine<double>;

}  // namespace wavebrdf::detail
