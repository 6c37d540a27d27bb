#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "unit_check.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"

namespace wavebrdf::cli {

namespace {

struct HeightfieldArgs {
    std::string type = "isotropic";
    std::string size = "256";
    std::string out;
    std::string png;
    bool no_png = false;
    bool quiet = false;
    bool false_colour = false;
    bool colour_bar = false;
    SurfaceParams params;
};

std::string default_png(const std::string& exr) {
    const auto dot = exr.rfind('.');
    const auto slash = exr.rfind('/');
    if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) return exr.substr(0, dot) + ".png";
    return exr + ".png";
}

void run(const HeightfieldArgs& a) {
    SurfaceParams p = a.params;
    p.type = parse_surface_type(a.type);
    parse_size("--size", a.size, p.rows, p.cols);
    const std::string png = a.no_png ? "" : (a.png.empty() ? default_png(a.out) : a.png);
    // `--out h.png` would have its default preview written over it.
    check_distinct_files({{"--out", a.out}, {a.png.empty() ? "the default preview" : "--png", png}});
    check_output_format("--out", a.out, {".exr"});
    check_output_format(a.png.empty() ? "the default preview" : "--png", png, {".png"});
    check_writable(a.out);
    if (!png.empty()) check_writable(png);
    const Heightfield hf = generate_heightfield(p);
    write_heightfield_exr(a.out, hf, "wavebrdf heightfield: " + describe_surface(p));
    if (!png.empty()) {
        // The grey one-channel preview as before unless a colour option asks for more.
        if (a.false_colour || a.colour_bar)
            write_preview_png(png, make_heightfield_preview(hf, a.false_colour, a.colour_bar));
        else
            write_heightfield_png(png, hf);
    }
    // The summary on stderr like every command's, so stdout stays free for data.
    if (!a.quiet) {
        const HeightStats s = height_stats(hf);
        std::fprintf(stderr, "%s: %s %dx%d, texel %.4g um, rms height %.4g um, range [%.4g, %.4g] um, rms slope %.4g\n",
                     a.out.c_str(), to_string(p.type), hf.rows(), hf.cols(), hf.texel_um(), s.rms_height_um, s.min_um,
                     s.max_um, s.rms_slope);
    }
    // No wavelength here: the phase at render's default, 0.5 um.
    print_units(warn_units(hf, 0.5, a.out), a.out, a.quiet);
}

}  // namespace

void add_heightfield_command(CLI::App& app) {
    auto args = std::make_shared<HeightfieldArgs>();
    CLI::App* cmd = app.add_subcommand("heightfield", "Generate a procedural periodic heightfield (EXR + PNG preview)");
    auto& p = args->params;
    cmd->add_option("--type", args->type, "flat, isotropic, brushed, scratched or grating")->capture_default_str();
    cmd->add_option("--size", args->size, "N or NxM texels (rows x columns)")->capture_default_str();
    cmd->add_option("--seed", p.seed, "random seed")
        ->check(std::function<std::string(const std::string&)>(seed_error))
        ->capture_default_str();
    cmd->add_option("--out", args->out, "output EXR (heights in units of texel width, R channel)")->required();
    cmd->add_option("--png", args->png, "preview PNG (default: the EXR name with .png)");
    cmd->add_flag("--no-png", args->no_png, "do not write a preview");
    cmd->add_flag("--false-colour,--false-color", args->false_colour,
                  "preview: heights in false colour (viridis) instead of grey");
    cmd->add_flag("--colour-bar,--color-bar", args->colour_bar, "preview: append a colour bar labelled in um");
    cmd->add_option("--texel-um", p.texel_um, "texel width w in um")->capture_default_str();
    cmd->add_option("--rms-height-um", p.rms_height_um, "isotropic/brushed: rms height in um")->capture_default_str();
    cmd->add_option("--rms-slope", p.rms_slope,
                    "isotropic/brushed: rms slope per axis (overrides --rms-height-um when > 0)")
        ->capture_default_str();
    cmd->add_option("--correlation-um", p.correlation_um, "correlation length in um")->capture_default_str();
    cmd->add_option("--anisotropy", p.anisotropy, "brushed: correlation along y / along x")->capture_default_str();
    cmd->add_option("--scratches", p.scratch_count, "scratched: number of scratches")->capture_default_str();
    cmd->add_option("--scratch-depth-um", p.scratch_depth_um, "scratched: groove depth in um")->capture_default_str();
    cmd->add_option("--scratch-width-um", p.scratch_width_um, "scratched: groove width in um")->capture_default_str();
    cmd->add_option("--amplitude-um", p.amplitude_um, "grating: amplitude A in um")->capture_default_str();
    cmd->add_option("--period-um", p.period_um, "grating: period in um")->capture_default_str();
    cmd->add_flag("--quiet", args->quiet, "print nothing");
    cmd->callback([args] { run(*args); });
}

}  // namespace wavebrdf::cli
