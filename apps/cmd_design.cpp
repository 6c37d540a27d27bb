// wavebrdf design: a surface relief for a target appearance (docs/design.md). Reads the target,
// runs the library's design (design_run.h), writes the run directory.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "commands.h"
#include "report.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/fabrication.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/text.h"

namespace wavebrdf::cli {

namespace {

struct DesignArgs {
    std::string target = "anti-mirror";
    std::string out;
    std::string region = "annulus:0.1,0.5";
    std::string errors;
    std::string palette;
    std::string start;
    double plate_pixel_um = 0.0;
    std::vector<double> band_um;
    double view_x = 0.0, view_y = 0.0;
    int anneal_sweeps = 0;
    bool given_view = false, given_spectral = false, given_lambda = false, force = false, quiet = false, no_plots = false,
         no_view_survey = false;
    DesignOptions options;
};

// design.json's warnings (a broken limit, a dim colour), each a stderr line, even with --quiet.
void print_warnings(const std::string& metrics_json) {
    for (const auto& w : nlohmann::json::parse(metrics_json).value("warnings", nlohmann::json::array()))
        std::cerr << "design: warning: " << w.get<std::string>() << "\n";
}

// --target image:PICTURE.png --palette …: a plate of palette designs (design_plate.h).
void run_plate_command(const DesignArgs& a) {
    PlateOptions po;
    po.design = a.options;
    po.palette = parse_palette(a.palette);
    po.plate_pixel_um = a.plate_pixel_um;
    const long long pixel_texels = plate_pixel_texels(po.design, po.plate_pixel_um);
    const std::string file = a.target.substr(6);
    if (file.empty()) throw std::invalid_argument("--target '" + a.target + "' names no picture; expected image:PICTURE.png");
    po.picture = read_plate_picture(file, k_max_fabrication_texels / (pixel_texels * pixel_texels));
    const PreparedPlate prepared = prepare_plate(po);
    const DesignOptions& o = po.design;
    if (!a.quiet) {
        std::cerr << "design: plate " << prepared.rows << "x" << prepared.cols << " texels of "
                  << format_shortest(o.texel_um) << " um (picture " << po.picture.rows << "x" << po.picture.cols
                  << ", " << prepared.pixel_texels << " texels a pixel), " << po.palette.size()
                  << " palette entries of " << o.size << "x" << o.size << " tiles; estimated memory "
                  << format_bytes(prepared.estimated_bytes) << "\n";
        for (const std::string& note : prepared.notes) std::cerr << "design: note: " << note << "\n";
    }
    int used = 0;
    for (long long n : prepared.pixels_per_entry) used += n > 0;
    Progress progress("design", used * (o.iterations + o.refine_passes), !a.quiet);
    const PlateResult result = run_plate(prepared, [&](int entry, const DesignStep& s) {
        progress.advance();
        progress.set_message(po.palette[static_cast<std::size_t>(entry)].text + " " + s.phase + " loss " +
                             format_shortest(s.loss));
        return true;
    });
    progress.finish();
    write_plate_directory(a.out, result, a.force);
    print_warnings(result.metrics_json);
    if (!a.quiet) {
        const nlohmann::json j = nlohmann::json::parse(result.metrics_json);
        for (const auto& e : j["entries"]) {
            if (!e.contains("views")) continue;
            std::cerr << "design: " << e["entry"].get<std::string>() << " (" << e["pixels"] << " pixels):";
            for (const auto& v : e["views"]) {
                std::cerr << " Y " << format_shortest(v["luminous_efficiency"].get<double>());
                if (v.contains("delta_uv")) std::cerr << ", delta u'v' " << format_shortest(v["delta_uv"].get<double>());
            }
            std::cerr << "\n";
        }
        std::cerr << "design: wrote " << a.out << " in " << format_shortest(j["timings_s"]["total"].get<double>())
                  << " s\n";
    }
}

// A metric for a summary line: three significant digits.
std::string three_digits(double v) { return wavebrdf::format_number(v, "%.3g"); }

// A number, or a list of them (an iridescent target's per-pair values) as "a, b, c".
std::string three_digits(const nlohmann::json& v) {
    if (!v.is_array()) return three_digits(v.get<double>());
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + three_digits(x.get<double>());
    return s;
}

// --start HEIGHTS.exr: a heightfield (a design's heights.exr, or any EXR in the heightfield
// convention) as heights in µm, its side and texel checked against --size and --texel-um.
std::vector<double> read_start_relief(const std::string& path, const DesignOptions& o) {
    const Heightfield hf = read_heightfield_exr(path);
    if (hf.rows() != o.size || hf.cols() != o.size)
        throw std::invalid_argument("--start " + path + " is " + std::to_string(hf.rows()) + " x " +
                                    std::to_string(hf.cols()) + " texels; expected " + std::to_string(o.size) + " x " +
                                    std::to_string(o.size) + " (--size)");
    if (!(std::abs(hf.texel_um() - o.texel_um) <= 1e-6 * o.texel_um))
        throw std::invalid_argument("--start " + path + " has texels of " + format_shortest(hf.texel_um()) +
                                    " um; expected --texel-um " + format_shortest(o.texel_um));
    return heights_um(hf);
}

void run(DesignArgs a) {
    DesignOptions& o = a.options;
    // Everything checked before any work: the output directory, then the options.
    check_run_directory(RunKind::Design, a.out, a.force);
    if (!a.given_spectral) o.spectral = 0;
    if (!a.band_um.empty()) {
        if (a.band_um.size() != 2) throw std::invalid_argument("--band-um expects two wavelengths A,B in um");
        o.band_um = {a.band_um[0], a.band_um[1]};
    }
    if (a.given_view) o.view = std::array<double, 2>{a.view_x, a.view_y};
    o.region = a.region;
    o.errors = parse_fabrication_errors(a.errors);
    if (a.no_view_survey) o.survey_views = false;
    if (a.target.rfind("image:", 0) == 0) {
        if (!a.start.empty()) throw std::invalid_argument("--start " + a.start + " with --target " + a.target +
                                                          ": a plate's tiles start at random; expected no --start");
        return run_plate_command(a);
    }
    if (!a.palette.empty()) throw std::invalid_argument("--palette goes with --target image:PICTURE.png");
    o.target = parse_design_target(a.target);
    if (o.target.kind == DesignKind::Iridescent && a.given_view)
        throw std::invalid_argument("--view-x/-y with --target " + a.target +
                                    ": an iridescent target's views are its spec's pairs; expected no --view-x/-y");
    if (o.target.kind == DesignKind::Brdf && a.given_lambda)
        throw std::invalid_argument("--lambda-um with --target " + a.target +
                                    ": a brdf target's wavelengths are its table's; expected no --lambda-um");
    if (!a.start.empty()) o.start_heights_um = read_start_relief(a.start, o);
    const PreparedDesign prepared = prepare_design(o);
    if (!a.quiet) {
        std::cerr << "design: " << o.size << "x" << o.size << " texels of " << format_shortest(o.texel_um) << " um, "
                  << (o.min_feature_um != 0.0 ? "grayscale (features >= " + format_shortest(o.min_feature_um) + " um)"
                                              : std::to_string(o.levels) + " levels")
                  << " within " << format_shortest(o.height_range_um) << " um, "
                  << prepared.lambdas_um.size() << " wavelength(s), " << prepared.orders
                  << " propagating orders; estimated memory " << format_bytes(prepared.estimated_bytes) << "\n";
        for (const std::string& note : prepared.notes) std::cerr << "design: note: " << note << "\n";
    }
    Progress progress("design", design_step_count(prepared), !a.quiet);
    const DesignResult result = run_design(prepared, [&](const DesignStep& s) {
        progress.advance();
        progress.set_message(s.phase + " loss " + format_shortest(s.loss));
        return true;
    });
    progress.finish();
    write_design_directory(a.out, result, a.force);
    if (!a.no_plots) draw_report(RunKind::Design, a.out);
    print_warnings(result.metrics_json);
    if (!a.quiet) {
        const nlohmann::json j = nlohmann::json::parse(result.metrics_json);
        if (j.contains("brightness_trade") && j["brightness_trade"]["blocks"].get<int>() > 0) {
            const auto& t = j["brightness_trade"];
            const char* per = t["model_y_before"].is_array() ? " (per pair)" : "";
            std::cerr << "design: Y " << three_digits(t["model_y_before"]) << per << " after the schedule, below "
                      << three_digits(t["y_floor"].get<double>()) << ": " << t["blocks"].get<int>()
                      << " more block(s) with the delta u'v' tolerance raised to "
                      << three_digits(t["tolerance_used"]) << " (--delta-uv-ceiling "
                      << three_digits(t["ceiling"].get<double>()) << ") reached Y "
                      << three_digits(t["model_y_after"]) << " (design.json brightness_trade)\n";
        }
        if (j.contains("mixture_bound")) {
            // A missed colour against what mixtures of the levels can do in this view.
            const auto& e = j["metrics"]["exact"];
            const auto& b = j["mixture_bound"];
            const auto& one = b["one_mixture"];
            const bool missed = e["delta_uv"].get<double>() > 0.04 || e["luminous_efficiency"].get<double>() < 0.05;
            if (missed && !b["reachable_at_target"].get<bool>()) {
                // The simplex's relaxation leaves ~1e-11 where the programme's optimum is 0.
                const double y = b["y_at_target"].get<double>();
                std::cerr << "design: " << o.target.text << " is out of reach for this view as level mixtures: bound Y "
                          << (y < 1e-6 ? std::string("< 1e-6") : three_digits(y)) << " < " << three_digits(b["min_y"].get<double>())
                          << " at its chromaticity";
                if (!b["delta_uv_at_min_y"].is_null())
                    std::cerr << ", delta u'v' >= " << three_digits(b["delta_uv_at_min_y"].get<double>()) << " at Y >= "
                              << three_digits(b["min_y"].get<double>());
                std::cerr << " (one mixture reaches delta u'v' " << three_digits(one["delta_uv"].get<double>()) << " at Y "
                          << three_digits(one["y"].get<double>()) << "; design.json mixture_bound)\n";
            } else if (missed) {
                std::cerr << "design: mixtures of these levels allow Y " << three_digits(b["y_at_target"].get<double>())
                          << " at the target chromaticity in this view (one mixture reaches delta u'v' "
                          << three_digits(one["delta_uv"].get<double>()) << " at Y " << three_digits(one["y"].get<double>())
                          << "): the levels do not rule it out\n";
            }
            if (missed && !b["design_check"]["absolute"]["within"].get<bool>())
                std::cerr << "design: this design's cone light (Y "
                          << three_digits(b["design_check"]["absolute"]["y"].get<double>())
                          << ") exceeds the mixture bound at its own chromaticity (Y "
                          << three_digits(b["design_check"]["absolute"]["bound_y_at_its_chromaticity"].get<double>())
                          << "): the bound does not cover this relief\n";
        }
        if (j.contains("cone_bound") && j["cone_bound"]["out_of_reach_at_target"].get<bool>()) {
            // Out of reach for every relief on these levels in this view, in incident power.
            const auto& c = j["cone_bound"];
            std::cerr << "design: " << o.target.text << " is out of reach for this view: no relief on these levels sends "
                      << "more than Y " << three_digits(c["y_at_target"].get<double>())
                      << " of the incident light into the view cone at its chromaticity, and none Y >= "
                      << three_digits(c["min_y"].get<double>()) << " within delta u'v' "
                      << three_digits(c["delta_uv_ruled_out"].get<double>()) << " of it (design.json cone_bound)\n";
            const auto& share = c["design_check"]["normalised"];
            if (!share["within"].get<bool>())
                std::cerr << "design: as a share of the reflected propagating power this design's cone light is Y "
                          << three_digits(share["y"].get<double>()) << ", above that bound at its chromaticity (Y "
                          << three_digits(share["bound_y_at_its_chromaticity"].get<double>())
                          << "): a share is lifted by the division by the reflected power; the metrics count incident power\n";
        }
        if (o.target.kind == DesignKind::Colour && j.contains("optimal_colour_bound")) {
            const auto& e = j["metrics"]["exact"];
            const auto& b = j["optimal_colour_bound"];
            if (e["delta_uv"].get<double>() > b["delta_uv"].get<double>() || e["luminous_efficiency"].get<double>() < 0.05)
                std::cerr << "design: " << o.target.text << " reached delta u'v' "
                          << three_digits(e["delta_uv"].get<double>()) << " at Y "
                          << three_digits(e["luminous_efficiency"].get<double>())
                          << "; no surface reflects this chromaticity brighter than Y "
                          << three_digits(b["y_at_target"].get<double>()) << " (Y "
                          << three_digits(b["y_within_delta_uv"].get<double>()) << " within delta u'v' "
                          << three_digits(b["delta_uv"].get<double>())
                          << ") under this light: the optimal-colour limit, design.json optimal_colour_bound\n";
        }
        if (o.target.kind == DesignKind::Iridescent && j.contains("optimal_colour_bound")) {
            const auto& pairs = j["metrics"]["exact"]["pairs"];
            const auto& bounds = j["optimal_colour_bound"];
            for (std::size_t q = 0; q < pairs.size() && q < bounds.size(); ++q) {
                const double d = pairs[q]["delta_uv"].get<double>(), y = pairs[q]["luminous_efficiency"].get<double>();
                if (d > bounds[q]["delta_uv"].get<double>() || y < 0.05)
                    std::cerr << "design: pair " << q + 1 << " reached delta u'v' " << three_digits(d) << " at Y "
                              << three_digits(y) << "; no surface reflects its chromaticity brighter than Y "
                              << three_digits(bounds[q]["y_at_target"].get<double>()) << " (Y "
                              << three_digits(bounds[q]["y_within_delta_uv"].get<double>()) << " within delta u'v' "
                              << three_digits(bounds[q]["delta_uv"].get<double>()) << ")\n";
            }
        }
        if (j.contains("view_survey") && !j["view_survey"]["best"].is_null()) {
            const auto& b = j["view_survey"]["best"];
            std::cerr << "design: reachable: from view (" << format_shortest(b["view"][0].get<double>()) << ", "
                      << format_shortest(b["view"][1].get<double>()) << ") a " << j["view_survey"]["size"].get<int>()
                      << "^2 design on these levels reaches delta u'v' " << format_shortest(b["delta_uv"].get<double>())
                      << " at Y " << format_shortest(b["luminous_efficiency"].get<double>())
                      << " (design.json view_survey lists every view tried)\n";
        }
        std::cerr << "design: exact scalar diffraction: " << j["metrics"]["exact"].dump() << "\n"
                  << "design: wrote " << a.out << " in " << format_shortest(j["timings_s"]["total"].get<double>())
                  << " s\n";
    }
}

}  // namespace

void add_design_command(CLI::App& app) {
    auto a = std::make_shared<DesignArgs>();
    CLI::App* cmd = app.add_subcommand("design", "Design a texel relief for a target appearance (docs/design.md)");
    cmd->add_option("--target", a->target, "anti-mirror, pattern:IMAGE.png, colour:#RRGGBB, iridescent:SPEC.json, brdf:TABLE.exr or image:PICTURE.png")
        ->capture_default_str();
    cmd->add_option("--palette", a->palette,
                    "image: the plate's designs, '#RRGGBB;#RRGGBB;...' or 'dir:X,Y;dir:X,Y;...'");
    cmd->add_option("--plate-pixel-um", a->plate_pixel_um,
                    "image: a picture pixel's side on the plate, a multiple of the tile period (default: one period)");
    cmd->add_option("--out", a->out, "run directory (new or empty; see --force)")->required();
    cmd->add_flag("--force", a->force, "reuse a directory holding only a design's outputs");
    cmd->add_option("--light-x", a->options.omega_i[0], "projected light direction, x")->capture_default_str();
    cmd->add_option("--light-y", a->options.omega_i[1], "projected light direction, y")->capture_default_str();
    auto* lambda = cmd->add_option("--lambda-um", a->options.lambda_um, "laser wavelength in um (default 0.5)");
    auto* spectral = cmd->add_option("--spectral", a->options.spectral,
                                     "white light: N equal-energy wavelengths over --band-um");
    lambda->excludes(spectral);
    cmd->add_option("--band-um", a->band_um, "white light's band A,B in um (default 0.36,0.83, the slices')")
        ->delimiter(',')
        ->expected(2);
    cmd->add_option("--specular-cone", a->options.specular_cone, "anti-mirror: sin of the mirror cone's half-angle")
        ->capture_default_str();
    cmd->add_option("--cone-limit", a->options.cone_limit,
                    "anti-mirror: most fraction of the reflected power in the cone at any wavelength")
        ->capture_default_str();
    cmd->add_option("--uniformity-limit", a->options.uniformity_limit,
                    "anti-mirror: most std/mean of the region's 16 bins at any wavelength")
        ->capture_default_str();
    cmd->add_option("--region", a->region, "anti-mirror: annulus:R1,R2 or disk:R about the mirror direction")
        ->capture_default_str();
    cmd->add_option("--window", a->options.window, "pattern: half-width of the window about the mirror direction")
        ->capture_default_str();
    auto* vx = cmd->add_option("--view-x", a->view_x, "colour: projected view direction, x (default: the mirror's)");
    auto* vy = cmd->add_option("--view-y", a->view_y, "colour: projected view direction, y (default: the mirror's)");
    cmd->add_option("--view-cone", a->options.view_cone, "colour, iridescent: sin of the view cone's half-angle")
        ->capture_default_str();
    cmd->add_option("--delta-uv-tolerance", a->options.delta_uv_tolerance,
                    "colour, iridescent (each pair): delta u'v' from the target the loss does not count, traded for "
                    "luminous efficiency")
        ->capture_default_str();
    cmd->add_option("--delta-uv-ceiling", a->options.delta_uv_ceiling,
                    "colour, iridescent (each pair): when the schedule ends below Y 0.05, continue in blocks raising "
                    "the tolerance up to this delta u'v' (0: stop after the schedule)")
        ->capture_default_str();
    cmd->add_option("--size", a->options.size, "N: the N x N periodic tile")->capture_default_str();
    cmd->add_option("--texel-um", a->options.texel_um, "texel width in um")->capture_default_str();
    cmd->add_option("--height-range-um", a->options.height_range_um, "every height within 0..H um")
        ->capture_default_str();
    auto* levels = cmd->add_option("--levels", a->options.levels, "K equally spaced height levels (2-256)")
                       ->capture_default_str();
    cmd->add_option("--level-step-um", a->options.level_step_um,
                    "spacing of the levels in um (default: H/(K-1); anti-mirror: designed, from the best of a survey of the steps on which the mirror order can be kept dark)");
    cmd->add_option("--min-feature-um", a->options.min_feature_um,
                    "grayscale relief: no lateral detail finer than this, um (contradicts --levels)");
    cmd->add_option("--fabrication-error", a->errors, "e.g. scale:5%,blur:0.3um (design for and score under them)");
    cmd->add_option("--seed", a->options.seed, "random start")->capture_default_str();
    cmd->add_option("--start", a->start,
                    "start from this relief (a heights.exr on the run's levels) instead of a random one");
    cmd->add_option("--continuation", a->options.continuation,
                    "design on smaller tiles first, each tiled into the next: auto (anti-mirror, and a colour or an "
                    "iridescent pair half of whose optimal-colour limit is below Y 10 %: from size/2 and its halves "
                    "while the specular or view cone holds an order besides the central one), off, or tile sizes such "
                    "as 64,128 (anti-mirror, colour, iridescent)")
        ->capture_default_str();
    auto* anneal = cmd->add_option(
        "--anneal-sweeps", a->anneal_sweeps,
        "anti-mirror on levels: heat-bath sweeps over the continuation's smallest tile after the loop designed it, "
        "then that tile repeated and scored (default 400 from a random start; 0: none)");
    cmd->add_option("--iterations", a->options.iterations, "relaxed iterations")->capture_default_str();
    cmd->add_option("--refine-passes", a->options.refine_passes, "discrete passes on the levels")
        ->capture_default_str();
    cmd->add_option("--max-memory-gb", a->options.max_memory_gb,
                    "refuse a design whose estimated memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "no progress bar or summary");
    cmd->add_flag("--no-plots", a->no_plots, "do not draw report.png");
    cmd->add_flag("--no-view-survey", a->no_view_survey,
                  "colour: when the colour is missed, do not design it for other views (design.json view_survey)");
    cmd->callback([a, spectral, lambda, vx, vy, levels, anneal] {
        a->given_spectral = spectral->count() > 0;
        if (anneal->count() > 0) a->options.anneal_sweeps = a->anneal_sweeps;
        // A grayscale relief has no levels: --min-feature-um without --levels.
        if (a->options.min_feature_um != 0.0 && levels->count() == 0) a->options.levels = 0;
        a->given_lambda = lambda->count() > 0;
        if ((vx->count() > 0) != (vy->count() > 0))
            throw std::invalid_argument("--view-x and --view-y go together; give both or neither");
        a->given_view = vx->count() > 0;
        run(*a);
    });
}

}  // namespace wavebrdf::cli
