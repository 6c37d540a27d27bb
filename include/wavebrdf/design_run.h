#pragma once
// One surface design as `wavebrdf design` and the Python module's design() run it, so that both
// share one implementation (docs/design.md): the options parsed and checked once, prepare (the
// target read, the diffraction orders of every wavelength, the memory estimate), run (the
// optimisation, the final relief on the allowed levels, its metrics under the design model, under
// exact scalar diffraction and under fabrication errors) with a callback, and writing the run
// directory. The CLI reads and writes files; the binding converts arrays.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace wavebrdf {

namespace detail {
class Target;
struct OrderSet;
}  // namespace detail
struct BrdfTable;

enum class DesignKind { AntiMirror, Pattern, Colour, Iridescent, Brdf };
const char* to_string(DesignKind kind);

// One (view direction, colour) pair of an iridescent target.
struct IridescentPair {
    std::array<double, 2> view{{0.0, 0.0}};  // projected ω_o, |view| < 1
    std::array<int, 3> srgb8{{255, 255, 255}};
    std::array<double, 3> linear_rgb{{1.0, 1.0, 1.0}};
};

// What the design aims for: `--target anti-mirror | pattern:IMAGE.png | colour:#RRGGBB |
// iridescent:SPEC.json | brdf:TABLE.exr`.
struct DesignTarget {
    DesignKind kind = DesignKind::AntiMirror;
    std::string text = "anti-mirror";  // as given
    // Pattern: the image's grey values in 0 … 1 (relative intensity), row-major, rows along ω_x.
    int image_rows = 0, image_cols = 0;
    std::vector<double> image;
    std::string image_file;  // "" when given as an array
    // Colour: the target as 8-bit sRGB (as typed) and as linear sRGB.
    std::array<int, 3> srgb8{{255, 255, 255}};
    std::array<double, 3> linear_rgb{{1.0, 1.0, 1.0}};
    // Iridescent: the pairs of SPEC.json (docs/design.md), each a view cone with its colour.
    std::vector<IridescentPair> pairs;
    std::string spec_file;
    // Brdf: the tabulated BRDF (table.h) and its file.
    std::shared_ptr<const BrdfTable> table;
    std::string table_file;
};

// Parses a --target text; a pattern's image is read from its PNG (8- or 16-bit, grey or RGB: the
// luminance; at most 1024 × 1024); an iridescent target's pairs from its JSON (at most 64 kB, 1 to
// 16 pairs); a brdf target's table from its EXR (read_brdf_table; the mosaic's size bounded from
// the header before its pixels are read). Throws std::invalid_argument naming the text (unknown
// kind, a colour that is not #RRGGBB, an unreadable or empty image, a bad spec or table) before
// any work.
DesignTarget parse_design_target(const std::string& text);
// A pattern target from grey values (row-major, rows × cols, finite, ≥ 0, not all equal).
DesignTarget pattern_target(int rows, int cols, std::vector<double> image);

// Fabrication errors the design is made robust to and scored under (`scale:5%,blur:0.3um`).
struct FabricationErrors {
    double scale = 0.0;    // relative error of every height (0 … 0.5): the loop averages 1 − s, 1, 1 + s
    double blur_um = 0.0;  // Gaussian σ of the written relief, µm (0 … 10): in the discrete refinement's mean (docs/design.md)
};
// Parses "scale:5%,blur:0.3um" (either part optional, "none" for no errors); std::invalid_argument.
FabricationErrors parse_fabrication_errors(const std::string& text);

// The options of `wavebrdf design` (its defaults).
struct DesignOptions {
    DesignTarget target;
    // Light and wavelengths, as `render` takes them: a laser lambda_um (when spectral is 0) or
    // white light sampled at `spectral` wavelengths over band_um (the slices' band 0.36 … 0.83 µm by
    // default: λ_k = a + (k + ½)(b − a)/N, spectral_wavelengths_um's samples), equal energy.
    // A brdf target takes its table's wavelengths and lights instead (spectral must be 0; omega_i
    // picks the table's nearest light when the table has more than 16).
    std::array<double, 2> omega_i{{0.0, 0.0}};
    double lambda_um = 0.5;
    int spectral = 0;
    std::array<double, 2> band_um{{0.36, 0.83}};
    // Anti-mirror.
    double specular_cone = 0.05;
    std::string region = "annulus:0.1,0.5";  // or disk:R, about the mirror direction
    // The limits the design keeps at every wavelength while it maximises the region's fraction:
    // the cone's fraction of the reflected power and the region's uniformity (std/mean of its 16
    // bins). The loop aims a little inside them; a final relief above either is reported in
    // design.json's warnings (docs/design.md).
    double cone_limit = 0.002;
    double uniformity_limit = 0.25;
    // Pattern: the window's half-width about the mirror direction.
    double window = 0.3;
    // Colour: the view direction (unset: the mirror direction) and its cone (iridescent: the
    // cone of every pair's view; the views are the pairs').
    std::optional<std::array<double, 2>> view;
    double view_cone = 0.05;
    // Colour, iridescent (each pair): the Δu′v′ from the target that the loss does not count
    // (0 … 0.1): within it the design trades chromaticity for luminous efficiency.
    double delta_uv_tolerance = 0.0;
    // Colour, iridescent (each pair): the most Δu′v′ the loop may trade for brightness when its
    // relief ends below the luminous efficiency a reached colour has (Y 0.05): it then continues
    // in blocks of the schedule (warm from the relief) with the tolerance (of each dim pair) raised
    // a quarter of the way to this ceiling per block (docs/design.md); 0, or a ceiling at or below
    // delta_uv_tolerance, stops after the schedule.
    double delta_uv_ceiling = 0.04;
    // The tile and the fabrication constraints.
    int size = 256;                 // N: the N × N tile, 2 … 2048
    double texel_um = 0.5;          // 0.05 … 100
    double height_range_um = 2.0;   // every height within [0, H], 0 < H ≤ 100
    int levels = 8;                 // K equally spaced levels 0, H/(K−1), …, H; 2 … 256 (0: grayscale)
    // The levels' spacing Δ (levels 0, Δ, …, (K−1)Δ, (K−1)Δ ≤ H); 0: H/(K−1), except for the
    // anti-mirror, whose step is the largest that lets every wavelength's mirror order cancel
    // (docs/design.md).
    double level_step_um = 0.0;
    // Grayscale (with levels 0): no lateral detail finer than this, µm (2 texels … the period), by
    // a filtered parameterisation evaluated on 256 levels (docs/design.md); 0: the levels above.
    double min_feature_um = 0.0;
    FabricationErrors errors;
    // A relief to start from (`--start HEIGHTS.exr`, start=): size² heights in µm, row-major, each
    // on one of the run's levels (where the anti-mirror's step is free, the start's own step: the
    // smallest gap between its heights, and that is where the loop's step starts); empty: a
    // random start. The relaxed phase starts warm from it (each texel's own level holding half the
    // weight); with iterations 0 the discrete passes start on it as it is, so with refine_passes 0
    // too the result is the start. Not with a grayscale relief.
    std::vector<double> start_heights_um;
    // Tile continuation (`--continuation`, docs/design.md): "auto", "off", or the sizes of smaller
    // tiles designed first, ascending, each dividing the next and --size ("64,128"). The first
    // starts at random (seed); each tile's relief, repeated to the next size, is where the next
    // starts, as a start relief would be. A tile of n² texels takes iterations and passes times
    // (size/n)² over the number of earlier tiles: together they cost about the last tile's CPU.
    // "auto": the anti-mirror on levels from a random start, even size: size/2 and its halves while
    // one holds an order besides the mirror one in the specular cone at every λ. Schedules: also colour.
    std::string continuation = "auto";
    // The anti-mirror's annealed last stage (`--anneal-sweeps`, docs/design.md): heat-bath sweeps
    // over the continuation's smallest tile (the run's own tile without one) after the loop designed
    // it, each texel drawn among its levels by the exact far field, then that tile repeated to
    // `size` and scored, in place of the larger tiles' polish. Unset: 400 where it applies (the
    // anti-mirror on levels from a random start, no fabrication errors, the sweeps' estimated CPU
    // within an hour), else none, said in the notes; 0: none (the continuation as before);
    // 1 … 100000: those sweeps, refused where annealing does not apply.
    std::optional<int> anneal_sweeps;
    // The optimisation.
    std::uint64_t seed = 1;
    int iterations = 200;       // relaxed (softmax over levels) iterations, 0 … 100000
    int refine_passes = 60;     // discrete passes on the final levels, 0 … 100000
    // Colour: when the design misses its colour, design it for other views too (design.json
    // view_survey; docs/design.md). A plate's palette entries leave it off.
    bool survey_views = true;
    double max_memory_gb = 0.0;  // refuse an estimate above this (0: the physical memory)
};

// The wavelengths of `options` (µm).
std::vector<double> design_wavelengths_um(const DesignOptions& options);

// One step of the optimisation, for progress and metrics.csv.
struct DesignStep {
    std::string phase;   // "relaxed" or "refine" (a continuation's earlier tile: "relaxed 32x32", ...)
    int iteration = 0;   // counted over both phases
    double loss = 0.0;
    double temperature = 0.0;  // softmax temperature (relaxed), or the refine pass's fraction of texels tried
};

// One tile of a continuation (DesignOptions::continuation): its size and budget.
struct DesignStage {
    int size = 0;
    int iterations = 0;
    int refine_passes = 0;
};

struct PreparedDesign {
    DesignOptions options;
    std::vector<double> lambdas_um;
    std::vector<double> levels_um;  // the allowed heights
    double estimated_bytes = 0.0;
    std::size_t orders = 0;         // propagating orders over all wavelengths
    std::vector<std::string> notes;
    std::shared_ptr<const std::vector<detail::OrderSet>> order_sets;
    std::shared_ptr<detail::Target> target;
    std::vector<int> start_level;   // the start relief's level per texel (empty: a random start)
    std::vector<DesignStage> stages;  // the continuation's smaller tiles, designed first (empty: none)
    // The annealed last stage (DesignOptions::anneal_sweeps): its sweeps (0: none), the tile it
    // anneals (the first stage's, else the run's own) and its estimated CPU seconds.
    int anneal_sweeps = 0;
    int anneal_size = 0;
    double anneal_cpu_estimate_s = 0.0;
    // The anti-mirror's level-step survey (where its step is free): the steps it designs a small
    // tile on, step_survey_size² texels, before the design runs on the best (empty: none).
    std::vector<double> step_survey_um;
    int step_survey_size = 0;
    // Whether the survey's tile is the first tile the loop designs (the continuation's first, or
    // the annealed tile), on the same seed: the run then starts from the best step's tile instead
    // of designing that tile again.
    bool step_survey_first_tile = false;
};

// The steps run_design reports through on_step (the survey's, the loops', the anneal's sweeps),
// for a progress bar's total.
long long design_step_count(const PreparedDesign& prepared);

// Estimated peak memory (bytes) of a design with these options (orders of every wavelength, the
// level weights and their optimiser state, the spectra and their gradients).
double estimate_design_bytes(const DesignOptions& options);

// Checks every option (std::invalid_argument / std::domain_error naming the value: contradicting
// constraints, a window, region or view cone reaching outside the visible disk, ranges), builds
// the orders and the target, and refuses (OutOfMemory, memory.h) an estimate above
// options.max_memory_gb, all before any optimisation.
PreparedDesign prepare_design(const DesignOptions& options);

struct DesignResult {
    int size = 0;
    double texel_um = 0.0;
    std::vector<double> heights_um;  // size², row-major, each one of levels_um
    std::vector<int> level;          // each texel's level index
    std::vector<double> levels_um;
    std::vector<double> lambdas_um;
    std::vector<DesignStep> curve;
    std::string metrics_json;        // design.json's content (target, constraints, metrics, timings)
    // Pictures on the window grid about the mirror direction: picture_size² pixels, linear RGB,
    // interleaved; the window's half-width picture_extent (ω units).
    int picture_size = 0;
    double picture_extent = 0.0;
    std::vector<float> target_picture, far_field_picture;
};

// Runs the design: the relaxed optimisation, quantisation onto the levels, discrete refinement,
// then the metrics. on_step gets every step; returning false stops early (the relief so far is
// finished and scored all the same).
DesignResult run_design(const PreparedDesign& prepared, const std::function<bool(const DesignStep&)>& on_step = {});

// Writes the run directory (docs/design.md): design.json, heights.exr (µm, self-describing), heights.x3p
// (where the x3p plugin loads),
// target.exr, far_field.exr, metrics.csv. A new or empty directory, or with `force` one holding
// only a design's outputs (run_directory.h).
void write_design_directory(const std::string& dir, const DesignResult& result, bool force);

}  // namespace wavebrdf
