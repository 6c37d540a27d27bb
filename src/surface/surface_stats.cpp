#include "wavebrdf/surface_stats.h"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "core/fftw_raii.h"
#include "surface/footprint_offsets.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// ISO 25178-3's default threshold for the ACF's decay (Sal, Str).
constexpr double k_acf_threshold = 0.2;
// The grids the spectra accept: the zero-padded ACF needs 4 · rows · cols complex values.
constexpr long long k_max_points = 1LL << 24;

std::size_t at(int i, int j, int cols) {
    return static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j);
}

std::string number(double x) { return format_number(x, "%.4g"); }

void validate(const HeightGrid& g) {
    if (g.rows < 2 || g.cols < 2)
        throw std::invalid_argument("surface of " + std::to_string(g.rows) + "x" + std::to_string(g.cols) +
                                    " points is too small; expected at least 2x2");
    if (static_cast<long long>(g.rows) * g.cols > k_max_points)
        throw std::invalid_argument("surface of " + std::to_string(g.rows) + "x" + std::to_string(g.cols) +
                                    " points is too large for its spectra; expected at most 2^24 points (crop it)");
    if (g.heights_um.size() != static_cast<std::size_t>(g.rows) * static_cast<std::size_t>(g.cols))
        throw std::invalid_argument("surface has " + std::to_string(g.heights_um.size()) + " heights; expected " +
                                    std::to_string(g.rows) + "x" + std::to_string(g.cols));
    if (!(std::isfinite(g.dx_um) && g.dx_um > 0.0 && std::isfinite(g.dy_um) && g.dy_um > 0.0))
        throw std::invalid_argument("surface spacing " + number(g.dx_um) + " x " + number(g.dy_um) +
                                    " um is invalid; expected finite and > 0");
    std::size_t bad = 0;
    for (const double z : g.heights_um) bad += std::isfinite(z) ? 0 : 1;
    if (bad > 0)
        throw std::invalid_argument("surface has " + std::to_string(bad) +
                                    " points that are not measured (NaN) or not finite; expected them filled "
                                    "first (--fill)");
}

// The heights less their mean.
std::vector<double> centred(const HeightGrid& g) {
    double sum = 0.0;
    for (const double z : g.heights_um) sum += z;
    const double mean = sum / static_cast<double>(g.heights_um.size());
    std::vector<double> z(g.heights_um);
    for (double& v : z) v -= mean;
    return z;
}

using detail::fftw_buffer;
using detail::FftwBuffer;
using Plan = detail::FftwPlan;

// |DFT|² of the mean-free heights on the grid itself (periodic), rows × cols, uncentred.
std::vector<double> periodogram(const HeightGrid& g) {
    const std::vector<double> z = centred(g);
    const std::size_t n = z.size();
    FftwBuffer<fftw_complex> data = fftw_buffer<fftw_complex>(n);
    Plan plan;
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        plan.reset(fftw_plan_dft_2d(g.rows, g.cols, data.get(), data.get(), FFTW_FORWARD, FFTW_ESTIMATE));
    }
    if (!plan) throw std::runtime_error("FFTW could not plan a " + std::to_string(g.rows) + "x" +
                                        std::to_string(g.cols) + " transform");
    for (std::size_t k = 0; k < n; ++k) {
        data[k][0] = z[k];
        data[k][1] = 0.0;
    }
    fftw_execute(plan.get());
    std::vector<double> p(n);
    for (std::size_t k = 0; k < n; ++k) p[k] = data[k][0] * data[k][0] + data[k][1] * data[k][1];
    return p;
}

// Signed frequency index of FFT bin k of an n-point transform.
int signed_bin(int k, int n) { return k <= n / 2 ? k : k - n; }

// Bilinear interpolation in a rows × cols array at fractional (i, j), both inside.
double bilinear(const std::vector<double>& a, int rows, int cols, double i, double j) {
    const int i0 = std::clamp(static_cast<int>(std::floor(i)), 0, rows - 2);
    const int j0 = std::clamp(static_cast<int>(std::floor(j)), 0, cols - 2);
    const double fi = i - i0, fj = j - j0;
    return (1 - fi) * ((1 - fj) * a[at(i0, j0, cols)] + fj * a[at(i0, j0 + 1, cols)]) +
           fi * ((1 - fj) * a[at(i0 + 1, j0, cols)] + fj * a[at(i0 + 1, j0 + 1, cols)]);
}

}  // namespace

HeightGrid height_grid(const Heightfield& hf) {
    HeightGrid g;
    g.rows = hf.cols();
    g.cols = hf.rows();
    g.dx_um = g.dy_um = hf.texel_um();
    g.heights_um.resize(hf.values().size());
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) g.heights_um[at(j, i, g.cols)] = hf.height_um(i, j);
    return g;
}

Spectrum2d power_spectrum_2d(const HeightGrid& g) {
    validate(g);
    const std::vector<double> p = periodogram(g);
    Spectrum2d s;
    s.rows = g.rows;
    s.cols = g.cols;
    s.step_x = 2.0 * k_pi / (g.cols * g.dx_um);
    s.step_y = 2.0 * k_pi / (g.rows * g.dy_um);
    s.values.assign(p.size(), 0.0);
    const double scale = g.dx_um * g.dy_um / static_cast<double>(p.size());
    for (int i = 0; i < g.rows; ++i)
        for (int j = 0; j < g.cols; ++j) {
            // Centred: bin (ky, kx) at (rows / 2 + ky, cols / 2 + kx).
            const int ci = (signed_bin(i, g.rows) + g.rows / 2 + g.rows) % g.rows;
            const int cj = (signed_bin(j, g.cols) + g.cols / 2 + g.cols) % g.cols;
            s.values[at(ci, cj, g.cols)] = scale * p[at(i, j, g.cols)];
        }
    return s;
}

RadialProfile radial_power_spectrum(const HeightGrid& g) {
    const Spectrum2d s = power_spectrum_2d(g);
    const double dq = std::max(s.step_x, s.step_y);
    const double q_max = std::min(s.step_x * (g.cols / 2), s.step_y * (g.rows / 2));
    const int bins = std::max(1, static_cast<int>(std::floor(q_max / dq)));
    RadialProfile r;
    std::vector<double> sum_q(static_cast<std::size_t>(bins), 0.0), sum_c(static_cast<std::size_t>(bins), 0.0);
    r.count.assign(static_cast<std::size_t>(bins), 0);
    for (int i = 0; i < g.rows; ++i)
        for (int j = 0; j < g.cols; ++j) {
            const double qy = (i - g.rows / 2) * s.step_y, qx = (j - g.cols / 2) * s.step_x;
            const double q = std::hypot(qx, qy);
            // Bin k holds (k − ½, k + ½] · dq; the zero frequency (the mean, removed) is left out.
            const int k = static_cast<int>(std::floor(q / dq + 0.5));
            if (q == 0.0 || k < 1 || k > bins) continue;
            sum_q[static_cast<std::size_t>(k - 1)] += q;
            sum_c[static_cast<std::size_t>(k - 1)] += s.values[at(i, j, g.cols)];
            ++r.count[static_cast<std::size_t>(k - 1)];
        }
    for (std::size_t k = 0; k < sum_q.size(); ++k) {
        if (r.count[k] == 0) continue;
        r.r.push_back(sum_q[k] / r.count[k]);
        r.value.push_back(sum_c[k] / r.count[k]);
    }
    r.count.erase(std::remove(r.count.begin(), r.count.end(), 0), r.count.end());
    return r;
}

SpectrumComparison compare_spectra(const Heightfield& truth, const Heightfield& estimate) {
    if (truth.rows() != estimate.rows() || truth.cols() != estimate.cols() ||
        !(truth.texel_um() == estimate.texel_um()))
        throw std::invalid_argument("the estimate (" + std::to_string(estimate.rows()) + "x" +
                                    std::to_string(estimate.cols()) + " texels) and the truth (" +
                                    std::to_string(truth.rows()) + "x" + std::to_string(truth.cols()) +
                                    ") differ in size or texel width; expected the same grid");
    const HeightGrid t = height_grid(truth), e = height_grid(estimate);
    HeightGrid d = t;
    for (std::size_t k = 0; k < d.heights_um.size(); ++k) d.heights_um[k] = e.heights_um[k] - t.heights_um[k];
    const RadialProfile pt = radial_power_spectrum(t), pe = radial_power_spectrum(e), pd = radial_power_spectrum(d);
    SpectrumComparison c;
    c.q_per_um = pt.r;
    c.truth_um4 = pt.value;
    c.estimate_um4 = pe.value;
    c.error_um4 = pd.value;
    c.count = pt.count;
    c.resolved_all = true;
    // Bins where both spectra hold only the FFT's rounding (1e-12 of the truth's largest bin and
    // below) count as resolved: their order is the arithmetic's, not the surfaces'.
    const double rounding =
        c.truth_um4.empty() ? 0.0 : 1e-12 * *std::max_element(c.truth_um4.begin(), c.truth_um4.end());
    double error_power = 0.0, truth_power = 0.0;
    for (std::size_t k = 0; k < c.q_per_um.size(); ++k) {
        error_power += c.error_um4[k] * c.count[k];
        truth_power += c.truth_um4[k] * c.count[k];
        if (c.resolved_all && c.error_um4[k] <= c.truth_um4[k] + rounding) {
            c.resolved_q_per_um = c.q_per_um[k];
        } else {
            c.resolved_all = false;
        }
    }
    c.resolved_wavelength_um = c.resolved_q_per_um > 0.0 ? 2.0 * k_pi / c.resolved_q_per_um
                                                         : std::numeric_limits<double>::infinity();
    c.error_power_ratio = truth_power > 0.0 ? error_power / truth_power : std::numeric_limits<double>::infinity();
    return c;
}

Spectrum2d autocorrelation_2d(const HeightGrid& g) {
    validate(g);
    const std::vector<double> z = centred(g);
    // Zero-padded to 2N × 2M: the circular correlation of the padded grid is the linear one for
    // every lag |a| < N, |b| < M, so no point meets one wrapped in from the opposite edge.
    const int pr = 2 * g.rows, pc = 2 * g.cols, half = pc / 2 + 1;
    FftwBuffer<double> real = fftw_buffer<double>(static_cast<std::size_t>(pr) * pc);
    FftwBuffer<fftw_complex> spec = fftw_buffer<fftw_complex>(static_cast<std::size_t>(pr) * half);
    Plan forward, inverse;
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        forward.reset(fftw_plan_dft_r2c_2d(pr, pc, real.get(), spec.get(), FFTW_ESTIMATE));
        inverse.reset(fftw_plan_dft_c2r_2d(pr, pc, spec.get(), real.get(), FFTW_ESTIMATE | FFTW_DESTROY_INPUT));
    }
    if (!forward || !inverse)
        throw std::runtime_error("FFTW could not plan a " + std::to_string(pr) + "x" + std::to_string(pc) +
                                 " transform");
    std::fill(real.get(), real.get() + static_cast<std::size_t>(pr) * pc, 0.0);
    for (int i = 0; i < g.rows; ++i)
        for (int j = 0; j < g.cols; ++j) real[at(i, j, pc)] = z[at(i, j, g.cols)];
    fftw_execute(forward.get());
    const std::size_t n_spec = static_cast<std::size_t>(pr) * half;
    for (std::size_t k = 0; k < n_spec; ++k) {
        spec[k][0] = spec[k][0] * spec[k][0] + spec[k][1] * spec[k][1];
        spec[k][1] = 0.0;
    }
    fftw_execute(inverse.get());  // unnormalised: × pr · pc
    Spectrum2d acf;
    acf.rows = 2 * g.rows - 1;
    acf.cols = 2 * g.cols - 1;
    acf.step_x = g.dx_um;
    acf.step_y = g.dy_um;
    acf.values.assign(static_cast<std::size_t>(acf.rows) * acf.cols, 1.0);
    const double zero = real[0];
    if (!(zero > 0.0)) return acf;  // flat: every lag correlates fully
    for (int a = -(g.rows - 1); a <= g.rows - 1; ++a)
        for (int b = -(g.cols - 1); b <= g.cols - 1; ++b) {
            const double overlap = static_cast<double>(g.rows - std::abs(a)) * (g.cols - std::abs(b));
            const double zero_overlap = static_cast<double>(g.rows) * g.cols;
            const double v = real[at((a + pr) % pr, (b + pc) % pc, pc)];
            acf.values[at(a + g.rows - 1, b + g.cols - 1, acf.cols)] = (v / overlap) / (zero / zero_overlap);
        }
    return acf;
}

RadialProfile radial_autocorrelation(const HeightGrid& g) {
    const Spectrum2d acf = autocorrelation_2d(g);
    const double dr = std::max(g.dx_um, g.dy_um);
    const double r_max = std::min(g.dx_um * ((g.cols - 1) / 2), g.dy_um * ((g.rows - 1) / 2));
    const int bins = static_cast<int>(std::floor(r_max / dr)) + 1;
    std::vector<double> sum_r(static_cast<std::size_t>(bins), 0.0), sum_v(static_cast<std::size_t>(bins), 0.0);
    std::vector<int> count(static_cast<std::size_t>(bins), 0);
    for (int a = -(g.rows - 1); a <= g.rows - 1; ++a)
        for (int b = -(g.cols - 1); b <= g.cols - 1; ++b) {
            const double r = std::hypot(a * g.dy_um, b * g.dx_um);
            const int k = static_cast<int>(std::floor(r / dr + 0.5));
            if (k >= bins) continue;
            sum_r[static_cast<std::size_t>(k)] += r;
            sum_v[static_cast<std::size_t>(k)] += acf.values[at(a + g.rows - 1, b + g.cols - 1, acf.cols)];
            ++count[static_cast<std::size_t>(k)];
        }
    RadialProfile out;
    for (std::size_t k = 0; k < count.size(); ++k) {
        if (count[k] == 0) continue;
        out.r.push_back(sum_r[k] / count[k]);
        out.value.push_back(sum_v[k] / count[k]);
        out.count.push_back(count[k]);
    }
    return out;
}

SurfaceParameters surface_parameters(const HeightGrid& g) {
    validate(g);
    const std::vector<double> z = centred(g);
    const double n = static_cast<double>(z.size());
    SurfaceParameters p;
    double s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, lo = z[0], hi = z[0];
    for (const double v : z) {
        s1 += std::abs(v);
        s2 += v * v;
        s3 += v * v * v;
        s4 += v * v * v * v;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    p.Sa = s1 / n;
    p.Sq = std::sqrt(s2 / n);
    p.Sp = hi;
    p.Sv = -lo;
    p.Sz = hi - lo;
    if (p.Sq > 0.0) {
        p.Ssk = (s3 / n) / (p.Sq * p.Sq * p.Sq);
        p.Sku = (s4 / n) / (p.Sq * p.Sq * p.Sq * p.Sq);
    }

    // Sdq: forward differences over the (rows − 1) × (cols − 1) points that have both, as
    // SurfaceTopography's rms gradient (which this reproduces to its 6 published digits on its
    // x3p example).
    // Sdr: each grid cell split into two triangles, the one at its first corner and the one at
    // the opposite corner; the area of each from the cross product of its two edges.
    const int rows = g.rows, cols = g.cols;
    const double dx = g.dx_um, dy = g.dy_um;
    double g2 = 0.0, area = 0.0;
#pragma omp parallel for reduction(+ : g2, area) schedule(static)
    for (int i = 0; i < rows; ++i) {
        if (i + 1 < rows) {
            for (int j = 0; j + 1 < cols; ++j) {
                const double gx = (z[at(i, j + 1, cols)] - z[at(i, j, cols)]) / dx;
                const double gy = (z[at(i + 1, j, cols)] - z[at(i, j, cols)]) / dy;
                g2 += gx * gx + gy * gy;
            }
            for (int j = 0; j + 1 < cols; ++j) {
                const double z00 = z[at(i, j, cols)], z01 = z[at(i, j + 1, cols)];
                const double z10 = z[at(i + 1, j, cols)], z11 = z[at(i + 1, j + 1, cols)];
                const double a1 = (z01 - z00) * dy, b1 = (z10 - z00) * dx;
                const double a2 = (z11 - z10) * dy, b2 = (z11 - z01) * dx;
                area += 0.5 * (std::sqrt(a1 * a1 + b1 * b1 + dx * dx * dy * dy) +
                               std::sqrt(a2 * a2 + b2 * b2 + dx * dx * dy * dy));
            }
        }
    }
    p.Sdq = std::sqrt(g2 / ((rows - 1.0) * (cols - 1.0)));
    p.Sdr = 100.0 * (area / ((rows - 1.0) * (cols - 1.0) * dx * dy) - 1.0);

    if (!(p.Sq > 0.0)) {
        p.Sal = 0.0;
        p.Str = 1.0;
        p.Std = 0.0;
        return p;
    }

    // Sal, Str: along rays from zero lag every 0.5° over half a turn (the ACF is point
    // symmetric), the first lag where the ACF falls to 0.2, linearly interpolated between
    // steps of a quarter of the finer spacing. A ray is searched out to half the grid's extent,
    // beyond which fewer than half the points overlap and the estimate turns noisy.
    {
        const Spectrum2d acf = autocorrelation_2d(g);
        const double half_x = dx * ((cols - 1) / 2), half_y = dy * ((rows - 1) / 2);
        const double step = 0.25 * std::min(dx, dy);
        const int rays = 360;
        double fastest = 1e300, slowest = 0.0, limit_min = 1e300;
        bool any = false, all = true;
        for (int k = 0; k < rays; ++k) {
            const double theta = k_pi * k / rays;
            const double c = std::cos(theta), s = std::sin(theta);
            double limit = 1e300;
            if (std::abs(c) > 1e-12) limit = std::min(limit, half_x / std::abs(c));
            if (std::abs(s) > 1e-12) limit = std::min(limit, half_y / std::abs(s));
            limit_min = std::min(limit_min, limit);
            double r0 = 0.0, v0 = 1.0, crossing = -1.0;
            for (double r1 = step; r1 <= limit + 1e-12; r1 += step) {
                const double v1 = bilinear(acf.values, acf.rows, acf.cols, rows - 1 + r1 * s / dy,
                                           cols - 1 + r1 * c / dx);
                if (v1 <= k_acf_threshold) {
                    crossing = r0 + (v0 - k_acf_threshold) / (v0 - v1) * (r1 - r0);
                    break;
                }
                r0 = r1;
                v0 = v1;
            }
            if (crossing < 0.0) {
                all = false;
                slowest = std::max(slowest, limit);
            } else {
                any = true;
                fastest = std::min(fastest, crossing);
                slowest = std::max(slowest, crossing);
            }
        }
        p.acf_decayed_everywhere = all;
        p.acf_decayed_somewhere = any;
        p.Sal = any ? fastest : limit_min;
        p.Str = slowest > 0.0 ? std::min(1.0, p.Sal / slowest) : 1.0;
    }

    // Std: the angular power spectrum, the PSD summed over the FFT bins in each 0.5° sector of
    // frequency directions (up to the smaller Nyquist frequency, the mean left out); the lay
    // runs across the direction of its maximum.
    {
        const std::vector<double> pw = periodogram(g);
        const int sectors = 360;
        std::vector<double> angular(static_cast<std::size_t>(sectors), 0.0);
        const double dqx = 1.0 / (cols * dx), dqy = 1.0 / (rows * dy);
        const double q_max = std::min(dqx * (cols / 2), dqy * (rows / 2));
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j) {
                const double qy = signed_bin(i, rows) * dqy, qx = signed_bin(j, cols) * dqx;
                const double q = std::hypot(qx, qy);
                if (q == 0.0 || q > q_max * (1.0 + 1e-12)) continue;
                double phi = std::atan2(qy, qx);
                if (phi < 0.0) phi += k_pi;
                const int sector = static_cast<int>(std::floor(phi / k_pi * sectors + 0.5)) % sectors;
                angular[static_cast<std::size_t>(sector)] += pw[at(i, j, cols)];
            }
        const int best = static_cast<int>(std::max_element(angular.begin(), angular.end()) - angular.begin());
        const double frequency_deg = 180.0 * best / sectors;
        p.Std = std::fmod(frequency_deg + 90.0, 180.0);
    }
    return p;
}

SurfaceParameters surface_parameters(const Heightfield& hf) { return surface_parameters(height_grid(hf)); }

std::vector<std::pair<std::string, double>> parameter_list(const SurfaceParameters& p) {
    return {{"Sq", p.Sq},   {"Ssk", p.Ssk}, {"Sku", p.Sku}, {"Sp", p.Sp},   {"Sv", p.Sv},   {"Sz", p.Sz},
            {"Sa", p.Sa},   {"Sal", p.Sal}, {"Str", p.Str}, {"Std", p.Std}, {"Sdq", p.Sdq}, {"Sdr", p.Sdr}};
}

namespace {

// The check's numbers from the sums over n points (heights already centred), and its warnings.
UnitCheck unit_check(double sum_sq, double slope_sum_sq, double n, double lambda_um) {
    UnitCheck c;
    c.rms_height_um = std::sqrt(sum_sq / n);
    c.rms_slope = std::sqrt(slope_sum_sq / (2.0 * n));
    c.lambda_um = lambda_um;
    c.phase_rms_rad = 4.0 * k_pi * c.rms_height_um / lambda_um;
    const std::string where = " (docs/model.md, \"Where the model holds\")";
    if (c.rms_slope > 1.0) {
        std::string w = "rms slope " + number(c.rms_slope) + " is above 1, outside the model's validity" + where;
        if (c.rms_slope <= 1000.0)
            w += "; if the heights are in nm, divide them by 1000 (rms slope " + number(c.rms_slope / 1000.0) + ")";
        c.warnings.push_back(w);
    }
    if (c.rms_height_um > 1000.0)
        c.warnings.push_back("rms height " + number(c.rms_height_um) +
                             " um is above 1 mm; heights in nm read as um?" + where);
    if (c.rms_height_um > 0.0 && c.rms_height_um < 1e-4)
        c.warnings.push_back("rms height " + number(c.rms_height_um) +
                             " um is below 0.1 nm (the surface reflects as a mirror); heights in m read as um?" +
                             where);
    return c;
}

}  // namespace

UnitCheck check_units(const HeightGrid& g, double lambda_um) {
    // Any heightfield, 1 × 1 included (the differences wrap onto the point itself).
    if (g.rows >= 2 && g.cols >= 2) validate(g);
    const std::vector<double> z = centred(g);
    const int rows = g.rows, cols = g.cols;
    double sq = 0.0, slope_sq = 0.0;
    // Slopes as the model takes them (Heightfield::slope): central differences that wrap.
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            sq += z[at(r, c, cols)] * z[at(r, c, cols)];
            const double sx = (z[at(r, (c + 1) % cols, cols)] - z[at(r, (c + cols - 1) % cols, cols)]) / (2 * g.dx_um);
            const double sy = (z[at((r + 1) % rows, c, cols)] - z[at((r + rows - 1) % rows, c, cols)]) / (2 * g.dy_um);
            slope_sq += sx * sx + sy * sy;
        }
    return unit_check(sq, slope_sq, static_cast<double>(z.size()), lambda_um);
}

UnitCheck check_units_footprint(const Heightfield& hf, double x_um, double y_um, double sigma_p_um,
                                double lambda_um) {
    // Exactly the texels of the footprint's kernels (each once, where a footprint wider than the
    // tile meets a texel twice): what a footprint read leaves of a file (io.h) is all there.
    const detail::FootprintOffsets k = detail::footprint_offsets(hf, x_um, y_um, sigma_p_um);
    const int rows = hf.rows(), cols = hf.cols();
    const double w = hf.texel_um();
    std::vector<char> seen(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols), 0);
    std::vector<std::size_t> texels;
    texels.reserve(k.size());
    for (std::size_t n = 0; n < k.size(); ++n) {
        const std::size_t t = at(k.row[n], k.col[n], cols);
        if (!seen[t]) texels.push_back(t);
        seen[t] = 1;
    }
    double mean = 0.0;
    for (const std::size_t t : texels) mean += hf.height_um(static_cast<int>(t / cols), static_cast<int>(t % cols));
    mean /= static_cast<double>(texels.size());
    double sq = 0.0, slope_sq = 0.0;
    for (const std::size_t t : texels) {
        const int i = static_cast<int>(t / cols), j = static_cast<int>(t % cols);
        const double z = hf.height_um(i, j) - mean;
        sq += z * z;
        const double sx = (hf.height_um((i + 1) % rows, j) - hf.height_um((i + rows - 1) % rows, j)) / (2 * w);
        const double sy = (hf.height_um(i, (j + 1) % cols) - hf.height_um(i, (j + cols - 1) % cols)) / (2 * w);
        slope_sq += sx * sx + sy * sy;
    }
    return unit_check(sq, slope_sq, static_cast<double>(texels.size()), lambda_um);
}

UnitCheck check_units(const Heightfield& hf, double lambda_um) { return check_units(height_grid(hf), lambda_um); }

std::string describe(const UnitCheck& c) {
    return "rms height " + number(c.rms_height_um) + " um, rms slope " + number(c.rms_slope) + ", phase rms " +
           number(c.phase_rms_rad) + " rad at " + number(c.lambda_um) + " um";
}

}  // namespace wavebrdf
