// wavebrdf table: a tabulated BRDF (table.h) of one footprint over a grid of light directions,
// written as one self-describing EXR mosaic (docs/table.md).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "unit_check.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/table.h"

namespace wavebrdf::cli {

namespace {

struct TableArgs {
    std::string heightfield;
    double texel_um = 1.0;
    double vscale = 1.0;
    // Whether --texel-um / --vscale were given: when not, the heightfield file's attributes apply.
    bool given_texel = false, given_vscale = false;
    std::string model = "OHS";
    double lambda_um = 0.5;
    int spectral = 0;  // used only when given_spectral
    bool given_spectral = false;
    std::string precision = "float";
    std::string lights = "32x32";
    TableSpec spec;
    RenderOptions options;
    RenderPathArgs path;
    std::string out;
    std::string png;
    bool quiet = false;
};

// The table on `comm`'s ranks (null: this process alone): every rank checks the options and
// reads the heightfield, renders its block of the lights, rank 0 writes.
void run_on(TableArgs a, const Communicator* comm) {
    const Communicator& ranks = comm ? *comm : serial_communicator();
    TableSpec& spec = a.spec;
    Heightfield hf(1, 1, {0.0});
    UnitCheck units;  // rank 0's, printed after the table
    // The options, checked on every rank alike (a bad one fails every rank, reported once).
    run_agreed(ranks, [&] {
        spec.query.model = parse_model(a.model);
        if (a.precision != "float" && a.precision != "double")
            throw std::invalid_argument("precision '" + a.precision + "' is unknown; expected float or double");
        spec.double_precision = a.precision == "double";
        if (a.given_spectral) {
            if (a.spectral < 1 || a.spectral > 256)
                throw std::domain_error("--spectral " + std::to_string(a.spectral) +
                                        " is out of range; expected 1 to 256 samples");
            spec.lambdas_um = spectral_wavelengths_um(a.spectral);
            spec.spectral = true;
        } else {
            validate_lambda(a.lambda_um);
            spec.lambdas_um = {a.lambda_um};
        }
        parse_size("--lights", a.lights, spec.lights.rows, spec.lights.cols);
        apply_render_path_options(a.path, a.options);
        validate(spec);
        if (a.out.empty()) throw std::invalid_argument("no output given; expected --out F.exr");
        check_distinct_files({{"--heightfield", a.heightfield}, {"--out", a.out}, {"--png", a.png}});
        check_output_format("--out", a.out, {".exr"});
        check_output_format("--png", a.png, {".png"});
        if (ranks.is_root()) {
            check_writable(a.out);
            if (!a.png.empty()) check_writable(a.png);
        }
        const HeightfieldScale scale = resolve_scale_with_warnings(a.heightfield, if_given(a.given_texel, a.texel_um),
                                                                   if_given(a.given_vscale, a.vscale), "--texel-um",
                                                                   "--vscale");
        // Every light of the table shares one footprint: only its rows are read (bit for bit as the whole file).
        hf = read_heightfield_exr_footprint(a.heightfield, spec.query.x_um, spec.query.sigma_p_um, scale.texel_um,
                                            scale.vscale)
                 .heightfield;
        if (ranks.is_root()) units = warn_units(hf, spec.query, spec.lambdas_um.front(), a.heightfield);
        if (!a.png.empty() && ranks.is_root()) {
            // The preview's copies (its mosaic in float, the exposure's in double) on top of the table.
            const double values = 3.0 * spec.lights.rows * spec.lights.cols * double(spec.resolution) * spec.resolution;
            require_memory(estimate_table_bytes(hf, spec, a.options) + 12.0 * values,
                           memory_limit(a.options.max_memory_gb), "table with its --png preview");
        }
    });

    // Split over ranks, the bar is rank 0's own block (the others' run alongside).
    Progress progress("table", table_work_units(spec, ranks), !a.quiet && ranks.is_root());
    a.options.progress = &progress;
    const auto start = std::chrono::steady_clock::now();
    const BrdfTable table = render_brdf_table(hf, spec, a.options, ranks);
    progress.finish();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!ranks.is_root()) return;
    write_brdf_table(a.out, table);
    if (!a.png.empty()) {
        RgbImage image;
        image.rows = spec.lights.rows * spec.resolution;
        image.cols = spec.lights.cols * spec.resolution;
        image.data = table_mosaic(table);
        // Reinhard at the slices' automatic exposure: the specular peaks differ by orders of
        // magnitude from the rest, which a clipped linear preview would lose.
        // With grid lines between the lights' slices and each light row and column labelled.
        write_preview_png(a.png,
                          make_table_preview(image, spec.resolution, table.light_x, table.light_y,
                                             auto_exposure(std::vector<double>(image.data.begin(), image.data.end()))));
    }
    if (!a.quiet) {
        std::size_t lights = 0;
        for (unsigned char r : table.rendered) lights += r;
        std::fprintf(stderr,
                     "rendered %dx%d lights (%zu inside max sin %g) of %dx%d slices, %zu wavelength%s, "
                     "model %s, %.3f s\n",
                     spec.lights.rows, spec.lights.cols, lights, spec.lights.max_sin, spec.resolution, spec.resolution,
                     spec.lambdas_um.size(), spec.lambdas_um.size() == 1 ? "" : "s", to_string(spec.query.model),
                     seconds);
    }
    if (ranks.is_root()) print_units(units, a.heightfield, a.quiet);
}

}  // namespace

void add_table_command(CLI::App& app) {
    auto a = std::make_shared<TableArgs>();
    CLI::App* cmd = app.add_subcommand(
        "table", "Tabulate the BRDF of one footprint over a grid of light directions into one EXR (docs/table.md)");
    cmd->add_option("--heightfield", a->heightfield, "heightfield EXR (R channel, heights in texel widths)")
        ->required();
    auto* texel = cmd->add_option("--texel-um", a->texel_um,
                                  "texel width w in um (default: the heightfield file's, else 1)");
    auto* vscale = cmd->add_option("--vscale", a->vscale, "vertical scale v (default: the heightfield file's, else 1)");
    cmd->add_option("--x-um", a->spec.query.x_um, "footprint centre along x (rows) in um")->capture_default_str();
    cmd->add_option("--y-um", a->spec.query.y_um, "footprint centre along y (columns) in um")->capture_default_str();
    cmd->add_option("--sigma-p-um", a->spec.query.sigma_p_um, "footprint (coherence) size sigma_p in um")
        ->capture_default_str();
    cmd->add_option("--model", a->model, "OHS, GHS, ROHS, RGHS or Kirchhoff")->capture_default_str();
    auto* lambda = cmd->add_option("--lambda-um", a->lambda_um, "single wavelength in um (default 0.5)");
    auto* spectral = cmd->add_option("--spectral", a->spectral,
                                     "N wavelengths over 0.36-0.83 um, CIE 1931 to linear sRGB");
    lambda->excludes(spectral);
    cmd->add_option("--lights", a->lights,
                    "light grid RxC: R values of omega_i,x (tile rows) by C of omega_i,y (tile columns), "
                    "omega_i = max_sin*((a+0.5)/R*2-1, (b+0.5)/C*2-1); lights outside max_sin are 0")
        ->capture_default_str();
    cmd->add_option("--max-light-sin", a->spec.lights.max_sin,
                    "sin theta_i at the light grid's edge (projected radius), 0 < s < 1")
        ->capture_default_str();
    cmd->add_option("--resolution", a->spec.resolution,
                    "slice size n of each light (n x n pixels; lights * n <= 16384 per side)")
        ->capture_default_str();
    cmd->add_option("--out", a->out,
                    "output EXR: a mosaic of the lights' slices (float RGB, f_r in 1/sr) with its axes as "
                    "attributes")
        ->required();
    cmd->add_option("--png", a->png,
                    "tonemapped 8-bit sRGB preview of the mosaic (auto exposure, Reinhard), grid lines, light labels");
    cmd->add_option("--precision", a->precision, "float or double (values are stored as float)")->capture_default_str();
    add_render_path_options(cmd, a->path);
    cmd->add_option("--max-memory-gb", a->options.max_memory_gb,
                    "refuse a table whose estimated peak memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "no progress bar or summary");
    cmd->callback([a, spectral, texel, vscale] {
        a->given_spectral = spectral->count() > 0;
        a->given_texel = texel->count() > 0;
        a->given_vscale = vscale->count() > 0;
        // Under mpiexec the lights are split over the ranks (table.h), errors printed once.
        run_on_world([&](const Communicator& world) { run_on(*a, world.size() > 1 ? &world : nullptr); });
    });
}

}  // namespace wavebrdf::cli
