#include "design/engine.h"

#include <fftw3.h>
#include <omp.h>

#include <algorithm>
#include <cmath>

#include "wavebrdf/constants.h"
#include <mutex>
#include <stdexcept>
#include <string>

#include "core/fftw_planner.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

double sinc(double x) {
    if (x == 0.0) return 1.0;
    const double px = k_pi * x;
    return std::sin(px) / px;
}

namespace {

int wrap(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}

}  // namespace

OrderSet make_order_set(int size, double texel_um, const std::array<double, 2>& omega_i, double lambda_um) {
    if (size < 1 || size > 8192)
        throw std::invalid_argument("tile size " + std::to_string(size) + " is out of range; expected 1 to 8192");
    if (!(texel_um >= 1e-3 && texel_um <= 1e3))
        throw std::domain_error("texel width " + format_shortest(texel_um) + " um is out of range; expected 0.001 to 1000");
    if (!(lambda_um >= 0.05 && lambda_um <= 100.0))
        throw std::domain_error("wavelength " + format_shortest(lambda_um) + " um is out of range; expected 0.05 to 100");
    const double r2i = omega_i[0] * omega_i[0] + omega_i[1] * omega_i[1];
    if (!(r2i < 1.0))
        throw std::domain_error("light direction (" + format_shortest(omega_i[0]) + ", " + format_shortest(omega_i[1]) +
                                ") is outside the unit disk; expected |omega_i| < 1");
    OrderSet s;
    s.lambda_um = lambda_um;
    s.k = 2.0 * k_pi / lambda_um;
    s.cos_i = std::sqrt(1.0 - r2i);
    s.period_um = size * texel_um;
    const double step = lambda_um / s.period_um;  // order spacing in ω
    const int reach = static_cast<int>(std::ceil(2.0 / step)) + 1;
    const double mx = -omega_i[0], my = -omega_i[1];
    for (int m = -reach; m <= reach; ++m) {
        if (m != 0 && m % size == 0) continue;
        const double ox = mx + step * m;
        if (std::abs(ox) >= 1.0) continue;
        const double sx = sinc(static_cast<double>(m) / size);
        for (int n = -reach; n <= reach; ++n) {
            if (n != 0 && n % size == 0) continue;
            const double oy = my + step * n;
            const double r2 = ox * ox + oy * oy;
            if (!(r2 < 1.0)) continue;
            const double cos_o = std::sqrt(1.0 - r2);
            const double sy = sinc(static_cast<double>(n) / size);
            s.m.push_back(m);
            s.n.push_back(n);
            s.bin.push_back(wrap(m, size) * size + wrap(n, size));
            s.q.push_back(s.cos_i + cos_o);
            s.env.push_back(sx * sx * sy * sy * cos_o / s.cos_i);
        }
    }
    return s;
}

struct LevelSpectra::Plans {
    fftw_complex* buffer = nullptr;
    fftw_plan forward = nullptr, backward = nullptr;
    ~Plans() {
        std::lock_guard<std::mutex> lock(fftw_planner_mutex());
        if (forward) fftw_destroy_plan(forward);
        if (backward) fftw_destroy_plan(backward);
        if (buffer) fftw_free(buffer);
    }
};

LevelSpectra::LevelSpectra(int size, int levels)
    : m_size(size), m_levels(levels), m_plans(std::make_unique<Plans>()) {
    const std::size_t n2 = static_cast<std::size_t>(size) * static_cast<std::size_t>(size);
    m_spectra.assign(n2 * static_cast<std::size_t>(levels), Complex(0.0, 0.0));
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    m_plans->buffer = fftw_alloc_complex(n2);
    if (!m_plans->buffer) throw std::bad_alloc();
    m_plans->forward = fftw_plan_dft_2d(size, size, m_plans->buffer, m_plans->buffer, FFTW_FORWARD, FFTW_ESTIMATE);
    m_plans->backward = fftw_plan_dft_2d(size, size, m_plans->buffer, m_plans->buffer, FFTW_BACKWARD, FFTW_ESTIMATE);
    if (!m_plans->forward || !m_plans->backward) throw std::runtime_error("FFTW could not plan the level spectra");
}

LevelSpectra::~LevelSpectra() = default;

void LevelSpectra::forward(const std::vector<double>& weights) {
    const std::size_t n2 = static_cast<std::size_t>(m_size) * static_cast<std::size_t>(m_size);
    const std::size_t levels = static_cast<std::size_t>(m_levels);
    if (weights.size() != n2 * levels) throw std::invalid_argument("level weights: size mismatch");
    const double scale = 1.0 / static_cast<double>(n2);
    auto* buffer = reinterpret_cast<Complex*>(m_plans->buffer);
    for (std::size_t l = 0; l < levels; ++l) {
        const double* w = weights.data() + l * n2;
        bool empty = true;
        for (std::size_t t = 0; t < n2; ++t) {
            buffer[t] = Complex(w[t], 0.0);
            empty = empty && w[t] == 0.0;
        }
        if (empty) {
            for (std::size_t b = 0; b < n2; ++b) m_spectra[b * levels + l] = 0.0;
            continue;
        }
        fftw_execute(m_plans->forward);
        for (std::size_t b = 0; b < n2; ++b) m_spectra[b * levels + l] = buffer[b] * scale;
    }
}

void LevelSpectra::adjoint(const std::vector<Complex>& spectra_gradient, std::vector<double>& weights_gradient) {
    const std::size_t n2 = static_cast<std::size_t>(m_size) * static_cast<std::size_t>(m_size);
    const std::size_t levels = static_cast<std::size_t>(m_levels);
    if (spectra_gradient.size() != n2 * levels) throw std::invalid_argument("spectra gradient: size mismatch");
    weights_gradient.assign(n2 * levels, 0.0);
    const double scale = 1.0 / static_cast<double>(n2);
    auto* buffer = reinterpret_cast<Complex*>(m_plans->buffer);
    for (std::size_t l = 0; l < levels; ++l) {
        // dL = Re Σ_b conj(B_b) (1/N²) Σ_t dp_t e^{−2πi b·t/N} = (1/N²) Σ_t dp_t Re[conj(Σ_b B_b e^{+2πi b·t/N})]
        for (std::size_t b = 0; b < n2; ++b) buffer[b] = spectra_gradient[b * levels + l];
        fftw_execute(m_plans->backward);
        double* g = weights_gradient.data() + l * n2;
        for (std::size_t t = 0; t < n2; ++t) g[t] = buffer[t].real() * scale;
    }
}

void order_flux(const OrderSet& orders, const LevelSpectra& spectra, const LevelHeights& heights,
                std::vector<Complex>& amplitude, std::vector<double>& flux) {
    const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(orders.size());
    const int levels = spectra.levels();
    amplitude.resize(orders.size());
    flux.resize(orders.size());
    const Complex* F = spectra.spectra().data();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t o = 0; o < count; ++o) {
        const double phase = orders.k * orders.q[o];
        // e^{−i k h_ℓ q} by recurrence over the equally spaced levels.
        Complex phasor = std::polar(1.0, -phase * heights.base_um);
        const Complex step = std::polar(1.0, -phase * heights.step_um);
        const Complex* f = F + static_cast<std::size_t>(orders.bin[o]) * static_cast<std::size_t>(levels);
        Complex a(0.0, 0.0);
        for (int l = 0; l < levels; ++l) {
            a += phasor * f[l];
            phasor *= step;
        }
        amplitude[o] = a;
        flux[o] = orders.env[o] * std::norm(a);
    }
}

void GradientBuffers::reset(int levels, int size) {
    const std::size_t total = static_cast<std::size_t>(size) * static_cast<std::size_t>(size) *
                              static_cast<std::size_t>(levels);
    per_thread.resize(static_cast<std::size_t>(std::max(1, omp_get_max_threads())));
    for (auto& b : per_thread) b.assign(total, Complex(0.0, 0.0));
}

std::vector<Complex>& GradientBuffers::sum() {
    for (std::size_t t = 1; t < per_thread.size(); ++t) {
        auto& a = per_thread[0];
        const auto& b = per_thread[t];
        for (std::size_t i = 0; i < a.size(); ++i) a[i] += b[i];
    }
    return per_thread[0];
}

void order_flux_adjoint(const OrderSet& orders, const LevelHeights& heights, const std::vector<Complex>& amplitude,
                        const std::vector<double>& flux_gradient, int levels, GradientBuffers& buffers) {
    const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(orders.size());
    const int threads = static_cast<int>(buffers.per_thread.size());
#pragma omp parallel num_threads(threads)
    {
        Complex* B = buffers.per_thread[static_cast<std::size_t>(omp_get_thread_num())].data();
#pragma omp for schedule(static)
        for (std::ptrdiff_t o = 0; o < count; ++o) {
            const double g = flux_gradient[static_cast<std::size_t>(o)];
            if (g == 0.0) continue;
            const double phase = orders.k * orders.q[static_cast<std::size_t>(o)];
            Complex phasor = std::polar(1.0, phase * heights.base_um);
            const Complex step = std::polar(1.0, phase * heights.step_um);
            const Complex c = 2.0 * g * orders.env[static_cast<std::size_t>(o)] * amplitude[static_cast<std::size_t>(o)];
            Complex* b = B + static_cast<std::size_t>(orders.bin[static_cast<std::size_t>(o)]) * static_cast<std::size_t>(levels);
            for (int l = 0; l < levels; ++l) {
                b[l] += c * phasor;
                phasor *= step;
            }
        }
    }
}

double order_flux_step_gradient(const OrderSet& orders, const LevelSpectra& spectra, const LevelHeights& heights,
                                const std::vector<Complex>& amplitude, const std::vector<double>& flux_gradient) {
    const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(orders.size());
    const int levels = spectra.levels();
    const Complex* F = spectra.spectra().data();
    double total = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (std::ptrdiff_t o = 0; o < count; ++o) {
        const auto u = static_cast<std::size_t>(o);
        const double g = flux_gradient[u];
        if (g == 0.0) continue;
        const double phase = orders.k * orders.q[u];
        Complex phasor = std::polar(1.0, -phase * heights.base_um);
        const Complex step = std::polar(1.0, -phase * heights.step_um);
        const Complex* f = F + static_cast<std::size_t>(orders.bin[u]) * static_cast<std::size_t>(levels);
        Complex d(0.0, 0.0);  // Σ_ℓ ℓ e^{−i k h_ℓ q} F_ℓ; ∂A/∂Δ = −i k q d
        for (int l = 0; l < levels; ++l) {
            d += static_cast<double>(l) * phasor * f[l];
            phasor *= step;
        }
        const Complex dA = Complex(0.0, -phase) * d;
        total += 2.0 * g * orders.env[u] * (std::conj(amplitude[u]) * dA).real();
    }
    return total;
}

}  // namespace wavebrdf::detail
