// The node layer (c3_nodes.h): Chebyshev interpolation in S = C3/2 of field-engine calls, its
// error bound and its adjoint. Adjoint: with B = W c1 conj(I) (dL = 2 Re Σ B dI), node j's
// cotangents are ℓ_j(S) B (Kirchhoff: × 2S, × (−λu_x), × (−λu_y)); the engine returns
// ∂L/∂w_vk and ∂L/∂b_k, and with w_vk ∝ e^{−i(4π/λ) S_j (H_k − H̄)} and b_k = S_j (2/λ) s_k
//   ∂L/∂H_k  += Σ_v 2 Re[G_vk · (−i(4π/λ) S_j) w_vk]
//   ∂L/∂s_kx += ∂L/∂b_kx · S_j (2/λ)  (+ Kirchhoff: 2 Re[G_xk · w_0k], w_x = w_0 s_x).
// H̄ is held fixed: |I|² does not depend on it.
#include "forward/c3_nodes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>

#include "wavebrdf/brdf.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/interrupt.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"

namespace wavebrdf::detail {

namespace {

// The bounds are taken on a log-spaced grid of ρ − 1 (1e-3 … 1e4, ten points a decade): they
// hold at every ρ, and their minimum is broad, so the grid loses little.
constexpr int k_rho_points = 71;
double rho_at(int i) { return 1.0 + std::pow(10.0, -3.0 + i / 10.0); }

// log Σ_c w_c exp(α_c ε + β_c ε²) at each grid ρ (−∞ for an empty or zero sum): the part of
// both bounds that does not depend on the node count, computed once per slice.
std::vector<double> cell_log_sums(const C3BoundCells& cells) {
    std::vector<double> out(k_rho_points, -std::numeric_limits<double>::infinity());
    for (int i = 0; i < k_rho_points; ++i) {
        const double rho = rho_at(i);
        const double eps = 0.5 * (rho - 1.0 / rho);
        double sum = 0.0, top = -std::numeric_limits<double>::infinity();
        for (std::size_t c = 0; c < cells.weight.size(); ++c)
            top = std::max(top, cells.alpha[c] * eps + cells.beta[c] * eps * eps);
        for (std::size_t c = 0; c < cells.weight.size(); ++c)
            sum += cells.weight[c] * std::exp(cells.alpha[c] * eps + cells.beta[c] * eps * eps - top);
        if (sum > 0.0) out[std::size_t(i)] = top + std::log(sum);
    }
    return out;
}

// Thm 8.2 of Trefethen's ATAP: 4 M ρ^{−(nodes−1)}/(ρ − 1), minimised over the grid.
double uniform_bound(int nodes, const std::vector<double>& log_sums) {
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < k_rho_points; ++i) {
        const double rho = rho_at(i);
        best = std::min(
            best, std::log(4.0) - double(nodes - 1) * std::log(rho) - std::log(rho - 1.0) + log_sums[std::size_t(i)]);
    }
    return std::exp(best);
}

// Hermite's formula f(x) − p(x) = (1/2πi) ∮ ℓ(x) f(z) / (ℓ(z) (z − x)) dz on E_ρ, with the node
// polynomial of the second-kind points ℓ(x) ∝ (x² − 1) U_{n−1}(x), n = nodes − 1; at
// z = (w + 1/w)/2, |w| = ρ: |(z² − 1) U_{n−1}(z)| = |w − 1/w| |w^n − w^{−n}| / 4 ≥ (ρ − 1/ρ)(ρ^n − ρ^{−n})/4,
// the perimeter is at most 2πa and the distance to [−1, 1] at least a − 1, a = (ρ + 1/ρ)/2.
double hermite_bound(int nodes, const std::vector<double>& log_sums) {
    const int n = nodes - 1;
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < k_rho_points; ++i) {
        const double rho = rho_at(i);
        const double log_rn = double(n) * std::log(rho) + std::log1p(-std::pow(rho, -2.0 * n));
        best = std::min(best, std::log(0.5 * (rho + 1.0 / rho)) + std::log(4.0) - std::log(rho - 1.0 / rho) - log_rn +
                                  std::log(2.0 * rho) - 2.0 * std::log(rho - 1.0) + log_sums[std::size_t(i)]);
    }
    return std::exp(best);
}

}  // namespace

double chebyshev_error_bound(int nodes, const C3BoundCells& cells) {
    return uniform_bound(nodes, cell_log_sums(cells));
}

double chebyshev_hermite_bound(int nodes, const C3BoundCells& cells) {
    return hermite_bound(nodes, cell_log_sums(cells));
}

double chebyshev_node_factor(int nodes, double t) {
    const double theta = std::acos(std::clamp(t, -1.0, 1.0));
    return std::min(1.0, std::abs(std::sin(theta) * std::sin(double(nodes - 1) * theta)));
}

double chebyshev_error_factor(int nodes, double alpha, double beta) {
    return chebyshev_error_bound(nodes, C3BoundCells{{1.0}, {alpha}, {beta}});
}

int chebyshev_node_count(const C3BoundCells& cells, double target_error) {
    const std::vector<double> log_sums = cell_log_sums(cells);
    for (int m = 2; m <= k_max_c3_nodes; ++m)
        if (uniform_bound(m, log_sums) <= target_error) return m;
    return k_max_c3_nodes + 1;
}

int chebyshev_node_count(double alpha, double beta, double weight_sum, double target_error) {
    return chebyshev_node_count(C3BoundCells{{weight_sum}, {alpha}, {beta}}, target_error);
}

template <typename Float>
std::shared_ptr<const typename C3Nodes<Float>::PixelFactors> C3Nodes<Float>::pixel_factors(const Query& query,
                                                                                           double lambda_um, int n) {
    // The cache holds weak references: an entry lives as long as some plan uses it.
    struct Entry {
        Model model;
        std::array<double, 2> omega_i;
        double lambda_um;
        int n;
        std::weak_ptr<const PixelFactors> factors;
    };
    static std::mutex mutex;
    static std::vector<Entry> cache;
    const auto find = [&]() -> std::shared_ptr<const PixelFactors> {
        for (const Entry& e : cache)
            if (e.model == query.model && e.omega_i == query.omega_i && e.lambda_um == lambda_um && e.n == n)
                if (auto f = e.factors.lock()) return f;
        return nullptr;
    };
    {
        const std::lock_guard<std::mutex> lock(mutex);
        if (auto f = find()) return f;
    }
    auto made = std::make_shared<PixelFactors>();
    PixelFactors& f = *made;
    const bool scaled = !is_separable(query.model);
    const std::size_t pixels = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    allocating("the " + std::to_string(n) + "x" + std::to_string(n) + " slice's per-pixel factors",
               (scaled ? 16.0 : 8.0) * double(pixels), [&] {
                   f.c1.assign(pixels, 0.0);
                   if (scaled) f.s.assign(pixels, 0.0);
               });
    // Rows in parallel (a 1024² slice has a million pixels, each two square roots).
    double s_lo = std::numeric_limits<double>::infinity();
    double s_hi = -std::numeric_limits<double>::infinity();
#pragma omp parallel for schedule(static) reduction(min     \
                                                    : s_lo) \
    reduction(max                                           \
              : s_hi) if (worth_parallel(static_cast <long long>(n) * n))
    for (int p = 0; p < n; ++p)
        for (const auto [q, ox, oy] : disk_row(p, n)) {
            const DirectionFactors d = direction_factors(query.model, query.omega_i, ox, oy, lambda_um);
            const std::size_t at = static_cast<std::size_t>(p) * n + q;
            f.c1[at] = d.c1;
            if (!scaled) continue;
            f.s[at] = d.phase_scale;
            s_lo = std::min(s_lo, d.phase_scale);
            s_hi = std::max(s_hi, d.phase_scale);
        }
    f.s_lo = s_lo;
    f.s_hi = s_hi;
    if (!scaled || !(f.s_lo <= f.s_hi)) f.s_lo = f.s_hi = 1.0;
    const std::lock_guard<std::mutex> lock(mutex);
    if (auto other = find()) return other;  // made by another thread meanwhile (the same values)
    cache.erase(std::remove_if(cache.begin(), cache.end(), [](const Entry& e) { return e.factors.expired(); }),
                cache.end());
    cache.push_back(Entry{query.model, query.omega_i, lambda_um, n, made});
    return made;
}

template <typename Float>
C3Nodes<Float>::C3Nodes(const Query& query, const SliceGrid& grid, double lambda_um, int n, double tolerance)
    : m_query(query),
      m_grid(grid),
      m_lambda_um(lambda_um),
      m_n(n),
      m_tolerance(tolerance),
      m_scaled(!is_separable(query.model)),
      m_kirchhoff(query.model == Model::Kirchhoff),
      m_pixels(pixel_factors(query, lambda_um, n)),
      m_c1(m_pixels->c1),
      m_s(m_pixels->s),
      m_s_lo(m_pixels->s_lo),
      m_s_hi(m_pixels->s_hi) {}

template <typename Float>
KernelWeights C3Nodes<Float>::node_weights(const FootprintKernels& k, double s) const {
    const double kappa = 4.0 * k_pi / m_lambda_um;
    KernelWeights w(m_kirchhoff ? 3 : 1, std::vector<std::complex<double>>(k.size()));
    for (std::size_t i = 0; i < k.size(); ++i) {
        w[0][i] = std::polar(k.weight[i], -kappa * s * (k.height_um[i] - m_h_ref));
        if (!m_kirchhoff) continue;
        w[1][i] = w[0][i] * k.slope_x[i];
        w[2][i] = w[0][i] * k.slope_y[i];
    }
    return w;
}

template <typename Float>
void C3Nodes<Float>::lagrange(std::size_t at, double* ell) const {
    const std::size_t m = m_node_t.size();
    if (m == 1) {
        ell[0] = 1.0;
        return;
    }
    const double r = 0.5 * (m_s_hi - m_s_lo);
    const double t = (m_s[at] - 0.5 * (m_s_hi + m_s_lo)) / r;
    double sum = 0.0;
    for (std::size_t j = 0; j < m; ++j) {
        const double d = t - m_node_t[j];
        if (d == 0.0) {
            std::fill(ell, ell + m, 0.0);
            ell[j] = 1.0;
            return;
        }
        ell[j] = m_bary[j] / d;
        sum += ell[j];
    }
    for (std::size_t j = 0; j < m; ++j) ell[j] /= sum;
}

template <typename Float>
void C3Nodes<Float>::compute_field(FieldEngine<Float>& engine, const FootprintKernels& kernels,
                                   ComplexMatrix<Float>& field, Progress* progress, bool report,
                                   const std::vector<ComplexMatrix<Float>>* middle) {
    using Complex = std::complex<Float>;
    const int n = m_n;
    const std::size_t m = m_node_s.size();
    std::vector<ComplexMatrix<Float>> fields;
    const long long units = work_units(n);
    long long reported = 0;
    if (!m_scaled) {
        engine.forward(node_weights(kernels, 1.0), 1.0, fields);
        field = std::move(fields[0]);
        if (progress) progress->advance(report ? units : 0);
        return;
    }
    field.setZero(n, n);
    for (std::size_t j = 0; j < m; ++j) {
        check_interrupt();  // between nodes (the engines' own loops do not poll)
        const bool reuse = middle && 2 * j + 1 == m;
        if (!reuse) engine.forward(node_weights(kernels, m_node_s[j]), m_node_s[j], fields);
        const std::vector<ComplexMatrix<Float>>& node = reuse ? *middle : fields;
        RegionGuard guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n * (long long)m))
        for (int p = 0; p < n; ++p)
            guard.run([&] {
                std::vector<double> ell(m);
                const double hx = m_lambda_um * m_grid.ux[static_cast<std::size_t>(p)];
                for (const auto [q, ox, oy] : disk_row(p, n)) {
                    const std::size_t at = static_cast<std::size_t>(p) * n + q;
                    lagrange(at, ell.data());
                    if (ell[j] == 0.0) continue;
                    std::complex<double> value = std::complex<double>(node[0](p, q));
                    if (m_kirchhoff) {
                        const double hy = m_lambda_um * m_grid.uy[static_cast<std::size_t>(q)];
                        value = 2.0 * m_s[at] * value - hx * std::complex<double>(node[1](p, q)) -
                                hy * std::complex<double>(node[2](p, q));
                    }
                    field(p, q) += Complex(ell[j] * value);
                }
            });
        guard.rethrow();
        if (progress) {
            const long long target = report ? units * static_cast<long long>(j + 1) / static_cast<long long>(m) : 0;
            progress->advance(target - reported);
            reported = target;
        }
    }
}

template <typename Float>
double C3Nodes<Float>::pixel_error(int m, const std::vector<double>& log_sums, const std::vector<double>& amp) const {
    // E_pq = min(uniform bound, |ℓ(t_pq)| × Hermite bound): small near the nodes, in particular
    // at the ends of the S range (normal light's specular peak sits at S = 1, a node). A pixel
    // whose uniform bound cannot raise the maximum skips the node factor.
    const double uniform = uniform_bound(m, log_sums), hermite = hermite_bound(m, log_sums);
    const double r = 0.5 * (m_s_hi - m_s_lo), s_mid = 0.5 * (m_s_hi + m_s_lo);
    double worst = 0.0;
    for (int p = 0; p < m_n; ++p)
        for (const auto [q, ox, oy] : disk_row(p, m_n)) {
            const std::size_t at = static_cast<std::size_t>(p) * m_n + q;
            if (!(m_c1[at] * uniform * (2.0 * amp[at] + uniform) > worst)) continue;
            const double e = std::min(uniform, hermite * chebyshev_node_factor(m, (m_s[at] - s_mid) / r));
            worst = std::max(worst, m_c1[at] * e * (2.0 * amp[at] + e));
        }
    return worst;
}

template <typename Float>
std::vector<Float> C3Nodes<Float>::forward(FieldEngine<Float>& engine, const FootprintKernels& k,
                                           ComplexMatrix<Float>& field, Progress* progress) {
    const int n = m_n;
    m_error = 0.0;
    if (!m_scaled) {
        m_node_t = {0.0};
        m_node_s = {1.0};
        m_bary = {1.0};
        m_h_ref = 0.0;
        compute_field(engine, k, field, progress, true, nullptr);
        return separable_slice<Float>(field, m_query, m_lambda_um, n, &m_c1);
    }
    // The bound's constants (c3_nodes.h), per kernel, gathered into cells of |H_k − H̄| and
    // |a_k|² (each kernel counted at its cell's upper edges, so the sum stays a bound).
    double h_lo = std::numeric_limits<double>::infinity(), h_hi = -h_lo, a2_max = 0.0, w_sq = 0.0;
    double hx_max = 0.0, hy_max = 0.0;
    for (std::size_t p = 0; p < m_grid.ux.size(); ++p) {
        hx_max = std::max(hx_max, std::abs(m_lambda_um * m_grid.ux[p]));
        hy_max = std::max(hy_max, std::abs(m_lambda_um * m_grid.uy[p]));
    }
    const double two_over_lambda = 2.0 / m_lambda_um;
    auto a2_of = [&](std::size_t i) {
        return two_over_lambda * two_over_lambda * (k.slope_x[i] * k.slope_x[i] + k.slope_y[i] * k.slope_y[i]);
    };
    for (std::size_t i = 0; i < k.size(); ++i) {
        h_lo = std::min(h_lo, k.height_um[i]);
        h_hi = std::max(h_hi, k.height_um[i]);
        a2_max = std::max(a2_max, a2_of(i));
        w_sq += k.weight[i] * k.weight[i];
    }
    m_h_ref = k.size() ? 0.5 * (h_lo + h_hi) : 0.0;
    const double r = 0.5 * (m_s_hi - m_s_lo);
    const double dh_max = k.size() ? 0.5 * (h_hi - h_lo) : 0.0;
    const double kappa_r = 4.0 * k_pi / m_lambda_um * r;
    const double gauss_r2 = 2.0 * k_pi * k_pi * k.sigma_um * k.sigma_um * r * r;
    constexpr int kHeightCells = 32, kSlopeCells = 8;
    C3BoundCells cells;
    {
        std::vector<double> weight(kHeightCells * kSlopeCells, 0.0);
        for (std::size_t i = 0; i < k.size(); ++i) {
            const double dh = std::abs(k.height_um[i] - m_h_ref);
            const int hc = dh_max > 0.0 ? std::min(kHeightCells - 1, int(dh / dh_max * kHeightCells)) : 0;
            const int sc = a2_max > 0.0 ? std::min(kSlopeCells - 1, int(a2_of(i) / a2_max * kSlopeCells)) : 0;
            const double c2 = m_kirchhoff
                                  ? 2.0 * m_s_hi + hx_max * std::abs(k.slope_x[i]) + hy_max * std::abs(k.slope_y[i])
                                  : 1.0;
            weight[std::size_t(hc * kSlopeCells + sc)] += std::abs(k.weight[i]) * c2;
        }
        for (int hc = 0; hc < kHeightCells; ++hc)
            for (int sc = 0; sc < kSlopeCells; ++sc) {
                const double w = weight[std::size_t(hc * kSlopeCells + sc)];
                if (w == 0.0) continue;
                cells.weight.push_back(w);
                cells.alpha.push_back(kappa_r * dh_max * (hc + 1) / kHeightCells);
                cells.beta.push_back(gauss_r2 * a2_max * (sc + 1) / kSlopeCells);
            }
    }
    const std::vector<double> log_sums = cell_log_sums(cells);
    // A priori: the field at the middle node S_c estimates the slice's peak and |I| per pixel
    // (the node count below).
    const double s_mid = 0.5 * (m_s_lo + m_s_hi);
    int m = 1;
    std::vector<ComplexMatrix<Float>> middle;
    if (r > 0.0) {
        engine.forward(node_weights(k, s_mid), s_mid, middle);
        double peak = 0.0;
        std::vector<double> amp(static_cast<std::size_t>(n) * n, 0.0);
        for (int p = 0; p < n; ++p)
            for (const auto [q, ox, oy] : disk_row(p, n)) {
                const std::size_t at = static_cast<std::size_t>(p) * n + q;
                std::complex<double> value = std::complex<double>(middle[0](p, q));
                if (m_kirchhoff)
                    value = 2.0 * m_s[at] * value -
                            m_lambda_um * m_grid.ux[std::size_t(p)] * std::complex<double>(middle[1](p, q)) -
                            m_lambda_um * m_grid.uy[std::size_t(q)] * std::complex<double>(middle[2](p, q));
                amp[at] = std::abs(value);
                peak = std::max(peak, m_c1[at] * amp[at] * amp[at]);
            }
        // The fewest (odd, so the middle node is one of them and is not computed again) nodes
        // whose per-pixel bound keeps c1 E (2|I| + E) within a quarter of tolerance × peak with
        // the middle node's |I| and peak; no estimate (an all-dark middle node): the field bound
        // against a quarter of the tolerance times the incoherent level √Σ|c_k w²|².
        m = k_max_c3_nodes + 1;
        for (int mm = 3; mm <= k_max_c3_nodes; mm += 2) {
            if (!(peak > 0.0)) {
                if (uniform_bound(mm, log_sums) <= 0.25 * m_tolerance * std::sqrt(w_sq)) {
                    m = mm;
                    break;
                }
                continue;
            }
            if (pixel_error(mm, log_sums, amp) <= 0.25 * m_tolerance * peak) {
                m = mm;
                break;
            }
        }
    }
    bool report = true;
    while (true) {
        if (m > k_max_c3_nodes) {
            m_node_s.clear();
            m_node_t.clear();
            m_bary.clear();
            return {};
        }
        m_node_t.assign(static_cast<std::size_t>(m), 0.0);
        m_bary.assign(static_cast<std::size_t>(m), 1.0);
        m_node_s.assign(static_cast<std::size_t>(m), s_mid);
        for (int j = 0; j < m && m > 1; ++j) {
            // Exactly 0 in the middle (odd m): the middle node's field is reused.
            m_node_t[static_cast<std::size_t>(j)] = 2 * j == m - 1 ? 0.0 : std::cos(k_pi * j / (m - 1));
            m_node_s[static_cast<std::size_t>(j)] = s_mid + r * m_node_t[static_cast<std::size_t>(j)];
            m_bary[static_cast<std::size_t>(j)] = (j % 2 ? -1.0 : 1.0) * (j == 0 || j == m - 1 ? 0.5 : 1.0);
        }
        m_error = m > 1 ? uniform_bound(m, log_sums) : 0.0;
        compute_field(engine, k, field, progress, report, m % 2 == 1 && !middle.empty() ? &middle : nullptr);
        report = false;
        std::vector<Float> slice = separable_slice<Float>(field, m_query, m_lambda_um, n, &m_c1);
        if (m_error == 0.0) return slice;
        // A posteriori: |Δf| ≤ c1 E_pq (2|I| + E_pq) = D at every pixel (E_pq the pointwise
        // bound); accept when D ≤ tol (peak − D).
        double peak = 0.0;
        std::vector<double> amp(static_cast<std::size_t>(n) * n, 0.0);
        for (int p = 0; p < n; ++p)
            for (const auto [q, ox, oy] : disk_row(p, n)) {
                const std::size_t at = static_cast<std::size_t>(p) * n + q;
                peak = std::max(peak, double(slice[at]));
                amp[at] = std::abs(std::complex<double>(field(p, q)));
            }
        const double worst = pixel_error(m, log_sums, amp);
        if (worst * (1.0 + m_tolerance) <= m_tolerance * peak) return slice;
        const double target = peak > 0.0 ? 0.5 * m_error * m_tolerance * peak / (worst * (1.0 + m_tolerance)) : 0.0;
        m = std::max(m + 2, chebyshev_node_count(cells, target));
        if (m % 2 == 0) ++m;
    }
}

template <typename Float>
KernelGradient C3Nodes<Float>::adjoint(FieldEngine<Float>& engine, const FootprintKernels& k,
                                       const ComplexMatrix<Float>& field, const std::vector<Float>& weights) const {
    using Complex = std::complex<Float>;
    const int n = m_n;
    const std::size_t m = m_node_s.size();
    // c1 is 0 outside the disk (pixel_factors), so every pixel takes the same formula: one
    // branch-free pass (columns outer: the matrix's order).
    ComplexMatrix<Float> b(n, n);
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n))
    for (int q = 0; q < n; ++q)
        for (int p = 0; p < n; ++p) {
            const std::size_t at = static_cast<std::size_t>(p) * n + q;
            const double scale = double(weights[at]) * m_c1[at];
            // The forward wrote non-finite pixels as 0: they carry no gradient.
            b(p, q) = std::isfinite(scale * double(std::norm(field(p, q))))
                          ? Complex(Float(scale)) * std::conj(field(p, q))
                          : Complex(0);
        }

    KernelGradient g;
    g.height.assign(k.size(), 0.0);
    g.slope_x.assign(k.size(), 0.0);
    g.slope_y.assign(k.size(), 0.0);
    g.log_weight.assign(k.size(), 0.0);
    const double kappa = 4.0 * k_pi / m_lambda_um;
    std::vector<ComplexMatrix<Float>> cot(m_kirchhoff ? 3 : 1);
    FieldGradient fg;
    for (std::size_t j = 0; j < m; ++j) {
        const double s_j = m_node_s[j];
        if (m == 1 && !m_kirchhoff) {
            cot[0] = std::move(b);  // used once (one node)
        } else {
            for (ComplexMatrix<Float>& c : cot) c.setZero(n, n);
            RegionGuard guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(n) * n * (long long)m))
            for (int p = 0; p < n; ++p)
                guard.run([&] {
                    std::vector<double> ell(m);
                    const double hx = m_lambda_um * m_grid.ux[static_cast<std::size_t>(p)];
                    for (const auto [q, ox, oy] : disk_row(p, n)) {
                        const std::size_t at = static_cast<std::size_t>(p) * n + q;
                        lagrange(at, ell.data());
                        const std::complex<double> lb = ell[j] * std::complex<double>(b(p, q));
                        if (!m_kirchhoff) {
                            cot[0](p, q) = Complex(lb);
                            continue;
                        }
                        const double hy = m_lambda_um * m_grid.uy[static_cast<std::size_t>(q)];
                        cot[0](p, q) = Complex(2.0 * m_s[at] * lb);
                        cot[1](p, q) = Complex(-hx * lb);
                        cot[2](p, q) = Complex(-hy * lb);
                    }
                });
            guard.rethrow();
        }
        const KernelWeights w = node_weights(k, s_j);
        engine.adjoint(w, s_j, cot, fg);
        const std::complex<double> dphase(0.0, -kappa * s_j);
        const double dshift = s_j * 2.0 / m_lambda_um;
        for (std::size_t i = 0; i < k.size(); ++i) {
            std::complex<double> dh = 0.0;
            for (std::size_t v = 0; v < w.size(); ++v) dh += fg.weight[v][i] * w[v][i];
            g.height[i] += 2.0 * std::real(dphase * dh);
            g.log_weight[i] += 2.0 * std::real(dh);  // every weight vector is linear in c_k
            g.slope_x[i] += fg.shift_x[i] * dshift;
            g.slope_y[i] += fg.shift_y[i] * dshift;
            if (m_kirchhoff) {
                g.slope_x[i] += 2.0 * std::real(fg.weight[1][i] * w[0][i]);
                g.slope_y[i] += 2.0 * std::real(fg.weight[2][i] * w[0][i]);
            }
        }
    }
    return g;
}

template class C3Nodes<float>;
template class C3Nodes<double>;

}  // namespace wavebrdf::detail
