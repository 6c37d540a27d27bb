// `wavebrdf genbrdf`: the flags of the reference program genBrdf (Yan et al. 2018's public
// release) with their meanings and defaults, so that existing scripts work unchanged.
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "slice_job.h"
#include "unit_check.h"
#include "wavebrdf/io.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/text.h"

namespace wavebrdf::cli {

namespace {

struct GenbrdfArgs {
    std::string input, output;
    double texel = 1.0, vscale = 1.0, mu_x = 0.0, mu_y = 0.0, sigma_p = 10.0;
    std::string method = "Wave", model = "OHS";
    double lambda = 0.5, s = 0.0, t = 0.0;
    int resolution = 256;
    double max_memory_gb = 0.0;  // 0: the physical memory
    bool quiet = false;
    std::string png;
    PreviewArgs preview;
    RenderPathArgs path;
    // Whether -w / -v were given. When not, a heightfield file's own attributes apply (files
    // written by wavebrdf carry them); genBrdf's files carry none and get genBrdf's defaults.
    bool given_texel = false, given_vscale = false;
};

// The steepest light genbrdf takes: tan θ_i = |(s, t)| ≤ 1e6.
constexpr double k_max_tan_theta_i = 1e6;

void run(const GenbrdfArgs& a) {
    if (a.method != "Wave")
        throw std::invalid_argument("method '" + a.method + "' is not supported; expected Wave (-m Wave)");
    Query q;
    q.model = parse_model(a.model);
    q.x_um = a.mu_x;
    q.y_um = a.mu_y;
    q.sigma_p_um = a.sigma_p;
    // genBrdf: ω_i = normalize(s, t, 1).xy. s² + t² + 1 overflowed to inf for -s 1e200 and
    // gave normal incidence; hypot does not overflow, and tan θ_i = |(s, t)| is bounded so that
    // |ω_i| stays below 1 in double (cos θ_i ≥ 1e-6, θ_i ≤ 89.99994°).
    const double tan_theta_i = std::hypot(a.s, a.t);
    if (!std::isfinite(a.s) || !std::isfinite(a.t) || tan_theta_i > k_max_tan_theta_i)
        throw std::domain_error("light direction -s " + format_shortest(a.s) + " -t " + format_shortest(a.t) +
                                " is invalid; expected finite values with sqrt(s^2 + t^2) <= 1e6 "
                                "(the direction (s, t, 1), up to 89.99994 degrees from the normal)");
    const double norm = std::hypot(tan_theta_i, 1.0);
    q.omega_i = {a.s / norm, a.t / norm};
    SliceJob job;
    // -l 0 selects genBrdf's 8-sample spectral mode (with correct CIE weights, see README).
    if (a.lambda == 0.0) {
        job.lambdas_um = spectral_wavelengths_um(8);
    } else {
        validate_lambda(a.lambda);
        job.lambdas_um = {a.lambda};
    }
    job.resolution = a.resolution;
    job.out_exr = a.output;
    job.png = a.png;
    job.preview = to_preview_options(a.preview);
    job.clip_negative = clip_negative_option(a.preview);
    job.with_alpha = true;
    job.quiet = a.quiet;
    job.options.max_memory_gb = a.max_memory_gb;
    apply_render_path_options(a.path, job.options);
    validate(q);
    validate_resolution(job.resolution);
    check_distinct_files({{"-i", a.input}, {"-o", a.output}, {"--png", a.png}});
    check_output_format("-o", a.output, {".exr"});
    check_output_format("--png", a.png, {".png"});
    const HeightfieldScale scale = resolve_scale_with_warnings(a.input, if_given(a.given_texel, a.texel),
                                                               if_given(a.given_vscale, a.vscale), "-w", "-v");
    // One footprint: only its rows are read (bit for bit the slice of the whole file).
    const Heightfield hf =
        read_heightfield_exr_footprint(a.input, q.x_um, q.sigma_p_um, scale.texel_um, scale.vscale).heightfield;
    const UnitCheck units = warn_units(hf, q, job.lambdas_um.front(), a.input);
    job.heightfield_file = a.input;
    job.made_by = "wavebrdf genbrdf";
    run_slice_job(hf, q, job);
    print_units(units, a.input, a.quiet);
}

}  // namespace

void add_genbrdf_command(CLI::App& app) {
    auto a = std::make_shared<GenbrdfArgs>();
    CLI::App* cmd = app.add_subcommand("genbrdf",
                                       "Drop-in for the reference program genBrdf (same flags and defaults)");
    cmd->footer(k_slice_unit_help);
    cmd->add_option("-i", a->input, "heightfield EXR")->required();
    cmd->add_option("-o", a->output, "output EXR (RGBA, f_r in 1/sr)")->required();
    auto* texel = cmd->add_option("-w", a->texel, "texel width in um (default: the file's, else 1)");
    auto* vscale = cmd->add_option("-v", a->vscale, "vertical scale (default: the file's, else 1)");
    cmd->add_option("-x", a->mu_x, "footprint centre x in um")->capture_default_str();
    cmd->add_option("-y", a->mu_y, "footprint centre y in um")->capture_default_str();
    cmd->add_option("-p", a->sigma_p, "footprint sigma_p in um")->capture_default_str();
    cmd->add_option("-m", a->method, "method (only Wave)")->capture_default_str();
    cmd->add_option("-d", a->model, "diffraction model: OHS, GHS, ROHS, RGHS, Kirchhoff")->capture_default_str();
    cmd->add_option("-l", a->lambda, "wavelength in um; 0 = spectral (8 samples)")->capture_default_str();
    cmd->add_option("-s", a->s, "light direction x (with z = 1, normalised)")->capture_default_str();
    cmd->add_option("-t", a->t, "light direction y (with z = 1, normalised)")->capture_default_str();
    cmd->add_option("-r", a->resolution, "output resolution")->capture_default_str();
    cmd->add_option("--max-memory-gb", a->max_memory_gb,
                    "refuse a render whose estimated peak memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    add_render_path_options(cmd, a->path);
    cmd->add_option("--png", a->png, "also an 8-bit preview (default: log scale, --log-decades below the peak)");
    add_preview_options(cmd, a->preview);
    cmd->add_flag("--quiet", a->quiet, "no progress bar or summary");
    cmd->callback([a, texel, vscale] {
        a->given_texel = texel->count() > 0;
        a->given_vscale = vscale->count() > 0;
        run(*a);
    });
}

}  // namespace wavebrdf::cli
