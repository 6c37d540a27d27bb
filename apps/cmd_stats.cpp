// `wavebrdf stats`: the ISO 25178-2 areal parameters of a surface file (surface_stats.h), as
// text or JSON on stdout, optionally after conditioning, and its radial PSD and ACF as CSV.
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "surface_options.h"
#include "wavebrdf/io.h"
#include "wavebrdf/surface_stats.h"
#include "wavebrdf/text.h"

namespace wavebrdf::cli {

namespace {

struct StatsArgs {
    std::string file;
    double spacing_um = 0.0;
    CLI::Option* spacing_option = nullptr;
    double lambda_um = 0.5;
    bool json = false, quiet = false;
    std::string psd, acf;
    ConditioningArgs conditioning;
};

std::string json_string(const std::string& text) {
    std::string out = "\"";
    for (const char ch : text) {
        const auto u = static_cast<unsigned char>(ch);
        if (ch == '"' || ch == '\\') {
            out += '\\';
            out += ch;
        } else if (u < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", u);
            out += buf;
        } else {
            out += ch;
        }
    }
    return out + "\"";
}

std::string json_number(double v) { return std::isfinite(v) ? format_shortest(v) : "null"; }

std::string profile_csv(const RadialProfile& p, const std::string& r_name, const std::string& v_name) {
    std::string text = r_name + "," + v_name + ",count\n";
    for (std::size_t k = 0; k < p.r.size(); ++k)
        text += format_shortest(p.r[k]) + "," + format_shortest(p.value[k]) + "," + std::to_string(p.count[k]) + "\n";
    return text;
}

void run(const StatsArgs& a) {
    validate_lambda(a.lambda_um);
    check_distinct_files({{"FILE", a.file}, {"--psd", a.psd}, {"--acf", a.acf}});
    check_output_format("--psd", a.psd, {".csv"});
    check_output_format("--acf", a.acf, {".csv"});
    if (!a.psd.empty()) check_writable(a.psd);
    if (!a.acf.empty()) check_writable(a.acf);
    const std::optional<double> spacing =
        a.spacing_option->count() > 0 ? std::optional<double>(a.spacing_um) : std::nullopt;
    MeasuredSurface surface = read_surface(a.file, spacing);
    if (any_conditioning(a.conditioning)) surface = condition_and_report(surface, a.conditioning, a.quiet);
    HeightGrid grid;
    grid.rows = surface.rows;
    grid.cols = surface.cols;
    grid.dx_um = surface.dx_um;
    grid.dy_um = surface.dy_um;
    grid.heights_um = surface.heights_um;
    const SurfaceParameters p = surface_parameters(grid);
    const UnitCheck check = check_units(grid, a.lambda_um);
    if (!a.quiet) std::fprintf(stderr, "%s: %s\n", a.file.c_str(), describe(check).c_str());
    for (const std::string& w : check.warnings)
        std::fprintf(stderr, "wavebrdf: warning: %s: %s\n", a.file.c_str(), w.c_str());
    if (!p.acf_decayed_everywhere)
        std::fprintf(stderr,
                     "wavebrdf: note: %s: the ACF stays above 0.2 out to half the surface in some direction; Str "
                     "is an upper bound%s\n",
                     a.file.c_str(), p.acf_decayed_somewhere ? "" : " and Sal a lower bound");
    if (a.json) {
        std::string out = "{\n";
        for (const auto& [name, value] : parameter_list(p)) out += "  " + json_string(name) + ": " + json_number(value) + ",\n";
        out += "  \"acf_decayed_everywhere\": " + std::string(p.acf_decayed_everywhere ? "true" : "false") + ",\n";
        out += "  \"rows\": " + std::to_string(surface.rows) + ",\n  \"cols\": " + std::to_string(surface.cols) + ",\n";
        out += "  \"dx_um\": " + json_number(surface.dx_um) + ",\n  \"dy_um\": " + json_number(surface.dy_um) + ",\n";
        out += "  \"format\": " + json_string(surface.format) + ",\n  \"conditioning\": [";
        bool first = true;
        for (const auto& [key, value] : surface.metadata)
            if (key == "conditioning") {
                out += (first ? "" : ", ") + json_string(value);
                first = false;
            }
        out += "],\n  \"units\": " +
               json_string("lengths (Sa, Sq, Sp, Sv, Sz, Sal, dx_um, dy_um) in um; Sdr in %; Std in degrees from x "
                           "towards y; Ssk, Sku, Sdq, Str dimensionless") +
               "\n}\n";
        std::fputs(out.c_str(), stdout);
    } else {
        const auto unit = [](const std::string& name) -> const char* {
            if (name == "Sdr") return " %";
            if (name == "Std") return " deg";
            if (name == "Ssk" || name == "Sku" || name == "Sdq" || name == "Str") return "";
            return " um";
        };
        std::printf("%s: %dx%d points, spacing %s x %s um (x, y), %s\n", a.file.c_str(), surface.rows, surface.cols,
                    format_shortest(surface.dx_um).c_str(), format_shortest(surface.dy_um).c_str(),
                    surface.format.c_str());
        for (const auto& [name, value] : parameter_list(p))
            std::printf("%-4s %.6g%s\n", name.c_str(), value, unit(name));
    }
    if (!a.psd.empty()) write_text_atomically(a.psd, profile_csv(radial_power_spectrum(grid), "q_per_um", "psd_um4"));
    if (!a.acf.empty()) write_text_atomically(a.acf, profile_csv(radial_autocorrelation(grid), "lag_um", "acf"));
}

}  // namespace

void add_stats_command(CLI::App& app) {
    auto a = std::make_shared<StatsArgs>();
    CLI::App* cmd = app.add_subcommand("stats", "ISO 25178-2 areal parameters, PSD and ACF of a surface file");
    cmd->footer(
        "Parameters over the whole grid as given (the mean removed; condition first for form removal). Definitions: "
        "docs/surfaces.md, \"Parameters\".");
    cmd->add_option("FILE", a->file, "surface file (any format read_surface knows, docs/surfaces.md)")->required();
    a->spacing_option =
        cmd->add_option("--spacing-um", a->spacing_um, "spacing in um for files that carry none (npy, text)");
    cmd->add_flag("--json", a->json, "print the parameters as JSON (keys Sa, Sq, ...; lengths in um)");
    cmd->add_option("--psd", a->psd, "write the radially averaged PSD as CSV (q in rad/um, C in um^4)");
    cmd->add_option("--acf", a->acf, "write the radially averaged ACF as CSV (lag in um)");
    cmd->add_option("--lambda-um", a->lambda_um, "wavelength for the phase rms of the unit check")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "no summary on stderr (warnings still print)");
    add_conditioning_options(cmd, a->conditioning);
    cmd->callback([a] { run(*a); });
}

}  // namespace wavebrdf::cli
