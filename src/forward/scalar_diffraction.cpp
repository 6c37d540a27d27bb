// The scalar-diffraction simulator (scalar_diffraction.h): the exact field of the interpolated
// heights, windowed, Fourier transformed at the slice's u by a separable matrix product.
#include "wavebrdf/scalar_diffraction.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "core/random.h"
#include "forward/scalar_diffraction_detail.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {
namespace {

// The Gabor window's kernel Gaussians are cut at this many σ (e^{−24.5} ≈ 2e-11 of the peak);
// the continuous window at this many σ_p (e^{−32} ≈ 1e-14).
constexpr double k_kernel_cut_sigmas = 7.0;
constexpr double k_window_cut_sigmas = 8.0;

using MatrixC = Eigen::Matrix<std::complex<double>, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Keys' cubic convolution kernel, a = −½: the four weights of samples i0−1 … i0+2 at fraction t.
void keys_weights(double t, double w[4]) {
    const double t2 = t * t, t3 = t2 * t;
    w[0] = -0.5 * t3 + t2 - 0.5 * t;
    w[1] = 1.5 * t3 - 2.5 * t2 + 1.0;
    w[2] = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
    w[3] = 0.5 * t3 - 0.5 * t2;
}

int wrap(long long i, int n) { return static_cast<int>(((i % n) + n) % n); }

struct Window {
    // Relative offsets δ (µm) of the kernels and their weights (Gabor), or σ_p (Gaussian).
    std::vector<double> dx, dy, weight;
    double sigma_um = 0.0;  // kernel σ = w/2
    double sigma_p_um = 0.0;
    ScalarWindow kind = ScalarWindow::Gabor;
    double x0 = 0.0, y0 = 0.0;                              // footprint centre, reduced modulo the period (µm)
    double lo_x = 0.0, hi_x = 0.0, lo_y = 0.0, hi_y = 0.0;  // support of W in δ (µm)
};

double reduce(double x, double period) {
    double r = std::fmod(x, period);
    if (r < 0.0) r += period;
    return r;
}

Window make_window(const Heightfield& hf, const Query& query, ScalarWindow kind) {
    validate(query);
    validate_footprint(query.sigma_p_um, hf.period_x_um(), hf.period_y_um());
    Window w;
    w.kind = kind;
    w.sigma_p_um = query.sigma_p_um;
    w.sigma_um = hf.texel_um() / 2.0;
    w.x0 = reduce(query.x_um, hf.period_x_um());
    w.y0 = reduce(query.y_um, hf.period_y_um());
    if (kind == ScalarWindow::Gabor) {
        const FootprintKernels k = footprint_kernels(hf, query.x_um, query.y_um, query.sigma_p_um);
        w.dx = k.dx_um;
        w.dy = k.dy_um;
        w.weight = k.weight;
        const double cut = k_kernel_cut_sigmas * w.sigma_um;
        w.lo_x = w.lo_y = 0.0;
        w.hi_x = w.hi_y = 0.0;
        if (!k.dx_um.empty()) {
            w.lo_x = *std::min_element(k.dx_um.begin(), k.dx_um.end());
            w.hi_x = *std::max_element(k.dx_um.begin(), k.dx_um.end());
            w.lo_y = *std::min_element(k.dy_um.begin(), k.dy_um.end());
            w.hi_y = *std::max_element(k.dy_um.begin(), k.dy_um.end());
        }
        w.lo_x -= cut, w.lo_y -= cut, w.hi_x += cut, w.hi_y += cut;
    } else {
        const double r = k_window_cut_sigmas * query.sigma_p_um;
        w.lo_x = w.lo_y = -r;
        w.hi_x = w.hi_y = r;
    }
    return w;
}


// One axis of the fine grid: samples x_a = (a + ½) h, a = first … first + count − 1, covering
// the window's support [x0 + lo, x0 + hi]; per sample its texel (i0) and Keys weights.
struct Axis {
    long long first = 0;
    int count = 0;
    double h = 0.0;
    std::vector<int> i0;
    std::vector<double> weights;  // 4 per sample
    double offset(int a) const { return (static_cast<double>(first + a) + 0.5) * h; }
};

Axis make_axis(double x0, double lo, double hi, double texel_um, int m, long long max_side) {
    Axis axis;
    axis.h = texel_um / m;
    const double a_lo = std::floor((x0 + lo) / axis.h - 0.5), a_hi = std::ceil((x0 + hi) / axis.h - 0.5);
    const double count = a_hi - a_lo + 1.0;
    if (!(count <= static_cast<double>(max_side)))
        throw_out_of_memory("the scalar-diffraction grid (" + std::to_string(static_cast<long long>(count)) +
                                " samples per side, above max_grid_side " + std::to_string(max_side) + ")",
                            16.0 * count * count);
    axis.first = static_cast<long long>(a_lo);
    axis.count = static_cast<int>(count);
    axis.i0.resize(axis.count);
    axis.weights.resize(4 * static_cast<std::size_t>(axis.count));
    for (int a = 0; a < axis.count; ++a) {
        // Texel coordinate τ = x/w − ½ (texel centres at integers), split without rounding
        // drift: x/w = (first + a + ½)/m.
        const long long num = 2 * (axis.first + a) + 1 - m;  // 2m·τ
        const long long den = 2LL * m;
        long long q = num / den;
        if (num % den != 0 && num < 0) --q;  // floor
        axis.i0[a] = static_cast<int>(q);
        keys_weights(static_cast<double>(num - q * den) / static_cast<double>(den),
                     &axis.weights[4 * static_cast<std::size_t>(a)]);
    }
    return axis;
}

// The field's integral I(u) at m samples per texel (h² Σ F e^{−i2πu·δ}).
std::vector<std::complex<double>> field_at(const Heightfield& hf, const Query& query, double lambda_um, int n,
                                           const Window& win, int m, long long max_side, int* side) {
    const double w = hf.texel_um();
    const Axis ax = make_axis(win.x0, win.lo_x, win.hi_x, w, m, max_side);
    const Axis ay = make_axis(win.y0, win.lo_y, win.hi_y, w, m, max_side);
    const int px = ax.count, py = ay.count, rows = hf.rows(), cols = hf.cols();
    *side = std::max(px, py);
    const double bytes = 16.0 * (double(px) * py + double(n) * (px + py) + double(px) * n + double(n) * n) +
                         8.0 * (double(rows) * py + double(px) * py);  // + the Gabor window
    MatrixC field, ex, ey, t;
    std::vector<double> along_y;
    allocating("the scalar-diffraction grid (" + std::to_string(px) + "x" + std::to_string(py) + ")", bytes, [&] {
        field.resize(px, py);
        ex.resize(n, px);
        ey.resize(n, py);
        t.resize(px, n);
        along_y.resize(static_cast<std::size_t>(rows) * py);
        return 0;
    });

    // Heights interpolated along y for every texel row, then along x per fine row; the field
    // e^{−i(4π/λ)H̃} times the window.
    const double k_phase = 4.0 * k_pi / lambda_um * hf.vscale() * w;  // h in texels → phase
    const bool parallel = detail::worth_parallel(static_cast<long long>(px) * py * 8);
    detail::RegionGuard guard;
#pragma omp parallel for schedule(static) if (parallel)
    for (int i = 0; i < rows; ++i)
        guard.run([&] {
            for (int b = 0; b < py; ++b) {
                const double* wy = &ay.weights[4 * static_cast<std::size_t>(b)];
                double s = 0.0;
                for (int d = 0; d < 4; ++d) s += wy[d] * hf.value(i, wrap(ay.i0[b] - 1 + d, cols));
                along_y[static_cast<std::size_t>(i) * py + b] = s;
            }
        });
    guard.rethrow();
    std::vector<double> gy;  // Gaussian window: its y factor
    if (win.kind == ScalarWindow::Gaussian) {
        gy.resize(py);
        for (int b = 0; b < py; ++b) {
            const double d = ay.offset(b) - win.y0;
            gy[b] = std::exp(-d * d / (2.0 * win.sigma_p_um * win.sigma_p_um));
        }
    }
#pragma omp parallel for schedule(static) if (parallel)
    for (int a = 0; a < px; ++a)
        guard.run([&] {
            const double* wx = &ax.weights[4 * static_cast<std::size_t>(a)];
            const double dxa = ax.offset(a) - win.x0;
            const double gx = win.kind == ScalarWindow::Gaussian
                                  ? std::exp(-dxa * dxa / (2.0 * win.sigma_p_um * win.sigma_p_um)) /
                                        (std::sqrt(k_pi) * win.sigma_p_um)
                                  : 0.0;
            const double* r[4];
            for (int d = 0; d < 4; ++d) r[d] = &along_y[static_cast<std::size_t>(wrap(ax.i0[a] - 1 + d, rows)) * py];
            for (int b = 0; b < py; ++b) {
                const double hh = wx[0] * r[0][b] + wx[1] * r[1][b] + wx[2] * r[2][b] + wx[3] * r[3][b];
                const double amp = win.kind == ScalarWindow::Gaussian ? gx * gy[b] : 1.0;
                field(a, b) = std::polar(amp, -k_phase * hh);
            }
        });
    guard.rethrow();

    if (win.kind == ScalarWindow::Gabor) {
        // W(δ) = Σ_k c_k w² G(δ; δ_k, σ): each kernel's separable Gaussian on its few samples.
        // Accumulated serially per kernel, kernels in order (reproducible), rows in parallel.
        Eigen::MatrixXd window = allocating("the scalar-diffraction window", 8.0 * px * py,
                                            [&] { return Eigen::MatrixXd::Zero(px, py).eval(); });
        const double s = win.sigma_um, norm = 1.0 / (2.0 * k_pi * s * s), cut = k_kernel_cut_sigmas * s;
        std::vector<int> a0(win.weight.size()), a1(win.weight.size());
        for (std::size_t k = 0; k < win.weight.size(); ++k) {
            a0[k] = std::max(0, static_cast<int>(std::floor((win.x0 + win.dx[k] - cut) / ax.h - 0.5 -
                                                            static_cast<double>(ax.first))));
            a1[k] = std::min(px - 1, static_cast<int>(std::ceil((win.x0 + win.dx[k] + cut) / ax.h - 0.5 -
                                                                static_cast<double>(ax.first))));
        }
#pragma omp parallel for schedule(static) if (parallel)
        for (int a = 0; a < px; ++a)
            guard.run([&] {
                const double dxa = ax.offset(a) - win.x0;
                for (std::size_t k = 0; k < win.weight.size(); ++k) {
                    if (a < a0[k] || a > a1[k]) continue;
                    const double ex_k = win.weight[k] * norm *
                                        std::exp(-(dxa - win.dx[k]) * (dxa - win.dx[k]) / (2 * s * s));
                    const double c = win.y0 + win.dy[k];
                    const int b0 = std::max(
                        0, static_cast<int>(std::floor((c - cut) / ay.h - 0.5 - static_cast<double>(ay.first))));
                    const int b1 = std::min(
                        py - 1, static_cast<int>(std::ceil((c + cut) / ay.h - 0.5 - static_cast<double>(ay.first))));
                    for (int b = b0; b <= b1; ++b) {
                        const double d = ay.offset(b) - c;
                        window(a, b) += ex_k * std::exp(-d * d / (2 * s * s));
                    }
                }
                for (int b = 0; b < py; ++b) field(a, b) *= window(a, b);
            });
        guard.rethrow();
    }

    // The phase matrices E[p][a] = e^{−i2π u_p δ_a}, u = (ω_i + ω_o)/λ, and I = h² E_x F E_yᵀ.
    for (int p = 0; p < n; ++p) {
        const double ux = (query.omega_i[0] + slice_omega(p, n)) / lambda_um;
        const double uy = (query.omega_i[1] + slice_omega(p, n)) / lambda_um;
        for (int a = 0; a < px; ++a) ex(p, a) = std::polar(1.0, -2.0 * k_pi * ux * (ax.offset(a) - win.x0));
        for (int b = 0; b < py; ++b) ey(p, b) = std::polar(1.0, -2.0 * k_pi * uy * (ay.offset(b) - win.y0));
    }
    detail::for_column_blocks(n, double(px) * py * n, [&](long long first, long long count) {
        t.middleCols(first, count).noalias() = field * ey.middleRows(first, count).transpose();
    });
    MatrixC result(n, n);
    detail::for_column_blocks(n, double(n) * px * n, [&](long long first, long long count) {
        result.middleCols(first, count).noalias() = ex * t.middleCols(first, count);
    });
    const double area = ax.h * ay.h;
    std::vector<std::complex<double>> out(static_cast<std::size_t>(n) * n);
    for (int p = 0; p < n; ++p)
        for (int q = 0; q < n; ++q) out[static_cast<std::size_t>(p) * n + q] = area * result(p, q);
    return out;
}

double relative_change(const std::vector<std::complex<double>>& a, const std::vector<std::complex<double>>& b) {
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        // On |I|² (what the slice holds): the global phase of I is the same on both grids.
        const double fa = std::norm(a[i]), fb = std::norm(b[i]);
        num += (fa - fb) * (fa - fb);
        den += fb * fb;
    }
    return den > 0.0 ? std::sqrt(num / den) : std::sqrt(num);
}

}  // namespace

namespace detail {

void validate_scalar_settings(const ScalarDiffractionSettings& s) {
    if (!(s.tolerance <= 0.1) || !(std::isfinite(s.tolerance)) || (s.tolerance > 0.0 && s.tolerance < 1e-12))
        throw std::domain_error("scalar diffraction: tolerance " + std::to_string(s.tolerance) +
                                " is out of range; expected ≤ 0 (no refinement) or 1e-12 … 0.1");
    if (s.max_samples_per_texel < 1 || s.max_samples_per_texel > 4096)
        throw std::domain_error("scalar diffraction: max_samples_per_texel " + std::to_string(s.max_samples_per_texel) +
                                " is out of range; expected 1 … 4096");
    if (s.min_samples_per_texel < 1 || s.min_samples_per_texel > s.max_samples_per_texel)
        throw std::domain_error("scalar diffraction: min_samples_per_texel " + std::to_string(s.min_samples_per_texel) +
                                " is out of range; expected 1 … " + std::to_string(s.max_samples_per_texel));
    if (s.max_grid_side < 1)
        throw std::domain_error("scalar diffraction: max_grid_side " + std::to_string(s.max_grid_side) +
                                " is out of range; expected ≥ 1");
}

}  // namespace detail

std::vector<std::complex<double>> scalar_field(const Heightfield& heightfield, const Query& query, double lambda_um,
                                               int resolution, const ScalarDiffractionSettings& settings,
                                               ScalarDiffractionInfo* info) {
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    detail::validate_scalar_settings(settings);
    if (query.model != Model::OHS && query.model != Model::ROHS)
        throw std::invalid_argument("scalar diffraction: model " + std::string(to_string(query.model)) +
                                    " is not supported; expected OHS or ROHS (S = 1)");
    const Window win = make_window(heightfield, query, settings.window);

    // The first m: ≥ 2 samples per cycle of the highest local frequency |u| + 2 max|∇H̃|/λ
    // (the interpolant's slope is at most 1.25× the largest texel difference), even so that
    // the interpolant's knots fall on cell edges of the midpoint rule.
    double slope = 0.0;
    for (int i = 0; i < heightfield.rows(); ++i)
        for (int j = 0; j < heightfield.cols(); ++j) {
            slope = std::max(slope, std::abs(heightfield.value(i + 1, j) - heightfield.value(i, j)));
            slope = std::max(slope, std::abs(heightfield.value(i, j + 1) - heightfield.value(i, j)));
        }
    slope *= 1.25 * std::abs(heightfield.vscale());
    const double u_max = (std::hypot(query.omega_i[0], query.omega_i[1]) + std::sqrt(2.0)) / lambda_um;
    const double nu = u_max + 2.0 * slope / lambda_um;
    int m = settings.min_samples_per_texel;
    if (settings.tolerance > 0.0) {
        const double wanted = std::ceil(2.0 * nu * heightfield.texel_um());
        if (wanted > m) m = static_cast<int>(std::min<double>(wanted, settings.max_samples_per_texel));
        if (m % 2 && m < settings.max_samples_per_texel) ++m;
    }
    int side = 0;
    std::vector<std::complex<double>> field = field_at(heightfield, query, lambda_um, resolution, win, m,
                                                       settings.max_grid_side, &side);
    double change = 0.0;
    if (settings.tolerance > 0.0) {
        for (;;) {
            if (2 * m > settings.max_samples_per_texel)
                throw std::runtime_error("scalar diffraction: the slice did not converge to tolerance " +
                                         std::to_string(settings.tolerance) + " within " +
                                         std::to_string(settings.max_samples_per_texel) +
                                         " samples per texel (last change " + std::to_string(change) +
                                         "); raise max_samples_per_texel or the tolerance");
            m *= 2;
            std::vector<std::complex<double>> finer = field_at(heightfield, query, lambda_um, resolution, win, m,
                                                               settings.max_grid_side, &side);
            change = relative_change(field, finer);
            field = std::move(finer);
            if (change <= settings.tolerance) break;
        }
    }
    if (info) *info = {m, side, change};
    return field;
}

std::vector<double> scalar_slice(const Heightfield& heightfield, const Query& query, double lambda_um, int resolution,
                                 const ScalarDiffractionSettings& settings, ScalarDiffractionInfo* info) {
    const std::vector<std::complex<double>> field = scalar_field(heightfield, query, lambda_um, resolution, settings,
                                                                 info);
    std::vector<double> slice(field.size(), 0.0);
    for (int p = 0; p < resolution; ++p)
        for (const auto [q, ox, oy] : disk_row(p, resolution)) {
            const double c1 = direction_factors(query.model, query.omega_i, ox, oy, lambda_um).c1;
            const std::size_t i = static_cast<std::size_t>(p) * resolution + q;
            slice[i] = std::isfinite(c1) ? c1 * std::norm(field[i]) : 0.0;
        }
    return slice;
}

double scalar_window_energy(const Heightfield& heightfield, const Query& query, ScalarWindow window) {
    const Window win = make_window(heightfield, query, window);
    if (window == ScalarWindow::Gaussian) return 1.0;
    const double s2 = win.sigma_um * win.sigma_um;
    double sum = 0.0;
    for (std::size_t k = 0; k < win.weight.size(); ++k)
        for (std::size_t l = 0; l < win.weight.size(); ++l) {
            const double dx = win.dx[k] - win.dx[l], dy = win.dy[k] - win.dy[l];
            sum += win.weight[k] * win.weight[l] * std::exp(-(dx * dx + dy * dy) / (4.0 * s2));
        }
    return sum / (4.0 * k_pi * s2);
}

}  // namespace wavebrdf
