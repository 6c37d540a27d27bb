#include "design/mixture_bound.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "wavebrdf/constants.h"

namespace wavebrdf::detail {

LpResult lp_maximise(const std::vector<double>& c, const std::vector<double>& A, const std::vector<double>& b) {
    const std::size_t n = c.size(), m = b.size();
    if (n == 0 || A.size() != m * n) throw std::invalid_argument("lp_maximise: A is not rows x variables");
    for (double v : b)
        if (!(v >= 0.0)) throw std::invalid_argument("lp_maximise: b has a negative entry; expected x = 0 feasible");
    // Tableau: m constraint rows [A | I | b] and the objective row [−c | 0 | 0]; the slacks start
    // basic. The right-hand sides are raised by tiny distinct amounts (a relaxation: the optimum can
    // only grow, by about their size times the duals), which breaks the degeneracy of the many
    // rows with b = 0, so the largest-coefficient rule cannot cycle.
    const std::size_t cols = n + m + 1;
    std::vector<double> t((m + 1) * cols, 0.0);
    std::vector<std::size_t> basis(m);
    std::uint64_t lcg = 0x9e3779b97f4a7c15ULL;
    for (std::size_t i = 0; i < m; ++i) {
        double norm = 0.0;
        for (std::size_t j = 0; j < n; ++j) norm = std::max(norm, std::abs(t[i * cols + j] = A[i * n + j]));
        t[i * cols + n + i] = 1.0;
        lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;
        const double u = static_cast<double>(lcg >> 11) * 0x1.0p-53;
        t[i * cols + cols - 1] = b[i] + 1e-12 * (1.0 + u) * std::max(norm, 1e-300);
        basis[i] = n + i;
    }
    double scale = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
        t[m * cols + j] = -c[j];
        scale = std::max(scale, std::abs(c[j]));
    }
    const double eps_cost = 1e-13 * std::max(scale, 1e-300), eps_pivot = 1e-10;
    LpResult r;
    const std::size_t limit = 20 * (m + n) + 1000;
    for (std::size_t it = 0;; ++it) {
        if (it >= limit) {
            r.status = LpResult::Status::IterationLimit;
            break;
        }
        // The entering column: the most negative reduced cost.
        std::size_t enter = cols;
        double most = -eps_cost;
        for (std::size_t j = 0; j + 1 < cols; ++j)
            if (t[m * cols + j] < most) {
                most = t[m * cols + j];
                enter = j;
            }
        if (enter == cols) break;
        // The leaving row: the least ratio; among near-ties the largest pivot.
        std::size_t leave = m;
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < m; ++i) {
            const double a = t[i * cols + enter];
            if (a <= eps_pivot) continue;
            const double ratio = std::max(0.0, t[i * cols + cols - 1]) / a;
            if (ratio < best * (1.0 - 1e-12) || (ratio <= best * (1.0 + 1e-12) && leave < m && a > t[leave * cols + enter])) {
                best = std::min(best, ratio);
                leave = i;
            }
        }
        if (leave == m) {
            r.status = LpResult::Status::Unbounded;
            break;
        }
        double* row = &t[leave * cols];
        const double pivot = row[enter];
        for (std::size_t j = 0; j < cols; ++j) row[j] /= pivot;
        for (std::size_t i = 0; i <= m; ++i) {
            if (i == leave) continue;
            double* other = &t[i * cols];
            const double f = other[enter];
            if (f == 0.0) continue;
            for (std::size_t j = 0; j < cols; ++j) other[j] -= f * row[j];
        }
        basis[leave] = enter;
    }
    r.x.assign(n, 0.0);
    for (std::size_t i = 0; i < m; ++i)
        if (basis[i] < n) r.x[basis[i]] = std::max(0.0, t[i * cols + cols - 1]);
    for (std::size_t j = 0; j < n; ++j) r.value += c[j] * r.x[j];
    return r;
}

std::vector<double> mixture_spectrum(const std::vector<double>& shares, const std::vector<double>& nu) {
    std::vector<double> R(nu.size());
    for (std::size_t w = 0; w < nu.size(); ++w) {
        std::complex<double> a = 0.0;
        for (std::size_t l = 0; l < shares.size(); ++l) a += shares[l] * std::polar(1.0, -static_cast<double>(l) * nu[w]);
        R[w] = std::norm(a);
    }
    return R;
}

namespace {

void check(const std::vector<double>& w, const std::vector<double>& nu, int levels) {
    if (w.empty() || w.size() != 3 * nu.size())
        throw std::invalid_argument("mixture bound: xyz weights are not 3 x the " + std::to_string(nu.size()) + " wavelengths");
    if (levels < 1 || levels > 256)
        throw std::invalid_argument("mixture bound: " + std::to_string(levels) + " levels; expected 1 to 256");
    for (double v : nu)
        if (!std::isfinite(v)) throw std::invalid_argument("mixture bound: a phase step is not finite");
}

// The programme's rows in r = (r_0 … r_{K−1}): R_λ(r) = a(ν_λ)·r, a(ν) = (1, 2cos ν, …, 2cos((K−1)ν)).
struct Programme {
    std::size_t K = 0;
    std::vector<double> A, b;
    std::vector<double> y, eu, ev, d;  // Y, the chromaticity rows' parts, X + 15Y + 3Z
    int grid = 0;

    void row(const std::vector<double>& a, double rhs) {
        A.insert(A.end(), a.begin(), a.end());
        b.push_back(rhs);
    }
};

std::vector<double> basis_row(double nu, std::size_t K) {
    std::vector<double> a(K);
    a[0] = 1.0;
    for (std::size_t m = 1; m < K; ++m) a[m] = 2.0 * std::cos(static_cast<double>(m) * nu);
    return a;
}

// The conditions every convex combination of autocorrelations meets, and the colour rows.
Programme base_programme(const std::vector<double>& w, const std::vector<double>& nu, int levels) {
    Programme p;
    p.K = static_cast<std::size_t>(levels);
    const std::size_t K = p.K, W = nu.size();
    std::vector<double> norm(K, 2.0);
    norm[0] = 1.0;
    p.row(norm, 1.0);  // r_0 + 2 Σ r_m ≤ 1 (the optimum of a homogeneous programme meets it)
    // R ≥ 0 on a grid fine for a trigonometric polynomial of degree K − 1, and at the samples.
    p.grid = std::max(128, 8 * levels);
    auto nonnegative = [&](double v) {
        auto a = basis_row(v, K);
        for (double& x : a) x = -x;
        p.row(a, 0.0);
    };
    for (int j = 0; j < p.grid; ++j) nonnegative(k_pi * j / (p.grid - 1));
    for (double v : nu) nonnegative(v);
    for (std::size_t m = 1; m < K; ++m) {  // r_m ≤ r_0 (Cauchy–Schwarz)
        std::vector<double> a(K, 0.0);
        a[0] = -1.0;
        a[m] = 1.0;
        p.row(a, 0.0);
    }
    p.y.assign(K, 0.0);
    p.eu.assign(K, 0.0);
    p.ev.assign(K, 0.0);
    p.d.assign(K, 0.0);
    for (std::size_t l = 0; l < W; ++l) {
        const auto a = basis_row(nu[l], K);
        const double x = w[l], y = w[W + l], z = w[2 * W + l];
        for (std::size_t m = 0; m < K; ++m) {
            p.y[m] += y * a[m];
            p.eu[m] += 4.0 * x * a[m];
            p.ev[m] += 9.0 * y * a[m];
            p.d[m] += (x + 15.0 * y + 3.0 * z) * a[m];
        }
    }
    return p;
}

// max Y with u′v′ = uv exactly (delta = 0) or within the polygon {n_i·(u′v′ − uv) ≤ delta}
// circumscribing the disk of radius delta.
LpResult solve(Programme p, const std::array<double, 2>& uv, double delta) {
    const std::size_t K = p.K;
    std::vector<double> cu(K), cv(K);
    for (std::size_t m = 0; m < K; ++m) {
        cu[m] = p.eu[m] - uv[0] * p.d[m];
        cv[m] = p.ev[m] - uv[1] * p.d[m];
    }
    if (delta == 0.0) {
        for (double s : {1.0, -1.0}) {
            std::vector<double> a(K), e(K);
            for (std::size_t m = 0; m < K; ++m) {
                a[m] = s * cu[m];
                e[m] = s * cv[m];
            }
            p.row(a, 0.0);
            p.row(e, 0.0);
        }
    } else {
        constexpr int k_sides = 32;
        for (int i = 0; i < k_sides; ++i) {
            const double th = 2.0 * k_pi * i / k_sides, nx = std::cos(th), ny = std::sin(th);
            std::vector<double> a(K);
            for (std::size_t m = 0; m < K; ++m) a[m] = nx * cu[m] + ny * cv[m] - delta * p.d[m];
            p.row(a, 0.0);
        }
    }
    return lp_maximise(p.y, p.A, p.b);
}

std::array<double, 2> uv_of(const Programme& p, const std::vector<double>& r) {
    double eu = 0.0, ev = 0.0, d = 0.0;
    for (std::size_t m = 0; m < p.K; ++m) {
        eu += p.eu[m] * r[m];
        ev += p.ev[m] * r[m];
        d += p.d[m] * r[m];
    }
    return d > 0.0 ? std::array<double, 2>{eu / d, ev / d} : std::array<double, 2>{0.0, 0.0};
}

}  // namespace

double mixture_bound_y(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                       const std::array<double, 2>& uv) {
    check(xyz_weights, nu, levels);
    const LpResult r = solve(base_programme(xyz_weights, nu, levels), uv, 0.0);
    if (r.status != LpResult::Status::Optimal) throw std::runtime_error("mixture bound: the simplex did not converge");
    return std::max(0.0, r.value);
}

MixtureBound mixture_bound(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                           const std::array<double, 2>& target_uv, double min_y) {
    check(xyz_weights, nu, levels);
    if (!(min_y >= 0.0 && min_y <= 1.0)) throw std::invalid_argument("mixture bound: min_y is not within 0 to 1");
    const Programme p = base_programme(xyz_weights, nu, levels);
    MixtureBound b;
    b.levels = levels;
    b.grid = p.grid;
    b.min_y = min_y;
    const LpResult at = solve(p, target_uv, 0.0);
    if (at.status != LpResult::Status::Optimal) throw std::runtime_error("mixture bound: the simplex did not converge");
    b.y_at_target = std::max(0.0, at.value);
    b.autocorrelation = at.x;
    b.uv_at_min_y = target_uv;
    if (b.y_at_target >= min_y) return b;
    // The smallest polygon radius whose best Y reaches min_y: monotone in the radius, so bisection;
    // `lo` stays a radius the programme proves short of min_y (a bound), `hi` one it reaches.
    double lo = 0.0, hi = 2.0;
    LpResult reach = solve(p, target_uv, hi);
    if (reach.status != LpResult::Status::Optimal || reach.value < min_y) {
        b.delta_uv_at_min_y = std::numeric_limits<double>::infinity();
        return b;
    }
    for (int i = 0; i < 40 && hi - lo > 1e-6; ++i) {
        const double mid = 0.5 * (lo + hi);
        const LpResult s = solve(p, target_uv, mid);
        if (s.status == LpResult::Status::Optimal && s.value >= min_y) {
            hi = mid;
            reach = s;
        } else {
            lo = mid;
        }
    }
    b.delta_uv_at_min_y = lo;
    b.uv_at_min_y = uv_of(p, reach.x);
    return b;
}

BestMixture best_mixture(const std::vector<double>& xyz_weights, const std::vector<double>& nu, int levels,
                         const std::array<double, 2>& target_uv, double tolerance, double min_y, std::uint64_t seed) {
    check(xyz_weights, nu, levels);
    const std::size_t K = static_cast<std::size_t>(levels), W = nu.size();
    std::vector<std::vector<std::complex<double>>> z(W, std::vector<std::complex<double>>(K));
    for (std::size_t w = 0; w < W; ++w)
        for (std::size_t l = 0; l < K; ++l) z[w][l] = std::polar(1.0, -static_cast<double>(l) * nu[w]);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    BestMixture best;
    bool have = false;
    // Better: Y ≥ min_y before not; then the closer chromaticity (all within tolerance equal);
    // then the larger Y.
    auto better = [&](const BestMixture& a, const BestMixture& c) {
        const bool ya = a.y >= min_y, yc = c.y >= min_y;
        if (ya != yc) return ya;
        const double da = std::max(a.delta_uv, tolerance), dc = std::max(c.delta_uv, tolerance);
        if (std::abs(da - dc) > 1e-12) return da < dc;
        return a.y > c.y;
    };
    constexpr int k_starts = 12, k_steps = 1500;
    for (int start = 0; start < 2 * k_starts; ++start) {
        // Even starts: the brightest near the target chromaticity; odd: the nearest with Y ≥ min_y.
        const bool brightest = start % 2 == 0;
        std::vector<double> theta(K), m1(K, 0.0), m2(K, 0.0), p(K), gp(K);
        for (double& t : theta) t = normal(rng);
        BestMixture cur;
        for (int it = 0; it <= k_steps; ++it) {
            const double mx = *std::max_element(theta.begin(), theta.end());
            double sum = 0.0;
            for (std::size_t l = 0; l < K; ++l) sum += p[l] = std::exp(theta[l] - mx);
            for (double& x : p) x /= sum;
            std::array<double, 3> X{0.0, 0.0, 0.0};
            std::vector<std::complex<double>> amp(W);
            for (std::size_t w = 0; w < W; ++w) {
                for (std::size_t l = 0; l < K; ++l) amp[w] += p[l] * z[w][l];
                const double R = std::norm(amp[w]);
                for (std::size_t c = 0; c < 3; ++c) X[c] += xyz_weights[c * W + w] * R;
            }
            const double d = std::max(X[0] + 15.0 * X[1] + 3.0 * X[2], 1e-15);
            const double u = 4.0 * X[0] / d, v = 9.0 * X[1] / d, du = u - target_uv[0], dv = v - target_uv[1];
            cur.y = X[1];
            cur.uv = {u, v};
            cur.delta_uv = std::hypot(du, dv);
            cur.shares = p;
            if (it == k_steps) break;
            // Loss and ∂/∂XYZ: brightest: (Δu′v′/0.002)² − Y/0.01; nearest: (Δu′v′/0.01)² + 100 (max(0, min_y − Y)/min_y)².
            const double s = brightest ? 1.0 / (0.002 * 0.002) : 1.0 / (0.01 * 0.01);
            std::array<double, 3> g{};
            const std::array<double, 3> dd{1.0, 15.0, 3.0};
            for (std::size_t c = 0; c < 3; ++c) {
                const double du_dx = (c == 0 ? 4.0 / d : 0.0) - u / d * dd[c];
                const double dv_dx = (c == 1 ? 9.0 / d : 0.0) - v / d * dd[c];
                g[c] = s * 2.0 * (du * du_dx + dv * dv_dx);
            }
            if (brightest) {
                g[1] -= 1.0 / 0.01;
            } else if (min_y > 0.0 && X[1] < min_y) {
                g[1] -= 200.0 * (min_y - X[1]) / (min_y * min_y);
            }
            std::fill(gp.begin(), gp.end(), 0.0);
            for (std::size_t w = 0; w < W; ++w) {
                double gR = 0.0;
                for (std::size_t c = 0; c < 3; ++c) gR += g[c] * xyz_weights[c * W + w];
                for (std::size_t l = 0; l < K; ++l) gp[l] += gR * 2.0 * (std::conj(amp[w]) * z[w][l]).real();
            }
            double pg = 0.0;
            for (std::size_t l = 0; l < K; ++l) pg += p[l] * gp[l];
            for (std::size_t l = 0; l < K; ++l) {
                const double gt = p[l] * (gp[l] - pg);
                m1[l] = 0.9 * m1[l] + 0.1 * gt;
                m2[l] = 0.999 * m2[l] + 0.001 * gt * gt;
                theta[l] -= 0.05 * (m1[l] / (1.0 - std::pow(0.9, it + 1))) /
                            (std::sqrt(m2[l] / (1.0 - std::pow(0.999, it + 1))) + 1e-12);
            }
        }
        if (!have || better(cur, best)) {
            best = cur;
            have = true;
        }
    }
    return best;
}

}  // namespace wavebrdf::detail
