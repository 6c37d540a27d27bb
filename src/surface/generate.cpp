#include "wavebrdf/generate.h"

#include <fftw3.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/fftw_raii.h"
#include "core/random.h"
#include "wavebrdf/constants.h"
#include "core/text.h"

namespace wavebrdf {

namespace {

// Random numbers depend on the seed only (random.h).
using detail::derive_seed;
using detail::fill_standard_normal;
using detail::uniform01;

constexpr int k_max_size = 16384;

// ---------------------------------------------------------------------------------------------
// Validation

void require_finite(double value, const char* name) {
    if (!std::isfinite(value))
        throw std::domain_error(std::string("surface parameter ") + name + " = " + format_shortest(value) +
                                " is not finite; expected a finite value");
}

void require_positive(double value, const char* name) {
    require_finite(value, name);
    if (!(value > 0.0))
        throw std::domain_error(std::string("surface parameter ") + name + " = " + format_shortest(value) +
                                " is invalid; expected a value > 0");
}

void require_non_negative(double value, const char* name) {
    require_finite(value, name);
    if (value < 0.0)
        throw std::domain_error(std::string("surface parameter ") + name + " = " + format_shortest(value) +
                                " is invalid; expected a value >= 0");
}

void require_size(int value, const char* name) {
    if (value < 1 || value > k_max_size)
        throw std::invalid_argument(std::string("surface ") + name + " = " + std::to_string(value) +
                                    " is invalid; expected 1 to " + std::to_string(k_max_size));
}

void validate(const SurfaceParams& p) {
    switch (p.type) {
        case SurfaceType::Flat:
        case SurfaceType::Isotropic:
        case SurfaceType::Brushed:
        case SurfaceType::Scratched:
        case SurfaceType::Grating: break;
        default:
            throw std::invalid_argument("surface type " + std::to_string(static_cast<int>(p.type)) +
                                        " is unknown; expected flat, isotropic, brushed, scratched "
                                        "or grating");
    }
    require_size(p.rows, "rows");
    require_size(p.cols, "cols");
    // Every field is checked whatever the type, so a bad value never hides until the type
    // changes; the defaults are all valid.
    require_positive(p.texel_um, "texel_um");
    require_non_negative(p.rms_height_um, "rms_height_um");
    require_non_negative(p.rms_slope, "rms_slope");
    require_positive(p.correlation_um, "correlation_um");
    require_positive(p.anisotropy, "anisotropy");
    if (p.scratch_count < 0 || p.scratch_count > k_max_scratches)
        throw std::domain_error("surface parameter scratch_count = " + std::to_string(p.scratch_count) +
                                " is invalid; expected a count from 0 to " + std::to_string(k_max_scratches));
    require_non_negative(p.scratch_depth_um, "scratch_depth_um");
    require_positive(p.scratch_width_um, "scratch_width_um");
    require_finite(p.amplitude_um, "amplitude_um");
    require_positive(p.period_um, "period_um");
}

// ---------------------------------------------------------------------------------------------
// FFTW: plans are made and destroyed under detail::fftw_planner_mutex (core/fftw_planner.h).
// FFTW_ESTIMATE plans without timing, hence the same plan (and the same rounding) on every call.
using detail::fftw_buffer;
using detail::FftwBuffer;
using Plan = detail::FftwPlan;

// ---------------------------------------------------------------------------------------------
// Gaussian-correlated noise

// log of the discrete power spectrum of the sampled, periodised Gaussian autocorrelation
// c[m] = exp(−m²/ℓ²) (m, ℓ in texels) at every bin k of an n-point DFT, up to an additive
// constant. The DFT of the periodised sequence is the DTFT of the infinite one at f = k/n:
//   Ĉ(f) = Σ_{m∈ℤ} exp(−m²/ℓ²) cos(2π f m)                  (converges fast for ℓ < 1)
//        = ℓ√π Σ_{q∈ℤ} exp(−π² ℓ² (f + q)²)                  (Poisson summation; fast for ℓ ≥ 1)
// Working with the log keeps the long-correlation case, where Ĉ underflows away from f = 0,
// usable: the caller normalises by the largest value before exponentiating.
std::vector<double> log_gaussian_spectrum(int n, double ell) {
    std::vector<double> log_c(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) {
        // Signed frequency in cycles per texel, in [−½, ½].
        const double f = static_cast<double>(k <= n / 2 ? k : k - n) / n;
        if (ell >= 1.0) {
            // Factor out the q = 0 term (the largest for |f| ≤ ½); the others are relative to it
            // and below e^-40 once q² − |q| > 40/(π²ℓ²) ≤ 4.1, i.e. |q| ≥ 3.
            const double a = k_pi * k_pi * ell * ell;
            double sum = 0.0;
            for (int q = -12; q <= 12; ++q) {
                const double e = a * (q * (2.0 * f + q));  // a·((f+q)² − f²) ≥ 0
                sum += std::exp(-e);
            }
            log_c[static_cast<std::size_t>(k)] = std::log(ell) - a * f * f + std::log(sum);
        } else {
            // exp(−m²/ℓ²) < e^-64 for m ≥ 8 when ℓ < 1; Ĉ ≥ 1 − 2Σ e^{−m²} > 0.2 here.
            double sum = 1.0;
            for (int m = 1; m <= 8; ++m) sum += 2.0 * std::exp(-(m * m) / (ell * ell)) * std::cos(2.0 * k_pi * f * m);
            log_c[static_cast<std::size_t>(k)] = std::log(sum);
        }
    }
    return log_c;
}

// Zero-mean Gaussian random field on a rows × cols periodic grid whose autocorrelation is
// proportional to exp(−Δx²/ℓx² − Δy²/ℓy²) (lengths in texels), with an arbitrary overall scale
// (the caller rescales). White noise is filtered by sqrt(Ĉx(kx) Ĉy(ky)) in the Fourier domain;
// the DC bin is zeroed. All zeros when the grid has no non-DC bin (1×1).
std::vector<double> gaussian_correlated_noise(int rows, int cols, double ell_x, double ell_y, std::uint64_t seed) {
    const std::size_t n_real = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
    std::vector<double> result(n_real, 0.0);
    if (n_real == 1) return result;

    const int half_cols = cols / 2 + 1;
    const std::size_t n_complex = static_cast<std::size_t>(rows) * static_cast<std::size_t>(half_cols);
    FftwBuffer<double> real = fftw_buffer<double>(n_real);
    FftwBuffer<fftw_complex> spectrum = fftw_buffer<fftw_complex>(n_complex);

    Plan forward;
    Plan backward;
    {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        // FFTW_ESTIMATE does not touch the arrays, so planning before filling them is safe.
        forward.reset(fftw_plan_dft_r2c_2d(rows, cols, real.get(), spectrum.get(), FFTW_ESTIMATE));
        backward.reset(
            fftw_plan_dft_c2r_2d(rows, cols, spectrum.get(), real.get(), FFTW_ESTIMATE | FFTW_DESTROY_INPUT));
    }
    if (!forward || !backward) throw std::runtime_error("FFTW could not plan the noise filter");

    std::mt19937_64 rng(seed);
    fill_standard_normal(real.get(), n_real, rng);
    fftw_execute(forward.get());

    // Filter amplitude sqrt(Ĉx Ĉy), normalised so that the largest non-DC bin has amplitude 1
    // (exp of a log difference: no underflow of every bin for very long correlations).
    const std::vector<double> log_x = log_gaussian_spectrum(rows, ell_x);
    const std::vector<double> log_y = log_gaussian_spectrum(cols, ell_y);
    const double neg_inf = -std::numeric_limits<double>::infinity();
    const double y_all = *std::max_element(log_y.begin(), log_y.end());
    const double x_nonzero = rows > 1 ? *std::max_element(log_x.begin() + 1, log_x.end()) : neg_inf;
    const double y_nonzero = cols > 1 ? *std::max_element(log_y.begin() + 1, log_y.end()) : neg_inf;
    const double log_max = std::max(log_x[0] + y_nonzero, x_nonzero + y_all);

    // One exp per bin of the summed logs: splitting it into per-axis factors could overflow
    // one and underflow the other when a correlation is much longer than the tile.
    spectrum[0][0] = 0.0;  // zero mean
    spectrum[0][1] = 0.0;
    for (int i = 0; i < rows; ++i) {
        const double lx = log_x[static_cast<std::size_t>(i)] - log_max;
        fftw_complex* row = spectrum.get() + static_cast<std::size_t>(i) * half_cols;
        for (int j = i == 0 ? 1 : 0; j < half_cols; ++j) {
            const double a = std::exp(0.5 * (lx + log_y[static_cast<std::size_t>(j)]));
            row[j][0] *= a;
            row[j][1] *= a;
        }
    }
    fftw_execute(backward.get());

    // Remove the mean left by rounding (the DC bin is already zero).
    double sum = 0.0;
    for (std::size_t k = 0; k < n_real; ++k) sum += real[k];
    const double mean = sum / static_cast<double>(n_real);
    for (std::size_t k = 0; k < n_real; ++k) result[k] = real[k] - mean;
    return result;
}

// rms of the values (texel units).
double rms_of(const std::vector<double>& values) {
    double sum = 0.0;
    for (const double v : values) sum += v * v;
    return std::sqrt(sum / static_cast<double>(values.size()));
}

// sqrt(mean(s_x² + s_y²) / 2) for periodic central differences of values in texel units.
double rms_slope_of(const std::vector<double>& h, int rows, int cols) {
    const auto at = [&](int i, int j) {
        return h[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)];
    };
    double sum = 0.0;
    for (int i = 0; i < rows; ++i) {
        const int ip = i + 1 == rows ? 0 : i + 1;
        const int im = i == 0 ? rows - 1 : i - 1;
        for (int j = 0; j < cols; ++j) {
            const int jp = j + 1 == cols ? 0 : j + 1;
            const int jm = j == 0 ? cols - 1 : j - 1;
            const double sx = 0.5 * (at(ip, j) - at(im, j));
            const double sy = 0.5 * (at(i, jp) - at(i, jm));
            sum += sx * sx + sy * sy;
        }
    }
    return std::sqrt(sum / (2.0 * static_cast<double>(h.size())));
}

// Gaussian-correlated surface with the realised rms height (or, when rms_slope > 0, rms slope)
// of the request; values in texel units. ell_x_um / ell_y_um along rows / columns.
std::vector<double> correlated_surface(const SurfaceParams& p, double ell_x_um, double ell_y_um, double rms_height_um,
                                       double rms_slope, std::uint64_t seed) {
    std::vector<double> h = gaussian_correlated_noise(p.rows, p.cols, ell_x_um / p.texel_um, ell_y_um / p.texel_um,
                                                      seed);
    const bool by_slope = rms_slope > 0.0;
    const double target = by_slope ? rms_slope : rms_height_um / p.texel_um;
    if (target == 0.0) return std::vector<double>(h.size(), 0.0);
    const double realised = by_slope ? rms_slope_of(h, p.rows, p.cols) : rms_of(h);
    if (!(realised > 0.0) || !std::isfinite(target / realised))
        throw std::invalid_argument("a " + std::to_string(p.rows) + "x" + std::to_string(p.cols) +
                                    " grid admits no zero-mean " + (by_slope ? "slope" : "height") +
                                    " variation, so rms " + (by_slope ? "slope " : "height ") +
                                    format_shortest(by_slope ? rms_slope : rms_height_um) + (by_slope ? "" : " um") +
                                    " cannot be reached; expected a larger grid or a zero rms");
    const double scale = target / realised;
    for (double& v : h) v *= scale;
    return h;
}

// ---------------------------------------------------------------------------------------------
// Scratches

// Sets groove[k] = max(groove[k], exp(−d²/(2σ²))) for one straight scratch: the segment through
// (px, py) with direction (c, s), |c| ≥ |s|, of length `length`, on a periodic rows × cols grid
// (all in texels, x along rows). Walks the unwrapped texels within `reach` of the segment, one
// band per row, and wraps their indices: an unwrapped texel is a torus texel seen against one
// lattice image of the scratch, so the maximum over them is the groove at the periodic distance.
// `transpose` swaps the roles of x and y when writing (for scratches closer to the y axis).
void rasterise_scratch(std::vector<double>& groove, int rows, int cols, double px, double py, double c, double s,
                       double length, double sigma, double reach, bool transpose) {
    assert(std::abs(c) >= std::abs(s));
    const int rows_u = transpose ? cols : rows;  // extent along the dominant axis u
    const int cols_u = transpose ? rows : cols;
    const double half = 0.5 * length;
    const double extent_u = half * std::abs(c) + reach;
    const double band = reach / std::abs(c);  // half-width, along v, of the strip d ≤ reach
    const double slope = s / c;
    const double inv_two_sigma2 = 1.0 / (2.0 * sigma * sigma);
    const long i_lo = static_cast<long>(std::floor(px - extent_u - 0.5));
    const long i_hi = static_cast<long>(std::ceil(px + extent_u - 0.5));
    for (long iu = i_lo; iu <= i_hi; ++iu) {
        const double x = static_cast<double>(iu) + 0.5;
        const double y_line = py + (x - px) * slope;
        const long j_lo = static_cast<long>(std::floor(y_line - band - 0.5));
        const long j_hi = static_cast<long>(std::ceil(y_line + band - 0.5));
        const long i_wrapped = ((iu % rows_u) + rows_u) % rows_u;
        for (long ju = j_lo; ju <= j_hi; ++ju) {
            const double y = static_cast<double>(ju) + 0.5;
            // Distance to the segment: project on the direction, clamp to the ends.
            const double dx = x - px;
            const double dy = y - py;
            const double t = std::clamp(dx * c + dy * s, -half, half);
            const double ex = dx - t * c;
            const double ey = dy - t * s;
            const double d2 = ex * ex + ey * ey;
            if (d2 > reach * reach) continue;
            const long j_wrapped = ((ju % cols_u) + cols_u) % cols_u;
            const long i = transpose ? j_wrapped : i_wrapped;
            const long j = transpose ? i_wrapped : j_wrapped;
            double& g =
                groove[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)];
            g = std::max(g, std::exp(-d2 * inv_two_sigma2));
        }
    }
}

// Normalised groove depth map (0 … 1) of `count` random scratches; lengths in texels.
std::vector<double> scratch_grooves(int rows, int cols, int count, double width, std::uint64_t seed) {
    std::vector<double> groove(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols), 0.0);
    const double sigma = 0.5 * width;
    // exp(−d²/2σ²) < e^-32 beyond 8σ. No point of the torus is farther than half the tile
    // diagonal from the nearest image of a scratch's centre, so a longer reach adds nothing.
    const double reach = std::min(8.0 * sigma, 0.5 * std::hypot(rows, cols) + 1.0);
    std::mt19937_64 rng(seed);
    for (int n = 0; n < count; ++n) {
        const double px = uniform01(rng) * rows;
        const double py = uniform01(rng) * cols;
        const double theta = uniform01(rng) * k_pi;
        const double c = std::cos(theta);
        const double s = std::sin(theta);
        // One period along the dominant axis: closes into a periodic line when the direction
        // is a lattice direction (axis-aligned; diagonal on a square tile).
        const double len_x = std::abs(c) > 0.0 ? rows / std::abs(c) : HUGE_VAL;
        const double len_y = std::abs(s) > 0.0 ? cols / std::abs(s) : HUGE_VAL;
        const double length = std::min(len_x, len_y);
        if (std::abs(c) >= std::abs(s))
            rasterise_scratch(groove, rows, cols, px, py, c, s, length, sigma, reach, false);
        else
            rasterise_scratch(groove, rows, cols, py, px, s, c, length, sigma, reach, true);
    }
    return groove;
}

}  // namespace

constexpr std::pair<SurfaceType, const char*> k_surface_type_names[] = {{SurfaceType::Flat, "flat"},
                                                                        {SurfaceType::Isotropic, "isotropic"},
                                                                        {SurfaceType::Brushed, "brushed"},
                                                                        {SurfaceType::Scratched, "scratched"},
                                                                        {SurfaceType::Grating, "grating"}};

SurfaceType parse_surface_type(const std::string& name) {
    SurfaceType type;
    if (detail::value_named(k_surface_type_names, name, type)) return type;
    throw std::invalid_argument("surface type '" + name +
                                "' is unknown; expected flat, isotropic, brushed, scratched or "
                                "grating");
}

const char* to_string(SurfaceType type) {
    const char* name = detail::name_of(k_surface_type_names, type);
    return name ? name : "unknown";
}

Heightfield generate_heightfield(const SurfaceParams& p) {
    validate(p);
    const std::size_t n = static_cast<std::size_t>(p.rows) * static_cast<std::size_t>(p.cols);
    std::vector<double> h;
    switch (p.type) {
        case SurfaceType::Flat: h.assign(n, 0.0); break;
        case SurfaceType::Isotropic:
            h = correlated_surface(p, p.correlation_um, p.correlation_um, p.rms_height_um, p.rms_slope,
                                   derive_seed(p.seed, 0));
            break;
        case SurfaceType::Brushed:
            h = correlated_surface(p, p.correlation_um, p.anisotropy * p.correlation_um, p.rms_height_um, p.rms_slope,
                                   derive_seed(p.seed, 0));
            break;
        case SurfaceType::Scratched: {
            // Smooth base; a 1×1 grid has none (there is no zero-mean variation to scale).
            const double base_rms_um = 0.1 * p.scratch_depth_um;
            if (n > 1)
                h = correlated_surface(p, 8.0 * p.correlation_um, 8.0 * p.correlation_um, base_rms_um, 0.0,
                                       derive_seed(p.seed, 1));
            else
                h.assign(n, 0.0);
            const std::vector<double> groove = scratch_grooves(p.rows, p.cols, p.scratch_count,
                                                               p.scratch_width_um / p.texel_um, derive_seed(p.seed, 2));
            const double depth = p.scratch_depth_um / p.texel_um;
            for (std::size_t k = 0; k < n; ++k) h[k] -= depth * groove[k];
            break;
        }
        case SurfaceType::Grating: {
            h.resize(n);
            for (int i = 0; i < p.rows; ++i) {
                const double x_um = (i + 0.5) * p.texel_um;
                const double value = p.amplitude_um * std::sin(2.0 * k_pi * x_um / p.period_um) / p.texel_um;
                std::fill_n(h.begin() + static_cast<std::ptrdiff_t>(i) * p.cols, p.cols, value);
            }
            break;
        }
    }
    return Heightfield(p.rows, p.cols, std::move(h), p.texel_um, 1.0);
}

HeightStats height_stats(const Heightfield& hf) {
    const std::vector<double>& values = hf.values();
    const double n = static_cast<double>(values.size());
    const double to_um = hf.vscale() * hf.texel_um();
    double sum = 0.0;
    double lo = values[0];
    double hi = values[0];
    for (const double v : values) {
        sum += v;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    const double mean = sum / n;
    double sum_sq = 0.0;
    for (const double v : values) sum_sq += (v - mean) * (v - mean);
    double slope_sq = 0.0;
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j) {
            const std::array<double, 2> s = hf.slope(i, j);
            slope_sq += s[0] * s[0] + s[1] * s[1];
        }
    HeightStats stats;
    stats.mean_um = to_um * mean;
    stats.rms_height_um = std::abs(to_um) * std::sqrt(sum_sq / n);
    // A negative vscale flips the surface: min and max swap.
    stats.min_um = std::min(to_um * lo, to_um * hi);
    stats.max_um = std::max(to_um * lo, to_um * hi);
    stats.rms_slope = std::sqrt(slope_sq / (2.0 * n));
    return stats;
}

Heightfield with_height_range(const Heightfield& hf, double range_um) {
    if (!(std::isfinite(range_um) && range_um > 0.0))
        throw std::domain_error("height range " + std::to_string(range_um) + " um is invalid; expected > 0");
    const HeightStats stats = height_stats(hf);
    const double now_um = stats.max_um - stats.min_um;
    if (!(now_um > 0.0)) throw std::domain_error("the heightfield is flat; there is no height range to scale");
    const double mean = stats.mean_um / (hf.vscale() * hf.texel_um());
    std::vector<double> v = hf.values();
    for (double& x : v) x = mean + (x - mean) * (range_um / now_um);
    return hf.with_values(std::move(v));
}

std::string describe_surface(const SurfaceParams& p) {
    std::string text = std::string("generate_heightfield type=") + to_string(p.type) +
                       " size=" + std::to_string(p.rows) + "x" + std::to_string(p.cols) +
                       " seed=" + std::to_string(p.seed) + " texel_um=" + format_shortest(p.texel_um);
    const auto add = [&](const char* name, double v) { text += std::string(" ") + name + "=" + format_shortest(v); };
    switch (p.type) {
        case SurfaceType::Flat: break;
        case SurfaceType::Isotropic:
        case SurfaceType::Brushed:
            if (p.rms_slope > 0.0)
                add("rms_slope", p.rms_slope);
            else
                add("rms_height_um", p.rms_height_um);
            add("correlation_um", p.correlation_um);
            if (p.type == SurfaceType::Brushed) add("anisotropy", p.anisotropy);
            break;
        case SurfaceType::Scratched:
            add("scratches", p.scratch_count);
            add("scratch_depth_um", p.scratch_depth_um);
            add("scratch_width_um", p.scratch_width_um);
            break;
        case SurfaceType::Grating:
            add("amplitude_um", p.amplitude_um);
            add("period_um", p.period_um);
            break;
    }
    return text;
}

}  // namespace wavebrdf
