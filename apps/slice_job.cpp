#include "slice_job.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "wavebrdf/io.h"
#include "wavebrdf/preview.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/text.h"

namespace wavebrdf::cli {

void run_slice_job(const Heightfield& heightfield, const Query& query, SliceJob job) {
    if (job.out_exr.empty() && job.png.empty())
        throw std::invalid_argument("no output given; expected --out F.exr and/or --png F.png");
    validate(query);
    validate_resolution(job.resolution);
    if (!job.out_exr.empty()) check_writable(job.out_exr);
    if (!job.png.empty()) check_writable(job.png);
    // make_slice_preview would reject them too, but only after the EXR is written: check up front.
    if (!job.png.empty()) validate_preview_options(job.preview);
    if (!job.png.empty() && job.preview.has_window) {
        try {
            window_pixels(job.preview.window, job.resolution);
        } catch (const std::exception& e) {
            throw std::invalid_argument(std::string("--") + e.what());
        }
    }

    Progress progress("render", work_units(job.resolution) * static_cast<long long>(job.lambdas_um.size()), !job.quiet);
    job.options.progress = &progress;
    const auto start = std::chrono::steady_clock::now();
    RgbImage image;
    image.rows = image.cols = job.resolution;
    std::vector<double> full;  // the double-precision slice, kept for .npy output
    if (job.use_double) {
        full = render_rgb<double>(heightfield, query, job.lambdas_um, job.resolution, job.options);
        image.data.assign(full.begin(), full.end());
    } else {
        image.data = render_rgb<float>(heightfield, query, job.lambdas_um, job.resolution, job.options);
    }
    progress.finish();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (job.clip_negative) {
        for (float& v : image.data) v = std::max(v, 0.0f);
        for (double& v : full) v = std::max(v, 0.0);
    }

    const auto ends_with = [](const std::string& s, const std::string& tail) {
        return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
    };
    if (!job.out_exr.empty() && ends_with(job.out_exr, ".npy")) {
        // NumPy output (n, n, 3) float64, for scripts that have no EXR reader.
        write_npy(job.out_exr, {std::size_t(image.rows), std::size_t(image.cols), 3},
                  job.use_double ? full : std::vector<double>(image.data.begin(), image.data.end()));
    } else if (!job.out_exr.empty()) {
        SliceAttributes attributes;
        attributes.query = query;
        attributes.lambdas_um = job.lambdas_um;
        attributes.resolution = job.resolution;
        attributes.channels = job.lambdas_um.size() == 1 ? 1 : 3;
        attributes.texel_um = heightfield.texel_um();
        attributes.vscale = heightfield.vscale();
        attributes.heightfield_rows = heightfield.rows();
        attributes.heightfield_cols = heightfield.cols();
        attributes.heightfield_file = job.heightfield_file;
        attributes.made_by = job.made_by;
        write_slice_exr(job.out_exr, image, attributes, job.with_alpha);
    }
    if (!job.png.empty()) write_preview_png(job.png, make_slice_preview(image, job.preview));
    if (!job.quiet) {
        float peak = 0.0f;
        for (float v : image.data) peak = std::max(peak, v);
        std::fprintf(stderr, "rendered %dx%d slice, %zu wavelength%s, model %s, peak %.4g, %.3f s\n", job.resolution,
                     job.resolution, job.lambdas_um.size(), job.lambdas_um.size() == 1 ? "" : "s",
                     to_string(query.model), double(peak), seconds);
    }
}

void add_preview_options(CLI::App* cmd, PreviewArgs& args) {
    auto* log = cmd->add_flag("--log", args.log, "preview: log scale (the default), the peak white");
    args.log_decades_option = cmd->add_option("--log-decades", args.log_decades,
                                              "preview, log scale: decades below the peak shown (0-30]")
                                  ->capture_default_str();
    args.exposure_option =
        cmd->add_option("--exposure", args.exposure,
                        "preview: linear scale instead of log, value * 2^exposure clipped to 1 (stops), sRGB curve")
            ->capture_default_str();
    args.reinhard_option = cmd->add_flag("--reinhard", args.reinhard,
                                         "preview: linear scale, Reinhard x/(1+x) before the sRGB curve");
    for (CLI::Option* linear : {args.exposure_option, args.reinhard_option}) {
        linear->excludes(log);
        linear->excludes(args.log_decades_option);
    }
    cmd->add_flag("--false-colour,--false-color", args.false_colour,
                  "preview: the luminance in false colour (viridis) instead of grey/colour");
    auto* bar = cmd->add_flag("--colour-bar,--color-bar", args.colour_bar,
                              "preview: a colour bar with tick labels in 1/sr right of the picture (log: powers of "
                              "ten); the default");
    cmd->add_flag("--no-colour-bar,--no-color-bar", args.no_colour_bar, "preview: no colour bar")->excludes(bar);
    cmd->add_flag("--no-axes", args.no_axes, "preview: no omega axes (a frame with ticks and labels wx, wy)");
    cmd->add_option("--window", args.window,
                    "preview: only the pixels whose omega lies in x0,x1,y0,y1 (each in [-1, 1]), scaled up");
    cmd->add_option("--negative", args.negative,
                    "keep or clip: negative linear sRGB values of a spectral slice (out-of-gamut colours, "
                    "docs/model.md) kept in the outputs, or set to 0")
        ->capture_default_str();
}

bool clip_negative_option(const PreviewArgs& args) {
    if (args.negative == "keep") return false;
    if (args.negative == "clip") return true;
    throw std::invalid_argument("--negative '" + args.negative + "' is unknown; expected keep or clip");
}

PreviewOptions to_preview_options(const PreviewArgs& args) {
    PreviewOptions o;
    const bool linear = args.exposure_option->count() > 0 || args.reinhard_option->count() > 0;
    o.scale = linear ? PreviewScale::Linear : PreviewScale::Log;
    o.log_decades = args.log_decades;
    o.exposure_stops = args.exposure;
    o.reinhard = args.reinhard;
    o.false_colour = args.false_colour;
    o.colour_bar = !args.no_colour_bar;
    o.axes = !args.no_axes;
    if (!args.window.empty()) {
        o.window = parse_omega_window(args.window, "--window");
        o.has_window = true;
    }
    o.unit = k_slice_unit_label;
    if (!(o.log_decades > 0.0 && o.log_decades <= 30.0))
        throw std::domain_error("--log-decades " + format_shortest(o.log_decades) +
                                " is out of range; expected more than 0 and at most 30");
    if (!std::isfinite(o.exposure_stops))
        throw std::domain_error("--exposure " + format_shortest(o.exposure_stops) +
                                " is invalid; expected a finite number of stops");
    return o;
}

}  // namespace wavebrdf::cli
