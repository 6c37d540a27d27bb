// The anti-mirror's level step: the rule and the survey (level_step.h).
#include "design/level_step.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "design/engine.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

// How dark levels 0, Δ, …, (K−1)Δ can make the mirror order over the whole band. Its amplitude
// is P(z) = Σ_ℓ a_ℓ z^ℓ, a_ℓ ≥ 0 the levels' shares (Σ a_ℓ = 1), z = e^{−iθ}, θ = 2 k Δ cos θ_i,
// whatever the texels' arrangement: a polynomial with non-negative coefficients that must be
// small on the arc of θ the band sweeps. A step with 2Δ cos θ_i a multiple of a wavelength in the
// band (θ = 2π) makes every design a mirror there; short of that, the shares that keep |P|² least
// on average over the band (a dense grid between its extreme wavelengths) are the minimum of the
// quadratic form a·G·a, G_ℓm = mean over the grid of cos((ℓ − m)θ), on the simplex: a small
// convex problem, solved exactly by an active set. Their worst power over the grid says how well a
// step suits the band. (The binomial shares C(K−1, ℓ)/2^{K−1}, |P| = |cos(θ/2)|^{K−1}, are dark only
// near θ = π: on 0.40–0.70 µm with 8 levels they need Δ ≤ 0.132 µm for a power of 1e-5 and 0.138 µm for
// 1e-4, where these shares allow 0.146 and 0.153 µm.)
MirrorShares dark_mirror_shares(double step_um, int levels, const std::vector<double>& lambdas_um, double cos_i) {
    const auto [lo, hi] = std::minmax_element(lambdas_um.begin(), lambdas_um.end());
    constexpr int k_dense = 128;
    const auto K = static_cast<std::size_t>(levels);
    std::vector<double> thetas;
    for (int d = 0; d <= (*hi > *lo ? k_dense : 0); ++d)
        thetas.push_back(4.0 * k_pi * step_um * cos_i / (*lo + (*hi - *lo) * d / k_dense));
    // G depends on ℓ − m only.
    std::vector<long double> c(K, 0.0L);
    for (std::size_t d = 0; d < K; ++d) {
        for (double th : thetas) c[d] += std::cos(static_cast<long double>(d) * static_cast<long double>(th));
        c[d] /= static_cast<long double>(thetas.size());
    }
    auto G = [&](std::size_t l, std::size_t m) { return c[l > m ? l - m : m - l] + (l == m ? 1e-13L : 0.0L); };
    // Primal active set from the uniform shares: on the free set F, the least a·G·a with
    // Σ a = 1 is a_F ∝ G_FF⁻¹ 1; step towards it until a share reaches 0 (it leaves F); at the
    // minimum over F, add the level whose gradient most undercuts the multiplier, until none does.
    std::vector<long double> x(K, 1.0L / static_cast<long double>(K));
    std::vector<char> free(K, 1);
    for (int guard = 0; guard < 4 * levels + 8; ++guard) {
        std::vector<std::size_t> F;
        for (std::size_t l = 0; l < K; ++l)
            if (free[l]) F.push_back(l);
        const std::size_t n = F.size();
        // Cholesky of G_FF, then y = G_FF⁻¹ 1.
        std::vector<long double> L(n * n, 0.0L), y(n, 1.0L);
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = 0; j <= i; ++j) {
                long double sum = G(F[i], F[j]);
                for (std::size_t k = 0; k < j; ++k) sum -= L[i * n + k] * L[j * n + k];
                L[i * n + j] = i == j ? std::sqrt(std::max(sum, 1e-30L)) : sum / L[j * n + j];
            }
        for (std::size_t i = 0; i < n; ++i) {
            for (std::size_t k = 0; k < i; ++k) y[i] -= L[i * n + k] * y[k];
            y[i] /= L[i * n + i];
        }
        for (std::size_t i = n; i-- > 0;) {
            for (std::size_t k = i + 1; k < n; ++k) y[i] -= L[k * n + i] * y[k];
            y[i] /= L[i * n + i];
        }
        long double total = 0.0L;
        for (long double v : y) total += v;
        std::vector<long double> s(K, 0.0L);
        bool feasible = true;
        for (std::size_t i = 0; i < n; ++i) {
            s[F[i]] = y[i] / total;
            feasible = feasible && s[F[i]] >= 0.0L;
        }
        if (!feasible) {
            long double alpha = 1.0L;
            for (std::size_t l : F)
                if (s[l] < 0.0L) alpha = std::min(alpha, x[l] / (x[l] - s[l]));
            for (std::size_t l : F) {
                x[l] += alpha * (s[l] - x[l]);
                if (x[l] <= 1e-18L) {
                    x[l] = 0.0L;
                    free[l] = 0;
                }
            }
            continue;
        }
        x = s;
        // Optimality: (G x)_ℓ ≥ x·G·x for every level outside F.
        long double quad = 0.0L;
        std::vector<long double> gx(K, 0.0L);
        for (std::size_t l = 0; l < K; ++l) {
            for (std::size_t m = 0; m < K; ++m) gx[l] += G(l, m) * x[m];
            quad += x[l] * gx[l];
        }
        std::size_t add = K;
        long double most = 1e-15L;
        for (std::size_t l = 0; l < K; ++l)
            if (!free[l] && quad - gx[l] > most) {
                most = quad - gx[l];
                add = l;
            }
        if (add == K) break;
        free[add] = 1;
    }
    MirrorShares r;
    r.shares.assign(x.begin(), x.end());
    r.worst_power = 0.0;
    for (double th : thetas) {
        std::complex<double> a(0.0, 0.0);
        for (std::size_t l = 0; l < K; ++l) a += r.shares[l] * std::polar(1.0, -th * static_cast<double>(l));
        r.worst_power = std::max(r.worst_power, std::norm(a));
    }
    return r;
}

// The rule's step: the largest Δ ≤ H/(K−1) on which some shares of the levels keep the mirror
// order's power at most k_mirror_power_wanted at every wavelength of the band, else the step of
// least such power. 1e-4 keeps the mirror order at a twentieth of a 0.2 % cone, so that a loop
// started there starts from a mirror order it can darken. It is the survey's first candidate, and
// the step where no survey runs (a fixed step's default, a blur error's, a run without a budget).
constexpr double k_mirror_power_wanted = 1e-4;
double anti_mirror_step(double range_um, int levels, const std::vector<double>& lambdas_um, double cos_i) {
    const double full = range_um / (levels - 1);
    double best = full, best_power = 1e300;
    constexpr int k_candidates = 1000;
    for (int c = 0; c < k_candidates; ++c) {
        const double step = full * (1.0 - static_cast<double>(c) / k_candidates);
        const double power = dark_mirror_shares(step, levels, lambdas_um, cos_i).worst_power;
        if (power <= k_mirror_power_wanted) return step;
        if (power < best_power) {
            best_power = power;
            best = step;
        }
    }
    return best;
}


namespace {

// The survey's tile at most this size (a divisor of the run's, so that its relief repeats into the
// run's tile with the same far field), its grid's spacing the step that moves the top level's
// phase by a quarter turn at the band's shortest wavelength, and at most this many steps (evenly
// chosen among the grid's where more qualify).
constexpr int k_step_survey_max_size = 32;
constexpr double k_step_survey_top_phase = k_pi / 2.0;
constexpr int k_step_survey_max_steps = 24;
// The shares' active set costs up to K Cholesky solves of K × K each: with more levels than this
// the survey would take longer to plan than to run, and the run starts on the rule's step.
constexpr int k_step_survey_max_levels = 32;

}  // namespace

void plan_step_survey(PreparedDesign& p, bool free) {
    const DesignOptions& o = p.options;
    if (!free || !p.start_level.empty() || o.iterations + o.refine_passes == 0) return;
    if (o.levels > k_step_survey_max_levels) {
        p.notes.push_back("level step not surveyed: " + std::to_string(o.levels) + " levels (the survey plans up to " +
                          std::to_string(k_step_survey_max_levels) + "); the design starts on the rule's step");
        return;
    }
    // The first tile the loop designs: the continuation's first, else the run's own.
    const int first = p.stages.empty() ? o.size : p.stages.front().size;
    int size = 1;
    for (int d = 1; d <= std::min(first, k_step_survey_max_size); ++d)
        if (o.size % d == 0) size = d;
    if (size < 2) return;
    const double cos_i = p.order_sets->front().cos_i;  // the anti-mirror's one light
    const double lambda_min = *std::min_element(p.lambdas_um.begin(), p.lambdas_um.end());
    const double full = o.height_range_um / (o.levels - 1);
    const double spacing = k_step_survey_top_phase * lambda_min / (4.0 * k_pi * (o.levels - 1) * cos_i);
    const double rule = p.levels_um[1] - p.levels_um[0];
    const double aim = k_anti_mirror_aim * o.cone_limit;
    std::vector<double> grid;
    for (int c = 0;; ++c) {
        const double step = full - c * spacing;
        if (step < 0.5 * spacing) break;
        if (std::abs(step - rule) < 0.5 * spacing) continue;
        if (dark_mirror_shares(step, o.levels, p.lambdas_um, cos_i).worst_power <= aim) grid.push_back(step);
    }
    std::vector<double> steps{rule};
    const std::size_t keep = std::min<std::size_t>(grid.size(), k_step_survey_max_steps - 1);
    for (std::size_t k = 0; k < keep; ++k) steps.push_back(grid[k * grid.size() / keep]);
    if (steps.size() < 2) return;
    std::sort(steps.rbegin(), steps.rend());
    p.step_survey_um = steps;
    p.step_survey_size = size;
    // The survey designs the loop's first tile itself where that tile is one of the run's earlier
    // stages (a continuation's first, or the tile the anneal takes) and is designed as the survey
    // designs it (no fabrication error).
    p.step_survey_first_tile = size == first && (!p.stages.empty() || p.anneal_sweeps > 0) && o.errors.scale == 0.0;
    p.notes.push_back("level step surveyed: " + std::to_string(steps.size()) + " steps from " +
                      format_number(steps.back(), "%.4g") + " to " + format_number(steps.front(), "%.4g") +
                      " um (the rule's and those on which the mirror order can be kept below the cone's aim), "
                      "each designed on a " + std::to_string(size) + "x" + std::to_string(size) + " tile at " +
                      std::to_string(o.iterations) + ":" + std::to_string(o.refine_passes) +
                      "; the design keeps the best (design.json step_survey)" +
                      (p.step_survey_first_tile ? ", and the best step's tile is its first" : ""));
}

StepSurvey run_step_survey(const PreparedDesign& p, const std::function<bool(const DesignStep&)>& on_step) {
    const DesignOptions& o = p.options;
    const auto t0 = std::chrono::steady_clock::now();
    const double rule = p.levels_um[1] - p.levels_um[0];
    nlohmann::json steps = nlohmann::json::array();
    StepSurvey best;
    double best_score = -1e300;
    bool stopped = false;
    int offset = 0;
    for (double step : p.step_survey_um) {
        if (stopped) break;
        DesignOptions v = o;
        v.size = p.step_survey_size;
        v.level_step_um = step;
        v.continuation = "off";
        v.anneal_sweeps = 0;
        v.survey_views = false;
        v.errors = {};
        const PreparedDesign pv = prepare_design(v);
        int last = 0;
        const DesignResult r = run_design(pv, [&](const DesignStep& s) {
            DesignStep t = s;
            t.phase = "step survey";
            t.iteration = offset + s.iteration;
            last = s.iteration + 1;
            if (on_step && !on_step(t)) stopped = true;
            return !stopped;
        });
        offset += last;
        const nlohmann::json j = nlohmann::json::parse(r.metrics_json);
        const nlohmann::json& e = j["metrics"]["exact"];
        const double region = e["region_fraction_mean"].get<double>();
        const double cone = e["specular_fraction_worst"].get<double>();
        const double uniformity = e["uniformity_worst"].get<double>();
        const double score = region - std::max(0.0, cone / o.cone_limit - 1.0) -
                             std::max(0.0, uniformity / o.uniformity_limit - 1.0);
        steps.push_back({{"step_um", step},
                         {"region_fraction_mean", region},
                         {"specular_fraction_worst", cone},
                         {"uniformity_worst", uniformity},
                         {"limits_met", cone <= o.cone_limit && uniformity <= o.uniformity_limit},
                         {"score", score},
                         {"seconds", j["timings_s"]["total"]}});
        if (score > best_score) {
            best_score = score;
            best.step_um = step;
            best.tile = r;
        }
    }
    best.json = {{"what", "the level steps surveyed: each designed on a tile of size^2 texels (a divisor of the run's, "
                          "so that its relief repeats into the run's tile) at the run's iterations and passes, the "
                          "same seed, no continuation or anneal, and scored by its exact metrics: the region's band "
                          "mean less max(0, x / limit - 1) for the cone's fraction and the uniformity at their worst "
                          "wavelengths; the design runs on the step of the highest score, kept fixed"},
                 {"size", p.step_survey_size},
                 {"iterations", o.iterations},
                 {"refine_passes", o.refine_passes},
                 {"rule_um", rule},
                 {"chosen_um", best.step_um},
                 {"stopped_early", stopped},
                 {"steps", steps},
                 {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}};
    return best;
}

}  // namespace wavebrdf::detail
