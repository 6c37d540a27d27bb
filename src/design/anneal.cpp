// Simulated annealing of an anti-mirror's relief with exact incremental order amplitudes (anneal.h).
#include "design/anneal.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <cmath>
#include <ctime>
#include <numeric>

#include "wavebrdf/constants.h"

#include <omp.h>

namespace wavebrdf::detail {

namespace {

constexpr int k_bins = 16;  // the anti-mirror region's bins: target groups 1 … 16
// Orders × levels of a trial from which the threads share it (a 32² tile at 16 wavelengths on
// 8 levels: 3.6e5, about 0.2 ms on one core).
constexpr double k_parallel_work = 1e5;

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

}  // namespace

AnnealAims anneal_aims(double cone_limit, double uniformity_limit) {
    return {k_anti_mirror_aim * cone_limit, 0.98 * uniformity_limit};
}

// The orders of every wavelength sorted into slots, one per distinct pair of target groups (the
// cone, a bin, inside, beyond; none), so that a slot's total is one running sum over its orders.
struct ReliefAnnealer::Impl {
    int N = 0, K = 0;
    AnnealAims aims;
    double rho = 0.0;
    std::size_t W = 0;
    int groups = 0;
    std::vector<std::size_t> w_slots;   // the slots of wavelength w: w_slots[w] … w_slots[w + 1] − 1
    std::vector<std::size_t> s_orders;  // the orders of slot s: s_orders[s] … s_orders[s + 1] − 1
    std::vector<std::array<int, 2>> s_groups;  // the target groups of slot s's orders
    std::vector<char> s_cone;                  // whether slot s is in the cone
    std::vector<int> s_bin;                    // slot s's region bin (0 … 15), −1: none
    std::vector<int> om, on;                   // order o's (m mod N, n mod N)
    std::vector<Complex> Es;                   // [o · K + ℓ] √env_o e^{−i k q_o h_ℓ} / N²
    // Es as float, [o · 2K + ℓ] real, [o · 2K + K + ℓ] imaginary, for the trials: the pass is
    // memory-bound; a move kept is applied in double precision (accept).
    std::vector<float> Eo;
    std::vector<Complex> twiddle;  // e^{−2πi s/N}
    std::vector<int> level;
    std::vector<Complex> A;        // √env_o · the order's amplitude
    std::vector<double> acc;       // each slot's total flux
    std::vector<double> lam_c, lam_u;
    std::vector<double> delta;     // a trial's change of every slot's total per level, [s · K + b]
    std::vector<int> row_phase, col_phase;
    // Whether a move's pass over the orders is shared among the threads (by whole wavelengths):
    // only where it is long enough to pay for the threads' meeting twice a texel.
    bool parallel = false, can_share = false;

    // Each wavelength's totals, with the trial's change for level b added (b < 0: none).
    struct Wave {
        double total = 0.0, cone = 0.0;
        std::array<double, k_bins> bins{};
    };
    Wave wave(std::size_t w, int b) const {
        Wave v;
        for (std::size_t s = w_slots[w]; s < w_slots[w + 1]; ++s) {
            const double x = acc[s] + (b >= 0 ? delta[s * static_cast<std::size_t>(K) + static_cast<std::size_t>(b)] : 0.0);
            v.total += x;
            if (s_cone[s]) v.cone += x;
            if (s_bin[s] >= 0) v.bins[static_cast<std::size_t>(s_bin[s])] += x;
        }
        return v;
    }
    // The region's fraction, the cone's and the uniformity (as the target's metrics define them).
    static std::array<double, 3> measures(const Wave& v) {
        double region = 0.0;
        for (double x : v.bins) region += x;
        const double mean = region / k_bins;
        double var = 0.0;
        for (double x : v.bins) var += (x - mean) * (x - mean);
        const double u = mean > 0.0 ? std::sqrt(var / k_bins) / mean : 0.0;
        return {v.total > 0.0 ? region / v.total : 0.0, v.total > 0.0 ? v.cone / v.total : 0.0, u};
    }

    AnnealScore score(int b, bool hinge) const {
        AnnealScore s;
        double penalty = 0.0;
        for (std::size_t w = 0; w < W; ++w) {
            const auto [region, cone, u] = measures(wave(w, b));
            s.region += region / static_cast<double>(W);
            s.cone_worst = std::max(s.cone_worst, cone);
            s.uniformity_worst = std::max(s.uniformity_worst, u);
            const double gc = cone / aims.cone - 1.0, gu = u / aims.uniformity - 1.0;
            if (hinge) {
                penalty += std::max(0.0, gc) + std::max(0.0, gu);
            } else {
                // The augmented-Lagrangian terms (max(0, λ + ρ g)² − λ²) / (2ρ) (target.h).
                const double lc = lam_c[w], lu = lam_u[w];
                const double pc = std::max(0.0, lc + rho * gc), pu = std::max(0.0, lu + rho * gu);
                penalty += (pc * pc - lc * lc + pu * pu - lu * lu) / (2.0 * rho);
            }
        }
        s.objective = s.region - penalty;
        s.within_aims = s.cone_worst <= aims.cone && s.uniformity_worst <= aims.uniformity;
        return s;
    }

    // Where texel (i, j) meets each order: (m i + n j) mod N = row_phase[m] + col_phase[n] (mod N).
    void set_phases(int t) {
        const int i = t / N, j = t % N;
        for (int x = 0; x < N; ++x) {
            row_phase[static_cast<std::size_t>(x)] = static_cast<int>((static_cast<long>(x) * i) % N);
            col_phase[static_cast<std::size_t>(x)] = static_cast<int>((static_cast<long>(x) * j) % N);
        }
    }
    std::size_t phase(std::size_t o) const {
        int ph = row_phase[static_cast<std::size_t>(om[o])] + col_phase[static_cast<std::size_t>(on[o])];
        if (ph >= N) ph -= N;
        return static_cast<std::size_t>(ph);
    }

    // delta for every level of texel t: one pass over the orders, the levels' loop innermost.
    template <int KC>
    void trial(int t) {
        const std::size_t Kn = static_cast<std::size_t>(KC > 0 ? KC : K);
        const std::size_t a = static_cast<std::size_t>(level[static_cast<std::size_t>(t)]);
        set_phases(t);
        const long waves = static_cast<long>(W);
#pragma omp parallel for schedule(static) if (parallel)
        for (long w = 0; w < waves; ++w) {
            for (std::size_t s = w_slots[static_cast<std::size_t>(w)]; s < w_slots[static_cast<std::size_t>(w) + 1]; ++s) {
                std::array<double, (KC > 0 ? KC : 256)> sum{};
                for (std::size_t o = s_orders[s]; o < s_orders[s + 1]; ++o) {
                    const Complex tw = twiddle[phase(o)];
                    const double tr = tw.real(), ti = tw.imag();
                    const float* er = Eo.data() + o * 2 * Kn;
                    const float* ei = er + Kn;
                    const double ar = A[o].real(), ai = A[o].imag();
                    const double old = ar * ar + ai * ai;
                    const float era = er[a], eia = ei[a];
                    for (std::size_t b = 0; b < Kn; ++b) {
                        const double dr = static_cast<double>(er[b] - era), di = static_cast<double>(ei[b] - eia);
                        const double nr = ar + dr * tr - di * ti, ni = ai + dr * ti + di * tr;
                        sum[b] += nr * nr + ni * ni - old;
                    }
                }
                for (std::size_t b = 0; b < Kn; ++b) delta[s * Kn + b] = sum[b];
            }
        }
    }
    void trial_any(int t) {
        if (K == 8) trial<8>(t);
        else if (K == 4) trial<4>(t);
        else if (K == 16) trial<16>(t);
        else trial<0>(t);
    }

    // Texel t to level b, in double precision; the slots' totals summed afresh.
    void accept(int t, int b) {
        const std::size_t Kn = static_cast<std::size_t>(K);
        const std::size_t a = static_cast<std::size_t>(level[static_cast<std::size_t>(t)]);
        set_phases(t);
        const long waves = static_cast<long>(W);
#pragma omp parallel for schedule(static) if (parallel)
        for (long w = 0; w < waves; ++w)
            for (std::size_t s = w_slots[static_cast<std::size_t>(w)]; s < w_slots[static_cast<std::size_t>(w) + 1]; ++s) {
                double sum = 0.0;
                for (std::size_t o = s_orders[s]; o < s_orders[s + 1]; ++o) {
                    const Complex d = Es[o * Kn + static_cast<std::size_t>(b)] - Es[o * Kn + a];
                    const Complex tw = twiddle[phase(o)];
                    A[o] += Complex(d.real() * tw.real() - d.imag() * tw.imag(), d.real() * tw.imag() + d.imag() * tw.real());
                    sum += A[o].real() * A[o].real() + A[o].imag() * A[o].imag();
                }
                acc[s] = sum;
            }
        level[static_cast<std::size_t>(t)] = b;
    }

    // The amplitudes afresh from the level masks' DFTs F_ℓ(m, n) = Σ_{i,j} [level(i, j) = ℓ]
    // e^{−2πi (m i + n j)/N}, row by row then column by column (each value summed by one thread in
    // a fixed order): A_o = Σ_ℓ Es[o, ℓ] F_ℓ(m_o, n_o).
    void refresh() {
        const std::size_t n = static_cast<std::size_t>(N), Kn = static_cast<std::size_t>(K);
        std::vector<Complex> G(n * n * Kn, Complex(0.0, 0.0)), F(n * n * Kn, Complex(0.0, 0.0));
        const long rows = N;
#pragma omp parallel for schedule(static) if (parallel)
        for (long i = 0; i < rows; ++i)
            for (std::size_t j = 0; j < n; ++j) {
                const std::size_t l = static_cast<std::size_t>(level[static_cast<std::size_t>(i) * n + j]);
                for (std::size_t f = 0; f < n; ++f) G[(static_cast<std::size_t>(i) * n + f) * Kn + l] += twiddle[(f * j) % n];
            }
#pragma omp parallel for schedule(static) if (parallel)
        for (long m = 0; m < rows; ++m)
            for (std::size_t i = 0; i < n; ++i) {
                const Complex tw = twiddle[(static_cast<std::size_t>(m) * i) % n];
                for (std::size_t f = 0; f < n * Kn; ++f) F[static_cast<std::size_t>(m) * n * Kn + f] += tw * G[i * n * Kn + f];
            }
        const long waves = static_cast<long>(W);
#pragma omp parallel for schedule(static) if (parallel)
        for (long w = 0; w < waves; ++w)
            for (std::size_t s = w_slots[static_cast<std::size_t>(w)]; s < w_slots[static_cast<std::size_t>(w) + 1]; ++s) {
                double sum = 0.0;
                for (std::size_t o = s_orders[s]; o < s_orders[s + 1]; ++o) {
                    const Complex* f = &F[(static_cast<std::size_t>(om[o]) * n + static_cast<std::size_t>(on[o])) * Kn];
                    Complex a(0.0, 0.0);
                    for (std::size_t l = 0; l < Kn; ++l) a += Es[o * Kn + l] * f[l];
                    A[o] = a;
                    sum += std::norm(a);
                }
                acc[s] = sum;
            }
    }
};

ReliefAnnealer::ReliefAnnealer(const std::vector<OrderSet>& sets, const Target& target, int size, int levels,
                               double step_um, const AnnealAims& aims, double rho)
    : m(std::make_unique<Impl>()) {
    Impl& p = *m;
    p.N = size;
    p.K = levels;
    p.aims = aims;
    p.rho = rho;
    p.W = sets.size();
    p.groups = target.groups();
    p.w_slots.push_back(0);
    p.s_orders.push_back(0);
    const double inv = 1.0 / (static_cast<double>(size) * size);
    for (std::size_t w = 0; w < sets.size(); ++w) {
        const OrderSet& set = sets[w];
        const auto& mem = target.members()[w];
        // The orders in slot order (by their pair of groups), each slot's in the sets' order.
        std::vector<std::size_t> order(set.size());
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return mem[x] < mem[y]; });
        for (std::size_t k = 0; k < order.size(); ++k) {
            const std::size_t o = order[k];
            if (k == 0 || mem[o] != mem[order[k - 1]]) {
                if (k > 0) p.s_orders.push_back(p.om.size());
                p.s_groups.push_back(mem[o]);
                p.s_cone.push_back(mem[o][0] == 0 ? 1 : 0);
                p.s_bin.push_back(mem[o][1] >= 1 && mem[o][1] <= k_bins ? mem[o][1] - 1 : -1);
            }
            p.om.push_back(((set.m[o] % size) + size) % size);
            p.on.push_back(((set.n[o] % size) + size) % size);
            const double scale = std::sqrt(set.env[o]) * inv;
            for (int l = 0; l < levels; ++l)
                p.Es.push_back(std::polar(scale, -set.k * set.q[o] * l * step_um));
        }
        if (!order.empty()) p.s_orders.push_back(p.om.size());
        p.w_slots.push_back(p.s_groups.size());
    }
    const std::size_t orders = p.om.size(), Kn = static_cast<std::size_t>(levels);
    p.Eo.resize(2 * orders * Kn);
    for (std::size_t o = 0; o < orders; ++o)
        for (std::size_t l = 0; l < Kn; ++l) {
            p.Eo[o * 2 * Kn + l] = static_cast<float>(p.Es[o * Kn + l].real());
            p.Eo[o * 2 * Kn + Kn + l] = static_cast<float>(p.Es[o * Kn + l].imag());
        }
    for (int s = 0; s < size; ++s) p.twiddle.push_back(std::polar(1.0, -2.0 * k_pi * s / size));
    p.A.assign(orders, Complex(0.0, 0.0));
    p.acc.assign(p.s_groups.size(), 0.0);
    p.lam_c.assign(p.W, 0.0);
    p.lam_u.assign(p.W, 0.0);
    p.delta.assign(p.s_groups.size() * Kn, 0.0);
    p.row_phase.assign(static_cast<std::size_t>(size), 0);
    p.col_phase.assign(static_cast<std::size_t>(size), 0);
    p.level.assign(static_cast<std::size_t>(size) * static_cast<std::size_t>(size), 0);
    p.can_share = static_cast<double>(orders) * levels >= k_parallel_work && omp_get_max_threads() > 1;
    p.parallel = p.can_share;
}

ReliefAnnealer::~ReliefAnnealer() = default;

void ReliefAnnealer::set_relief(const std::vector<int>& level) {
    assert(level.size() == m->level.size());
    m->level = level;
    m->refresh();
}

void ReliefAnnealer::refresh() { m->refresh(); }

const std::vector<int>& ReliefAnnealer::level() const { return m->level; }

AnnealScore ReliefAnnealer::score(bool use_hinge) const { return m->score(-1, use_hinge); }

Fractions ReliefAnnealer::fractions() const {
    const Impl& p = *m;
    Fractions f(p.W, std::vector<double>(static_cast<std::size_t>(p.groups), 0.0));
    for (std::size_t w = 0; w < p.W; ++w) {
        double total = 0.0;
        for (std::size_t s = p.w_slots[w]; s < p.w_slots[w + 1]; ++s) {
            total += p.acc[s];
            for (int q : p.s_groups[s])
                if (q >= 0) f[w][static_cast<std::size_t>(q)] += p.acc[s];
        }
        if (total > 0.0)
            for (double& x : f[w]) x /= total;
    }
    return f;
}

long ReliefAnnealer::heat_sweep(double temperature, std::mt19937_64& rng, const std::function<void()>& on_move) {
    Impl& p = *m;
    std::vector<int> order(p.level.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<double> value(static_cast<std::size_t>(p.K)), weight(static_cast<std::size_t>(p.K));
    long moved = 0;
    for (int t : order) {
        p.trial_any(t);
        double top = -1e300;
        for (int b = 0; b < p.K; ++b) top = std::max(top, value[static_cast<std::size_t>(b)] = p.score(b, false).objective);
        // The heat bath: level b with probability ∝ exp(objective_b / T).
        double sum = 0.0;
        for (std::size_t b = 0; b < value.size(); ++b) sum += weight[b] = std::exp((value[b] - top) / temperature);
        double r = unit(rng) * sum;
        std::size_t b = 0;
        while (b + 1 < value.size() && r >= weight[b]) r -= weight[b++];
        if (static_cast<int>(b) == p.level[static_cast<std::size_t>(t)]) continue;
        p.accept(t, static_cast<int>(b));
        ++moved;
        if (on_move) on_move();
    }
    return moved;
}

long ReliefAnnealer::greedy_pass() {
    Impl& p = *m;
    long kept = 0;
    for (int t = 0; t < static_cast<int>(p.level.size()); ++t) {
        p.trial_any(t);
        const int a = p.level[static_cast<std::size_t>(t)];
        int best = a;
        double best_value = p.score(-1, true).objective;
        for (int b = 0; b < p.K; ++b) {
            const double v = p.score(b, true).objective;
            if (b != a && v > best_value + 1e-12) {
                best = b;
                best_value = v;
            }
        }
        if (best != a) {
            p.accept(t, best);
            ++kept;
        }
    }
    return kept;
}

bool ReliefAnnealer::can_share() const { return m->can_share; }
void ReliefAnnealer::set_shared(bool shared) { m->parallel = shared && m->can_share; }

void ReliefAnnealer::update_multipliers() {
    Impl& p = *m;
    for (std::size_t w = 0; w < p.W; ++w) {
        const auto [region, cone, u] = Impl::measures(p.wave(w, -1));
        (void)region;
        p.lam_c[w] = std::max(0.0, p.lam_c[w] + p.rho * (cone / p.aims.cone - 1.0));
        p.lam_u[w] = std::max(0.0, p.lam_u[w] + p.rho * (u / p.aims.uniformity - 1.0));
    }
}

namespace {

// A relief the anneal may keep, with its score.
struct Candidate {
    std::vector<int> level;
    AnnealScore score, hinge;
    std::string from;
};

bool better(const Candidate& x, const Candidate& y) {
    if (x.score.within_aims != y.score.within_aims) return x.score.within_aims;
    if (x.score.within_aims) return x.score.region > y.score.region;
    return x.hinge.objective > y.hinge.objective;
}

}  // namespace

AnnealOutcome anneal_relief(const std::vector<OrderSet>& sets, const Target& target, int size, int levels,
                            double step_um, const AnnealAims& aims, const AnnealSchedule& schedule,
                            const std::vector<int>& start, const std::function<bool(const AnnealProgress&)>& on_progress) {
    const double c0 = cpu_seconds();
    ReliefAnnealer an(sets, target, size, levels, step_um, aims, schedule.rho);
    AnnealOutcome out;
    std::vector<Candidate> candidates;
    const auto candidate = [&](std::string from) {
        an.refresh();
        candidates.push_back({an.level(), an.score(false), an.score(true), std::move(from)});
    };
    an.set_relief(start);
    candidate("start");
    out.start = candidates.back().score;

    // The sweeps, keeping the best relief within the aims.
    std::mt19937_64 rng(schedule.seed);
    std::vector<int> best_level;
    double best_region = -1.0;
    const auto keep_best = [&] {
        const AnnealScore s = an.score();
        if (s.within_aims && s.region > best_region) {
            best_region = s.region;
            best_level = an.level();
        }
    };
    // Shared or not (can_share): every k_probe sweeps one sweep of each, timed, then the faster.
    constexpr int k_probe = 50;
    double shared_s = 0.0, alone_s = 0.0;
    for (int k = 0; k < schedule.sweeps; ++k) {
        const double x = schedule.sweeps > 1 ? static_cast<double>(k) / (schedule.sweeps - 1) : 1.0;
        const double T = schedule.t_start * std::pow(schedule.t_end / schedule.t_start, x);
        const int probe = k % k_probe;
        if (probe < 2) an.set_shared(probe == 0);
        const auto t0 = std::chrono::steady_clock::now();
        const long moved = an.heat_sweep(T, rng, keep_best);
        if (probe < 2) {
            const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            (probe == 0 ? shared_s : alone_s) = s;
            if (probe == 1) an.set_shared(shared_s < alone_s);
        }
        out.moves += moved;
        an.update_multipliers();
        an.refresh();
        if (on_progress && !on_progress({k + 1, T, an.score(), moved, best_region})) break;
    }

    // The descents, from the last relief and from the best one.
    const auto descend = [&](const std::string& from) {
        for (int pass = 0; pass < schedule.greedy_passes; ++pass) {
            const long kept = an.greedy_pass();
            out.greedy_moves += kept;
            if (kept == 0) break;
        }
        candidate(from);
    };
    if (schedule.sweeps > 0) descend("greedy from the last");
    if (!best_level.empty()) {
        an.set_relief(best_level);
        candidate("sweeps");
        descend("greedy from the best");
    }
    const Candidate* kept = &candidates.front();
    for (const Candidate& c : candidates)
        if (better(c, *kept)) kept = &c;
    out.level = kept->level;
    out.kept = kept->score;
    out.kept_from = kept->from;
    out.cpu_seconds = cpu_seconds() - c0;
    return out;
}

double anneal_cpu_estimate_s(double orders, int size, int levels, int sweeps) {
    // Measured on a 32² tile's 1024 texels over 45 276 orders on 8 levels: 0.35 CPU-s a sweep in
    // the study (experiments/2026-12-01-antimirror-annealing.md), 0.17–0.21 here (400 sweeps in
    // 68 CPU-s within the acceptance run): about 5 ns per texel and order, the levels' loop included.
    constexpr double k_seconds = 5e-9;
    return k_seconds * (4.0 + levels) / 12.0 * orders * static_cast<double>(size) * size * sweeps;
}

}  // namespace wavebrdf::detail
