// Point evaluation (point_eval.h): every sample gathers its footprint's kernels once, reduced to
// three λ-independent numbers each (amplitude a_k, Gaussian exponent e_k, path difference p_k),
// and the wavelengths are an inner loop of one exponential and one sine/cosine per kernel. Those
// two run through the polynomial versions below so that the loop over kernels vectorises (the C
// library's exp and sincos are calls the compiler cannot vectorise); both are accurate to about
// 1e-11, far below the tests' 1e-6.
#include "wavebrdf/point_eval.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <complex>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "core/text.h"
#include "surface/footprint_offsets.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf {

namespace {

// Rounding to the nearest integer by adding and subtracting 1.5 · 2^52 (exact for |v| < 2^51 in
// the default rounding mode; the library is not built with -ffast-math, which would fold it):
// std::floor does not vectorise without -fno-trapping-math.
constexpr double k_round_magic = 6755399441055744.0;

// e^{−x} for x ≥ 0: x = n ln 2 − r with |r| ≤ ln2/2, e^{r} by its Taylor series to degree 10
// (remainder < 3e-13 relative; measured 3e-13 against std::exp), times 2^{−n} built in the
// exponent bits. Beyond 708 the result is 0 (e^{−708} ≈ 3e-308, the smallest normal double).
// Branch-free, so that the loops over kernels vectorise.
inline double exp_neg(double x) {
    const double y = x < 708.0 ? x : 708.0;
    const double n = (y * 1.4426950408889634 + k_round_magic) - k_round_magic;
    const double r = (n * 6.93147180369123816490e-01 - y) + n * 1.90821492927058770002e-10;
    double p = 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    p = p * r + 1.0;
    // 2^{−n}, n in 0 … 1022: the biased exponent 1023 − n in the low bits of 2^52 + (1023 − n),
    // shifted into place.
    const double magic = (1023.0 - n) + 4503599627370496.0;
    std::uint64_t bits;
    std::memcpy(&bits, &magic, sizeof bits);
    bits <<= 52;
    double scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return x > 708.0 ? 0.0 : p * scale;
}

// cos(2πt) and sin(2πt): t reduced to f in [−½, ½] turns, then to a quarter turn q/4 plus
// |x| ≤ π/4, where the Taylor series of sin (to x^11) and cos (to x^12) leave < 1e-11 (measured
// 7e-12 against std::sin/cos over |t| ≤ 1234 turns); |t| < 2^50.
inline void cis_turns(double t, double& c_out, double& s_out) {
    const double f = t - ((t + k_round_magic) - k_round_magic);
    const double q = (4.0 * f + k_round_magic) - k_round_magic;  // −2 … 2
    const double x = (f - 0.25 * q) * 6.283185307179586;
    const double x2 = x * x;
    double s = -1.0 / 39916800.0;
    s = s * x2 + 1.0 / 362880.0;
    s = s * x2 - 1.0 / 5040.0;
    s = s * x2 + 1.0 / 120.0;
    s = s * x2 - 1.0 / 6.0;
    s = s * x2 * x + x;
    double c = 1.0 / 479001600.0;
    c = c * x2 - 1.0 / 3628800.0;
    c = c * x2 + 1.0 / 40320.0;
    c = c * x2 - 1.0 / 720.0;
    c = c * x2 + 1.0 / 24.0;
    c = c * x2 - 0.5;
    c = c * x2 + 1.0;
    // Quarter turns, without branches or selects (so the loop vectorises): q = ±1 swaps sin and
    // cos, and the signs follow the quadrant.
    const double aq = std::abs(q);
    const double odd = aq * (2.0 - aq);              // 1 for q = ±1, else 0
    const double half_turn = 0.5 * aq * (aq - 1.0);  // 1 for q = ±2, else 0
    const double sin_sign = 1.0 - 2.0 * half_turn - odd * (1.0 - q);
    const double cos_sign = 1.0 - 2.0 * half_turn - odd * (1.0 + q);
    s_out = sin_sign * (odd * c + (1.0 - odd) * s);
    c_out = cos_sign * (odd * s + (1.0 - odd) * c);
}

// One sample's kernels, in the form of the header: a_k, e_k, p_k, and for the adjoint the texel,
// the window weight c_k w² and the Gaussian's argument v = ω_h + 2S s_k.
struct Gathered {
    std::vector<double> amp, expo, path;
    std::vector<double> window, vx, vy;
    std::vector<std::size_t> texel;
    std::vector<int> row, col;
    double total = 0.0;    // A = Σ |a_k| over every kernel of the footprint
    double skipped = 0.0;  // Σ |a_k| over the pruned ones
    // Per-sample constants.
    double hx = 0.0, hy = 0.0, hz = 0.0, scale = 1.0;
    std::vector<double> c1;  // per wavelength

    std::size_t size() const { return amp.size(); }
};

}  // namespace

void validate_prune_tolerance(double tolerance) {
    if (!(tolerance == 0.0 || (tolerance >= 1e-12 && tolerance <= 1e-1)))
        throw std::domain_error("prune tolerance " + format_shortest(tolerance) +
                                " is out of range; expected 0 (no pruning) or 1e-12 to 0.1");
}

void validate(const PointSample& sample, const Heightfield& heightfield) {
    Query q;
    q.x_um = sample.x_um;
    q.y_um = sample.y_um;
    q.sigma_p_um = sample.sigma_p_um;
    q.omega_i = sample.omega_i;
    validate(q);
    const double ox = sample.omega_o[0], oy = sample.omega_o[1];
    if (!std::isfinite(ox) || !std::isfinite(oy) || ox * ox + oy * oy >= 1.0)
        throw std::domain_error("view direction (" + format_shortest(ox) + ", " + format_shortest(oy) +
                                ") is invalid; expected a projected direction with |omega_o| < 1");
    validate_footprint(sample.sigma_p_um, heightfield.period_x_um(), heightfield.period_y_um());
}

PointEvaluator::PointEvaluator(const Heightfield& heightfield, std::vector<double> lambdas_um,
                               const PointEvalOptions& options)
    : m_heightfield(heightfield),
      m_lambdas(std::move(lambdas_um)),
      m_options(options),
      m_rows(heightfield.rows()),
      m_cols(heightfield.cols()) {
    if (m_lambdas.empty() || m_lambdas.size() > static_cast<std::size_t>(k_max_spectral_samples))
        throw std::invalid_argument("point evaluation got " + std::to_string(m_lambdas.size()) +
                                    " wavelengths; expected 1 to " + std::to_string(k_max_spectral_samples));
    for (double l : m_lambdas) validate_lambda(l);
    validate_prune_tolerance(options.prune_tolerance);
    m_cutoff = options.prune_tolerance > 0.0 ? std::log(3.0 / options.prune_tolerance)
                                             : std::numeric_limits<double>::infinity();
    const std::size_t texels = static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols);
    m_height_um.resize(texels);
    m_slope_x.resize(texels);
    m_slope_y.resize(texels);
    for (int i = 0; i < m_rows; ++i)
        for (int j = 0; j < m_cols; ++j) {
            const std::size_t t = heightfield.index(i, j);
            const auto s = heightfield.slope(i, j);
            m_height_um[t] = heightfield.height_um(i, j);
            m_slope_x[t] = s[0];
            m_slope_y[t] = s[1];
        }
}

namespace {

// The kernels of `sample` (gabor.h's selection, the same order), pruned at exponent `cutoff`
// over λ_max.
void gather(const Heightfield& hf, const std::vector<double>& height, const std::vector<double>& slope_x,
            const std::vector<double>& slope_y, const std::vector<double>& lambdas, Model model, double cutoff,
            const PointSample& sample, bool for_adjoint, Gathered& g) {
    const detail::FootprintOffsets off = detail::footprint_offsets(hf, sample.x_um, sample.y_um, sample.sigma_p_um);
    const DirectionFactors f0 = direction_factors(model, sample.omega_i, sample.omega_o[0], sample.omega_o[1], 1.0);
    g.hx = sample.omega_i[0] + sample.omega_o[0];
    g.hy = sample.omega_i[1] + sample.omega_o[1];
    g.hz = f0.cos_theta_i + f0.cos_theta_o;
    g.scale = f0.phase_scale;
    g.c1.resize(lambdas.size());
    double lambda_max = 0.0;
    for (std::size_t l = 0; l < lambdas.size(); ++l) {
        g.c1[l] = direction_factors(model, sample.omega_i, sample.omega_o[0], sample.omega_o[1], lambdas[l]).c1;
        lambda_max = std::max(lambda_max, lambdas[l]);
    }
    const double limit = cutoff * lambda_max * lambda_max;  // e_k > limit ⇔ e_k / λ_max² > T
    const double gauss = 2.0 * k_pi * k_pi * off.sigma_um * off.sigma_um;
    const double w2 = hf.texel_um() * hf.texel_um();
    const bool kirchhoff = model == Model::Kirchhoff;
    const double two_s = 2.0 * g.scale;
    const std::size_t n = off.size();
    for (auto* v : {&g.amp, &g.expo, &g.path, &g.window, &g.vx, &g.vy}) v->resize(n);
    g.texel.resize(n);
    // Every kernel's numbers in one loop without branches (it vectorises: the window weight
    // through exp_neg, equal to window_weight's std::exp to 3e-13), then the pruned ones removed.
    {
        const int* row = off.row.data();
        const int* col = off.col.data();
        const double* dxs = off.dx_um.data();
        const double* dys = off.dy_um.data();
        const double* hs = height.data();
        const double* sxs = slope_x.data();
        const double* sys = slope_y.data();
        double* amp = g.amp.data();
        double* expo = g.expo.data();
        double* path = g.path.data();
        double* window = g.window.data();
        double* vxs = g.vx.data();
        double* vys = g.vy.data();
        std::size_t* texel = g.texel.data();
        const std::size_t cols = static_cast<std::size_t>(hf.cols());
        const double peak = w2 / (std::sqrt(k_pi) * sample.sigma_p_um);
        const double inv_two_var = 1.0 / (2.0 * sample.sigma_p_um * sample.sigma_p_um);
        const double hx = g.hx, hy = g.hy, hz = g.hz;
        const double kirch = kirchhoff ? 1.0 : 0.0;
#pragma omp simd
        for (std::size_t k = 0; k < n; ++k) {
            const std::size_t t = static_cast<std::size_t>(row[k]) * cols + static_cast<std::size_t>(col[k]);
            const double dx = dxs[k], dy = dys[k];
            const double sx = sxs[t], sy = sys[t];
            const double wk = peak * exp_neg((dx * dx + dy * dy) * inv_two_var);
            const double vx = hx + two_s * sx, vy = hy + two_s * sy;
            texel[k] = t;
            window[k] = wk;
            amp[k] = wk * (1.0 + kirch * (hz - hx * sx - hy * sy - 1.0));
            vxs[k] = vx;
            vys[k] = vy;
            expo[k] = gauss * (vx * vx + vy * vy);
            path[k] = two_s * hs[t] + hx * dx + hy * dy;
        }
    }
    g.total = g.skipped = 0.0;
    for (std::size_t k = 0; k < n; ++k) g.total += std::abs(g.amp[k]);
    if (for_adjoint) {
        g.row.assign(off.row.begin(), off.row.end());
        g.col.assign(off.col.begin(), off.col.end());
    }
    if (std::isfinite(limit)) {
        std::size_t kept = 0;
        for (std::size_t k = 0; k < n; ++k) {
            if (g.expo[k] > limit) {
                g.skipped += std::abs(g.amp[k]);
                continue;
            }
            g.amp[kept] = g.amp[k];
            g.expo[kept] = g.expo[k];
            g.path[kept] = g.path[k];
            if (for_adjoint) {
                g.window[kept] = g.window[k];
                g.vx[kept] = g.vx[k];
                g.vy[kept] = g.vy[k];
                g.texel[kept] = g.texel[k];
                g.row[kept] = g.row[k];
                g.col[kept] = g.col[k];
            }
            ++kept;
        }
        for (auto* v : {&g.amp, &g.expo, &g.path, &g.window, &g.vx, &g.vy}) v->resize(kept);
        g.texel.resize(kept);
        if (for_adjoint) {
            g.row.resize(kept);
            g.col.resize(kept);
        }
    }
}

// I(λ) = Σ_k a_k e^{−e_k/λ²} e^{−i2πp_k/λ}: (re, im).
void field_at(const Gathered& g, double lambda, double& re_out, double& im_out) {
    const double inv = 1.0 / lambda, inv2 = inv * inv;
    const double* amp = g.amp.data();
    const double* expo = g.expo.data();
    const double* path = g.path.data();
    const std::size_t n = g.size();
    double re = 0.0, im = 0.0;
#pragma omp simd reduction(+ : re, im)
    for (std::size_t k = 0; k < n; ++k) {
        const double a = amp[k] * exp_neg(expo[k] * inv2);
        double c, s;
        cis_turns(path[k] * inv, c, s);
        re += a * c;
        im -= a * s;
    }
    re_out = re;
    im_out = im;
}

// Single precision (PointEvalOptions::single_precision): the same sum with the kernels' numbers
// rounded to float and float polynomials (e^{−x}: degree 6, < 2e-7 relative; sin/cos: degrees
// 7/8, < 4e-7), twice the SIMD lanes. The path in turns stays below 2^22 for any footprint
// these tests and images use (p_k/λ: tens to thousands of turns), where float keeps the phase
// to ~1e-4 rad or better.
inline float exp_neg_f(float x) {
    const float y = x < 87.0f ? x : 87.0f;
    const float magic = 12582912.0f;  // 1.5 · 2^23
    const float n = (y * 1.44269504f + magic) - magic;
    const float r = (n * 0.693145752f - y) + n * 1.42860677e-6f;
    float p = 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const float biased = (127.0f - n) + 8388608.0f;  // 2^23 + (127 − n)
    std::uint32_t bits;
    std::memcpy(&bits, &biased, sizeof bits);
    bits <<= 23;
    float scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return x > 87.0f ? 0.0f : p * scale;
}

inline void cis_turns_f(float f, float& c_out, float& s_out) {  // f in [−½, ½]
    const float magic = 12582912.0f;
    const float q = (4.0f * f + magic) - magic;
    const float x = (f - 0.25f * q) * 6.28318531f;
    const float x2 = x * x;
    float s = -1.0f / 5040.0f;
    s = s * x2 + 1.0f / 120.0f;
    s = s * x2 - 1.0f / 6.0f;
    s = s * x2 * x + x;
    float c = 1.0f / 40320.0f;
    c = c * x2 - 1.0f / 720.0f;
    c = c * x2 + 1.0f / 24.0f;
    c = c * x2 - 0.5f;
    c = c * x2 + 1.0f;
    const float aq = std::abs(q);
    const float odd = aq * (2.0f - aq);
    const float half_turn = 0.5f * aq * (aq - 1.0f);
    const float sin_sign = 1.0f - 2.0f * half_turn - odd * (1.0f - q);
    const float cos_sign = 1.0f - 2.0f * half_turn - odd * (1.0f + q);
    s_out = sin_sign * (odd * c + (1.0f - odd) * s);
    c_out = cos_sign * (odd * s + (1.0f - odd) * c);
}

// The kernels' numbers in float, once per sample.
struct GatheredFloat {
    std::vector<float> amp, expo, path;
    void from(const Gathered& g) {
        amp.assign(g.amp.begin(), g.amp.end());
        expo.assign(g.expo.begin(), g.expo.end());
        path.assign(g.path.begin(), g.path.end());
    }
};

void field_at_float(const GatheredFloat& g, double lambda, double& re_out, double& im_out) {
    const float inv = static_cast<float>(1.0 / lambda), inv2 = inv * inv;
    const float* amp = g.amp.data();
    const float* expo = g.expo.data();
    const float* path = g.path.data();
    const std::size_t n = g.amp.size();
    const float magic = 12582912.0f;
    float re = 0.0f, im = 0.0f;
#pragma omp simd reduction(+ : re, im)
    for (std::size_t k = 0; k < n; ++k) {
        const float a = amp[k] * exp_neg_f(expo[k] * inv2);
        const float t = path[k] * inv;
        float c, s;
        cis_turns_f(t - ((t + magic) - magic), c, s);
        re += a * c;
        im -= a * s;
    }
    re_out = double(re);
    im_out = double(im);
}

std::size_t thread_count(std::size_t samples, std::size_t work_per_sample) {
    const long long work = static_cast<long long>(samples) *
                           static_cast<long long>(std::max<std::size_t>(1, work_per_sample));
    return detail::worth_parallel(work) ? static_cast<std::size_t>(omp_get_max_threads()) : 1;
}

}  // namespace

void PointEvaluator::evaluate(const PointSample* samples, std::size_t count, double* values, double* bound) const {
    const std::size_t L = m_lambdas.size();
    const int threads = static_cast<int>(thread_count(count, 256 * L));
    detail::RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        Gathered g;
        GatheredFloat gf;
#pragma omp for schedule(dynamic, 16)
        for (std::size_t s = 0; s < count; ++s)
            guard.run([&] {
                gather(m_heightfield, m_height_um, m_slope_x, m_slope_y, m_lambdas, m_options.model, m_cutoff,
                       samples[s], false, g);
                if (m_options.single_precision) gf.from(g);
                const double eps = std::exp(-m_cutoff) * g.skipped;
                for (std::size_t l = 0; l < L; ++l) {
                    double re, im;
                    if (m_options.single_precision)
                        field_at_float(gf, m_lambdas[l], re, im);
                    else
                        field_at(g, m_lambdas[l], re, im);
                    const double v = g.c1[l] * (re * re + im * im);
                    values[s * L + l] = std::isfinite(v) ? v : 0.0;
                    if (bound) {
                        const double b = g.c1[l] * (2.0 * std::hypot(re, im) + eps) * eps;
                        bound[s * L + l] = std::isfinite(b) ? b : 0.0;
                    }
                }
            });
    }
    guard.rethrow();
}

namespace {

// Calls visit(k, dt/dH_k, dt/ds_kx, dt/ds_ky) for every kernel of `g` at wavelength λ.
template <typename Visit>
void visit_derivatives(const Gathered& g, double lambda, double gauss, bool kirchhoff, Visit&& visit) {
    const double inv = 1.0 / lambda, inv2 = inv * inv;
    const double dphase_dh = 4.0 * k_pi * g.scale * inv;  // t ∝ e^{−i (4π S/λ) H}
    const double dexpo = 4.0 * gauss * g.scale * inv2;    // ∂(e_k/λ²)/∂s = 4 gauss S v / λ²
    for (std::size_t k = 0; k < g.size(); ++k) {
        const double e = exp_neg(g.expo[k] * inv2);
        double c, s;
        cis_turns(g.path[k] * inv, c, s);
        const std::complex<double> cisv(c, -s);
        const std::complex<double> t = g.amp[k] * e * cisv;
        const std::complex<double> dh = std::complex<double>(0.0, -dphase_dh) * t;
        std::complex<double> dsx = (-dexpo * g.vx[k]) * t;
        std::complex<double> dsy = (-dexpo * g.vy[k]) * t;
        if (kirchhoff) {  // a_k = c_k w² (hz − h·s): ∂a/∂s = −c_k w² h
            const std::complex<double> base = g.window[k] * e * cisv;
            dsx -= g.hx * base;
            dsy -= g.hy * base;
        }
        visit(k, dh, dsx, dsy);
    }
}

}  // namespace

void PointEvaluator::adjoint(const PointSample* samples, std::size_t count, const double* weights,
                             std::vector<double>& gradient) const {
    const std::size_t texels = static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols);
    if (gradient.empty()) gradient.assign(texels, 0.0);
    if (gradient.size() != texels)
        throw std::invalid_argument("gradient has " + std::to_string(gradient.size()) +
                                    " values; expected rows*cols = " + std::to_string(texels));
    const std::size_t L = m_lambdas.size();
    const double gauss = 2.0 * k_pi * k_pi * 0.25 * m_heightfield.texel_um() * m_heightfield.texel_um();
    const double v = m_heightfield.vscale(), vw = v * m_heightfield.texel_um();
    const bool kirchhoff = m_options.model == Model::Kirchhoff;
    const int threads = static_cast<int>(thread_count(count, 256 * L));
    std::vector<std::vector<double>> partial(static_cast<std::size_t>(threads));
    detail::RegionGuard guard;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        std::vector<double>& local = partial[static_cast<std::size_t>(omp_get_thread_num())];
        guard.run([&] { local.assign(texels, 0.0); });
        Gathered g;
        std::vector<double> gh, gsx, gsy;
        // Static: each thread always gets the same samples, so the sum is reproducible.
#pragma omp for schedule(static)
        for (std::size_t s = 0; s < count; ++s)
            guard.run([&] {
                bool any = false;
                for (std::size_t l = 0; l < L; ++l) any = any || weights[s * L + l] != 0.0;
                if (!any) return;
                gather(m_heightfield, m_height_um, m_slope_x, m_slope_y, m_lambdas, m_options.model, m_cutoff,
                       samples[s], true, g);
                gh.assign(g.size(), 0.0);
                gsx.assign(g.size(), 0.0);
                gsy.assign(g.size(), 0.0);
                for (std::size_t l = 0; l < L; ++l) {
                    const double wgt = weights[s * L + l];
                    if (wgt == 0.0) continue;
                    double re, im;
                    field_at(g, m_lambdas[l], re, im);
                    if (!std::isfinite(g.c1[l] * (re * re + im * im))) continue;
                    // df = 2 c1 Re(conj(I) dI).
                    const std::complex<double> b = 2.0 * wgt * g.c1[l] * std::complex<double>(re, -im);
                    visit_derivatives(g, m_lambdas[l], gauss, kirchhoff,
                                      [&](std::size_t k, std::complex<double> dh, std::complex<double> dsx,
                                          std::complex<double> dsy) {
                                          gh[k] += std::real(b * dh);
                                          gsx[k] += std::real(b * dsx);
                                          gsy[k] += std::real(b * dsy);
                                      });
                }
                for (std::size_t k = 0; k < g.size(); ++k) {
                    const int i = g.row[k], j = g.col[k];
                    local[g.texel[k]] += vw * gh[k];
                    // s = v (h[i+1] − h[i−1]) / 2 along each axis, periodic.
                    local[m_heightfield.index((i + 1) % m_rows, j)] += 0.5 * v * gsx[k];
                    local[m_heightfield.index((i + m_rows - 1) % m_rows, j)] -= 0.5 * v * gsx[k];
                    local[m_heightfield.index(i, (j + 1) % m_cols)] += 0.5 * v * gsy[k];
                    local[m_heightfield.index(i, (j + m_cols - 1) % m_cols)] -= 0.5 * v * gsy[k];
                }
            });
    }
    guard.rethrow();
    for (const auto& local : partial)
        for (std::size_t t = 0; t < texels; ++t) gradient[t] += local[t];
}

void PointEvaluator::tangent(const PointSample* samples, std::size_t count, const std::vector<double>& direction,
                             double* values) const {
    const std::size_t texels = static_cast<std::size_t>(m_rows) * static_cast<std::size_t>(m_cols);
    if (direction.size() != texels)
        throw std::invalid_argument("tangent direction has " + std::to_string(direction.size()) +
                                    " values; expected rows*cols = " + std::to_string(texels));
    const std::size_t L = m_lambdas.size();
    const double gauss = 2.0 * k_pi * k_pi * 0.25 * m_heightfield.texel_um() * m_heightfield.texel_um();
    const double v = m_heightfield.vscale(), vw = v * m_heightfield.texel_um();
    const bool kirchhoff = m_options.model == Model::Kirchhoff;
    Gathered g;
    for (std::size_t s = 0; s < count; ++s) {
        gather(m_heightfield, m_height_um, m_slope_x, m_slope_y, m_lambdas, m_options.model, m_cutoff, samples[s], true,
               g);
        for (std::size_t l = 0; l < L; ++l) {
            double re, im;
            field_at(g, m_lambdas[l], re, im);
            std::complex<double> d_field = 0.0;
            visit_derivatives(
                g, m_lambdas[l], gauss, kirchhoff,
                [&](std::size_t k, std::complex<double> dh, std::complex<double> dsx, std::complex<double> dsy) {
                    const int i = g.row[k], j = g.col[k];
                    const double dH = vw * direction[g.texel[k]];
                    const double dsx_k = 0.5 * v *
                                         (direction[m_heightfield.index((i + 1) % m_rows, j)] -
                                          direction[m_heightfield.index((i + m_rows - 1) % m_rows, j)]);
                    const double dsy_k = 0.5 * v *
                                         (direction[m_heightfield.index(i, (j + 1) % m_cols)] -
                                          direction[m_heightfield.index(i, (j + m_cols - 1) % m_cols)]);
                    d_field += dh * dH + dsx * dsx_k + dsy * dsy_k;
                });
            const double val = g.c1[l] * (re * re + im * im);
            values[s * L + l] = std::isfinite(val) ? 2.0 * g.c1[l] * std::real(std::complex<double>(re, -im) * d_field)
                                                   : 0.0;
        }
    }
}

}  // namespace wavebrdf
