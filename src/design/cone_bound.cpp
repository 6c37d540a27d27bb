#include "design/cone_bound.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "core/cholesky.h"
#include "design/engine.h"
#include "wavebrdf/constants.h"

namespace wavebrdf::detail {

namespace {

// The dual programme: every matrix constraint is T(v_k(z)) ⪰ 0 with v_k affine in z,
// T(v)_ii = v_0, T(v)_ij = v_|i−j| / 2.
struct Dual {
    std::size_t K = 0, n = 0;
    std::vector<std::vector<double>> base;  // per constraint: K
    std::vector<std::vector<double>> jac;   // per constraint: K × n, row-major
    std::vector<std::size_t> positive;      // variables that must stay > 0
    std::vector<std::size_t> capped;        // variables that must stay within ±cap
    double cap = 0.0;
    std::vector<double> objective;          // n

    std::vector<double> v(std::size_t k, const std::vector<double>& z) const {
        std::vector<double> out = base[k];
        for (std::size_t m = 0; m < K; ++m)
            for (std::size_t i = 0; i < n; ++i) out[m] += jac[k][m * n + i] * z[i];
        return out;
    }
    std::vector<double> toeplitz(const std::vector<double>& v) const {
        std::vector<double> t(K * K);
        for (std::size_t i = 0; i < K; ++i)
            for (std::size_t j = 0; j < K; ++j) {
                const std::size_t d = i > j ? i - j : j - i;
                t[i * K + j] = d == 0 ? v[0] : 0.5 * v[d];
            }
        return t;
    }
    // −Σ log det − Σ log z_i, or +∞ outside the interior.
    double barrier(const std::vector<double>& z) const {
        double f = 0.0;
        for (std::size_t i : positive) {
            if (!(z[i] > 0.0)) return HUGE_VAL;
            f -= std::log(z[i]);
        }
        for (std::size_t i : capped) {
            if (!(std::abs(z[i]) < cap)) return HUGE_VAL;
            f -= std::log(cap - z[i]) + std::log(cap + z[i]);
        }
        for (std::size_t k = 0; k < base.size(); ++k) {
            std::vector<double> t = toeplitz(v(k, z));
            if (cholesky_in_place(t, K, false) < K) return HUGE_VAL;
            for (std::size_t i = 0; i < K; ++i) f -= 2.0 * std::log(t[i * K + i]);
        }
        return f;
    }
    double value(const std::vector<double>& z) const {
        double s = 0.0;
        for (std::size_t i = 0; i < n; ++i) s += objective[i] * z[i];
        return s;
    }
};

// Minimises the objective over the interior by a log-barrier Newton method from a strictly
// feasible start; returns the last strictly feasible point's value (a valid bound at any stage).
double minimise(const Dual& d, std::vector<double> z, double stop_below, double stop_above) {
    const std::size_t n = d.n, K = d.K;
    if (!std::isfinite(d.barrier(z))) throw std::runtime_error("cone bound: the dual's start is not interior");
    const double barrier_dims = static_cast<double>(d.base.size() * K + d.positive.size() + 2 * d.capped.size());
    double t = 1.0;
    std::vector<double> grad(n), hess(n * n), dz(n), minv(K * K), tau(K), q(K * K), b(K * K * K);
    for (int outer = 0; outer < 60; ++outer) {
        for (int inner = 0; inner < 60; ++inner) {
            std::fill(hess.begin(), hess.end(), 0.0);
            for (std::size_t i = 0; i < n; ++i) grad[i] = t * d.objective[i];
            for (std::size_t i : d.positive) {
                grad[i] -= 1.0 / z[i];
                hess[i * n + i] += 1.0 / (z[i] * z[i]);
            }
            for (std::size_t i : d.capped) {
                grad[i] += 1.0 / (d.cap - z[i]) - 1.0 / (d.cap + z[i]);
                hess[i * n + i] += 1.0 / ((d.cap - z[i]) * (d.cap - z[i])) + 1.0 / ((d.cap + z[i]) * (d.cap + z[i]));
            }
            for (std::size_t k = 0; k < d.base.size(); ++k) {
                std::vector<double> l = d.toeplitz(d.v(k, z));
                if (cholesky_in_place(l, K, false) < K) throw std::runtime_error("cone bound: left the interior");
                for (std::size_t j = 0; j < K; ++j) {
                    std::vector<double> e(K, 0.0);
                    e[j] = 1.0;
                    cholesky_solve(l, K, e);
                    for (std::size_t i = 0; i < K; ++i) minv[i * K + j] = e[i];
                }
                // τ_m = tr(M⁻¹ E_m); B_m = M⁻¹ E_m; Q_mm' = tr(B_m B_m').
                for (std::size_t m = 0; m < K; ++m) {
                    double s = 0.0;
                    for (std::size_t i = 0; i + m < K; ++i) s += minv[i * K + i + m];
                    tau[m] = s;
                    for (std::size_t i = 0; i < K; ++i)
                        for (std::size_t j = 0; j < K; ++j) {
                            double v = 0.0;
                            if (m == 0) {
                                v = minv[i * K + j];
                            } else {
                                if (j >= m) v += 0.5 * minv[i * K + j - m];
                                if (j + m < K) v += 0.5 * minv[i * K + j + m];
                            }
                            b[(m * K + i) * K + j] = v;
                        }
                }
                for (std::size_t m = 0; m < K; ++m)
                    for (std::size_t m2 = m; m2 < K; ++m2) {
                        double s = 0.0;
                        for (std::size_t i = 0; i < K; ++i)
                            for (std::size_t j = 0; j < K; ++j) s += b[(m * K + i) * K + j] * b[(m2 * K + j) * K + i];
                        q[m * K + m2] = q[m2 * K + m] = s;
                    }
                const std::vector<double>& J = d.jac[k];
                for (std::size_t i = 0; i < n; ++i) {
                    double s = 0.0;
                    for (std::size_t m = 0; m < K; ++m) s += J[m * n + i] * tau[m];
                    grad[i] -= s;
                }
                std::vector<double> qj(K * n, 0.0);  // Q J
                for (std::size_t m = 0; m < K; ++m)
                    for (std::size_t m2 = 0; m2 < K; ++m2) {
                        const double f = q[m * K + m2];
                        if (f == 0.0) continue;
                        for (std::size_t i = 0; i < n; ++i) qj[m * n + i] += f * J[m2 * n + i];
                    }
                for (std::size_t m = 0; m < K; ++m)
                    for (std::size_t i = 0; i < n; ++i) {
                        const double f = J[m * n + i];
                        if (f == 0.0) continue;
                        for (std::size_t j = 0; j < n; ++j) hess[i * n + j] += f * qj[m * n + j];
                    }
            }
            std::vector<double> h = hess;
            // Newton step on the Jacobi-scaled system (the variables' curvatures differ by many
            // orders of magnitude near the boundary).
            std::vector<double> scale(n);
            for (std::size_t i = 0; i < n; ++i) scale[i] = 1.0 / std::sqrt(std::max(h[i * n + i], 1e-300));
            for (std::size_t i = 0; i < n; ++i)
                for (std::size_t j = 0; j < n; ++j) h[i * n + j] *= scale[i] * scale[j];
            for (std::size_t i = 0; i < n; ++i) h[i * n + i] += 1e-12;
            for (std::size_t i = 0; i < n; ++i) dz[i] = -grad[i] * scale[i];
            if (cholesky_in_place(h, n, false) == n) cholesky_solve(h, n, dz);
            for (std::size_t i = 0; i < n; ++i) dz[i] *= scale[i];
            double decrement = 0.0;
            for (std::size_t i = 0; i < n; ++i) decrement -= grad[i] * dz[i];
            if (!(decrement > 1e-10)) break;
            const double f0 = t * d.value(z) + d.barrier(z);
            double s = 1.0;
            std::vector<double> trial(n);
            bool moved = false;
            for (int ls = 0; ls < 60; ++ls, s *= 0.5) {
                for (std::size_t i = 0; i < n; ++i) trial[i] = z[i] + s * dz[i];
                const double fb = d.barrier(trial);
                if (std::isfinite(fb) && t * d.value(trial) + fb <= f0 - 0.25 * s * decrement) {
                    moved = true;
                    break;
                }
            }
            if (!moved) break;
            z = trial;
            if (d.value(z) < stop_below) return d.value(z);
        }
        const double v = d.value(z), gap = barrier_dims / t;
        if (v < stop_below || v - gap > stop_above) return v;
        if (gap < 1e-9 * std::max(1e-3, std::abs(v))) return v;
        t *= 10.0;
    }
    return d.value(z);
}

}  // namespace

ConeProgramme cone_programme(int size, double texel_um, double view_cone, const std::vector<double>& lambdas_um,
                             double level_step_um, int levels) {
    if (size < 1 || size > 8192) throw std::invalid_argument("cone bound: tile size " + std::to_string(size) + " is out of range");
    if (levels < 1 || levels > 64) throw std::invalid_argument("cone bound: " + std::to_string(levels) + " levels; expected 1 to 64");
    if (lambdas_um.empty()) throw std::invalid_argument("cone bound: no wavelengths");
    const double period = size * texel_um;
    const double lmin = *std::min_element(lambdas_um.begin(), lambdas_um.end());
    const int reach = static_cast<int>(std::floor(view_cone * period / lmin));
    if (2 * reach >= size)
        throw std::invalid_argument("cone bound: the view cone holds order " + std::to_string(reach) + " of a " +
                                    std::to_string(size) + "-texel tile; expected below half the tile");
    ConeProgramme p;
    p.levels = levels;
    p.wavelengths = static_cast<int>(lambdas_um.size());
    const double c2 = view_cone * view_cone;
    for (int m = 0; m <= reach; ++m)
        for (int n = 0; n <= m; ++n)
            if ((lmin * m / period) * (lmin * m / period) + (lmin * n / period) * (lmin * n / period) <= c2)
                p.classes.push_back({m, n});
    std::stable_sort(p.classes.begin(), p.classes.end(), [](const auto& a, const auto& b) {
        return a[0] * a[0] + a[1] * a[1] < b[0] * b[0] + b[1] * b[1];
    });
    const std::size_t C = p.classes.size(), K = static_cast<std::size_t>(levels), W = lambdas_um.size();
    p.power.assign(W * C * K, 0.0);
    for (std::size_t w = 0; w < W; ++w) {
        const double lambda = lambdas_um[w];
        for (std::size_t c = 0; c < C; ++c) {
            const double dx = lambda * p.classes[c][0] / period, dy = lambda * p.classes[c][1] / period;
            if (dx * dx + dy * dy > c2) continue;
            const double cos_o = std::sqrt(1.0 - dx * dx - dy * dy);
            const double env = std::pow(sinc(static_cast<double>(p.classes[c][0]) / size), 2) *
                               std::pow(sinc(static_cast<double>(p.classes[c][1]) / size), 2) * cos_o;
            const double nu = 2.0 * k_pi / lambda * level_step_um * (1.0 + cos_o);
            double* row = &p.power[(w * C + c) * K];
            row[0] = env;
            for (std::size_t k = 1; k < K; ++k) row[k] = 2.0 * env * std::cos(static_cast<double>(k) * nu);
        }
    }
    return p;
}

double cone_bound_y(const ConeProgramme& p, const std::vector<double>& xyz_weights, const std::array<double, 2>& uv,
                    double delta, double stop_below, double stop_above) {
    const std::size_t K = static_cast<std::size_t>(p.levels), C = p.classes.size(), W = static_cast<std::size_t>(p.wavelengths);
    if (xyz_weights.size() != 3 * W) throw std::invalid_argument("cone bound: xyz weights are not 3 x the wavelengths");
    // The class functionals: XYZ per coefficient.
    std::vector<double> X(3 * C * K, 0.0);
    for (std::size_t c3 = 0; c3 < 3; ++c3)
        for (std::size_t w = 0; w < W; ++w)
            for (std::size_t i = 0; i < C * K; ++i) X[c3 * C * K + i] += xyz_weights[c3 * W + w] * p.power[w * C * K + i];
    auto at = [&](std::size_t c3, std::size_t c, std::size_t k) { return X[c3 * C * K + c * K + k]; };
    // The colour conditions g_j(coefficients) = 0 (free multipliers) or ≤ 0 (non-negative ones).
    std::vector<std::vector<double>> conditions;
    const bool polygon = delta > 0.0;
    auto cond = [&](double a, double b, double e) {
        std::vector<double> g(C * K);
        for (std::size_t c = 0; c < C; ++c)
            for (std::size_t k = 0; k < K; ++k) {
                const double dd = at(0, c, k) + 15.0 * at(1, c, k) + 3.0 * at(2, c, k);
                const double cu = 4.0 * at(0, c, k) - uv[0] * dd, cv = 9.0 * at(1, c, k) - uv[1] * dd;
                g[c * K + k] = a * cu + b * cv - e * dd;
            }
        conditions.push_back(std::move(g));
    };
    if (!polygon) {
        cond(1.0, 0.0, 0.0);
        cond(0.0, 1.0, 0.0);
    } else {
        for (int i = 0; i < 32; ++i) cond(std::cos(2.0 * k_pi * i / 32), std::sin(2.0 * k_pi * i / 32), delta);
    }
    const std::size_t G = conditions.size();
    Dual d;
    d.K = K;
    // z = [π (K), ρ ≥ 0, colour multipliers (G), α ≥ 0 (K − 1), β ≥ 0 (K − 1)]
    const std::size_t ip = 0, ir = K, ig = K + 1, ia = K + 1 + G, ib = ia + (K - 1);
    d.n = ib + (K - 1);
    const std::size_t n = d.n;
    d.objective.assign(n, 0.0);
    // S_0(0) = 1 holds for every relief and forces every other class to vanish at ν = 0, which
    // leaves the set no interior and the dual no attained optimum; the programme keeps
    // S_0(0) ≤ 1 only (a relaxation: still a bound), multiplier ρ ≥ 0.
    d.objective[ip] = 1.0;
    d.objective[ir] = 1.0;
    d.positive.push_back(ir);
    for (std::size_t i = ia; i < n; ++i) d.positive.push_back(i);
    // The colour multipliers are kept within ±cap: a smaller dual set, so still a bound, and one
    // whose barrier problems stay bounded where the dual optimum is not attained (a colour the
    // set reaches only with Y = 0, as red and yellow in the mirror cone).
    d.cap = 1e4;
    for (std::size_t i = ig; i < ia; ++i) d.capped.push_back(i);
    if (polygon)
        for (std::size_t i = ig; i < ia; ++i) d.positive.push_back(i);
    std::vector<double> ones2(K, 2.0);
    ones2[0] = 1.0;
    for (std::size_t c = 0; c <= C; ++c) {  // c == C: the rest of the tile (v = π)
        std::vector<double> base(K, 0.0), J(K * n, 0.0);
        for (std::size_t m = 0; m < K; ++m) J[m * n + ip + m] = 1.0;
        if (c < C) {
            for (std::size_t m = 0; m < K; ++m) {
                base[m] = -at(1, c, m);
                for (std::size_t g = 0; g < G; ++g) J[m * n + ig + g] = conditions[g][c * K + m];
            }
        }
        if (c == 0) {
            for (std::size_t m = 0; m < K; ++m) J[m * n + ir] = ones2[m];
            for (std::size_t m = 1; m < K; ++m) {
                J[m * n + ia + m - 1] = -1.0;  // −α_m e_m
                J[m * n + ib + m - 1] = 1.0;   // −β_m (e_0 − e_m)
                J[0 * n + ib + m - 1] = -1.0;
            }
        }
        d.base.push_back(std::move(base));
        d.jac.push_back(std::move(J));
    }
    // A strictly feasible start: multipliers small, π_0 large enough for every Toeplitz matrix to
    // be diagonally dominant.
    std::vector<double> z(n, 0.0);
    for (std::size_t i = ia; i < n; ++i) z[i] = 1.0;
    z[ir] = 1e-3;
    if (polygon)
        for (std::size_t i = ig; i < ia; ++i) z[i] = 1e-3;
    double need = 0.0;
    for (std::size_t k = 0; k < d.base.size(); ++k) {
        const std::vector<double> v = d.v(k, z);
        double off = 0.0;
        for (std::size_t m = 1; m < K; ++m) off += std::abs(v[m]);
        need = std::max(need, off - v[0]);
    }
    z[ip] = need + 1.0;
    return minimise(d, z, stop_below, stop_above);
}

ConeBound cone_bound(const ConeProgramme& p, const std::vector<double>& xyz_weights, const std::array<double, 2>& target_uv,
                     double min_y) {
    ConeBound b;
    b.classes = static_cast<int>(p.classes.size());
    b.min_y = min_y;
    b.y_at_target = std::max(0.0, cone_bound_y(p, xyz_weights, target_uv));
    if (b.y_at_target >= min_y) return b;
    // Bisection on the radius: `lo` stays a radius the bound proves short of min_y.
    double lo = 0.0, hi = 0.5;
    if (cone_bound_y(p, xyz_weights, target_uv, hi, min_y, min_y) < min_y) {
        b.delta_uv_ruled_out = hi;
        return b;
    }
    while (hi - lo > 2e-4) {
        const double mid = 0.5 * (lo + hi);
        if (cone_bound_y(p, xyz_weights, target_uv, mid, min_y, min_y) < min_y)
            lo = mid;
        else
            hi = mid;
    }
    b.delta_uv_ruled_out = lo;
    return b;
}

std::vector<double> cone_relief_point(const ConeProgramme& p, const std::vector<int>& level, int size) {
    const std::size_t K = static_cast<std::size_t>(p.levels), C = p.classes.size(), N = static_cast<std::size_t>(size);
    if (level.size() != N * N) throw std::invalid_argument("cone_relief_point: the relief is not size^2 levels");
    std::vector<double> g((C + 1) * K, 0.0);
    for (std::size_t c = 0; c < C; ++c) {
        const int m = p.classes[c][0], n = p.classes[c][1];
        std::vector<std::array<int, 2>> members;
        for (int sm : {1, -1})
            for (int sn : {1, -1}) {
                members.push_back({sm * m, sn * n});
                members.push_back({sn * n, sm * m});
            }
        std::sort(members.begin(), members.end());
        members.erase(std::unique(members.begin(), members.end()), members.end());
        for (const auto& f : members) {
            std::vector<std::complex<double>> F(K, 0.0);
            for (std::size_t i = 0; i < N; ++i)
                for (std::size_t j = 0; j < N; ++j)
                    F[static_cast<std::size_t>(level[i * N + j])] +=
                        std::polar(1.0, -2.0 * k_pi * (f[0] * static_cast<double>(i) + f[1] * static_cast<double>(j)) / size);
            for (auto& x : F) x /= static_cast<double>(N * N);
            for (std::size_t k = 0; k < K; ++k)
                for (std::size_t l = 0; l + k < K; ++l) g[c * K + k] += (F[l] * std::conj(F[l + k])).real();
        }
    }
    // The rest of the tile, by Parseval: the classes and the rest sum to 1 at every ν.
    g[C * K] = 1.0;
    for (std::size_t c = 0; c < C; ++c)
        for (std::size_t k = 0; k < K; ++k) g[C * K + k] -= g[c * K + k];
    return g;
}

}  // namespace wavebrdf::detail
