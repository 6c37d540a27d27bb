#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "slice_job.h"
#include "unit_check.h"
#include "wavebrdf/io.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::cli {

namespace {

struct RenderArgs {
    std::string heightfield;
    double texel_um = 1.0;
    double vscale = 1.0;
    // Whether --texel-um / --vscale were given: when not, the heightfield file's attributes apply.
    bool given_texel = false, given_vscale = false;
    Query query;
    std::string model = "OHS";
    double lambda_um = 0.5;
    int spectral = 0;  // used only when given_spectral
    bool given_spectral = false;
    std::string precision = "float";
    RenderPathArgs path;
    SliceJob job;
    PreviewArgs preview;
};

void run(RenderArgs a) {
    a.query.model = parse_model(a.model);
    apply_render_path_options(a.path, a.job.options);
    if (a.precision != "float" && a.precision != "double")
        throw std::invalid_argument("precision '" + a.precision + "' is unknown; expected float or double");
    a.job.use_double = a.precision == "double";
    // Whether --spectral was given, not its value: --spectral 0 is an error, not "absent".
    if (a.given_spectral) {
        if (a.spectral < 1 || a.spectral > 256)
            throw std::domain_error("--spectral " + std::to_string(a.spectral) +
                                    " is out of range; expected 1 to 256 samples");
        a.job.lambdas_um = spectral_wavelengths_um(a.spectral);
    } else {
        validate_lambda(a.lambda_um);
        a.job.lambdas_um = {a.lambda_um};
    }
    validate(a.query);
    validate_resolution(a.job.resolution);
    a.job.preview = to_preview_options(a.preview);
    a.job.clip_negative = clip_negative_option(a.preview);
    check_distinct_files({{"--heightfield", a.heightfield}, {"--out", a.job.out_exr}, {"--png", a.job.png}});
    check_output_format("--out", a.job.out_exr, {".exr", ".npy"});
    check_output_format("--png", a.job.png, {".png"});
    const HeightfieldScale scale = resolve_scale_with_warnings(a.heightfield, if_given(a.given_texel, a.texel_um),
                                                               if_given(a.given_vscale, a.vscale), "--texel-um",
                                                               "--vscale");
    // One footprint: only its rows are read (bit for bit the slice of the whole file).
    const Heightfield hf = read_heightfield_exr_footprint(a.heightfield, a.query.x_um, a.query.sigma_p_um,
                                                          scale.texel_um, scale.vscale)
                               .heightfield;
    const UnitCheck units = warn_units(hf, a.query, a.job.lambdas_um.front(), a.heightfield);
    a.job.heightfield_file = a.heightfield;
    a.job.made_by = "wavebrdf render";
    run_slice_job(hf, a.query, a.job);
    print_units(units, a.heightfield, a.job.quiet);
}

}  // namespace

void add_render_command(CLI::App& app) {
    auto a = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "Render one BRDF slice of a heightfield (docs/model.md)");
    cmd->footer(k_slice_unit_help);
    cmd->add_option("--heightfield", a->heightfield, "heightfield EXR (R channel, heights in texel widths)")
        ->required();
    auto* texel = cmd->add_option("--texel-um", a->texel_um,
                                  "texel width w in um (default: the heightfield file's, else 1)");
    auto* vscale = cmd->add_option("--vscale", a->vscale, "vertical scale v (default: the heightfield file's, else 1)");
    cmd->add_option("--x-um", a->query.x_um, "footprint centre along x (rows) in um")->capture_default_str();
    cmd->add_option("--y-um", a->query.y_um, "footprint centre along y (columns) in um")->capture_default_str();
    cmd->add_option("--sigma-p-um", a->query.sigma_p_um, "footprint (coherence) size sigma_p in um")
        ->capture_default_str();
    cmd->add_option("--model", a->model, "OHS, GHS, ROHS, RGHS or Kirchhoff")->capture_default_str();
    auto* lambda = cmd->add_option("--lambda-um", a->lambda_um, "single wavelength in um (default 0.5)");
    auto* spectral = cmd->add_option("--spectral", a->spectral,
                                     "N wavelengths over 0.36-0.83 um, CIE 1931 to linear sRGB");
    lambda->excludes(spectral);
    cmd->add_option("--light-x", a->query.omega_i[0], "projected light direction, x")->capture_default_str();
    cmd->add_option("--light-y", a->query.omega_i[1], "projected light direction, y")->capture_default_str();
    cmd->add_option("--resolution", a->job.resolution, "slice size n (n x n pixels, 1-8192)")->capture_default_str();
    cmd->add_option("--out", a->job.out_exr, "output EXR (float RGB, f_r in 1/sr), or .npy (n x n x 3 float64)");
    cmd->add_option("--png", a->job.png, "8-bit preview (default: log scale, --log-decades below the peak)");
    add_preview_options(cmd, a->preview);
    cmd->add_option("--precision", a->precision, "float or double")->capture_default_str();
    add_render_path_options(cmd, a->path);
    cmd->add_option("--prune-tolerance", a->job.options.prune_tolerance,
                    "direct path: pruning error bound relative to the slice peak (0-1e-6)")
        ->capture_default_str();
    cmd->add_option("--max-memory-gb", a->job.options.max_memory_gb,
                    "refuse a render whose estimated peak memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->job.quiet, "no progress bar or summary");
    cmd->callback([a, spectral, texel, vscale] {
        a->given_spectral = spectral->count() > 0;
        a->given_texel = texel->count() > 0;
        a->given_vscale = vscale->count() > 0;
        run(*a);
    });
}

}  // namespace wavebrdf::cli
