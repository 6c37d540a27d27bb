// Tile continuation: design on smaller tiles, tile, continue (continuation.h).
#include "design/continuation.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <optional>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "design/anneal.h"
#include "design/colour_bound.h"
#include "design/target.h"
#include "wavebrdf/design.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

namespace {

std::vector<int> parse_continuation_sizes(const std::string& text) {
    std::vector<int> sizes;
    std::size_t at = 0;
    while (at <= text.size()) {
        const std::size_t comma = std::min(text.find(',', at), text.size());
        const std::string part = text.substr(at, comma - at);
        std::size_t used = 0;
        int n = 0;
        try {
            n = std::stoi(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (part.empty() || used != part.size())
            throw std::invalid_argument("--continuation " + text +
                                        " is not a schedule; expected auto, off, or tile sizes such as 64,128");
        sizes.push_back(n);
        at = comma + 1;
    }
    return sizes;
}

// A given schedule's sizes against the run: ascending, each dividing the next and the run's size.
void check_continuation_sizes(const DesignOptions& o, const std::vector<int>& sizes, bool grayscale) {
    const std::string& c = o.continuation;
    if (o.target.kind != DesignKind::AntiMirror && o.target.kind != DesignKind::Colour &&
        o.target.kind != DesignKind::Iridescent)
        throw std::invalid_argument("--continuation " + c + " with --target " + o.target.text +
                                    ": a continuation is for the anti-mirror, colour and iridescent targets; expected auto or off");
    if (grayscale)
        throw std::invalid_argument("--continuation " + c +
                                    " with a grayscale relief (--min-feature-um): a continuation tiles reliefs on levels; expected auto or off");
    if (!o.start_heights_um.empty())
        throw std::invalid_argument("--continuation " + c +
                                    " with a start relief (--start): the start is where the design begins; expected auto or off");
    for (std::size_t i = 0; i < sizes.size(); ++i) {
        const int next = i + 1 < sizes.size() ? sizes[i + 1] : o.size;
        if (!(sizes[i] >= 2 && sizes[i] < next && next % sizes[i] == 0))
            throw std::invalid_argument("--continuation " + c + ": tile " + std::to_string(sizes[i]) +
                                        " does not divide " + std::to_string(next) +
                                        "; expected ascending sizes of at least 2, each dividing the next and --size " +
                                        std::to_string(o.size));
    }
}

// A tile of `tile`² texels' share of the budget: times (size/tile)², so that it costs about what
// the run's own tile does, divided among the `earlier` tiles, so that they cost together about that.
int scaled_budget(int budget, int size, int tile, std::size_t earlier) {
    const double factor = static_cast<double>(size) / tile;
    return static_cast<int>(std::min(100000.0, budget * factor * factor / static_cast<double>(earlier)));
}

// auto's tiles: N/2, then halved again while the half still holds, at every wavelength, an order
// besides the central one inside the cone of half-width `cone` (the orders lie λ/(n·texel) apart in
// direction cosines), so that every tile sees the cone's own orders, not one order alone.
// Whether an n² tile's orders lie at most `cone` apart at every wavelength (λ/(n·texel) ≤ cone), so
// that a cone of that half-width holds one wherever it points.
bool orders_within_cone(const DesignOptions& o, int n, double cone) {
    double lambda_max = 0.0;
    for (double lambda : design_wavelengths_um(o)) lambda_max = std::max(lambda_max, lambda);
    return lambda_max / (n * o.texel_um) <= cone;
}

// Whether the run's view cone (or one of them) is centred off the mirror direction.
bool cone_off_the_mirror(const DesignOptions& o) {
    if (o.target.kind == DesignKind::Iridescent) return true;
    return o.view && ((*o.view)[0] != -o.omega_i[0] || (*o.view)[1] != -o.omega_i[1]);
}

std::vector<int> auto_sizes(const DesignOptions& o, double cone) {
    // Not below a 2² tile, the smallest --size (coarse texels hold the cone's orders on any tile).
    std::vector<int> sizes{o.size / 2};
    while (sizes.front() % 2 == 0 && sizes.front() / 2 >= 2 && orders_within_cone(o, sizes.front() / 2, cone))
        sizes.insert(sizes.begin(), sizes.front() / 2);
    return sizes;
}

// The most of its optimal-colour limit a design on its tile alone reaches, rounded up: every
// colour that reached its chromaticity on the colour acceptance's tile got 21-43 % of its limit,
// the docs' iridescent pairs 5-16 % (experiments/2026-12-01-colour-continuation-rule.md).
constexpr double k_reached_share_of_limit = 0.5;

// Whether a colour (or any iridescent pair) is in the regime where the colour loss's two terms
// compete: half of its optimal-colour limit (the brightest reflectance spectrum of its chromaticity
// under this white light), the most a design on its tile alone reaches, is below the luminous
// efficiency the loss asks for (k_colour_loss_min_y), so the tile alone ends where the loss still
// counts Y and its schedule trades the chromaticity for it.
bool colour_loss_terms_compete(const DesignOptions& o) {
    const auto weights = colour_xyz_weights(design_wavelengths_um(o));
    const auto dim = [&](const std::array<double, 3>& linear_rgb) {
        const auto uv = xyz_to_uv(linear_srgb_to_xyz(linear_rgb));
        return k_reached_share_of_limit * optimal_colour_bound(weights, uv, 0.0).y_at_target < k_colour_loss_min_y;
    };
    if (o.target.kind == DesignKind::Colour) return dim(o.target.linear_rgb);
    return std::any_of(o.target.pairs.begin(), o.target.pairs.end(),
                       [&](const IridescentPair& pair) { return dim(pair.linear_rgb); });
}

}  // namespace

std::vector<DesignStage> continuation_stages(const DesignOptions& o, bool grayscale) {
    const std::string& c = o.continuation;
    if (c == "off") return {};
    std::vector<int> sizes;
    if (c == "auto") {
        if (grayscale || !o.start_heights_um.empty() || o.size % 2 != 0) return {};
        if (o.target.kind == DesignKind::AntiMirror) sizes = auto_sizes(o, o.specular_cone);
        // A cone off the mirror (an iridescent pair's, a colour's given view) may hold no order of the
        // half tile unless its orders lie within the cone: the half would design an empty cone (an
        // iridescent pair's is refused) where the tile does not. The mirror order is in every mirror cone.
        else if ((o.target.kind == DesignKind::Colour || o.target.kind == DesignKind::Iridescent) &&
                 colour_loss_terms_compete(o) && (!cone_off_the_mirror(o) || orders_within_cone(o, o.size / 2, o.view_cone)))
            sizes = auto_sizes(o, o.view_cone);
        else return {};
    } else {
        sizes = parse_continuation_sizes(c);
        check_continuation_sizes(o, sizes, grayscale);
    }
    std::vector<DesignStage> stages;
    for (int n : sizes)
        stages.push_back({n, scaled_budget(o.iterations, o.size, n, sizes.size()),
                          scaled_budget(o.refine_passes, o.size, n, sizes.size())});
    return stages;
}

std::vector<int> tile_levels(const std::vector<int>& level, int n, int size) {
    std::vector<int> out(static_cast<std::size_t>(size) * static_cast<std::size_t>(size));
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
            out[static_cast<std::size_t>(y) * size + x] = level[static_cast<std::size_t>(y % n) * n + x % n];
    return out;
}

namespace {

using ContinuationClock = std::chrono::steady_clock;

double continuation_seconds(ContinuationClock::time_point since) {
    return std::chrono::duration<double>(ContinuationClock::now() - since).count();
}

// p started from `level` (n² texels, tiled to p's size) on levels `step` apart.
void start_from_tile(PreparedDesign& p, const std::vector<int>& level, int n, double step) {
    p.start_level = tile_levels(level, n, p.options.size);
    for (std::size_t k = 0; k < p.levels_um.size(); ++k) p.levels_um[k] = static_cast<double>(k) * step;
}

// design.json of the last tile, told that it continued `stages` (their schedule entries).
std::string continued_json(const PreparedDesign& p, double rule, const std::string& last_json, nlohmann::json stages,
                           double stage_seconds, double total_seconds) {
    nlohmann::json j = nlohmann::json::parse(last_json);
    const DesignOptions& o = p.options;
    stages.push_back({{"size", o.size}, {"iterations", o.iterations}, {"refine_passes", o.refine_passes},
                      {"seconds", j["timings_s"]["total"]}});
    std::string sizes;
    for (const auto& s : stages) sizes += (sizes.empty() ? "" : " -> ") + std::to_string(s["size"].get<int>());
    j["continuation"] = {{"what", "designed on each tile in turn (" + sizes +
                                      "): the first from a random start, each next from the last relief "
                                      "repeated to its size; a tile of n^2 texels took the iterations and passes "
                                      "times (size/n)^2 divided by the number of earlier tiles (together about the "
                                      "last tile's CPU)" +
                                      std::string(stages[0].contains("designed_by")
                                                      ? ", but for the first, the step survey's best tile, designed at "
                                                        "the run's iterations and passes"
                                                      : "") +
                                      "; exact: each tile's relief scored by exact scalar diffraction"},
                         {"setting", o.continuation},
                         {"schedule", stages}};
    j["options"]["continuation"] = o.continuation;
    j["start"] = "random (seed) on the continuation's first tile, " + std::to_string(stages[0]["size"].get<int>()) +
                 " x " + std::to_string(stages[0]["size"].get<int>());
    if (j.contains("level_step")) {
        j["level_step"]["what"] = "the anti-mirror's level step, a design variable: started on the rule's step on the "
                                  "continuation's first tile and moved with the texels by its gradient on every tile, "
                                  "(levels - 1) x step <= height_range_um";
        j["level_step"]["start_um"] = rule;
        nlohmann::json notes = nlohmann::json::array();
        for (const auto& note : j["notes"])
            if (note.get<std::string>().find("designed from the start relief's") == std::string::npos) notes.push_back(note);
        const double final_um = j["level_step"]["final_um"].get<double>();
        notes.push_back("level step " + format_number(final_um, "%.4g") + " um (top level " +
                        format_number(final_um * (o.levels - 1), "%.4g") + " um), designed on the continuation's tiles from the rule's " +
                        format_number(rule, "%.4g") + " um");
        j["notes"] = notes;
    }
    j["timings_s"]["continuation"] = stage_seconds;
    j["timings_s"]["total"] = total_seconds;
    return j.dump(2);
}

// design.json of an annealed run (continued_json's, from the last tile's): the loop designed the
// n² tile, the anneal ("anneal" block) was its last stage, the run's tile is that relief repeated.
std::string annealed_json(const PreparedDesign& p, int n, const std::string& json, nlohmann::json anneal) {
    nlohmann::json j = nlohmann::json::parse(json);
    const DesignOptions& o = p.options;
    const std::string tile = std::to_string(n) + "x" + std::to_string(n);
    const bool surveyed = j["continuation"]["schedule"][0].contains("designed_by");
    j["continuation"]["what"] = std::string(surveyed ? "the step survey designed the " : "the loop designed the ") +
                                tile + " tile" + (p.stages.empty() ? "" : " (the continuation's first)") +
                                ", the anneal (anneal) was its last stage, and the " + std::to_string(o.size) + "x" +
                                std::to_string(o.size) + " tile is that relief repeated and scored (a tiled relief "
                                "reflects exactly its tile's orders), not polished";
    j["options"]["anneal_sweeps"] = p.anneal_sweeps;
    if (!p.start_level.empty()) j["start"] = "the given relief (start_heights_um, --start)";
    if (!anneal.is_null()) {
        j["timings_s"]["anneal"] = anneal["seconds"];
        j["anneal"] = std::move(anneal);
    }
    if (j.contains("level_step")) {
        j["level_step"]["what"] = "the anti-mirror's level step, a design variable: moved with the texels by its gradient "
                                  "while the loop designed the " + tile + " tile, then fixed while annealing, "
                                  "(levels - 1) x step <= height_range_um";
        for (auto& note : j["notes"])
            if (note.get<std::string>().find("designed on the continuation's tiles") != std::string::npos) {
                std::string text = note.get<std::string>();
                text.replace(text.find("on the continuation's tiles"), std::string("on the continuation's tiles").size(),
                             "on the " + tile + " tile (then annealed)");
                note = text;
            }
    }
    return j.dump(2);
}

// The annealed last stage (anneal.h) on the tile sp designed, from its relief `level` on levels
// `step` apart: the relief kept, and design.json's "anneal" block. Reports every sweep through
// `report` as a step of phase "anneal NxN" (loss: 1 − the annealed objective; temperature: T);
// a false return stops the sweeps.
struct AnnealedTile {
    std::vector<int> level;
    nlohmann::json json;
};
AnnealedTile anneal_tile(const PreparedDesign& sp, int sweeps, double cpu_estimate_s, const std::vector<int>& level,
                         double step, const DesignStepFn& report) {
    const DesignOptions& o = sp.options;
    const auto t0 = ContinuationClock::now();
    AnnealSchedule schedule;
    schedule.sweeps = sweeps;
    schedule.seed = o.seed;
    const AnnealAims aims = anneal_aims(o.cone_limit, o.uniformity_limit);
    const std::string phase = "anneal " + std::to_string(o.size) + "x" + std::to_string(o.size);
    int run = 0;
    const AnnealOutcome a = anneal_relief(
        *sp.order_sets, *sp.target, o.size, o.levels, step, aims, schedule, level, [&](const AnnealProgress& g) {
            run = g.sweep;
            return !report || report({phase, g.sweep - 1, 1.0 - g.current.objective, g.temperature});
        });
    const auto scores = [](const AnnealScore& s) {
        return nlohmann::json{{"region_fraction_mean", s.region}, {"specular_fraction_worst", s.cone_worst},
                              {"uniformity_worst", s.uniformity_worst}, {"within_aims", s.within_aims}};
    };
    nlohmann::json j{
        {"what", "heat-bath sweeps over the tile's texels, each texel set to a level drawn with probability "
                 "proportional to exp(objective / T) by the exact far field updated move by move; objective: the "
                 "region's band mean less the augmented-Lagrangian terms (max(0, l + rho g)^2 - l^2) / (2 rho) of "
                 "g = x / aim - 1 for the cone's fraction and the uniformity at every wavelength, the multipliers l "
                 "moved after every sweep (l <- max(0, l + rho g)); T geometric from t_start to t_end; then "
                 "best-improvement passes from the last relief and from the best one; kept: the relief within both "
                 "aims at every wavelength of the highest region among the loop's, the best seen and the passes' ends"},
        {"tile", o.size},
        {"sweeps", sweeps},
        {"sweeps_run", run},
        {"schedule", {{"t_start", schedule.t_start}, {"t_end", schedule.t_end}, {"kind", "geometric"}}},
        {"rho", schedule.rho},
        {"aims", {{"cone", aims.cone}, {"uniformity", aims.uniformity}}},
        {"greedy_passes", schedule.greedy_passes},
        {"seed", schedule.seed},
        {"level_step_um", step},
        {"before", scores(a.start)},
        {"after", scores(a.kept)},
        {"kept_from", a.kept_from},
        {"moves", a.moves},
        {"greedy_moves", a.greedy_moves},
        {"cpu_s", a.cpu_seconds},
        {"cpu_estimate_s", cpu_estimate_s},
        {"seconds", continuation_seconds(t0)}};
    return {a.level, j};
}

}  // namespace

DesignResult run_continued(const PreparedDesign& p, const DesignStepFn& on_step, const RunOneDesign& run_one,
                           const DesignResult* first_tile) {
    const auto start = ContinuationClock::now();
    std::vector<DesignStep> curve;
    int offset = 0;
    std::string tile;  // an earlier tile's steps are marked with its size (the report's curve, one line a phase)
    bool stopped = false;
    // A tile's step as the run's curve holds it: after the earlier tiles' steps, marked with the tile.
    const auto in_run = [&](DesignStep t) {
        t.iteration += offset;
        t.phase += tile;
        return t;
    };
    const DesignStepFn forward = [&](const DesignStep& s) {
        const DesignStep t = in_run(s);
        curve.push_back(t);
        if (!stopped && on_step && !on_step(t)) stopped = true;
        return !stopped;
    };
    nlohmann::json stages = nlohmann::json::array();
    std::vector<int> level;
    int n = 0;
    double step = 0.0;
    // Annealed: the loop designs the first tile alone (the run's own without a continuation), and
    // the anneal on it is the last stage.
    const bool anneal = p.anneal_sweeps > 0;
    std::vector<DesignStage> schedule = p.stages;
    if (anneal) {
        if (schedule.empty()) schedule.push_back({p.options.size, p.options.iterations, p.options.refine_passes});
        schedule.resize(1);
    }
    std::optional<PreparedDesign> first;
    for (const DesignStage& s : schedule) {
        DesignOptions o = p.options;
        o.size = s.size;
        o.iterations = s.iterations;
        o.refine_passes = s.refine_passes;
        o.continuation = "off";
        o.anneal_sweeps = 0;
        o.survey_views = false;  // an earlier tile is no design of its own: the last tile surveys
        const auto t0 = ContinuationClock::now();
        tile = " " + std::to_string(s.size) + "x" + std::to_string(s.size);
        PreparedDesign sp = prepare_design(o);
        if (!level.empty()) start_from_tile(sp, level, n, step);
        const bool made = first_tile && level.empty();
        if (made)
            for (const DesignStep& t : first_tile->curve) curve.push_back(in_run(t));
        const DesignResult r = made ? *first_tile : run_one(sp, forward);
        const nlohmann::json j = nlohmann::json::parse(r.metrics_json);
        const nlohmann::json& options = j["options"];
        stages.push_back({{"size", s.size}, {"iterations", options["iterations"]}, {"refine_passes", options["refine_passes"]},
                          {"seconds", made ? j["timings_s"]["total"] : nlohmann::json(continuation_seconds(t0))},
                          {"level_step_um", r.levels_um[1] - r.levels_um[0]},
                          {"exact", j["metrics"]["exact"]}, {"warnings", j["warnings"]}});
        if (made) stages.back()["designed_by"] = "the step survey (its best step's tile)";
        level = r.level;
        n = s.size;
        step = r.levels_um[1] - r.levels_um[0];
        if (!curve.empty()) offset = curve.back().iteration + 1;
        if (anneal) first = std::move(sp);
    }
    nlohmann::json anneal_json;
    if (anneal && !stopped) {
        tile.clear();
        AnnealedTile a = anneal_tile(*first, p.anneal_sweeps, p.anneal_cpu_estimate_s, level, step, forward);
        level = std::move(a.level);
        anneal_json = std::move(a.json);
        if (!curve.empty()) offset = curve.back().iteration + 1;
    }
    const double stage_seconds = continuation_seconds(start);
    tile.clear();
    PreparedDesign last = p;
    last.stages.clear();
    start_from_tile(last, level, n, step);
    if (anneal) {
        // The annealed tile repeated is the design: scored as it is (a tiled relief reflects exactly its
        // tile's orders), not polished (the loop's phases from it lower the region it reached).
        last.options.iterations = 0;
        last.options.refine_passes = 0;
    }
    DesignResult r = run_one(last, forward);
    r.curve = std::move(curve);
    r.metrics_json = continued_json(anneal ? last : p, p.levels_um[1] - p.levels_um[0], r.metrics_json,
                                    std::move(stages), stage_seconds, continuation_seconds(start));
    if (anneal) r.metrics_json = annealed_json(p, n, r.metrics_json, std::move(anneal_json));
    return r;
}

}  // namespace wavebrdf::detail
