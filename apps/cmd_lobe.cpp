// wavebrdf lobe: an analytic microfacet lobe (GGX or Beckmann, lobe.h) written as a BRDF table
// file, the format `wavebrdf table` writes (docs/table.md), so it serves wherever a table does.
#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "commands.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"
#include "wavebrdf/lobe.h"
#include "wavebrdf/model.h"
#include "wavebrdf/table.h"

namespace wavebrdf::cli {

namespace {

struct LobeArgs {
    std::string distribution = "ggx";
    double alpha = 0.2;
    double alpha_x = 0.0, alpha_y = 0.0;
    bool given_alpha_x = false, given_alpha_y = false;
    std::string lights = "32x32";
    LobeTableSpec spec;
    double max_memory_gb = 0.0;
    std::string out;
    std::string png;
    bool quiet = false;
};

void run(LobeArgs a) {
    LobeTableSpec& spec = a.spec;
    spec.lobe.distribution = parse_lobe_distribution(a.distribution);
    spec.lobe.alpha_x = a.given_alpha_x ? a.alpha_x : a.alpha;
    spec.lobe.alpha_y = a.given_alpha_y ? a.alpha_y : a.alpha;
    validate(spec.lobe);
    validate_lambda(spec.lambda_um);
    parse_size("--lights", a.lights, spec.lights.rows, spec.lights.cols);
    if (a.out.empty()) throw std::invalid_argument("no output given; expected --out F.exr");
    check_distinct_files({{"--out", a.out}, {"--png", a.png}});
    check_output_format("--out", a.out, {".exr"});
    check_output_format("--png", a.png, {".png"});
    check_writable(a.out);
    if (!a.png.empty()) check_writable(a.png);
    const auto start = std::chrono::steady_clock::now();
    const BrdfTable table = lobe_table(spec, a.max_memory_gb);
    write_brdf_table(a.out, table);
    if (!a.png.empty()) {
        RgbImage image;
        image.rows = spec.lights.rows * spec.resolution;
        image.cols = spec.lights.cols * spec.resolution;
        image.data = table_mosaic(table);
        // With grid lines between the lights' slices and each light row and column labelled.
        write_preview_png(a.png,
                          make_table_preview(image, spec.resolution, table.light_x, table.light_y,
                                             auto_exposure(std::vector<double>(image.data.begin(), image.data.end()))));
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!a.quiet)
        std::fprintf(stderr, "wrote %s: %s, %dx%d lights within sin %g, %dx%d slices, %.3f s\n", a.out.c_str(),
                     table.source.c_str(), spec.lights.rows, spec.lights.cols, spec.lights.max_sin, spec.resolution,
                     spec.resolution, seconds);
}

}  // namespace

void add_lobe_command(CLI::App& app) {
    auto a = std::make_shared<LobeArgs>();
    CLI::App* cmd = app.add_subcommand(
        "lobe", "Write an analytic GGX or Beckmann BRDF lobe as a BRDF table file (docs/table.md, Analytic lobes)");
    cmd->add_option("--distribution", a->distribution, "ggx or beckmann")->capture_default_str();
    cmd->add_option("--alpha", a->alpha, "roughness alpha of an isotropic lobe, 0.001 ... 4")->capture_default_str();
    auto* ax = cmd->add_option("--alpha-x", a->alpha_x, "roughness along x (slice rows), 0.001 ... 4 (default --alpha)");
    auto* ay =
        cmd->add_option("--alpha-y", a->alpha_y, "roughness along y (slice columns), 0.001 ... 4 (default --alpha)");
    cmd->add_option("--fresnel-f0", a->spec.lobe.fresnel_f0,
                    "Schlick's F0, 0 ... 1; 1 (default): no Fresnel, a perfect reflector as the wave-optical models")
        ->capture_default_str();
    cmd->add_option("--lights", a->lights,
                    "light grid RxC (or N), omega_i = max_sin*((a+0.5)/R*2-1, (b+0.5)/C*2-1), as wavebrdf table")
        ->capture_default_str();
    cmd->add_option("--max-light-sin", a->spec.lights.max_sin, "sin theta_i at the light grid's edge, 0 < s < 1")
        ->capture_default_str();
    cmd->add_option("--resolution", a->spec.resolution,
                    "slice size n of each light (n x n pixels; lights * n <= 16384 per side)")
        ->capture_default_str();
    cmd->add_option("--lambda-um", a->spec.lambda_um,
                    "the wavelength recorded in the file, um (the lobe does not depend on it)")
        ->capture_default_str();
    cmd->add_option("--out", a->out, "output EXR: the table mosaic (float RGB, f_r in 1/sr)")->required();
    cmd->add_option("--png", a->png, "tonemapped 8-bit sRGB preview of the mosaic (auto exposure, Reinhard), grid lines, light labels");
    cmd->add_option("--max-memory-gb", a->max_memory_gb,
                    "refuse a table whose estimated memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "no summary");
    cmd->callback([a, ax, ay] {
        a->given_alpha_x = ax->count() > 0;
        a->given_alpha_y = ay->count() > 0;
        run(*a);
    });
}

}  // namespace wavebrdf::cli
