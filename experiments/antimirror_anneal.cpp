// Issue 37 study (experiments/2026-12-01-antimirror-annealing.md): simulated annealing over the
// discrete relief of a small anti-mirror tile with exact incremental evaluation. One texel moved
// from level a to b changes every order's amplitude by
//   ΔA_o = (e^{−i k q_o h_b} − e^{−i k q_o h_a}) e^{−2πi (m_o i + n_o j)/N} / N²,
// so each trial costs one pass over the orders of all wavelengths (the library's order sets,
// src/design/engine.h) and updates the per-wavelength totals (all orders, the cone, the region's
// 16 bins: the anti-mirror target's groups, src/design/target.cpp). The relief read, the best one
// kept and the one written are scored afresh with the library's exact evaluation (level_flux,
// group_fractions, the target's metrics), and the largest difference between the incremental
// fractions and those is printed (it must be rounding).
//   antimirror_anneal key=value ...
//     start=R.exr (a relief on levels, e.g. a design's heights.exr; its step derived as the
//     design run derives a --start's) or random=SEED (uniform levels, with step=µm)
//     size=32 texel=0.5 levels=8 spectral=16 band=0.4,0.7 (the acceptance's anti-mirror; levels 8 only)
//     heat=0 (heat-bath sweeps: every unit in a random order set to a level drawn with
//     probability ∝ exp(objective / T) among its 8) t0=1e-4 t1=1e-7 (the temperature, geometric
//     over the sweeps, in units of the region's band mean) seed=1
//     aim_cone=0.0019 aim_u=0.245 (the relief kept: the best within both aims at every wavelength)
//     rho=0 (0: hinge penalty mu · Σ max(0, x/aim − 1), mu=1 ramped to mu1 over the sweeps;
//     > 0: augmented Lagrangian, see Problem::rho) sym=1 (4: moves on the quarter turn's orbits)
//     greedy=0 (passes of best-improvement descent afterwards, hinge penalty mu_greedy=1, from the
//     last relief and from the best one; the better within the aims is kept)
//     out=best.exr tile=1 (the relief written, repeated tile × tile: a tiled relief reflects
//     exactly its tile's orders, so `wavebrdf design --size 32·tile --start` scores it as its tile)
//   Prints the library's exact metrics of the start, the last and the final relief, with
//   `deviation`, the largest difference between the incremental fractions and the library's.
//   Environment: OMP_NUM_THREADS=1 for one thread.
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <ctime>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "design/engine.h"
#include "design/relief.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

using namespace wavebrdf;
using detail::Complex;

namespace {

constexpr int k_groups = 18;  // 0 … 15 the region's bins, 16 the cone, 17 the rest

struct Args {
    std::map<std::string, std::string> kv;
    std::string get(const std::string& k, const std::string& d) const {
        auto it = kv.find(k);
        return it == kv.end() ? d : it->second;
    }
    double num(const std::string& k, double d) const { return std::stod(get(k, std::to_string(d))); }
};

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

struct Problem {
    int N = 32, K = 8;
    double texel = 0.5, step = 0.0;
    std::vector<double> lambdas;
    std::vector<detail::OrderSet> sets;
    std::unique_ptr<detail::Target> target;
    // Flattened orders of all wavelengths.
    std::vector<int> w, g, pm, pn, slot;  // slot: w · k_groups + g
    std::vector<double> env;
    std::vector<Complex> E;      // [o · K + ℓ] = e^{−i k q_o h_ℓ}, h_ℓ = ℓ · step
    std::vector<Complex> Es;     // E · √env_o / N²: the amplitudes are kept as √env_o A_o
    std::vector<unsigned> packed;  // m mod N | (n mod N) << 8 | slot << 16
    std::vector<std::size_t> slot_start;  // the orders of slot q: slot_start[q] … slot_start[q + 1] − 1
    // Es as float, order-major, [o · 2K + ℓ] re, [o · 2K + K + ℓ] im, for the trials: the pass is
    // memory-bound, and a move kept is applied in double precision (accept), so the state does not
    // carry the float rounding.
    std::vector<float> Eo;
    // The moves' units: single texels, or with sym=4 the orbits of the quarter turn
    // (i, j) → (−j, i) mod N, whose far field is then symmetric under quarter turns about the
    // mirror direction, so that the four quadrant bins of each ring hold equal power.
    std::vector<std::vector<int>> orbits;
    std::vector<Complex> twiddle;  // e^{−2πi s/N}
    double aim_cone = 0.0019, aim_u = 0.245, mu = 1.0;
    // rho > 0: the augmented-Lagrangian terms (max(0, λ + ρ g)² − λ²)/(2ρ) of g = x/aim − 1 per
    // wavelength and limit in place of the hinge mu · max(0, g), the multipliers λ moved after
    // every sweep (λ ← max(0, λ + ρ g)) as the design loop moves its own between blocks.
    double rho = 0.0;
    mutable std::vector<double> lam_c, lam_u;
};

void build(Problem& p) {
    p.target = detail::make_anti_mirror({0.05, 0.1, 0.5, 0.002, 0.25});
    for (double l : p.lambdas) p.sets.push_back(detail::make_order_set(p.N, p.texel, {0.0, 0.0}, l));
    p.target->assign(p.sets);
    // The orders sorted by slot (wavelength, group), so that trial_all sums each slot in registers.
    std::vector<std::array<int, 3>> all;  // slot, wavelength, order
    for (std::size_t s = 0; s < p.sets.size(); ++s) {
        const auto& mem = p.target->members()[s];
        for (std::size_t o = 0; o < p.sets[s].size(); ++o) {
            int g = 17;
            if (mem[o][1] >= 1) g = mem[o][1] - 1;
            else if (mem[o][0] == 0) g = 16;
            all.push_back({static_cast<int>(s) * k_groups + g, static_cast<int>(s), static_cast<int>(o)});
        }
    }
    std::stable_sort(all.begin(), all.end(), [](const auto& x, const auto& y) { return x[0] < y[0]; });
    p.slot_start.assign(p.sets.size() * k_groups + 1, 0);
    for (const auto& [slot, s, o] : all) {
        const auto& set = p.sets[static_cast<std::size_t>(s)];
        const std::size_t u = static_cast<std::size_t>(o);
        p.w.push_back(s);
        p.g.push_back(slot % k_groups);
        p.slot.push_back(slot);
        ++p.slot_start[static_cast<std::size_t>(slot) + 1];
        p.pm.push_back(((set.m[u] % p.N) + p.N) % p.N);
        p.pn.push_back(((set.n[u] % p.N) + p.N) % p.N);
        p.env.push_back(set.env[u]);
        for (int l = 0; l < p.K; ++l) p.E.push_back(std::polar(1.0, -set.k * set.q[u] * l * p.step));
    }
    std::partial_sum(p.slot_start.begin(), p.slot_start.end(), p.slot_start.begin());
    const std::size_t O = p.w.size();
    const double inv = 1.0 / (static_cast<double>(p.N) * p.N);
    p.Es.resize(p.E.size());
    p.Eo.assign(2 * p.E.size(), 0.0f);
    for (std::size_t o = 0; o < O; ++o) {
        p.packed.push_back(static_cast<unsigned>(p.pm[o]) | static_cast<unsigned>(p.pn[o]) << 8 |
                           static_cast<unsigned>(p.slot[o]) << 16);
        for (std::size_t l = 0; l < static_cast<std::size_t>(p.K); ++l) {
            const Complex e = p.E[o * static_cast<std::size_t>(p.K) + l] * (std::sqrt(p.env[o]) * inv);
            p.Es[o * static_cast<std::size_t>(p.K) + l] = e;
            p.Eo[o * 2 * static_cast<std::size_t>(p.K) + l] = static_cast<float>(e.real());
            p.Eo[o * 2 * static_cast<std::size_t>(p.K) + static_cast<std::size_t>(p.K) + l] = static_cast<float>(e.imag());
        }
    }
    for (int s = 0; s < p.N; ++s) p.twiddle.push_back(std::polar(1.0, -2.0 * k_pi * s / p.N));
}

struct Score {
    double objective = 0.0, region = 0.0, cone_worst = 0.0, u_worst = 0.0;
    bool feasible = false;
};

Score score(const Problem& p, const std::vector<double>& acc) {
    const std::size_t W = p.lambdas.size();
    Score s;
    double penalty = 0.0;
    for (std::size_t w = 0; w < W; ++w) {
        const double* a = &acc[w * k_groups];
        double total = 0.0, region = 0.0;
        for (int g = 0; g < k_groups; ++g) total += a[g];
        for (int g = 0; g < 16; ++g) region += a[g];
        const double mean = region / 16.0;
        double var = 0.0;
        for (int g = 0; g < 16; ++g) var += (a[g] - mean) * (a[g] - mean);
        const double u = mean > 0.0 ? std::sqrt(var / 16.0) / mean : 0.0;
        const double c = a[16] / total;
        s.region += region / total / static_cast<double>(W);
        s.cone_worst = std::max(s.cone_worst, c);
        s.u_worst = std::max(s.u_worst, u);
        if (p.rho > 0.0) {
            const double lc = p.lam_c[w], lu = p.lam_u[w];
            const double pc = std::max(0.0, lc + p.rho * (c / p.aim_cone - 1.0));
            const double pu = std::max(0.0, lu + p.rho * (u / p.aim_u - 1.0));
            penalty += (pc * pc - lc * lc + pu * pu - lu * lu) / (2.0 * p.rho * p.mu);
        } else {
            penalty += std::max(0.0, c / p.aim_cone - 1.0) + std::max(0.0, u / p.aim_u - 1.0);
        }
    }
    s.objective = s.region - p.mu * penalty;
    s.feasible = s.cone_worst <= p.aim_cone && s.u_worst <= p.aim_u;
    return s;
}

// λ ← max(0, λ + ρ g) at the relief's totals (rho > 0).
void update_multipliers(const Problem& p, const std::vector<double>& acc) {
    for (std::size_t w = 0; w < p.lambdas.size(); ++w) {
        const double* a = &acc[w * k_groups];
        double total = 0.0, region = 0.0, var = 0.0;
        for (int g = 0; g < k_groups; ++g) total += a[g];
        for (int g = 0; g < 16; ++g) region += a[g];
        const double mean = region / 16.0;
        for (int g = 0; g < 16; ++g) var += (a[g] - mean) * (a[g] - mean);
        const double u = mean > 0.0 ? std::sqrt(var / 16.0) / mean : 0.0;
        p.lam_c[w] = std::max(0.0, p.lam_c[w] + p.rho * (a[16] / total / p.aim_cone - 1.0));
        p.lam_u[w] = std::max(0.0, p.lam_u[w] + p.rho * (u / p.aim_u - 1.0));
    }
}

struct State {
    std::vector<int> level;
    std::vector<Complex> A;
    std::vector<double> flux, acc;
};

// Amplitudes by the direct sum over texels (not the library's FFT).
void fresh(const Problem& p, State& s) {
    const std::size_t O = p.w.size();
    s.A.assign(O, Complex(0.0, 0.0));
    const double inv = 1.0 / (static_cast<double>(p.N) * p.N);
    for (std::size_t o = 0; o < O; ++o) {
        Complex a(0.0, 0.0);
        for (int i = 0; i < p.N; ++i)
            for (int j = 0; j < p.N; ++j) {
                const int l = s.level[static_cast<std::size_t>(i * p.N + j)];
                a += p.E[o * p.K + l] * p.twiddle[static_cast<std::size_t>((p.pm[o] * i + p.pn[o] * j) % p.N)];
            }
        s.A[o] = a * (inv * std::sqrt(p.env[o]));
    }
    s.flux.resize(O);
    s.acc.assign(p.lambdas.size() * k_groups, 0.0);
    for (std::size_t o = 0; o < O; ++o) {
        s.flux[o] = std::norm(s.A[o]);
        s.acc[static_cast<std::size_t>(p.w[o] * k_groups + p.g[o])] += s.flux[o];
    }
}

// The change of the totals for every level of unit u (its texels together) at once ([slot · K + ℓ]; ℓ = its own: 0):
// one pass over the order-major table, the levels' loop vectorised.
void trial_all(const Problem& p, const State& s, int u, std::vector<double>& delta) {
    const std::vector<int>& texels = p.orbits[static_cast<std::size_t>(u)];
    const std::size_t a = static_cast<std::size_t>(s.level[static_cast<std::size_t>(texels[0])]);
    constexpr std::size_t K = 8;  // the acceptance's levels (checked in main)
    delta.assign(p.lambdas.size() * k_groups * K, 0.0);
    const unsigned mask = static_cast<unsigned>(p.N - 1);
    const double* A = reinterpret_cast<const double*>(s.A.data());
    const double* tw = reinterpret_cast<const double*>(p.twiddle.data());
    unsigned ti_[4] = {}, tj_[4] = {};
    const std::size_t count = texels.size();
    for (std::size_t x = 0; x < count; ++x) {
        ti_[x] = static_cast<unsigned>(texels[x] / p.N);
        tj_[x] = static_cast<unsigned>(texels[x] % p.N);
    }
    for (std::size_t q = 0; q + 1 < p.slot_start.size(); ++q) {
        double sum[K] = {};
        for (std::size_t o = p.slot_start[q]; o < p.slot_start[q + 1]; ++o) {
            const unsigned k = p.packed[o];
            const float* er = p.Eo.data() + o * 2 * K;
            const float* ei = er + K;
            double tr = 0.0, ti = 0.0;
            for (std::size_t x = 0; x < count; ++x) {
                const std::size_t ph = ((k & 255u) * ti_[x] + ((k >> 8) & 255u) * tj_[x]) & mask;
                tr += tw[2 * ph];
                ti += tw[2 * ph + 1];
            }
            const double ar = A[2 * o], ai = A[2 * o + 1];
            const double old = ar * ar + ai * ai;
            const float era = er[a], eia = ei[a];
            for (std::size_t b = 0; b < K; ++b) {
                const double dr = static_cast<double>(er[b] - era), di = static_cast<double>(ei[b] - eia);
                const double nr = ar + dr * tr - di * ti, ni = ai + dr * ti + di * tr;
                sum[b] += nr * nr + ni * ni - old;
            }
        }
        for (std::size_t b = 0; b < K; ++b) delta[q * K + b] = sum[b];
    }
}

// The objective of each level of unit u (its own level's: the current objective).
std::vector<Score> level_scores(const Problem& p, const State& s, int u, std::vector<double>& delta,
                                std::vector<double>& acc) {
    trial_all(p, s, u, delta);
    const int t = p.orbits[static_cast<std::size_t>(u)][0];
    const std::size_t K = static_cast<std::size_t>(p.K), G = s.acc.size();
    std::vector<Score> out(K);
    for (std::size_t b = 0; b < K; ++b) {
        acc = s.acc;
        if (static_cast<int>(b) != s.level[static_cast<std::size_t>(t)])
            for (std::size_t q = 0; q < G; ++q) acc[q] += delta[q * K + b];
        out[b] = score(p, acc);
    }
    return out;
}

// Applies the move of unit u to level b in double precision, the totals summed afresh from the
// orders' fluxes.
void accept(const Problem& p, State& s, int u, int b) {
    const std::size_t K = static_cast<std::size_t>(p.K);
    for (int t : p.orbits[static_cast<std::size_t>(u)]) {
        const int i = t / p.N, j = t % p.N, a = s.level[static_cast<std::size_t>(t)];
        for (std::size_t o = 0; o < s.A.size(); ++o) {
            const Complex d = p.Es[o * K + static_cast<std::size_t>(b)] - p.Es[o * K + static_cast<std::size_t>(a)];
            const Complex w = p.twiddle[static_cast<std::size_t>((p.pm[o] * i + p.pn[o] * j) & (p.N - 1))];
            s.A[o] += Complex(d.real() * w.real() - d.imag() * w.imag(), d.real() * w.imag() + d.imag() * w.real());
        }
        s.level[static_cast<std::size_t>(t)] = b;
    }
    std::fill(s.acc.begin(), s.acc.end(), 0.0);
    for (std::size_t o = 0; o < s.A.size(); ++o) {
        s.flux[o] = s.A[o].real() * s.A[o].real() + s.A[o].imag() * s.A[o].imag();
        s.acc[static_cast<std::size_t>(p.slot[o])] += s.flux[o];
    }
}

// The units of the moves: every texel alone (sym 1) or the quarter turn's orbits (sym 4).
std::vector<std::vector<int>> make_orbits(int N, int sym) {
    std::vector<std::vector<int>> out;
    std::vector<char> seen(static_cast<std::size_t>(N * N), 0);
    for (int t = 0; t < N * N; ++t) {
        if (seen[static_cast<std::size_t>(t)]) continue;
        std::vector<int> orbit;
        int i = t / N, j = t % N;
        for (int r = 0; r < (sym == 4 ? 4 : 1); ++r) {
            const int u = i * N + j;
            if (!seen[static_cast<std::size_t>(u)]) {
                seen[static_cast<std::size_t>(u)] = 1;
                orbit.push_back(u);
            }
            const int ni = (N - j) % N, nj = i;
            i = ni;
            j = nj;
        }
        out.push_back(orbit);
    }
    return out;
}

// The library's exact scores of the relief: fractions (its groups) and metrics.
nlohmann::json library_metrics(const Problem& p, const std::vector<int>& level, detail::Fractions* f) {
    detail::LevelRelief r;
    r.levels = p.K;
    r.heights.base_um = 0.0;
    r.heights.step_um = p.step;
    r.level = level;
    const auto flux = detail::level_flux(r, p.N, p.sets, 1.0);
    std::vector<double> totals;
    *f = detail::group_fractions(*p.target, flux, &totals);
    return p.target->metrics(*f);
}

// Largest difference between the incremental totals (as fractions) and the library's fractions.
double deviation(const Problem& p, const State& s, const detail::Fractions& f) {
    double worst = 0.0;
    for (std::size_t w = 0; w < p.lambdas.size(); ++w) {
        const double* a = &s.acc[w * k_groups];
        double total = 0.0;
        for (int g = 0; g < k_groups; ++g) total += a[g];
        for (int g = 0; g < 16; ++g) worst = std::max(worst, std::abs(a[g] / total - f[w][static_cast<std::size_t>(g + 1)]));
        worst = std::max(worst, std::abs(a[16] / total - f[w][0]));
    }
    return worst;
}

void write_relief(const Problem& p, const std::vector<int>& level, int tile, const std::string& path) {
    const int M = p.N * tile;
    std::vector<double> values(static_cast<std::size_t>(M) * M);
    for (int i = 0; i < M; ++i)
        for (int j = 0; j < M; ++j)
            values[static_cast<std::size_t>(i) * M + j] =
                level[static_cast<std::size_t>((i % p.N) * p.N + j % p.N)] * p.step / p.texel;
    write_heightfield_exr(path, Heightfield(M, M, std::move(values), p.texel, 1.0), "antimirror_anneal");
}

void report(const char* what, const Problem& p, const State& s) {
    detail::Fractions f;
    const nlohmann::json m = library_metrics(p, s.level, &f);
    std::printf("%s region_mean=%.12f region_worst=%.12f cone_worst=%.12f uniformity_worst=%.12f deviation=%.2e\n", what,
                m["region_fraction_mean"].get<double>(), m["region_fraction_worst"].get<double>(),
                m["specular_fraction_worst"].get<double>(), m["uniformity_worst"].get<double>(), deviation(p, s, f));
}

// Best-improvement descent: each pass tries every texel's every other level and keeps the best
// move of each texel when it raises the objective. Returns the number of moves kept.
long greedy_pass(const Problem& p, State& s, std::vector<double>& delta, std::vector<double>& acc) {
    long kept = 0;
    for (int u = 0; u < static_cast<int>(p.orbits.size()); ++u) {
        const std::vector<Score> v = level_scores(p, s, u, delta, acc);
        const int a = s.level[static_cast<std::size_t>(p.orbits[static_cast<std::size_t>(u)][0])];
        int best = a;
        for (int b = 0; b < p.K; ++b)
            if (v[static_cast<std::size_t>(b)].objective > v[static_cast<std::size_t>(best)].objective + 1e-12) best = b;
        if (best != a) {
            accept(p, s, u, best);
            ++kept;
        }
    }
    return kept;
}

// One heat-bath sweep at temperature T: the texels in a random order, each set to a level drawn
// with probability ∝ exp(objective / T) among its K levels. Keeps the best relief within the aims.
long heat_sweep(const Problem& p, State& s, double T, std::mt19937_64& rng, std::vector<double>& delta,
                std::vector<double>& acc, State& best, Score& best_score) {
    std::vector<int> order(p.orbits.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    long moved = 0;
    std::vector<double> weight(static_cast<std::size_t>(p.K));
    for (int u : order) {
        const std::vector<Score> v = level_scores(p, s, u, delta, acc);
        double top = -1e300;
        for (const Score& x : v) top = std::max(top, x.objective);
        double sum = 0.0;
        for (std::size_t b = 0; b < v.size(); ++b) sum += weight[b] = std::exp((v[b].objective - top) / T);
        double r = unit(rng) * sum;
        std::size_t b = 0;
        while (b + 1 < v.size() && r >= weight[b]) r -= weight[b++];
        if (static_cast<int>(b) == s.level[static_cast<std::size_t>(p.orbits[static_cast<std::size_t>(u)][0])]) continue;
        accept(p, s, u, static_cast<int>(b));
        ++moved;
        const Score now = score(p, s.acc);
        if (now.feasible && (!best_score.feasible || now.region > best_score.region)) {
            best = s;
            best_score = now;
        }
    }
    return moved;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        Args args;
        for (int a = 1; a < argc; ++a) {
            const std::string s = argv[a];
            const auto eq = s.find('=');
            if (eq == std::string::npos) throw std::invalid_argument("argument '" + s + "' is not key=value");
            args.kv[s.substr(0, eq)] = s.substr(eq + 1);
        }
        Problem p;
        p.N = static_cast<int>(args.num("size", 32));
        if (p.N < 2 || p.N > 256 || (p.N & (p.N - 1)) != 0) throw std::invalid_argument("size must be a power of two up to 256");
        p.texel = args.num("texel", 0.5);
        p.K = static_cast<int>(args.num("levels", 8));
        if (p.K != 8) throw std::invalid_argument("levels must be 8 (trial_all's vectorised loop)");
        const int spectral = static_cast<int>(args.num("spectral", 16));
        const std::string band = args.get("band", "0.4,0.7");
        const double lo = std::stod(band.substr(0, band.find(','))), hi = std::stod(band.substr(band.find(',') + 1));
        for (int k = 0; k < spectral; ++k) p.lambdas.push_back(lo + (k + 0.5) * (hi - lo) / spectral);
        p.aim_cone = args.num("aim_cone", 0.0019);
        p.aim_u = args.num("aim_u", 0.245);
        p.mu = args.num("mu", 1.0);
        p.rho = args.num("rho", 0.0);
        p.lam_c.assign(p.lambdas.size(), 0.0);
        p.lam_u.assign(p.lambdas.size(), 0.0);
        const unsigned long seed = std::stoul(args.get("seed", "1"));
        std::mt19937_64 rng(seed);
        State s;
        const std::size_t n2 = static_cast<std::size_t>(p.N) * p.N;
        if (args.kv.count("start")) {
            const std::vector<double> h = heights_um(read_heightfield_exr(args.get("start", "")));
            if (h.size() != n2) throw std::invalid_argument("start is not size x size");
            p.step = detail::start_step_um(h);  // as the design run reads a --start's step
            for (double v : h) s.level.push_back(static_cast<int>(std::lround(v / p.step)));
        } else {
            p.step = args.num("step", 0.1675);
            std::mt19937_64 start_rng(std::stoul(args.get("random", "1")));
            std::uniform_int_distribution<int> lvl(0, p.K - 1);
            for (std::size_t t = 0; t < n2; ++t) s.level.push_back(lvl(start_rng));
        }
        const int sym = static_cast<int>(args.num("sym", 1));
        if (sym != 1 && sym != 4) throw std::invalid_argument("sym must be 1 or 4");
        p.orbits = make_orbits(p.N, sym);
        int changed = 0;  // a start made symmetric: each orbit takes its first texel's level
        for (const auto& orbit : p.orbits)
            for (int t : orbit)
                if (s.level[static_cast<std::size_t>(t)] != s.level[static_cast<std::size_t>(orbit[0])]) {
                    s.level[static_cast<std::size_t>(t)] = s.level[static_cast<std::size_t>(orbit[0])];
                    ++changed;
                }
        build(p);
        std::printf("orders=%zu step_um=%.9f units=%zu symmetrised=%d\n", p.w.size(), p.step, p.orbits.size(), changed);
        const double c0 = cpu_seconds();
        fresh(p, s);
        report("start", p, s);
        std::vector<double> acc, delta;
        State best = s;
        Score best_score = score(p, s.acc);
        const double t0 = args.num("t0", 1e-4), t1 = args.num("t1", 1e-7);
        Score cur = score(p, s.acc);
        const double heat = args.num("heat", 0.0);
        const long heat_sweeps = static_cast<long>(heat);
        const double mu0 = p.mu, mu1 = args.num("mu1", p.mu);  // the penalty ramps geometrically mu → mu1
        for (long k = 0; k < heat_sweeps; ++k) {
            const double T = t0 * std::pow(t1 / t0, static_cast<double>(k) / static_cast<double>(std::max(1L, heat_sweeps - 1)));
            p.mu = mu0 * std::pow(mu1 / mu0, static_cast<double>(k) / static_cast<double>(std::max(1L, heat_sweeps - 1)));
            const long moved = heat_sweep(p, s, T, rng, delta, acc, best, best_score);
            if (p.rho > 0.0) update_multipliers(p, s.acc);
            if ((k + 1) % 5 == 0 || k + 1 == heat_sweeps) {
                cur = score(p, s.acc);
                std::printf("heat sweep=%ld T=%.3g mu=%.3g objective=%.6f region=%.6f cone=%.6f u=%.4f moved=%ld best=%.6f cpu=%.0f\n",
                            k + 1, T, p.mu, cur.objective, cur.region, cur.cone_worst, cur.u_worst, moved,
                            best_score.feasible ? best_score.region : 0.0, cpu_seconds() - c0);
                std::fflush(stdout);
                fresh(p, s);
            }
        }
        // The descent (hinge penalty mu_greedy) from the best relief within the aims and from the
        // last one; the better within the aims is kept.
        const int passes = static_cast<int>(args.num("greedy", 0));
        p.mu = args.num("mu_greedy", 1.0);
        p.rho = 0.0;
        std::vector<State> ends{s};
        if (heat_sweeps > 0) {
            report("last", p, s);
            if (best_score.feasible) ends.push_back(best);
        }
        for (State& e : ends) {
            for (int pass = 0; pass < passes; ++pass) {
                const long kept = greedy_pass(p, e, delta, acc);
                const Score v = score(p, e.acc);
                std::printf("greedy pass=%d kept=%ld objective=%.6f region=%.6f cone=%.6f u=%.4f cpu=%.0f\n", pass + 1,
                            kept, v.objective, v.region, v.cone_worst, v.u_worst, cpu_seconds() - c0);
                std::fflush(stdout);
                if (kept == 0) break;
            }
            const Score v = score(p, e.acc), w = score(p, s.acc);
            if (&e == &ends[0] || (v.feasible && (!w.feasible || v.region > w.region))) s = e;
        }
        report("final", p, s);
        std::printf("cpu_s=%.1f\n", cpu_seconds() - c0);
        if (args.kv.count("out")) write_relief(p, s.level, static_cast<int>(args.num("tile", 1)), args.get("out", ""));
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "antimirror_anneal: %s\n", e.what());
        return 1;
    }
}
